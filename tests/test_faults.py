"""Faults made on purpose: every run ends identical to an uninterrupted one, or with one
line on stderr, a non-zero exit and nothing finished lost.

* kill -9 at several moments: right after the store is opened, after some blocks, while the
  result file is being written (complete but not yet renamed); SIGINT and SIGTERM mid-run;
* an injected write failure standing in for a full disk: the file-size limit (RLIMIT_FSIZE, so
  the write really fails in the C library, as netCDF4/HDF5 see a full disk) on the final NetCDF
  write of ``run`` and of ``query --format netcdf``, and ENOSPC on a block write;
* damaged working-store blocks (flipped bytes, truncated, edited and saved back, swapped, taken
  from another sweep, empty) and a damaged manifest, found on resume or only at assembly;
* a damaged result file (flipped bytes in one variable's chunk);
* every dask.distributed worker lost (and replaced), the scheduler lost, a bad scheduler address;
* bad input.

Subprocess runs pause at a named point of the pipeline through ``HARNESS`` (a wrapper around
``cli.main`` that patches one method), so every kill lands where it is meant to, not by timing.
"""

from __future__ import annotations

import logging
import os
import resource
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from cosserat_channel import cli, solve_point
from cosserat_channel import status as st
from cosserat_channel.parameters import ETA_MIN, ParameterError
from cosserat_channel.sweep import budget, engine, run_sweep, schedulers
from cosserat_channel.sweep.plan import Plan
from cosserat_channel.sweep.spec import SweepError, load_sweep
from cosserat_channel.sweep.store import partial_dir
from support import LOCAL_CLUSTER, SCHEDULER_HTTP, assert_identical, without_heartbeat

# 72 points, 28 integrations (eps L products repeat); with --block-size 4, 7 blocks. About a second.
SWEEP = """\
[grid]
eps = [0.01, 0.02, 0.05]
L = [5.0, 10.0, 20.0]
K = [0.5, 5.0]
A = [0.3333333333333333, 1.0]
N = [1.0, 1.5]
[output]
variables = ["Delta", "slip", "sigma_yx_wall", "xi_stop", "stage1_steps"]
"""
BLOCKS = 7
RUN = ("--workers", "1", "--block-size", "4", "--overwrite")  # out.nc holds an earlier result
SENTINEL = b"an earlier result, to be replaced whole or left alone"

HARNESS = r'''
import errno, os, sys, threading, time
mode, marker, release = sys.argv[1:4]
from cosserat_channel import cli
from cosserat_channel.sweep import store

def pause():
    open(marker, "w").close()
    deadline = time.monotonic() + 60
    while not os.path.exists(release) and time.monotonic() < deadline:
        time.sleep(0.01)

kind, _, n = mode.partition(":")
if kind == "open":
    orig_open = store.WorkStore.open.__func__
    def open_(cls, *a, **k):
        s = orig_open(cls, *a, **k)
        pause()
        return s
    store.WorkStore.open = classmethod(open_)
elif kind in ("block", "enospc"):
    orig_put = store.WorkStore.put
    count = [0]
    lock = threading.Lock()
    def put(self, k, result):
        with lock:
            count[0] += 1
            c = count[0]
        if kind == "enospc" and c > int(n):
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        orig_put(self, k, result)
        if kind == "block" and c == int(n):
            pause()
    store.WorkStore.put = put
elif kind == "publish":
    orig_publish = store.WorkStore.publish
    def publish(self, output, write):
        def slow(path):
            write(path)
            pause()  # the file is complete, not yet renamed onto the output
        orig_publish(self, output, slow)
    store.WorkStore.publish = publish
sys.exit(cli.main(sys.argv[4:]))
'''


@pytest.fixture(scope="module")
def reference():
    """The uninterrupted result, in memory."""
    return run_sweep(load_sweep(_mapping()), workers=1)


def _mapping():
    import tomllib

    return tomllib.loads(SWEEP)


@pytest.fixture
def sweep_file(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SWEEP)
    return path


def harness(tmp_path, mode, *argv, limit=None):
    """Start the CLI under HARNESS in a subprocess; returns (process, marker, release)."""
    script = tmp_path / "harness.py"
    script.write_text(HARNESS)
    marker, release = tmp_path / f"marker-{mode}", tmp_path / f"release-{mode}"
    for f in (marker, release):
        f.unlink(missing_ok=True)

    def limits():
        # A shell starts background jobs with SIGINT ignored, and an ignored disposition survives
        # exec: Python would then install no KeyboardInterrupt handler and the SIGINT test would
        # test nothing. The CLI under test gets the disposition a terminal gives it.
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        if limit is not None:
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    proc = subprocess.Popen(
        [sys.executable, str(script), mode, str(marker), str(release), *map(str, argv)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=limits,
    )
    return proc, marker, release


def wait_for(proc, marker, timeout=120):
    deadline = time.monotonic() + timeout
    while not marker.exists():
        if proc.poll() is not None:
            pytest.fail(f"the run ended before the pause point: {proc.communicate()}")
        if time.monotonic() > deadline:
            proc.kill()
            pytest.fail("the pause point was never reached")
        time.sleep(0.01)


def package_env() -> dict:
    """The environment for a process of its own that imports this package (the one under test,
    whatever the process's working directory)."""
    import cosserat_channel

    src = str(Path(cosserat_channel.__file__).resolve().parents[1])
    return dict(os.environ, PYTHONPATH=os.pathsep.join(
        [src, *filter(None, [os.environ.get("PYTHONPATH")])]))


def one_line_error(stderr: str) -> str:
    errors = [line for line in stderr.splitlines() if "error:" in line]
    assert len(errors) == 1, stderr
    assert "Traceback" not in stderr, stderr
    return errors[0]


def rerun(sweep_file, out, capsys):
    """The same command again, in-process: it must finish and resume what was kept."""
    assert cli.main(["run", str(sweep_file), "-o", str(out), *RUN]) == 0
    return capsys.readouterr().err


# ---------------------------------------------------------------------------------------------
# Signals
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mode, sig", [
    ("open", signal.SIGKILL),  # store and manifest made, nothing computed
    ("block:3", signal.SIGKILL),  # three blocks stored
    ("publish", signal.SIGKILL),  # every block stored, result written under its temporary name
    ("block:5", signal.SIGKILL),
])
def test_kill_at_several_moments_then_rerun_is_identical(tmp_path, sweep_file, reference,
                                                         capsys, mode, sig):
    out = tmp_path / "out.nc"
    out.write_bytes(SENTINEL)
    proc, marker, _ = harness(tmp_path, mode, "run", sweep_file, "-o", out, *RUN)
    wait_for(proc, marker)
    proc.send_signal(sig)
    proc.communicate(timeout=60)
    assert proc.returncode == -sig
    assert out.read_bytes() == SENTINEL  # the old result is untouched
    kept = len(list(Path(partial_dir(out)).glob("block_*.npz")))
    err = rerun(sweep_file, out, capsys)
    assert f"{kept} done before, {BLOCKS - kept} to compute" in err
    assert "WARNING" not in err.upper() and "damaged" not in err
    assert_identical(out, reference)
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.startswith(("marker", "harness"))) \
        == ["out.nc", "s.toml"]


