"""Helpers shared by the tests: a small sweep, the result-file assertion of the sweep-store and
fault tests, a command line in a subprocess for the interruption tests, and Python in a fresh
process for the import tests."""

import os
import subprocess
import sys

import numpy as np
import xarray as xr

# A dask scheduler's HTTP endpoints (its metrics, served with the dashboard off too) on a free
# port of the loopback interface: by default they take port 8787 on every interface, which the
# other test process, or anything else on the machine, may hold (dask then warns and moves).
LOCAL_CLUSTER = dict(dashboard_address=None, scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
SCHEDULER_HTTP = ["--no-dashboard", "--dashboard-address", "127.0.0.1:0"]  # ``dask scheduler``'s

# Eight points, solved in well under a second once the kernels are loaded.
SMALL_SWEEP = """\
[grid]
eps = [0.02, 0.05]
L = 10.0
K = [0.5, 5.0]
A = 0.3333333333333333
N = 1.0
"""


def run_python(code: str) -> str:
    """Run ``code`` in a fresh interpreter (matplotlib's Agg backend); its stdout, stripped.
    Fails the test when it exits non-zero."""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=dict(os.environ, MPLBACKEND="Agg"))
    assert proc.returncode == 0, proc.stderr
    return proc.stdout.strip()


def assert_identical(path, ds):
    """The result file at ``path`` holds exactly the variables and values of ``ds`` (NaN = NaN)."""
    with xr.open_dataset(path) as f:
        f.load()
        assert set(f.data_vars) == set(ds.data_vars)
        for v in ds.data_vars:
            assert np.array_equal(f[v].values, ds[v].values, equal_nan=True), v


def start_cli(*argv):
    """``cosserat-channel ARGV`` in a subprocess of this package's sources, with the SIGINT
    disposition a terminal gives it (a shell starts background jobs with SIGINT ignored, and
    Python then installs no KeyboardInterrupt handler: a Ctrl-C test would test nothing)."""
    return _start(["-m", "cosserat_channel.cli", *map(str, argv)])


def start_python(code: str, *argv):
    """``python -c CODE ARGV`` in a subprocess as :func:`start_cli` starts one (a command
    under a harness that marks the moment to interrupt it)."""
    return _start(["-c", code, *map(str, argv)])


def _start(args):
    import signal

    import cosserat_channel

    src = os.path.dirname(os.path.dirname(os.path.abspath(cosserat_channel.__file__)))
    path = [p for p in (src, os.environ.get("PYTHONPATH")) if p]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(path))
    return subprocess.Popen([sys.executable, *args], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=env,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


def wait_until(proc, condition, timeout=600):
    """Poll ``condition()`` until it is true; fail if ``proc`` ends first or time runs out."""
    import time

    import pytest

    deadline = time.monotonic() + timeout
    while not condition():
        if proc.poll() is not None:
            pytest.fail(f"the command ended before the moment to interrupt it: {proc.communicate()}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail("the moment to interrupt the command never came")
        time.sleep(0.05)


def one_error_line(stderr: str) -> str:
    """The one ``error:`` line of a command's stderr; fails on a traceback or any other error."""
    assert "Traceback" not in stderr, stderr
    errors = [line for line in stderr.splitlines() if "error:" in line]
    assert len(errors) == 1, stderr
    return errors[0]


def without_heartbeat(stderr: str, command: str) -> list[str]:
    """The lines of ``stderr`` less ``command``'s progress heartbeat: with stderr not a terminal,
    a long command prints its status as a line of its own once a minute (``Progress``), so a run
    that takes longer than that (a cold kernel cache, a loaded machine) has such lines too."""
    import re

    beat = re.compile(rf"cosserat-channel: {re.escape(command)}: .* \(\d+:\d\d\)")
    return [line for line in stderr.splitlines() if not beat.fullmatch(line)]


def assert_legend_lines_show_their_curves(fig):
    """Every line entry of every legend of ``fig`` is drawn as its curve is: a dashed or dash-dot
    handle at least one period of its pattern long (shorter, it shows a solid dash), and an
    entry labelling a curve of its axes in that curve's colour and line style."""
    from matplotlib.colors import to_rgba
    from matplotlib.lines import Line2D

    legends = [(ax, ax.get_legend()) for ax in fig.axes] + [(None, leg) for leg in fig.legends]
    checked = 0
    for ax, leg in legends:
        if leg is None:
            continue
        length = leg.handlelength * leg.prop.get_size_in_points()
        for handle, text in zip(leg.legend_handles, leg.get_texts()):
            if not isinstance(handle, Line2D) or handle.get_linestyle() in ("-", "None", ""):
                continue
            period = sum(handle._dash_pattern[1] or ())
            assert 0 < period <= length, (text.get_text(), period, length)
            checked += 1
            curves = [] if ax is None else [ln for ln in ax.get_lines()
                                            if ln.get_label() == text.get_text()]
            for ln in curves:
                assert to_rgba(ln.get_color()) == to_rgba(handle.get_color()), text.get_text()
                assert ln.get_linestyle() == handle.get_linestyle(), text.get_text()
    return checked
