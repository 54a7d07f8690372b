"""The command line: output formats, exit codes and one-line errors (in-process, one subprocess)."""

import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys

import pytest

from cosserat_channel import cli
from cosserat_channel.solver.point import solve_point
from support import SMALL_SWEEP, one_error_line, start_python, wait_until, without_heartbeat

# Paper figure 2: eps = 1/30, L = 10, K = 0.5, A = 1/3, N = 1. str() of a float round-trips, so
# the command line sees exactly the floats the API call below gets.
FIG2 = (1 / 30, 10.0, 0.5, 1 / 3, 1.0)
FIG2_ARGS = ["--eps", str(1 / 30), "--L", "10", "--K", "0.5", "--A", str(1 / 3), "--N", "1"]
MATERIAL_ARGS = ["--d-p", "0.002", "--rho-p", "2940", "--phi", "25"]
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _point_args(**override):
    """``point`` arguments for figure 2 with some options replaced (value None drops it)."""
    values = dict(zip(["--eps", "--L", "--K", "--A", "--N"], FIG2_ARGS[1::2]))
    values.update(override)
    args = ["point"]
    for flag, value in values.items():
        if value is not None:
            args += [flag, value]
    return args


@pytest.fixture(scope="module")
def fig2_result():
    """The API's answer for figure 2, to compare the command line against."""
    return solve_point(*FIG2)


def test_json_output_matches_api(capsys, fig2_result):
    """--json prints one JSON object with status ok and the API's Delta."""
    code = cli.main(["point", *FIG2_ARGS, "--json"])
    out, err = capsys.readouterr()
    assert code == 0
    assert err == ""
    data = json.loads(out)
    assert data["status"] == "ok"
    assert data["message"] == fig2_result.status.message
    assert math.isclose(data["Delta"], fig2_result.Delta, rel_tol=1e-9)
    assert out.count("\n") == 1  # exactly one line, one object


def test_table_output_has_status_and_delta(capsys, fig2_result):
    """The table names the status and shows Delta with its unit; no NaN rows for an ok point."""
    code = cli.main(["point", *FIG2_ARGS])
    out, _ = capsys.readouterr()
    assert code == 0
    assert "ok: " + fig2_result.status.message in out
    delta_line = next(line for line in out.splitlines() if line.split()[:1] == ["Delta"])
    assert f"{fig2_result.Delta:.10g}" in delta_line
    assert "particle diameters" in delta_line
    assert "xi_stop" not in out  # NaN for an ok point: skipped
    assert "nan" not in out.lower()
    assert "stage1_accepted=" in out.splitlines()[-1]


def test_material_adds_solids_fraction(capsys):
    """With --d-p --rho-p --phi the JSON carries nu near the paper's 0.6 and stresses in Pa."""
    code = cli.main(["point", *FIG2_ARGS, *MATERIAL_ARGS, "--json"])
    data = json.loads(capsys.readouterr().out)
    assert code == 0
    assert 0.59 <= data["nu"] <= 0.61
    assert data["sigma_xx_wall_Pa"] > 0  # compressive positive


def test_material_table_has_dimensional_units(capsys):
    """The table shows nu and the wall couple stress in Pa m when a material is given."""
    cli.main(["point", *FIG2_ARGS, *MATERIAL_ARGS])
    out = capsys.readouterr().out
    rows = {line.split()[0]: line for line in out.splitlines() if line.startswith("  ")}
    assert "nu" in rows
    assert "Pa m" in rows["m_wall_Pa_m"]
    assert " Pa " in rows["sigma_xx_wall_Pa"]


def test_point_without_solution_is_an_answer(capsys):
    """A point with no solution exits 0, names its status, and reports Delta as null."""
    code = cli.main(_point_args(**{"--eps": "0.4"}) + ["--json"])
    out, err = capsys.readouterr()
    assert code == 0
    assert err == ""
    data = json.loads(out)
    assert data["status"] == "eps_too_large_axis"
    assert data["Delta"] is None


def test_table_skips_nan_outputs_for_non_ok_point(capsys):
    """The table of a point without solution lists no output rows and no NaN."""
    code = cli.main(_point_args(**{"--eps": "0.4"}))
    out = capsys.readouterr().out
    assert code == 0
    assert "eps_too_large_axis" in out
    assert "Delta" not in out
    assert "nan" not in out.lower()


@pytest.mark.parametrize(
    "args, named",
    [
        (_point_args(**{"--eps": "0"}), "eps"),  # eps in (0, 1]
        (_point_args(**{"--eps": "-1"}), "eps"),
        (_point_args(**{"--eps": "nan"}), "eps"),  # must reach check_point, not slip through
        (_point_args(**{"--eps": "inf"}), "eps"),
        (_point_args(**{"--L": "0"}), "L ="),
        (_point_args(**{"--K": "-1"}), "K ="),
        (_point_args(**{"--N": "0"}), "N ="),
        (_point_args() + ["--rtol", "2"], "rtol"),  # rtol in [1e-13, 1)
        (_point_args() + ["--rtol", "0"], "rtol"),
        (_point_args(**{"--eps": "abc"}), "--eps"),  # argparse: not a float
        (_point_args(**{"--A": None}), "--A"),  # argparse: required option missing
        (_point_args() + ["--d-p", "0.002"], "--rho-p, --phi"),  # partial material
        (_point_args() + ["--plot", "/nonexistent/dir/x.png"], "--plot"),  # checked before solving
        (_point_args() + ["--bogus"], "--bogus"),  # unknown option
        ([], "COMMAND"),  # no subcommand
    ],
)
def test_bad_input_is_one_line_exit_2(capsys, args, named):
    """Rejected input exits 2 with one stderr line naming the parameter, and nothing on stdout."""
    code = cli.main(args)
    out, err = capsys.readouterr()
    assert code == 2
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("cosserat-channel: error: ")
    assert named in lines[0]