@pytest.mark.parametrize("sig, code, words", [
    (signal.SIGINT, 130, "interrupted;"),
    (signal.SIGTERM, 143, "terminated (SIGTERM);"),  # what batch schedulers send
])
def test_sigint_and_sigterm_are_one_line_and_resume(tmp_path, sweep_file, reference, capsys, sig,
                                                    code, words):
    out = tmp_path / "out.nc"
    proc, marker, release = harness(tmp_path, "block:2", "run", sweep_file, "-o", out, *RUN)
    wait_for(proc, marker)
    proc.send_signal(sig)
    time.sleep(0.2)
    release.touch()  # let the paused worker thread finish so the process can exit
    _, stderr = proc.communicate(timeout=60)
    assert proc.returncode == code, stderr
    line = one_line_error(stderr)
    assert words in line and "run the same command again to resume" in line
    assert not out.exists()
    err = rerun(sweep_file, out, capsys)
    assert "0 done before" not in err
    assert_identical(out, reference)


# ---------------------------------------------------------------------------------------------
# A full disk
# ---------------------------------------------------------------------------------------------
def test_final_write_fails_keeps_blocks_then_resumes(tmp_path, sweep_file, reference, capsys):
    """The file-size limit lets the blocks (a few kB each) through, not the result (~100 kB)."""
    out = tmp_path / "out.nc"
    out.write_bytes(SENTINEL)
    proc, _, _ = harness(tmp_path, "none", "run", sweep_file, "-o", out, *RUN, limit=40_000)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 1
    line = one_line_error(stderr)
    assert "cannot write" in line and "HDF error" in line and "resume" in line
    assert out.read_bytes() == SENTINEL
    assert len(list(Path(partial_dir(out)).glob("block_*.npz"))) == BLOCKS
    assert not list(Path(partial_dir(out)).glob("*.tmp")) and not list(tmp_path.glob(".*.tmp"))
    err = rerun(sweep_file, out, capsys)
    assert f"{BLOCKS} done before, 0 to compute" in err
    assert_identical(out, reference)


def test_block_write_fails_keeps_finished_blocks(tmp_path, sweep_file, reference, capsys):
    out = tmp_path / "out.nc"
    proc, _, _ = harness(tmp_path, "enospc:4", "run", sweep_file, "-o", out, *RUN)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 1
    assert "No space left on device" in one_line_error(stderr)
    assert len(list(Path(partial_dir(out)).glob("block_*.npz"))) == 4
    err = rerun(sweep_file, out, capsys)
    assert f"4 done before, {BLOCKS - 4} to compute" in err
    assert_identical(out, reference)


def test_query_netcdf_write_fails_in_one_line(tmp_path, sweep_file, reference):
    out = tmp_path / "out.nc"
    run_sweep(str(sweep_file), str(out), workers=1)
    sub = tmp_path / "sub.nc"
    proc, _, _ = harness(tmp_path, "none", "query", out, "--format", "netcdf", "-o", sub,
                         limit=20_000)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 1
    line = one_line_error(stderr)
    assert "-o: cannot write" in line and "HDF error" in line
    assert not sub.exists() and not list(tmp_path.glob(".*.tmp"))


# ---------------------------------------------------------------------------------------------
# Damaged working stores
# ---------------------------------------------------------------------------------------------
def leave_store(sweep_file, out, monkeypatch, block_size=4):
    """Run until every block is stored, then stop before the result is assembled."""
    with monkeypatch.context() as m:
        m.setattr(engine, "assemble", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("stop")))
        with pytest.raises(RuntimeError, match="stop"):
            run_sweep(str(sweep_file), str(out), workers=1, block_size=block_size)
    return Path(partial_dir(out))


def flip(path: Path, start: int, n: int = 64) -> None:
    data = bytearray(path.read_bytes())
    for i in range(start, min(start + n, len(data))):
        data[i] ^= 0xA5
    path.write_bytes(bytes(data))