@pytest.mark.parametrize("args, name", [
    (["boundary", "--A", "5000", "--N", "1"], "A"),
    (["boundary", "--A=-5000", "--N", "1"], "A"),
    (["boundary", "--A", "0", "--N", "1e300"], "N"),
    (["boundary", "--A", "0", "--N", "0"], "N"),
    (["boundary", "--A", "0:5000:3", "--N", "1"], "A"),
    (["phase-plane", "--eps", "0.03", "--L", "10", "--A", "5000", "--N", "1"], "A"),
    (["phase-plane", "--eps", "0.03", "--L", "10", "--A", "0.3", "--N", "1e300"], "N"),
    (["atlas", "--A", "0:5000"], "A"),
    (["atlas", "--N", "0.5:1e300"], "N"),
])
def test_every_command_refuses_what_point_refuses(capsys, tmp_path, monkeypatch, args, name):
    """boundary, phase-plane and atlas check A and N against the ranges of parameters.py, as
    'point' does, before any solve and without writing anything."""
    from cosserat_channel.parameters import PARAMETERS

    monkeypatch.chdir(tmp_path)
    code = cli.main(args + ["-o", str(tmp_path / ("x.png" if args[0] == "phase-plane" else
                                                   "x.nc"))])
    out, err = capsys.readouterr()
    assert (code, out) == (2, "")
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("cosserat-channel: error: "), err
    assert f"{name} = " in lines[0] and PARAMETERS[name].interval in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_help_returns_zero(capsys):
    """--help prints the subcommand's usage and returns 0 instead of raising SystemExit."""
    code = cli.main(["point", "--help"])
    out = capsys.readouterr().out
    assert code == 0
    assert "--eps" in out and "--plot" in out


def test_plot_writes_png_atomically(capsys, tmp_path, fig2_result):
    """--plot writes a PNG, leaves no temporary file, and still prints the JSON."""
    target = tmp_path / "fig2.png"
    code = cli.main(["point", *FIG2_ARGS, "--json", "--plot", str(target)])
    out, err = capsys.readouterr()
    assert code == 0
    assert err == ""
    assert target.read_bytes()[:8] == PNG_SIGNATURE
    assert os.listdir(tmp_path) == ["fig2.png"]
    assert math.isclose(json.loads(out)["Delta"], fig2_result.Delta, rel_tol=1e-9)


def test_plot_of_non_ok_point_writes_nothing(capsys, tmp_path):
    """For a point without solution --plot writes no file, notes why on stderr, and exits 0."""
    target = tmp_path / "none.png"
    code = cli.main(_point_args(**{"--eps": "0.4"}) + ["--plot", str(target)])
    _, err = capsys.readouterr()
    assert code == 0
    assert os.listdir(tmp_path) == []
    assert len(err.splitlines()) == 1
    assert "no profile to plot" in err


def test_plot_unknown_file_type_is_rejected(capsys, tmp_path):
    """A --plot suffix matplotlib cannot write is an input error before any solving."""
    code = cli.main(_point_args() + ["--plot", str(tmp_path / "x.nosuchformat")])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.splitlines()) == 1 and ".nosuchformat" in err
    assert os.listdir(tmp_path) == []