def test_damaged_blocks_are_recomputed_with_a_warning(tmp_path, sweep_file, reference,
                                                      monkeypatch, caplog):
    """Items 2 and 3: each kind of damage is found, warned about and recomputed."""
    out = tmp_path / "out.nc"
    store = leave_store(sweep_file, out, monkeypatch)
    b = [store / f"block_{k:05d}.npz" for k in range(BLOCKS)]
    flip(b[0], len(b[0].read_bytes()) // 2)  # flipped bytes inside the data
    b[1].write_bytes(b[1].read_bytes()[:-100])  # truncated
    z = dict(np.load(b[2]))  # edited and saved back, digest field and all
    z["res"] = z["res"] * 1.5
    with open(b[2], "wb") as f:
        np.savez(f, **z)
    tmp = store / "swap"
    b[3].rename(tmp)  # two blocks swapped
    b[4].rename(b[3])
    tmp.rename(b[4])
    b[5].write_bytes(b"")  # empty
    # a block of another sweep's store, same grid shape and plan, other values
    other = tmp_path / "other.toml"
    other.write_text(SWEEP.replace("K = [0.5, 5.0]", "K = [0.5, 6.0]"))
    other_store = leave_store(other, tmp_path / "other.nc", monkeypatch)
    (other_store / "block_00006.npz").replace(b[6])
    with caplog.at_level(logging.WARNING, logger="cosserat_channel.sweep"):
        run_sweep(str(sweep_file), str(out), workers=1)
    damaged = sorted(int(r.getMessage().split()[1]) for r in caplog.records
                     if "is damaged" in r.getMessage())
    assert damaged == [0, 1, 2, 3, 4, 5, 6]
    assert_identical(out, reference)
    assert not store.exists()


def test_damaged_manifest_is_rewritten_and_good_blocks_reused(tmp_path, sweep_file, reference,
                                                              monkeypatch, capsys):
    out = tmp_path / "out.nc"
    store = leave_store(sweep_file, out, monkeypatch)
    (store / "manifest.json").write_bytes(b"\x00{ not json")
    err = rerun(sweep_file, out, capsys)
    assert "manifest.json" in err and f"{BLOCKS} done before, 0 to compute" in err
    assert_identical(out, reference)


def test_block_damaged_after_the_resume_check_is_recomputed_at_assembly(
        tmp_path, sweep_file, reference, monkeypatch, caplog):
    out = tmp_path / "out.nc"
    store = leave_store(sweep_file, out, monkeypatch)
    original = engine.WorkStore.done

    def done_then_damage(self, blocks):
        finished = original(self, blocks)
        flip(store / "block_00004.npz", 200)
        return finished

    monkeypatch.setattr(engine.WorkStore, "done", done_then_damage)
    with caplog.at_level(logging.WARNING, logger="cosserat_channel.sweep"):
        run_sweep(str(sweep_file), str(out), workers=1)
    assert [r.getMessage().split()[1] for r in caplog.records if "damaged" in r.getMessage()] \
        == ["4"]
    assert_identical(out, reference)


# ---------------------------------------------------------------------------------------------
# A damaged result file
# ---------------------------------------------------------------------------------------------
def test_damaged_result_file_fails_to_read_never_changes(tmp_path, sweep_file, capsys):
    out = tmp_path / "out.nc"
    ds = run_sweep(str(sweep_file), str(out), workers=1)
    raw = out.read_bytes()
    chunk = np.ascontiguousarray(ds["sigma_yx_wall"].values).tobytes()  # stored uncompressed
    at = raw.find(chunk)
    assert at > 0
    bad = tmp_path / "bad.nc"
    bad.write_bytes(raw)
    flip(bad, at + 8, 64)
    with xr.open_dataset(bad) as f:
        with pytest.raises(RuntimeError, match="HDF error"):
            f["sigma_yx_wall"].values  # noqa: B018 (reading the values is the test)
        assert np.array_equal(f["Delta"].values, ds["Delta"].values, equal_nan=True)
    for argv in (["query", str(bad)], ["query", str(bad), "--where", "sigma_yx_wall < 0"],
                 ["query", str(bad), "--format", "netcdf", "-o", str(tmp_path / "sub.nc")],
                 ["plot", str(bad), "--x", "eps", "--y", "sigma_yx_wall", "-o",
                  str(tmp_path / "p.png")]):
        assert cli.main(argv) == 1, argv
        line = one_line_error(capsys.readouterr().err)
        assert "damaged" in line and "sigma_yx_wall" in line
    assert not (tmp_path / "sub.nc").exists() and not (tmp_path / "p.png").exists()
    assert not list(tmp_path.glob(".*.tmp"))


@pytest.fixture(scope="module")
def result_file(tmp_path_factory):
    """A finished result of SWEEP, to copy and damage."""
    path = tmp_path_factory.mktemp("result") / "out.nc"
    path.with_suffix(".toml").write_text(SWEEP)
    run_sweep(str(path.with_suffix(".toml")), str(path), workers=1).close()
    return path


def copy_of(result_file, tmp_path, name="r.nc") -> Path:
    path = tmp_path / name
    path.write_bytes(result_file.read_bytes())
    return path


def damaged_chunk(result_file, tmp_path, name="sigma_yx_wall") -> Path:
    """A copy of the result with bytes flipped inside the (uncompressed) chunk of ``name``."""
    path = copy_of(result_file, tmp_path, "bad.nc")
    with xr.open_dataset(result_file) as f:
        chunk = np.ascontiguousarray(f[name].values).tobytes()
    at = path.read_bytes().find(chunk)
    assert at > 0
    flip(path, at + 8, 64)
    return path


def test_info_reads_what_it_describes(tmp_path, result_file, monkeypatch, capsys):
    """info read only 'status', and called a file with a damaged variable healthy. It now reads
    the variables through (up to CHECK_BYTES of values, saying which it did not read)."""
    from cosserat_channel.results import describe

    assert cli.main(["info", str(result_file)]) == 0
    assert "checked  every variable read through without error" in capsys.readouterr().out
    bad = damaged_chunk(result_file, tmp_path)
    assert cli.main(["info", str(bad)]) == 1
    line = one_line_error(capsys.readouterr().err)
    assert "damaged" in line and "'sigma_yx_wall'" in line
    # With a budget too small for the damaged variable, info says that it did not read it.
    monkeypatch.setattr(describe, "CHECK_BYTES", 600)
    assert cli.main(["info", str(bad)]) == 0
    out = capsys.readouterr().out
    checked = next(line for line in out.splitlines() if line.startswith("checked"))
    assert "all but" in checked and "sigma_yx_wall" in checked and "--check-all" in checked
    assert cli.main(["info", str(bad), "--check-all"]) == 1
    assert "'sigma_yx_wall'" in one_line_error(capsys.readouterr().err)


def test_info_escapes_control_characters_from_the_file(tmp_path, result_file, capsys):
    """Attribute text went to the terminal raw: escape sequences in a file (a title change, a
    cleared screen, a bell) acted on it. They are shown escaped."""
    import netCDF4

    path = copy_of(result_file, tmp_path)
    evil = "\x1b]0;owned\x07\x1b[2J\r\u202e"
    with netCDF4.Dataset(path, "a") as nc:
        nc["Delta"].description = "shear layer" + evil  # what info shows of a variable
        nc["eps"].units = "1" + evil
        nc.created = "2026" + evil
        nc.sweep_toml = nc.sweep_toml + "\n# " + evil
    assert cli.main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert not any(c in out for c in "\x1b\x07\r\u202e")
    assert "shear layer\\x1b]0;owned\\x07\\x1b[2J\\r\\u202e" in out
    assert out.count("owned") == 4  # every attribute shown, escaped


def test_damaged_global_attributes_are_one_line(tmp_path, result_file, capsys):
    """A bit flipped in the global attributes made netCDF4 raise AttributeError ("Can't open HDF5
    attribute"), a traceback out of info, query and plot."""
    import netCDF4

    raw = result_file.read_bytes()
    at = raw.find(b"Conventions")  # the attribute messages of the root group lie around it
    bad = tmp_path / "bad.nc"
    found = []
    for start in range(max(0, at - 128), at + 32, 4):
        data = bytearray(raw)
        for i in range(start, start + 4):
            data[i] ^= 0xFF
        bad.write_bytes(bytes(data))
        try:
            with netCDF4.Dataset(bad) as nc:
                nc.ncattrs()
        except AttributeError:
            found.append(start)
            break
        except (OSError, RuntimeError):
            pass
    if not found:
        pytest.skip("no flip near the global attributes gives AttributeError in this HDF5")
    for argv in (["info", str(bad)], ["query", str(bad)], ["query", str(bad), "--sel", "L=10"],
                 ["plot", str(bad), "--x", "eps", "--y", "Delta", "--at",
                  "L=10,K=0.5,A=1,N=1", "-o", str(tmp_path / "p.png")]):
        assert cli.main(argv) == 2, argv
        assert "damaged" in one_line_error(capsys.readouterr().err)
    assert not (tmp_path / "p.png").exists()


@pytest.mark.parametrize("flag_values", ["abc", np.nan, np.array([0.0, 1.5, 2, 3, 4, 5])])
def test_unusable_status_flags_are_one_line(tmp_path, result_file, capsys, flag_values):
    """status:flag_values a string or NaN: int() raised out of info and query."""
    import netCDF4

    path = copy_of(result_file, tmp_path)
    with netCDF4.Dataset(path, "a") as nc:
        nc["status"].delncattr("flag_values")
        nc["status"].flag_values = flag_values
    for argv in (["info", str(path)], ["query", str(path)],
                 ["query", str(path), "--sel", "L=10", "--where", "status == ok"],
                 ["query", str(path), "--format", "json"],
                 ["plot", str(path), "--x", "eps", "--y", "Delta", "--at", "L=10,K=0.5,A=1,N=1",
                  "-o", str(tmp_path / "p.png")]):
        assert cli.main(argv) == 2, argv
        assert "flag_values" in one_line_error(capsys.readouterr().err)


def test_time_units_on_a_coordinate_give_text_in_json(tmp_path, result_file, capsys):
    """eps:units = "days since ..." makes xarray decode eps as dates, which json.dumps refused
    (TypeError). Dates are written as their text, as CSV and the table do."""
    import json

    import netCDF4

    path = copy_of(result_file, tmp_path)
    with netCDF4.Dataset(path, "a") as nc:
        nc["eps"].units = "days since 2000-01-01"
    assert cli.main(["query", str(path), "--format", "json", "--sel", "L=10"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert len(rows) == 3 * 2 * 2 * 2 and all(r["eps"].startswith("2000-01-01T") for r in rows)
    assert cli.main(["query", str(path), "--format", "csv", "--sel", "L=10"]) == 0
    assert capsys.readouterr().out.count("2000-01-01T") == len(rows)


def write_huge(path: Path, shape, chunks=None) -> None:
    """A file declaring a grid of ``shape`` with its coordinates and no values written."""
    import netCDF4

    with netCDF4.Dataset(path, "w") as nc:
        nc.source = "cosserat-channel run"
        for d, n in zip(("eps", "L", "K", "A", "N"), shape):
            nc.createDimension(d, n)
            nc.createVariable(d, "f8", (d,))[:] = np.linspace(0.01, 0.1, n)
        dims = ("eps", "L", "K", "A", "N")
        nc.createVariable("status", "i1", dims, chunksizes=chunks).setncatts(st.cf_flag_attrs())
        nc.createVariable("Delta", "f8", dims, chunksizes=chunks)


# A command in a process of its own, its libraries imported first; then the growth of its peak
# resident memory while the command runs (KiB) is written to the file named by $GROWTH.
GROWN_BY_THE_COMMAND = """
import os, resource, sys
import dask.array, matplotlib, netCDF4, numpy, xarray
matplotlib.use("Agg")
import matplotlib.pyplot
from cosserat_channel import cli
from cosserat_channel.results import describe, light, selection
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
code = cli.main(sys.argv[1:])
with open(os.environ["GROWTH"], "w") as f:
    f.write(str(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before))
sys.exit(code)
"""


@pytest.mark.parametrize("shape, chunks", [
    ((100_000, 1_000, 10, 10, 10), None),  # 10^11 points, contiguous
    ((10_000, 1_000, 10, 1, 1), None),  # 10^8 points, contiguous: 800 MB in one piece
    ((10_000, 1_000, 10, 10, 1), (10, 10, 10, 10, 1)),  # 10^9 points, in unwritten chunks
])
def test_a_huge_declared_grid_is_refused_before_reading(tmp_path, shape, chunks):
    """An 827 kB file declaring a 10^13-point grid took 5 GB in info and 11 GB in query: the
    declared sizes are checked against the file before anything is read. Under a 3 GB address
    space limit every command answers in one line, and its memory grows by less than 64 MiB
    while it runs (its libraries loaded before): the smallest grid here is 10^8 points, whose
    status alone (one byte a point) is 95 MiB, its Delta 763 MiB. A bound of memory, not of
    time, so that a slow or loaded machine passes as well."""
    path = tmp_path / "huge.nc"
    write_huge(path, shape, chunks)
    assert path.stat().st_size < 1_000_000

    def limits():
        resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))

    growth = tmp_path / "growth"
    for argv in (["info", path], ["query", path], ["query", path, "--sel", "eps=0.01"],
                 ["query", path, "--where", "Delta > 1"],
                 ["plot", path, "--x", "eps", "--y", "Delta", "-o", tmp_path / "p.png"]):
        proc = subprocess.run([sys.executable, "-c", GROWN_BY_THE_COMMAND, *map(str, argv)],
                              capture_output=True, text=True, preexec_fn=limits, timeout=600,
                              env=dict(package_env(), GROWTH=str(growth)))
        assert proc.returncode == 2, (argv, proc.stderr[-2000:])
        line = one_line_error(proc.stderr)
        assert "nothing read" in line, line
        assert int(growth.read_text()) < 64 * 1024, (argv, growth.read_text())
        growth.unlink()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["huge.nc"]


def test_query_closes_the_light_reader_before_rereading(tmp_path, result_file, monkeypatch,
                                                        capsys):
    """A small query reads through netCDF4 alone; when that fails on a damaged file, the file is
    read again through xarray and dask to name the damage. With both handles open, HDF5 once
    ended in SIGBUS: the first is closed before the second opens."""
    from cosserat_channel.results import light, selection

    bad = damaged_chunk(result_file, tmp_path)
    opened, open_at_reopen = [], []
    real_light, real_open = light.open_light, selection.open_results

    def open_light(path):
        f = real_light(path)
        opened.append(f)
        return f

    def open_results(path):
        open_at_reopen.extend(f.nc.isopen() for f in opened if f is not None)
        return real_open(path)

    monkeypatch.setattr(light, "open_light", open_light)
    monkeypatch.setattr(selection, "open_results", open_results)
    assert cli.main(["query", str(bad), "--vars", "sigma_yx_wall"]) == 1
    assert "damaged" in one_line_error(capsys.readouterr().err)
    assert opened and opened[0] is not None  # the light reader was used, and failed
    assert open_at_reopen == [False]


# ---------------------------------------------------------------------------------------------
# A lost worker
# ---------------------------------------------------------------------------------------------
def test_every_worker_lost_gives_identical_result(tmp_path, sweep_file, reference):
    """Every worker process killed (by PID) once the first block is home: the nannies start new
    ones, the tasks (which carry their own inputs) run again there, the result is identical."""
    distributed = pytest.importorskip("dask.distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  **LOCAL_CLUSTER) as cluster, \
            distributed.Client(cluster) as client:
        pids = set(client.run(os.getpid).values())
        out = tmp_path / "out.nc"
        spec = load_sweep(str(sweep_file))
        orig = engine.WorkStore.put
        lost = []

        def put(self, k, result):  # the first block home: kill every worker, which hold others
            orig(self, k, result)
            if not lost:
                for pid in pids:
                    os.kill(pid, signal.SIGKILL)
                lost.append(k)

        engine.WorkStore.put = put
        try:
            run_sweep(spec, str(out), scheduler=client, block_size=1).close()
        finally:
            engine.WorkStore.put = orig
        assert lost
        assert not pids & set(client.run(os.getpid).values())  # the blocks ran on new workers
    assert_identical(out, reference)


def test_lost_scheduler_is_one_line_exit_1_then_rerun_resumes(tmp_path, sweep_file, reference,
                                                              monkeypatch, capsys):
    distributed = pytest.importorskip("dask.distributed")
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True,
                                       **LOCAL_CLUSTER)
    orig = engine.WorkStore.put

    def put(self, k, result):  # the second block home: the scheduler (and its cluster) goes
        orig(self, k, result)
        if len(list(Path(self.directory).glob("block_*.npz"))) == 2:
            cluster.close()

    monkeypatch.setattr(engine.WorkStore, "put", put)
    out = tmp_path / "out.nc"
    try:
        code = cli.main(["run", str(sweep_file), "-o", str(out), "--scheduler",
                         cluster.scheduler_address, *RUN])
    finally:
        cluster.close()
    assert code == 1
    line = one_line_error(capsys.readouterr().err)
    assert "lost the dask scheduler" in line and "rerun the same command to resume" in line
    kept = len(list(Path(partial_dir(out)).glob("block_*.npz")))
    assert 2 <= kept < BLOCKS and not out.exists()
    monkeypatch.setattr(engine.WorkStore, "put", orig)
    err = rerun(sweep_file, out, capsys)
    assert f"{kept} done before" in err
    assert_identical(out, reference)


@pytest.mark.parametrize("address, words", [
    ("foo bar", "is not a dask scheduler address"),
    ("tcp://127.0.0.1:9", "no dask scheduler answers"),  # the discard port: nothing listens
])
def test_bad_scheduler_is_one_line_before_any_store(tmp_path, sweep_file, capsys, address, words):
    # What is timed is the try to connect: dask.distributed is imported first, its import (a
    # second or more, many on a loaded machine) not counted
    pytest.importorskip("dask.distributed")
    out = tmp_path / "out.nc"
    t0 = time.perf_counter()
    assert cli.main(["run", str(sweep_file), "-o", str(out), "--scheduler", address]) == 2
    assert time.perf_counter() - t0 < schedulers.CONNECT_TIMEOUT + 10
    assert words in one_line_error(capsys.readouterr().err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


@pytest.mark.parametrize("address", ["tls://127.0.0.1:9", "ucx://127.0.0.1:9", "inproc://x",
                                     "tcp://[::1"])
def test_unusable_scheduler_address_is_one_line_and_quiet_at_exit(tmp_path, sweep_file, address):
    """tls:// without dask's TLS set-up and ucx:// without UCX raised TypeError (a traceback);
    after any failed connection the half-made client's __del__ printed another at exit, 10 s
    later. In a process of its own: stderr is one line, and the process ends at once after it
    (timed from the line: the interpreter's start and imports, many seconds on a loaded machine,
    are not what is asserted)."""
    script = "import sys; from cosserat_channel import cli; sys.exit(cli.main(sys.argv[1:]))"
    proc = subprocess.Popen([sys.executable, "-c", script, "run", str(sweep_file), "-o",
                             str(tmp_path / "out.nc"), "--scheduler", address],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                            env=package_env())
    watchdog = threading.Timer(120, proc.kill)  # a hang ends in a failure, not in a hung test
    watchdog.start()
    try:
        stderr = proc.stderr.readline()
        t0 = time.perf_counter()  # from the command's line to its exit: the interpreter's end
        stderr += proc.stderr.read()
        proc.wait()
    finally:
        watchdog.cancel()
    assert proc.returncode == 2, stderr
    assert "scheduler:" in one_line_error(stderr)
    assert stderr.count("\n") == 1, stderr
    assert time.perf_counter() - t0 < schedulers.CONNECT_TIMEOUT  # not a wait for the client
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


class SubprocessCluster:
    """A dask scheduler and nanny-managed workers, each a process of its own started here (so
    that the test can kill them like a batch system or a crash does), on the loopback address."""

    def __init__(self, tmp_path, n_workers):
        import json

        env = package_env()
        file = tmp_path / "scheduler.json"
        quiet = dict(stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
        self.scheduler = subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
             "--port", "0", *SCHEDULER_HTTP, "--scheduler-file", str(file)], **quiet)
        self.nannies = []
        try:
            deadline = time.monotonic() + 60
            while not (file.exists() and file.stat().st_size):
                assert time.monotonic() < deadline, "the scheduler did not start"
                time.sleep(0.1)
            self.address = json.loads(file.read_text())["address"]
            self.nannies = [subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", self.address, "--host",
                 "127.0.0.1", "--nthreads", "1", "--no-dashboard"], **quiet)
                for _ in range(n_workers)]
            from dask.distributed import Client

            with Client(self.address, timeout=30) as client:
                client.wait_for_workers(n_workers, timeout=120)
                self.workers = set(client.run(os.getpid).values())
        except BaseException:
            self.close()
            raise

    def kill_workers(self) -> None:
        """SIGKILL every nanny, then every worker: nothing is left to start them again."""
        for proc in self.nannies:
            proc.kill()
            proc.wait()
        for pid in self.workers:
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass

    def close(self) -> None:
        for proc in [*self.nannies, self.scheduler]:
            proc.kill()
            proc.wait()
        for pid in getattr(self, "workers", ()):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


@pytest.fixture
def subprocess_cluster(tmp_path):
    pytest.importorskip("dask.distributed")
    clusters = []

    def start(n_workers):
        clusters.append(SubprocessCluster(tmp_path, n_workers))
        return clusters[-1]

    yield start
    for c in clusters:
        c.close()


def test_every_worker_and_nanny_killed_ends_in_one_line(tmp_path, sweep_file, reference,
                                                        monkeypatch, capsys, subprocess_cluster):
    """All workers killed with their nannies mid-run: the tasks waited for ever and 'run' hung,
    silent. A cluster without a worker for --no-workers-timeout seconds ends the run: one line,
    exit 1, the finished blocks kept; the same command resumes (here, without a cluster)."""
    cluster = subprocess_cluster(2)
    orig = engine.WorkStore.put
    killed = []

    def put(self, k, result):  # the first block home: every worker and nanny goes
        orig(self, k, result)
        if not killed:
            cluster.kill_workers()
            killed.append(time.perf_counter())

    monkeypatch.setattr(engine.WorkStore, "put", put)
    out = tmp_path / "out.nc"
    code = cli.main(["run", str(sweep_file), "-o", str(out), "--scheduler", cluster.address,
                     "--no-workers-timeout", "3", "--workers", "1", "--block-size", "1"])
    assert code == 1 and killed
    # from the kill, not from the start: the workers' first compile of the kernels comes before
    # the first block and takes minutes on a busy machine; a hang never ends at all
    assert time.perf_counter() - killed[0] < 60
    line = one_line_error(capsys.readouterr().err)
    assert "has had no worker for 3 s" in line and "rerun the same command to resume" in line
    kept = len(list(Path(partial_dir(out)).glob("block_*.npz")))
    assert 1 <= kept < 28 and not out.exists()  # 28 blocks of one integration
    monkeypatch.setattr(engine.WorkStore, "put", orig)
    assert cli.main(["run", str(sweep_file), "-o", str(out), "--workers", "1"]) == 0
    assert f"{kept} done before" in capsys.readouterr().err
    assert_identical(out, reference)