def test_cli_import_is_light():
    """Importing cli pulls in neither numba nor matplotlib (heavy modules load lazily)."""
    code = (
        "import sys, cosserat_channel.cli; "
        "print(sorted(m for m in ('numba', 'matplotlib') if m in sys.modules))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    out = proc.stdout
    assert out.strip() == "[]"


def test_installed_executable_error_is_one_line():
    """The installed console script exits 2 with a single stderr line for --eps nan."""
    exe = shutil.which("cosserat-channel", path=os.path.join(sys.prefix, "bin")) or shutil.which(
        "cosserat-channel"
    )
    assert exe is not None, "cosserat-channel is not installed in this environment"
    proc = subprocess.run(
        [exe, *_point_args(**{"--eps": "nan"})], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("cosserat-channel: error: eps = nan")


# ---------------------------------------------------------------------------------------------
# Outputs never replace inputs; finished results are kept unless --overwrite
# ---------------------------------------------------------------------------------------------


@pytest.fixture()
def small_result(tmp_path):
    toml = tmp_path / "s.toml"
    toml.write_text(SMALL_SWEEP)
    out = tmp_path / "s.nc"
    assert cli.main(["run", str(toml), "-o", str(out)]) == 0
    return toml, out


def test_query_output_onto_its_input_is_refused(capsys, small_result, tmp_path):
    """-o naming the queried file (as given, via ./, or a hard link) exits 2; the file is intact."""
    _, out = small_result
    before = out.read_bytes()
    os.link(out, tmp_path / "link.nc")
    capsys.readouterr()
    for target, fmt in [(str(out), "csv"), (os.path.join(str(tmp_path), ".", "s.nc"), "netcdf"),
                        (str(tmp_path / "link.nc"), "json")]:
        code = cli.main(["query", str(out), "--sel", "K=0.5", "--format", fmt, "-o", target])
        err = capsys.readouterr().err
        assert code == 2 and "input" in err and len(err.splitlines()) == 1
    assert out.read_bytes() == before


def test_run_keeps_a_finished_result_unless_overwrite(capsys, small_result, monkeypatch):
    """The same sweep again: exit 0, a note, nothing computed, the file untouched; --overwrite
    computes it again; a result of another sweep is refused (exit 2) and kept."""
    toml, out = small_result
    before = out.read_bytes()
    capsys.readouterr()
    from cosserat_channel.sweep import engine

    def no_work(*args, **kwargs):
        raise AssertionError("computed although the result is finished")

    with monkeypatch.context() as m:
        m.setattr(engine, "Plan", no_work)
        assert cli.main(["run", str(toml), "-o", str(out)]) == 0
        err = capsys.readouterr().err
        assert "already the finished result" in err and "--overwrite" in err
        other = toml.with_name("other.toml")
        other.write_text(SMALL_SWEEP.replace("K = [0.5, 5.0]", "K = [0.5, 6.0]"))
        assert cli.main(["run", str(other), "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert "another sweep" in err and "--overwrite" in err and len(err.splitlines()) == 1
        assert cli.main(["run", str(toml), "-o", str(toml)]) == 2
        assert "input" in capsys.readouterr().err
    assert out.read_bytes() == before and toml.read_text() == SMALL_SWEEP
    assert cli.main(["run", str(toml), "-o", str(out), "--overwrite"]) == 0
    assert "to compute" in capsys.readouterr().err


def test_boundary_reuses_its_own_file_and_keeps_another(capsys, tmp_path, monkeypatch):
    """boundary -o B.nc: the same arguments reuse B.nc (no tracing), others are refused unless
    --overwrite."""
    from cosserat_channel import regimes

    b = tmp_path / "b.nc"
    def args(n="1", *extra):
        return ["boundary", "--A", "0.3333333333333333", "--N", n, "--coarse", "8", "--trace",
                "-o", str(b),
                *extra]

    assert cli.main(args()) == 0
    first = capsys.readouterr().out
    with monkeypatch.context() as m:
        m.setattr(regimes, "trace_boundary", lambda *a, **k: pytest.fail("traced again"))
        assert cli.main(args()) == 0
        out, err = capsys.readouterr()
        assert out == first and "reused" in err
        assert cli.main(args("2")) == 2
        assert "--overwrite" in capsys.readouterr().err
    assert cli.main(args("2", "--overwrite")) == 0


def test_boundary_draws_from_the_shipped_atlas_and_says_so(capsys, tmp_path, monkeypatch):
    """Without --atlas or --trace, boundary answers from the shipped whole-plane atlas without
    tracing, names it on stderr and in the file (by its name alone), and agrees with a trace to the atlas's
    tolerance; --trace traces; --atlas with --trace is refused in one line."""
    import numpy as np
    import xarray as xr

    from cosserat_channel import regimes

    argv = ["boundary", "--A", "0.3333333333333333,2", "--N", "1.5"]
    with monkeypatch.context() as m:
        m.setattr(regimes, "trace_boundary", lambda *a, **k: pytest.fail("traced"))
        assert cli.main([*argv, "-o", str(tmp_path / "a.nc")]) == 0
    err = capsys.readouterr().err
    assert "shipped atlas" in err and "whole_plane.nc" in err and "tol 1e-08" in err
    assert cli.main([*argv, "--trace", "-o", str(tmp_path / "t.nc")]) == 0
    assert "atlas" not in capsys.readouterr().err
    with xr.open_dataset(tmp_path / "a.nc") as a, xr.open_dataset(tmp_path / "t.nc") as t:
        # The atlas's file name, not where it is on this machine.
        assert a.attrs["atlas"].startswith("shipped atlas whole_plane.nc (tol 1e-08")
        assert np.array_equal(a["edge_kind"].values, t["edge_kind"].values)
        np.testing.assert_allclose(a["eta_max"].values, t["eta_max"].values, rtol=2e-8)
    assert cli.main([*argv, "--trace", "--atlas", str(tmp_path / "a.nc"), "-o",
                     str(tmp_path / "x.nc")]) == 2
    assert "--atlas and --trace" in capsys.readouterr().err
    # The paper's point (eta_min beyond the range there): from the atlas, to its tolerance.
    assert cli.main(["boundary", "--A", "0.3333333333333333", "--N", "1", "-o",
                     str(tmp_path / "p.nc")]) == 0
    assert "shipped atlas" in capsys.readouterr().err
    with xr.open_dataset(tmp_path / "p.nc") as p:
        assert abs(float(p["eta_max"].values[0, 0]) / 3.30886055554 - 1) < 2e-8
    # Just below, where eta_min enters the answered range inside one deepest cell, the atlas
    # states more than its tolerance for it: there boundary traces.
    assert cli.main(["boundary", "--A", "0.3333333333333333", "--N", "0.98", "-o",
                     str(tmp_path / "q.nc")]) == 0
    assert "tracing instead" in capsys.readouterr().err
    with xr.open_dataset(tmp_path / "q.nc") as q:
        assert "atlas" not in q.attrs
        ref = regimes.trace_edge(1 / 3, 0.98)
        assert abs(float(q["eta_max"].values[0, 0]) / ref.eta_max - 1) < 1e-10


@pytest.mark.parametrize("stop, code, word", [(KeyboardInterrupt, 130, "interrupted"),
                                               (cli.common.Terminated, 143, "terminated")])
def test_atlas_stopped_while_tracing_ends_in_one_line_and_writes_nothing(
        capsys, tmp_path, monkeypatch, stop, code, word):
    """Ctrl-C (SIGTERM) while the atlas traces: exit 130 (143) with one line saying that nothing
    was written, and a file already at -o (replaced only once an atlas is whole) as it was."""
    from cosserat_channel import atlas

    def tracing(*args, progress=None, **kwargs):
        progress(1, 3, 25)
        raise stop

    monkeypatch.setattr(atlas, "build_atlas", tracing)
    out = tmp_path / "atlas.nc"
    out.write_bytes(b"an earlier atlas")
    assert cli.main(["atlas", "-o", str(out), "--overwrite", "--workers", "1"]) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"cosserat-channel: error: {word}; nothing written")
    assert out.read_bytes() == b"an earlier atlas"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["atlas.nc"]


# ``cosserat-channel ARGV`` that touches the file MARKER when the first edge starts tracing.
TRACE_HARNESS = """
import pathlib, sys
from cosserat_channel import cli
from cosserat_channel.regimes import trace

marker, real = pathlib.Path(sys.argv[1]), trace.trace_edge

def marked(*args, **kwargs):
    marker.touch()
    return real(*args, **kwargs)

trace.trace_edge = marked
sys.exit(cli.main(sys.argv[2:]))
"""


@pytest.mark.slow
@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"),
                                              (signal.SIGTERM, 143, "terminated")])
def test_boundary_trace_stopped_ends_in_one_line_and_keeps_the_file(tmp_path, sig, code, word):
    """Ctrl-C (SIGTERM) while ``boundary --trace`` traces: exit 130 (143), one line saying that
    nothing was written, and the file at -o as it was."""
    out, marker = tmp_path / "edge.nc", tmp_path / "marker"
    out.write_bytes(b"an earlier edge")
    proc = start_python(TRACE_HARNESS, marker, "boundary", "--trace", "--A=-0.9:0.9:30",
                        "--N", "0.5:2:30", "-o", out, "--overwrite", "--plot", tmp_path / "e.png")
    wait_until(proc, marker.exists)
    proc.send_signal(sig)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == code, stderr
    line = one_error_line(stderr)
    assert line.startswith(f"cosserat-channel: error: {word}; no file written ({out} untouched)")
    assert out.read_bytes() == b"an earlier edge"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["edge.nc", "marker"]


@pytest.mark.parametrize("stop, code, word", [(KeyboardInterrupt, 130, "interrupted"),
                                               (cli.common.Terminated, 143, "terminated")])
def test_a_command_stopped_outside_its_own_handling_ends_in_one_line(capsys, monkeypatch, stop,
                                                                     code, word):
    """Ctrl-C where a command keeps nothing of its own (here: point, while it solves): one line
    and exit 130 (143), no traceback."""
    import cosserat_channel.solver.point as point

    def stopped(*args, **kwargs):
        raise stop

    monkeypatch.setattr(point, "solve_point", stopped)
    assert cli.main(_point_args()) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"cosserat-channel: error: {word}; stopped before")


ATLAS_SMALL = ["atlas", "--A", "0.25:0.5", "--N", "0.8:0.9", "--tol", "1e-3", "--degree", "2",
               "--max-depth", "1", "--workers", "1"]