def test_scheduler_killed_mid_run_is_one_line(tmp_path, sweep_file, subprocess_cluster):
    """The scheduler killed mid-run: some thirty lines of distributed.client's tracebacks came
    before the run's own line. The run's stderr is its own lines alone."""
    cluster = subprocess_cluster(1)
    out = tmp_path / "out.nc"
    proc, marker, release = harness(tmp_path, "block:1", "run", sweep_file, "-o", out,
                                    "--scheduler", cluster.address, "--block-size", "1")
    wait_for(proc, marker)
    cluster.scheduler.kill()
    cluster.scheduler.wait()
    time.sleep(1)
    release.touch()
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 1, stderr
    assert "lost the dask scheduler" in one_line_error(stderr)
    assert all(line.startswith("cosserat-channel: ") for line in stderr.splitlines()), stderr
    assert list(Path(partial_dir(out)).glob("block_*.npz"))


# ---------------------------------------------------------------------------------------------
# Bad input
# ---------------------------------------------------------------------------------------------
FIG2 = (1 / 30, 10.0, 0.5, 1 / 3, 1.0)


@pytest.mark.parametrize("index, value", [
    (1, True), (1, np.bool_(True)), (0, "0.1"), (1, b"10"), (2, 10**400), (1, 10**400),
    (3, 1 + 2j), (4, None), (4, [1.0]), (1, 1e-320), (0, 5e-324),
    (1, 1e300), (4, 1e234), (3, 1e4), (3, -1e4),  # overflowing eps L, N^2, A^2 in the kernels
])
def test_solve_point_refuses_bad_parameters(index, value):
    point = list(FIG2)
    point[index] = value
    with pytest.raises(ParameterError):
        solve_point(*point)


@pytest.mark.parametrize("kwargs", [
    dict(profile="abc"), dict(profile=[0.5 + 1j]), dict(profile=[[0.5]]), dict(profile=[2.0]),
    dict(rtol=1.0), dict(rtol=True), dict(atol=0.1), dict(atol=1.0), dict(atol=5e-324),
    dict(material={"d_p": 1e308, "rho_p": 2940, "phi": 25}),
    dict(material={"d_p": 0.002, "rho_p": 1e300, "phi": 25}),
    dict(material={"d_p": 0.002, "rho_p": 2940, "phi": 25, "g": 1e300}),
    dict(material={"d_p": 5e-324, "rho_p": 2940, "phi": 25}),  # log(0) in the closure
    dict(material={"d_p": 0.002, "rho_p": 2940, "phi": 1e-300}),
    dict(material={"d_p": 0.002, "rho_p": 2940, "phi": 25, "Lambda": 5e-324}),
])
def test_solve_point_refuses_bad_options(kwargs):
    with pytest.raises(ParameterError):
        solve_point(*FIG2, **kwargs)


def test_large_atol_is_refused_by_name(capsys):
    """Item 1: atol = 0.1 said eps_too_large_path, atol = 1 integration_failed."""
    for atol in ("0.1", "1", "1e-5"):
        argv = ["point", "--eps", "0.0333", "--L", "10", "--K", "0.5", "--A", "0.33", "--N", "1",
                "--atol", atol]
        assert cli.main(argv) == 2
        assert "atol" in one_line_error(capsys.readouterr().err)
    assert cli.main(argv[:-2] + ["--atol", "1e-6"]) == 0
    assert "status  ok" in capsys.readouterr().out