def _stop_after(monkeypatch, n, stop=KeyboardInterrupt):
    """regimes.trace_edge counting its calls, raising ``stop`` at call ``n + 1`` (never if None)."""
    from cosserat_channel import regimes
    from cosserat_channel.regimes.trace import trace_edge as trace

    calls = [0]

    def counted(*args, **kwargs):
        calls[0] += 1
        if n is not None and calls[0] > n:
            raise stop
        return trace(*args, **kwargs)

    monkeypatch.setattr(regimes, "trace_edge", counted)
    return calls


@pytest.mark.parametrize("stop, code, word", [(KeyboardInterrupt, 130, "interrupted"),
                                               (cli.common.Terminated, 143, "terminated")])
def test_atlas_stopped_keeps_its_traces_and_the_same_command_resumes(
        capsys, tmp_path, monkeypatch, stop, code, word):
    """Ctrl-C (SIGTERM) after some traces: one line, exit 130 (143), the traces kept in
    OUT.nc.partial; the same command resumes from them (a note says how many), traces only the
    rest, writes the atlas an uninterrupted run writes, and removes the partial file."""
    import xarray as xr

    fresh, out = tmp_path / "fresh.nc", tmp_path / "atlas.nc"
    whole = _stop_after(monkeypatch, None)
    assert cli.main([*ATLAS_SMALL, "-o", str(fresh)]) == 0
    n_all = whole[0]
    capsys.readouterr()
    _stop_after(monkeypatch, 7, stop)
    assert cli.main([*ATLAS_SMALL, "-o", str(out)]) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"cosserat-channel: error: {word}; the 7 edges")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["atlas.nc.partial", "fresh.nc"]
    rerun = _stop_after(monkeypatch, None)
    assert cli.main([*ATLAS_SMALL, "-o", str(out)]) == 0
    assert "resuming from the 7 edges traced before" in capsys.readouterr().err
    assert rerun[0] == n_all - 7
    assert sorted(p.name for p in tmp_path.iterdir()) == ["atlas.nc", "fresh.nc"]
    assert xr.load_dataset(out).identical(xr.load_dataset(fresh))


@pytest.mark.parametrize("stop, code, word", [(KeyboardInterrupt, 130, "interrupted"),
                                               (cli.common.Terminated, 143, "terminated")])
def test_atlas_stopped_while_writing_keeps_its_traces(capsys, tmp_path, monkeypatch, stop, code,
                                                      word):
    """Ctrl-C (SIGTERM) while the finished atlas is written: one line, no traceback, no atlas file
    (written whole or not at all), every trace kept in OUT.nc.partial, and the rerun traces
    nothing."""
    from cosserat_channel import atlas

    real = atlas.save_atlas

    def stopped(*args, **kwargs):
        raise stop

    monkeypatch.setattr(atlas, "save_atlas", stopped)
    calls = _stop_after(monkeypatch, None)
    assert cli.main([*ATLAS_SMALL, "-o", str(tmp_path / "a.nc")]) == code
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"cosserat-channel: error: {word}; the "
                                               f"{calls[0]} edges")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.nc.partial"]
    monkeypatch.setattr(atlas, "save_atlas", real)
    rerun = _stop_after(monkeypatch, None)
    assert cli.main([*ATLAS_SMALL, "-o", str(tmp_path / "a.nc")]) == 0
    assert rerun[0] == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.nc"]


@pytest.mark.parametrize("fault, words", [(OSError(28, "No space left on device"),
                                           "could not be kept (cannot write"),
                                          (KeyboardInterrupt(), "stopped again")])
def test_atlas_stopped_while_keeping_its_traces_says_so(capsys, tmp_path, monkeypatch, fault,
                                                         words):
    """A full disk, or a second Ctrl-C, while the traces are written: one line saying they are
    lost, exit 130, nothing left behind."""
    from cosserat_channel import atlas

    def failing(*args):
        raise fault

    monkeypatch.setattr(atlas, "save_traces", failing)
    _stop_after(monkeypatch, 2)
    assert cli.main([*ATLAS_SMALL, "-o", str(tmp_path / "a.nc")]) == 130
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and words in err[0] and "a.nc.partial" in err[0]
    assert list(tmp_path.iterdir()) == []


def test_atlas_refuses_a_partial_file_it_cannot_resume(capsys, tmp_path, monkeypatch):
    """At OUT.nc.partial: another build's traces, a damaged file, a FIFO, a directory, a symbolic
    link: exit 2 in one line naming it, nothing traced, the thing left exactly as it was."""
    out = tmp_path / "atlas.nc"
    partial = tmp_path / "atlas.nc.partial"
    _stop_after(monkeypatch, 3)
    assert cli.main([*ATLAS_SMALL, "--tol", "1e-2", "-o", str(out)]) == 130
    capsys.readouterr()
    other = partial.read_bytes()
    calls = _stop_after(monkeypatch, 0)
    assert cli.main([*ATLAS_SMALL, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "holds the traces of another atlas" in err[0] and "tol" in err[0]
    assert partial.read_bytes() == other
    partial.write_bytes(other[: len(other) // 2])
    assert cli.main([*ATLAS_SMALL, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot be read as the traces" in err[0]
    assert partial.read_bytes() == other[: len(other) // 2]
    partial.unlink()
    for make, what in [(os.mkfifo, "a FIFO"), (os.mkdir, "a directory"),
                       (lambda p: os.symlink(tmp_path / "elsewhere", p), "a symbolic link")]:
        make(partial)
        before = partial.lstat()
        assert cli.main([*ATLAS_SMALL, "-o", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and f"is {what}, not the traces" in err[0] and str(partial) in err[0]
        after = partial.lstat()
        assert (after.st_mode, after.st_ino, after.st_mtime_ns) == (
            before.st_mode, before.st_ino, before.st_mtime_ns)
        if what == "a directory":
            partial.rmdir()
        else:
            partial.unlink()
    assert calls[0] == 0 and not out.exists() and not (tmp_path / "elsewhere").exists()


def test_every_command_keeps_an_existing_file_unless_overwrite(capsys, small_result, tmp_path):
    """query -o (a finished result too), plot -o, point --plot, phase-plane -o, boundary --plot
    and atlas -o/--plot: an existing file (or a symbolic link) is kept, exit 2 in one line
    naming it and --overwrite, before any work; with --overwrite it is replaced."""
    toml, result = small_result
    finished = tmp_path / "fin.nc"
    finished.write_bytes(result.read_bytes())
    old = tmp_path / "old.png"
    old.write_bytes(b"a file of the user's")
    link = tmp_path / "link.png"
    link.symlink_to(tmp_path / "nowhere")
    query = ["query", str(result), "--sel", "K=0.5"]
    plot = ["plot", str(result), "--x", "eps", "--y", "Delta", "--hue", "K"]
    refused = [
        [*query, "--format", "csv", "-o", str(finished)],
        [*query, "--format", "netcdf", "-o", str(finished)],
        [*query, "-o", str(old)],
        [*plot, "-o", str(old)],
        [*plot, "-o", str(link)],
        [*_point_args(), "--plot", str(old)],
        ["phase-plane", *FIG2_ARGS[:4], *FIG2_ARGS[6:], "-o", str(old)],
        ["boundary", "--A", "0.5", "--N", "1", "-o", str(tmp_path / "b.nc"), "--plot", str(old)],
        ["atlas", "--A", "0.25:0.5", "--N", "0.8:0.9", "-o", str(finished)],
        ["atlas", "--A", "0.25:0.5", "--N", "0.8:0.9", "-o", str(tmp_path / "a.nc"), "--plot",
         str(old)],
    ]
    before = {p.name: (p.lstat().st_ino, p.read_bytes() if p.is_file() else None)
              for p in tmp_path.iterdir()}
    capsys.readouterr()
    for argv in refused:
        assert cli.main(argv) == 2, argv
        out, err = capsys.readouterr()
        assert len(err.splitlines()) == 1 and "exists" in err and "--overwrite" in err, err
        assert str(argv[-1]) in err and out == ""
    assert {p.name: (p.lstat().st_ino, p.read_bytes() if p.is_file() else None)
            for p in tmp_path.iterdir()} == before
    assert cli.main([*query, "--format", "csv", "-o", str(finished), "--overwrite"]) == 0
    assert finished.read_text().startswith("eps,")
    assert cli.main([*plot, "-o", str(link), "--overwrite"]) == 0
    assert link.read_bytes()[:8] == PNG_SIGNATURE and not link.is_symlink()


def test_plot_at_matches_exactly_and_names_what_to_fix(capsys, small_result, tmp_path):
    """A varying dimension not fixed: exit 2 with a ready --at example; an off-grid --at names the
    nearest values; --nearest takes them and says so; the example as given works."""
    _, out = small_result
    png = str(tmp_path / "d.png")
    base = ["plot", str(out), "--x", "eps", "--y", "Delta", "-o", png]
    capsys.readouterr()
    assert cli.main(base) == 2
    err = capsys.readouterr().err
    assert "K vary" in err and "--at K=0.5 " in err and "K: 0.5, 5" in err
    assert cli.main(base + ["--at", "K=0.4"]) == 2
    assert "nearest grid value: 0.5;" in capsys.readouterr().err
    assert not os.path.exists(png)
    assert cli.main(base + ["--at", "K=0.4", "--nearest"]) == 0
    assert "took the nearest, K=0.5" in capsys.readouterr().err
    os.unlink(png)
    assert cli.main(base + ["--at", "K=0.5"]) == 0
    assert capsys.readouterr().err == "" and os.path.exists(png)


def test_plot_at_refuses_nan_and_a_dimension_given_twice(capsys, small_result, tmp_path):
    """--at L=nan said "nearest grid value: " with nothing after it; --at N=1,N=1 was taken
    silently (the last won). Both exit 2 in one line, no figure written."""
    _, out = small_result
    png = tmp_path / "d.png"
    base = ["plot", str(out), "--x", "eps", "--y", "Delta", "-o", str(png), "--at"]
    capsys.readouterr()
    for at, words in (("K=nan", "K: the value must be finite; got nan"),
                      ("K=-inf", "K: the value must be finite"),
                      ("K=0.5,K=0.5", "--at K: given twice"),
                      ("K=0.5, K = 5", "--at K: given twice")):
        assert cli.main(base + [at]) == 2, at
        err = capsys.readouterr().err
        assert words in err and err.count("\n") == 1 and "nearest grid value: ;" not in err, err
    for at in ("K=nan", "K=0.5,K=0.5"):  # --nearest does not make them usable
        assert cli.main(base + [at, "--nearest"]) == 2
        capsys.readouterr()
    assert not png.exists()


@pytest.mark.parametrize("flag, value", [("--A", "-1e4"), ("--K", "-1E-3"), ("--N", "-inf"),
                                         ("--eps", "-.5e-2")])
def test_negative_value_after_a_space_says_how_to_give_it(capsys, flag, value):
    """argparse takes '-1e4' for an option ("expected one argument"): the line says to write
    --A=-1e4, and that spelling reaches the parameter check (exit 2 naming the parameter, each
    value here being outside its range)."""
    args = _point_args(**{flag: None})
    assert cli.main(args + [flag, value]) == 2
    err = capsys.readouterr().err
    assert f"expected one argument (a negative value goes after '=': {flag}={value})" in err
    assert err.count("\n") == 1
    assert cli.main(args + [f"{flag}={value}"]) == 2
    err = capsys.readouterr().err
    assert "expected one argument" not in err and flag[2:] in err and err.count("\n") == 1
    assert cli.main(args + [flag, "-x"]) == 2  # not a number: no hint
    assert "goes after '='" not in capsys.readouterr().err


def test_bench_exit_code_says_whether_the_targets_were_met(capsys, tmp_path, monkeypatch):
    """A full report with a missed required target exits 1 (FAIL printed, report written); an
    informative miss or a --quick run exits 0, --quick marking its lines as no verdict."""
    from types import SimpleNamespace

    from cosserat_channel.measure import workprecision
    from cosserat_channel.measure.harness import Verdict

    targets = [Verdict("speed", False, "2x slower"), Verdict("max error", False, "", required=False),
               Verdict("median error", True, "")]
    fake = SimpleNamespace(targets=targets, paths={"md": str(tmp_path / "r.md")})
    monkeypatch.setattr(workprecision, "run", lambda *a, **k: fake)
    assert cli.main(["bench", "-o", str(tmp_path / "r")]) == 1
    out, err = capsys.readouterr()
    assert "FAIL: speed" in out and "1 required target(s)" in err
    assert cli.main(["bench", "--quick", "-o", str(tmp_path / "r")]) == 0
    out, err = capsys.readouterr()
    assert all(line.startswith("quick set, not a verdict: ") for line in out.splitlines()[:3])
    fake.targets = targets[1:]
    assert cli.main(["bench", "-o", str(tmp_path / "r")]) == 0


# ---------------------------------------------------------------------------------------------
# Progress: a live line on a terminal, nothing otherwise
# ---------------------------------------------------------------------------------------------
class _Terminal:
    """A stream that says it is a terminal and records what is written."""

    def __init__(self, tty=True):
        self.tty, self.text = tty, ""

    def isatty(self):
        return self.tty

    def write(self, s):
        self.text += s

    def flush(self):
        pass


class _Clock:
    """Seconds since it was made, for the elapsed time a status line may show: a machine that
    keeps the test from running for a second (a loaded CI host) shows 0:01, not 0:00."""

    def __init__(self):
        import time

        self.t0, self.monotonic = time.monotonic(), time.monotonic

    def shows(self, status: str, text: str) -> bool:
        """Whether ``text`` holds ``status (m:ss)`` with m:ss within the time since then."""
        elapsed = self.monotonic() - self.t0
        return any(60 * int(m) + int(s) <= elapsed
                   for m, s in re.findall(re.escape(status) + r" \((\d+):(\d\d)\)", text))


def test_progress_draws_on_a_terminal_and_clears_its_line():
    """update() redraws one line in place with the elapsed time; exit clears it; line() prints."""
    term, clock = _Terminal(), _Clock()
    with cli.common.Progress("boundary", "tracing", stream=term) as bar:
        bar.update("3/8 edges traced")
        bar.line("a permanent line")
    assert clock.shows("\r\x1b[Kcosserat-channel: boundary: 3/8 edges traced", term.text)
    assert "a permanent line\n" in term.text
    assert term.text.endswith("\r\x1b[K")  # the status line is gone at the end


def test_progress_report_is_the_one_progress_protocol():
    """report(done, total, text): the line every long command shows, from any library callback."""
    term, clock = _Terminal(), _Clock()
    with cli.common.Progress("paper", "solving", stream=term) as bar:
        bar.report(3, 13, "figure5")
        assert bar.text == "3/13 figure5"
        bar.report(7, None, "cells traced")
        assert bar.text == "7 cells traced"
    assert clock.shows("cosserat-channel: paper: 3/13 figure5", term.text)


def test_progress_is_silent_when_not_a_terminal_or_before_its_delay():
    """Redirected stderr: only line() output; within the delay: nothing."""
    pipe = _Terminal(tty=False)
    with cli.common.Progress("bench", "x", stream=pipe) as bar:
        bar.update("running")
        bar.line("kept")
    assert pipe.text == "kept\n"
    term = _Terminal()
    with cli.common.Progress("point", "solving", delay=60.0, stream=term) as bar:
        bar.update("still solving")
    assert term.text == ""


def test_progress_prints_a_heartbeat_line_when_not_a_terminal():
    """Redirected stderr in a long command: the status as lines of their own, one per
    heartbeat, with the text of the latest update and no terminal control codes."""
    import time

    pipe, clock = _Terminal(tty=False), _Clock()
    done = "cosserat-channel: atlas: 3 cells done"
    with cli.common.Progress("atlas", "tracing", stream=pipe, heartbeat=0.05) as bar:
        bar.update("3 cells done")
        # Two beats after the update, however long the machine keeps the beating thread waiting
        # (a fixed sleep counts on it running within the sleep).
        deadline = time.monotonic() + 600
        while pipe.text.count(done) < 2 and time.monotonic() < deadline:
            time.sleep(0.01)
    lines = pipe.text.splitlines()
    assert pipe.text.count(done) >= 2 and "\x1b" not in pipe.text
    # A beat before the update (this thread held back past the first beat) shows the text
    # before it; every beat after it shows the update.
    texts = [line.rsplit(" (", 1)[0] for line in lines]
    first = texts.index(done)
    assert set(texts[:first]) <= {"cosserat-channel: atlas: tracing"} and set(texts[first:]) == {done}
    assert all(clock.shows(text, line) for text, line in zip(texts, lines)), lines


def test_long_commands_report_progress(capsys, tmp_path, monkeypatch):
    """boundary passes its edges to the progress line; with stderr not a terminal the command
    prints nothing on stderr but the heartbeat (a minute's compile on a cold kernel cache)."""
    seen = []
    real = cli.common.Progress.update
    monkeypatch.setattr(cli.common.Progress, "update", lambda self, text: (seen.append(text),
                                                                     real(self, text)))
    code = cli.main(["boundary", "--A", "0,0.5", "--N", "1", "--coarse", "8", "--trace",
                     "-o", str(tmp_path / "b.nc")])
    assert code == 0
    assert without_heartbeat(capsys.readouterr().err, "boundary") == []
    assert seen == ["1/2 edges traced", "2/2 edges traced"]


def test_run_reports_its_blocks_on_the_progress_line(capsys, tmp_path, monkeypatch):
    """run passes the sweep's blocks to the progress line, the run's log lines print above it."""
    seen = []
    real = cli.common.Progress.update
    monkeypatch.setattr(cli.common.Progress, "update", lambda self, text: (seen.append(text),
                                                                     real(self, text)))
    monkeypatch.setattr(cli.common.Progress, "line", lambda self, text: seen.append("line"))
    toml = tmp_path / "s.toml"
    toml.write_text(SMALL_SWEEP)
    assert cli.main(["run", str(toml), "-o", str(tmp_path / "s.nc"), "--block-size", "1"]) == 0
    counts = [text for text in seen if text.endswith(" blocks solved")]
    total = int(counts[0].split()[0].split("/")[1])
    assert counts == [f"{done}/{total} blocks solved" for done in range(total + 1)] and total > 1
    assert "line" in seen


# ---------------------------------------------------------------------------------------------
# Typos, misplaced files and spellings
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("args, named", [
    (["point", "--esp", "0.1", "--L", "10", "--K", "0.5", "--A", "0.3", "--N", "1"],
     "unrecognized option --esp; did you mean --eps?"),
    (_point_args() + ["--jsn"], "unrecognized option --jsn; did you mean --json?"),
    (["--verison"], "did you mean --version?"),
    (["point", "--eps", "0.1", "--l", "10", "--K", "0.5", "--A", "0.3", "--N", "1"],
     "unrecognized option --l; did you mean --L?"),
    (_point_args() + ["--zzzz", "3"], "unrecognized option --zzzz; see 'cosserat-channel point"),
])
def test_unknown_option_is_named_with_the_closest_spelling(capsys, args, named):
    """A mistyped option is named (not the required option it leaves out), with a suggestion."""
    assert cli.main(args) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.splitlines()) == 1 and named in err, err


def test_point_takes_gravity_and_the_closure_constants(capsys):
    """``point`` with a material takes --g, --Lambda, --nu-min ... (the library's material keys):
    the same answer as solve_point with that material, listed in the report; without a material
    they are refused in one line naming them."""
    material = ["--d-p", "0.002", "--rho-p", "2940", "--phi", "25"]
    assert cli.main(_point_args() + material + ["--Lambda", "900", "--g", "9.7", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    ref = solve_point(1 / 30, 10, 0.5, 1 / 3, 1, material={"d_p": 0.002, "rho_p": 2940,
                                                            "phi": 25, "Lambda": 900, "g": 9.7})
    assert data["nu"] == ref.nu and data["sigma_xx_wall_Pa"] == ref.sigma_xx_wall_Pa
    assert cli.main(_point_args() + material + ["--Lambda", "900"]) == 0
    report = capsys.readouterr().out
    assert any(line.split()[:2] == ["Lambda", "900"] for line in report.splitlines()), report
    assert cli.main(_point_args() + ["--g", "9.7", "--nu-max", "0.6"]) == 2
    err = capsys.readouterr().err
    assert "--g, --nu-max: only with a material" in err and len(err.splitlines()) == 1


def test_boundary_without_output_prints_its_table_alone(capsys, tmp_path, monkeypatch):
    """``boundary`` without -o prints the table (here from the shipped atlas) and writes nothing."""
    monkeypatch.chdir(tmp_path)
    assert cli.main(["boundary", "--A", "0.3333333333333333", "--N", "1"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split() == ["A", "N", "eta_max", "kind", "status", "above"]
    assert abs(float(out[1].split()[2]) / 3.30886055554 - 1) < 2e-8
    assert os.listdir(tmp_path) == []


def test_run_of_a_result_file_says_it_is_one(capsys, small_result):
    """``run OUT.nc``: a result is not a sweep file; one line that says so, the file kept."""
    _, out = small_result
    before = out.read_bytes()
    capsys.readouterr()
    assert cli.main(["run", str(out)]) == 2
    err = capsys.readouterr().err
    assert "is a NetCDF file" in err and "info" in err and "UTF-8" not in err
    assert out.read_bytes() == before


def test_plot_unknown_variable_is_quoted_whole(capsys, small_result, tmp_path):
    """The name a user mistyped is shown as typed, quotes on both sides."""
    _, out = small_result
    capsys.readouterr()
    code = cli.main(["plot", str(out), "--x", "eps", "--y", "Delat", "--at", "K=0.5", "-o",
                     str(tmp_path / "d.png")])
    err = capsys.readouterr().err
    assert code == 2 and "got 'Delat'" in err, err


def test_stability_takes_o_output_and_the_older_output_dir():
    """-o/--output as every command; --output-dir still parses, unlisted in --help."""
    parser = cli.build_parser()
    for flag in ("-o", "--output", "--output-dir"):
        assert parser.parse_args(["stability", flag, "d"]).output_dir == "d"
    assert parser.parse_args(["stability"]).output_dir == "stability_report"
    sub = parser._subparsers._group_actions[0].choices["stability"]
    assert "--output-dir" not in sub.format_help() and "--output" in sub.format_help()


def test_example_lists_prints_and_copies_the_shipped_sweeps(capsys, tmp_path):
    """example: the list (sweeps, then fit measurements), one printed, one copied (kept unless
    --overwrite), an unknown name."""
    from cosserat_channel.sweep.spec import example_copy, example_measurements, examples, load_sweep

    shipped, measurements = examples(), example_measurements()
    assert cli.main(["example"]) == 0
    listed = capsys.readouterr().out.splitlines()
    assert [line.split()[0] for line in listed] == [*shipped, *measurements]
    assert "quickstart" in shipped and "fit_profile.csv" in measurements
    assert cli.main(["example", "quickstart"]) == 0
    assert capsys.readouterr().out == shipped["quickstart"]
    target = tmp_path / "q.toml"
    assert cli.main(["example", "quickstart", "-o", str(target)]) == 0
    assert load_sweep(target).size == 576
    target.write_text("# mine\n")
    assert cli.main(["example", "large_5d", "-o", str(target)]) == 2
    assert "--overwrite" in capsys.readouterr().err and target.read_text() == "# mine\n"
    assert cli.main(["example", "large_5d.toml", "-o", str(target), "--overwrite"]) == 0
    assert target.read_text() == example_copy("large_5d", shipped["large_5d"], str(target))
    capsys.readouterr()
    assert cli.main(["example", "nope"]) == 2
    err = capsys.readouterr().err
    assert "quickstart" in err and "fit_profile.csv" in err


def test_example_copy_runs_as_printed_outside_a_clone(capsys, tmp_path, monkeypatch):
    """``example quickstart -o quickstart.toml`` in an empty directory (no demo/, no sweeps/), then
    the command its note prints: the result is written beside it, and the copy's header names
    the copy and its result; only the output path and the header's commands differ from the
    shipped file."""
    from cosserat_channel.sweep.spec import examples

    monkeypatch.chdir(tmp_path)
    assert cli.main(["example", "quickstart", "-o", "mine.toml"]) == 0
    note = capsys.readouterr().err.strip()
    assert note.endswith("run it with: cosserat-channel run mine.toml")
    command = note.rsplit("run it with: ", 1)[1].split()
    assert cli.main(command[1:]) == 0
    assert sorted(os.listdir(tmp_path)) == ["mine.nc", "mine.toml"]
    text = (tmp_path / "mine.toml").read_text()
    assert "demo/" not in text and "sweeps/" not in text
    assert 'path = "mine.nc"' in text and "#   cosserat-channel info mine.nc" in text
    changed = [(a, b) for a, b in zip(examples()["quickstart"].splitlines(), text.splitlines())
               if a != b]
    assert len(changed) == 4 and all("quickstart" in a and "mine" in b for a, b in changed)


def test_example_copies_the_fit_measurements_and_says_how_to_fit_them(capsys, tmp_path,
                                                                       monkeypatch):
    """``example fit_profile -o data.csv`` copies the shipped CSV as it is, the command its note
    prints fits the copy, and ``example fit_table1.csv`` prints the other."""
    from cosserat_channel.sweep.spec import example_measurements

    monkeypatch.chdir(tmp_path)
    assert cli.main(["example", "fit_profile", "-o", "data.csv"]) == 0
    assert (tmp_path / "data.csv").read_text() == example_measurements()["fit_profile.csv"]
    note = capsys.readouterr().err.strip()
    assert note.endswith("fit it with: cosserat-channel fit data.csv --free L,K --fixed A=1/3,N=1")
    assert cli.main(note.rsplit("fit it with: ", 1)[1].split()[1:]) == 0
    assert "L" in capsys.readouterr().out
    assert cli.main(["example", "fit_table1.csv"]) == 0
    assert capsys.readouterr().out == example_measurements()["fit_table1.csv"]


# ---------------------------------------------------------------------------------------------
# Engineers' inputs and exact fractions
# ---------------------------------------------------------------------------------------------
def test_point_takes_exact_fractions(capsys, fig2_result):
    """--eps 1/30 --A 1/3 is figure 2 exactly: the same floats as 1/30 and 1/3 in Python."""
    args = ["point", "--eps", "1/30", "--L", "10", "--K", "1/2", "--A", "1/3", "--N", "1", "--json"]
    assert cli.main(args) == 0
    data = json.loads(capsys.readouterr().out)
    assert (data["eps"], data["A"], data["K"]) == (1 / 30, 1 / 3, 0.5)
    assert data["Delta"] == fig2_result.Delta
    assert cli.main(_point_args(**{"--eps": "1/x"})) == 2
    assert "--eps" in capsys.readouterr().err


def test_point_takes_width_and_wall_friction(capsys):
    """Table 1 as an engineer states it: W = 0.155 m, d_p = 2.29 mm, phi = 30, delta_w = 8
    degrees: the point of eps = d_p/W and N = sin(phi)/tan(delta_w), which the report shows."""
    from cosserat_channel.parameters import N_from_friction

    eps, N = 0.00229 / 0.155, N_from_friction(30, 8)
    base = ["point", "--L", "10", "--K", "0.5", "--A", "1/3", "--W", "0.155", "--d-p", "0.00229",
            "--delta-w", "8", "--phi", "30"]
    assert cli.main(base + ["--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert (data["eps"], data["N"]) == (eps, N) and round(N, 3) == 3.558
    assert data["inputs"] == {"W": 0.155, "d_p": 0.00229, "delta_w": 8.0, "phi": 30.0}
    ref = solve_point(eps, 10, 0.5, 1 / 3, N)
    assert data["Delta"] == ref.Delta and "nu" not in data or data["nu"] is None
    # with rho_p the same inputs are also the material
    assert cli.main(base + ["--rho-p", "1180"]) == 0
    out = capsys.readouterr().out
    assert "(from W and d_p)" in out and "(from delta_w and phi)" in out and "nu " in out
    assert f"{eps:.10g}" in out and f"{N:.10g}" in out


@pytest.mark.parametrize("extra, named", [
    (["--W", "0.155", "--N", "1"], "--W needs --d-p"),
    (["--W", "0.155", "--d-p", "0.002", "--eps", "0.1", "--N", "1"], "--eps and --W both give"),
    (["--W", "0.001", "--d-p", "0.002", "--N", "1"], "eps = d_p/W = 2"),
    (["--eps", "0.05", "--delta-w", "95", "--phi", "30"], "delta_w = 95.0 is outside"),
    (["--eps", "0.05", "--delta-w", "8", "--phi", "30", "--rho-p", "1180"], "missing --d-p"),
    (["--eps", "0.05"], "give --N, or --delta-w with --phi"),
])
def test_physical_inputs_refused_in_one_line(capsys, extra, named):
    assert cli.main(["point", "--L", "10", "--K", "0.5", "--A", "0.3", *extra]) == 2
    out, err = capsys.readouterr()
    assert out == "" and len(err.splitlines()) == 1 and named in err, err


def test_run_compress_option_picks_the_codec(tmp_path, capsys):
    """--compress overrides the sweep's [output] compress (default zlib): the file's filters say
    which codec wrote it."""
    import netCDF4

    toml = tmp_path / "c.toml"
    toml.write_text(SMALL_SWEEP.replace("K = [0.5, 5.0]", "K = {linspace = [0, 5, 3000]}")
                    + '\n[output]\nvariables = ["Delta"]\ncompress = "zstd"\n')
    for option, codec in ([], "zstd"), (["--compress", "zlib"], "zlib"), (["--compress", "none"],
                                                                          None):
        out = tmp_path / f"c-{codec}.nc"
        assert cli.main(["run", str(toml), "-o", str(out), *option]) == 0
        with netCDF4.Dataset(out) as nc:
            filters = nc["Delta"].filters()
        assert filters["fletcher32"]
        assert [k for k in ("zlib", "zstd") if filters[k]] == ([codec] if codec else [])
    assert cli.main(["run", str(toml), "--compress", "gzip"]) == 2
    assert "invalid choice" in capsys.readouterr().err
def test_python_m_runs_the_command_and_importing_main_runs_nothing():
    """``python -m cosserat_channel.cli`` is the command; importing its ``__main__`` (as
    documentation tools do) parses no arguments and exits nothing."""
    from cosserat_channel import __version__

    run = subprocess.run([sys.executable, "-m", "cosserat_channel.cli", "--version"],
                         capture_output=True, text=True)
    assert run.returncode == 0 and __version__ in run.stdout
    imported = subprocess.run([sys.executable, "-c", "import cosserat_channel.cli.__main__; "
                               "print('imported')", "html"], capture_output=True, text=True)
    assert imported.returncode == 0 and imported.stdout == "imported\n", imported.stderr


def test_ctrl_c_inside_llvm_callbacks_waits_until_they_return():
    """Ctrl-C while LLVM calls llvmlite back (Numba loading a kernel) is raised once the main
    thread is out of llvmlite, not inside the callback, where it would be lost and LLVM crash."""
    import time

    inside = {"__name__": "llvmlite.binding.callback", "signal": signal, "time": time}
    exec("def callback():\n"
         "    signal.raise_signal(signal.SIGINT)\n"
         "    end = time.monotonic() + 0.3\n"
         "    while time.monotonic() < end:\n"
         "        pass\n"
         "    return 'returned'\n", inside)
    returned = []
    # The disposition a command starts with (a library that ran earlier in this process may
    # have left its own handler, under which a SIGINT raises nothing at all).
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(KeyboardInterrupt):
            with cli.common.interruptible(term=False):
                returned.append(inside["callback"]())
                # Python code that runs, so that the main thread handles the signal sent again
                # as soon as it comes, whichever thread of the process received it.
                end = time.monotonic() + 30
                while time.monotonic() < end:
                    time.sleep(0.01)
        assert returned == ["returned"]
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    finally:
        signal.signal(signal.SIGINT, previous)


def test_the_command_exits_with_mains_code_and_its_objects_left_to_the_process_end(monkeypatch):
    """The console entry (the installed command, ``python -m cosserat_channel.cli``) exits with
    main's code, having told the collector that what is alive then lives until the end: the
    interpreter's exit does not traverse it again."""
    import gc

    monkeypatch.setattr(cli, "main", lambda: 3)
    before = gc.get_freeze_count()
    try:
        with pytest.raises(SystemExit) as exit_:
            cli.console()
        assert exit_.value.code == 3
        assert gc.get_freeze_count() > before
    finally:
        gc.unfreeze()