@pytest.mark.parametrize("argv", [
    ["point", "--eps", "0.0333", "--L=1e-320", "--K", "0.5", "--A", "0.33", "--N", "1"],
    ["phase-plane", "--eps", "0.0333", "--L=1e-320", "--A", "0.33", "--N", "1", "-o", "pp.png"],
    ["boundary", "--A=1", "--N=1", "--eta-range", "1e-320:1", "-o", "b.nc"],
    ["boundary", "--A=1", "--N=1", "--eta-range", "1:1e300", "-o", "b.nc"],
    ["boundary", "--A=1:2:1000000000", "--N=1", "-o", "b.nc"],
    ["boundary", "--A=1:2:1000", "--N=1:2:1000", "-o", "b.nc"],
    ["point", "--eps", "0.0333", "--L", "10", "--K", "0.5", "--A", "0.33", "--N", "1",
     "--d-p", "1e308", "--rho-p", "2940", "--phi", "25"],
])
def test_bad_input_is_one_line_exit_2(tmp_path, monkeypatch, capsys, argv):
    """Items 8, 11, 12: one line, exit 2, at once (no 23 GB list, no ZeroDivisionError)."""
    monkeypatch.chdir(tmp_path)
    assert cli.main(argv) == 2
    one_line_error(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []


def test_tiny_eps_L_in_a_sweep_is_refused_without_numpy_warnings():
    """Item 8: eps L below ETA_MIN is a SweepError; planning such a grid warns nothing."""
    grid = {"eps": [1e-300, 0.1], "L": [1e-20, 10.0], "K": 0.5, "A": 1.0, "N": 1.0}
    with pytest.raises(SweepError, match="grid: eps L"):
        load_sweep({"grid": grid})
    with pytest.raises(SweepError, match="grid: eps L"):
        load_sweep({"grid": {**grid, "eps": 0.1, "L": [10.0, 1e300]}})
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Plan({d: np.atleast_1d(np.asarray(v, dtype=float)) for d, v in grid.items()})
    assert ETA_MIN <= 1e-12


def test_a_long_axis_is_refused_before_its_values_are_made():
    """eps = {logspace = [-3, -1, 10000000000]} (within the grid's 10^10 points) was a 74.5 GiB
    allocation and a traceback: the axis is refused by its count, nothing allocated."""
    import tracemalloc

    grid = {"eps": {"logspace": [-3, -1, 10_000_000_000]}, "L": 10.0, "K": 0.5, "A": 1.0,
            "N": 1.0}
    tracemalloc.start()
    try:
        with pytest.raises(SweepError, match=r"grid\.eps: 10,000,000,000 values exceed"):
            load_sweep({"grid": grid})
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20


@pytest.mark.parametrize("short", ["memory", "disk"])
def test_memory_and_disk_are_checked_before_the_plan(tmp_path, monkeypatch, short):
    """10^8 points on one axis took 13.5 GB (the plan) before the disk check refused them. Both
    checks now come from the grid's counts, before the plan: 10^7 points here, refused with
    the few MB the check takes (the plan would take some 700 MB)."""
    import tracemalloc

    from cosserat_channel import files

    spec = load_sweep({"grid": {"eps": {"logspace": [-3, -1, 10_000_000]}, "L": 10.0,
                                "K": 0.5, "A": 1.0, "N": 1.0}})
    if short == "memory":
        monkeypatch.setattr(budget, "available_memory", lambda: 100 << 20)
    else:
        monkeypatch.setattr(budget, "available_memory", lambda: None)
        real = files.shutil.disk_usage
        monkeypatch.setattr(files.shutil, "disk_usage", lambda p: real(p)._replace(free=1000))
    tracemalloc.start()
    try:
        with pytest.raises(SweepError, match=f"{short}"):
            run_sweep(spec, str(tmp_path / "out.nc"), workers=1)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < 20 << 20
    assert list(tmp_path.iterdir()) == []


BIG = "1" + "0" * 400  # a TOML integer (unbounded) above the largest float, about 1.8e308


@pytest.mark.parametrize("eps", [BIG, f"[0.1, {BIG}]", f"{{linspace = [0.1, {BIG}, 3]}}",
                                 f"{{logspace = [-3, {BIG}, 3]}}"])
def test_a_toml_integer_beyond_the_largest_float_is_one_line(tmp_path, capsys, eps):
    """float() of such an integer raised OverflowError out of load_sweep."""
    path = tmp_path / "big.toml"
    path.write_text(f"[grid]\neps = {eps}\nL = 10\nK = 0.5\nA = 1.0\nN = 1.0\n")
    with pytest.raises(SweepError, match=r"grid\.eps.*beyond the largest float"):
        load_sweep(str(path))
    assert cli.main(["run", str(path), "-o", str(tmp_path / "big.nc")]) == 2
    assert "beyond the largest float" in one_line_error(capsys.readouterr().err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["big.toml"]


@pytest.mark.parametrize("argv, written", [
    (["point", "--eps", "0.0333", "--L", "10", "--K", "0.5", "--A", "0.33", "--N", "1"], None),
    (["point", "--eps", "0.0333", "--L", "10", "--K", "0.5", "--A", "0.33", "--N", "1", "--plot",
      "p.png"], "p.png"),
    (["boundary", "--A", "0.3333333333333333", "--N", "1", "--coarse", "8", "--trace", "-o",
      "b.nc"],
     "b.nc"),
])
def test_a_reader_that_leaves_early_is_one_line_and_keeps_the_files(tmp_path, argv, written):
    """'point ... | head -1': BrokenPipeError, a traceback, and 'boundary' printed before writing
    its traced file, so the file was lost. The pipe is closed before anything is printed."""
    script = "import sys; from cosserat_channel import cli; sys.exit(cli.main(sys.argv[1:]))"
    proc = subprocess.Popen([sys.executable, "-c", script, *argv], cwd=tmp_path,
                            env=package_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    proc.stdout.close()  # the reader is gone before the command prints
    stderr = proc.stderr.read()
    proc.wait(timeout=300)
    assert proc.returncode == 1, stderr
    assert "broken pipe" in one_line_error(stderr)
    # one line besides the heartbeat that a run past a minute prints (a cold kernel cache)
    assert len(without_heartbeat(stderr, argv[0])) == 1, stderr
    assert "Exception ignored" not in stderr, stderr
    if written == "b.nc":
        with xr.open_dataset(tmp_path / written) as f:
            assert np.isfinite(f["eta_max"].values).all()
    elif written:
        assert (tmp_path / written).read_bytes().startswith(b"\x89PNG")


def test_info_and_query_on_a_string_coordinate(tmp_path, capsys):
    """Item 9: a flagged status next to a string coordinate: info answers, query says why not."""
    path = tmp_path / "s.nc"
    xr.Dataset({"status": (("eps", "A"), np.zeros((2, 2), np.int8), st.cf_flag_attrs()),
                "Delta": (("eps", "A"), np.ones((2, 2)))},
               coords={"eps": ["a", "b"], "A": [1.0, 2.0]}).to_netcdf(path)
    assert cli.main(["info", str(path)]) == 0
    assert "eps" in capsys.readouterr().out
    assert cli.main(["query", str(path)]) == 0
    capsys.readouterr()
    for extra in (["--sel", "eps=1"], ["--where", "eps > 1"], ["--range", "eps=0:1"]):
        assert cli.main(["query", str(path), *extra]) == 2
        assert "not numeric" in one_line_error(capsys.readouterr().err)


def test_byte_order_mark_and_empty_output(tmp_path, sweep_file, reference, capsys):
    """Item 12: a TOML file with a BOM runs; -o '' is refused instead of writing elsewhere."""
    bom = tmp_path / "bom.toml"
    bom.write_bytes(b"\xef\xbb\xbf" + sweep_file.read_bytes())
    assert load_sweep(str(bom)).sha256 == load_sweep(str(sweep_file)).sha256
    for argv in (["run", str(sweep_file), "-o", ""], ["run", str(sweep_file), "-o", " "]):
        assert cli.main(argv) == 2
        assert "empty" in one_line_error(capsys.readouterr().err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bom.toml", "s.toml"]
