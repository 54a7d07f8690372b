"""``atlas`` killed outright (SIGKILL: an out-of-memory kill, a batch system's hard limit) keeps
the edges it traced so far: they are saved as the build goes, and the same command resumes from
them to the very file an uninterrupted build writes.

Each build runs in a process of its own that saves its traces after every cell (the interval
set to 0) and is killed by a real SIGKILL: after its first saving, in the middle of a saving
(the new file written but not yet renamed), from outside at a moment the test does not choose,
and while the finished atlas is written. The rerun after each kill goes on from what is kept."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from test_faults import package_env

ARGS = ["atlas", "--A", "0.25:0.5", "--N", "0.8:0.9", "--tol", "1e-3", "--degree", "2",
        "--max-depth", "1", "--workers", "1"]

# cli.main with the traces saved after every cell; KILL_AT names the moment the process kills
# itself with SIGKILL: "save:K" after its K-th saving, "saving:K" inside its K-th saving (the
# temporary file written, not yet renamed onto the partial file), "atlas" when the finished
# atlas is to be written.
BUILD = r"""
import os, signal, sys
from cosserat_channel import atlas, cli, files
from cosserat_channel.cli import _atlas
_atlas.SAVE_SECONDS = 0.0
when, _, k = os.environ.get("KILL_AT", "").partition(":")
count = [0]
def kill():
    os.kill(os.getpid(), signal.SIGKILL)
save_traces, save_npz = atlas.save_traces, files.save_npz
def saved(*a, **kw):
    count[0] += 1
    save_traces(*a, **kw)
    if when == "save" and count[0] == int(k):
        kill()
def half_saved(path, arrays):
    save_npz(path, arrays)
    if when == "saving" and count[0] == int(k):
        kill()
def write_atlas(*a, **kw):
    kill()
atlas.save_traces, files.save_npz = saved, half_saved
if when == "atlas":
    atlas.save_atlas = write_atlas
sys.exit(cli.main(sys.argv[1:]))
"""


def _build(out, kill_at="", **popen):
    env = dict(package_env(), KILL_AT=kill_at)
    return subprocess.Popen([sys.executable, "-c", BUILD, *ARGS, "-o", str(out)], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **popen)


def _kept(partial) -> int:
    """Edges in the partial file (0 when there is none)."""
    if not partial.exists():
        return 0
    with np.load(partial) as z:
        return int(z["A"].size)


@pytest.mark.slow
def test_atlas_killed_at_any_moment_resumes_to_the_file_an_uninterrupted_build_writes(tmp_path):
    ref = tmp_path / "ref" / "atlas.nc"
    ref.parent.mkdir()
    done = _build(ref)
    _, err = done.communicate(timeout=900)
    assert done.returncode == 0, err
    assert sorted(p.name for p in ref.parent.iterdir()) == ["atlas.nc"]  # nothing left behind

    out = tmp_path / "atlas.nc"
    partial = tmp_path / "atlas.nc.partial"
    seen = 0
    for kill_at in ("save:1", "saving:2", "outside", "atlas"):
        if kill_at == "outside":
            # Killed from outside once the build has gone on beyond what it resumed from.
            proc = _build(out)
            deadline = time.monotonic() + 900
            while _kept(partial) <= seen and proc.poll() is None and time.monotonic() < deadline:
                time.sleep(0.05)
            proc.send_signal(signal.SIGKILL)
            proc.communicate(timeout=60)
            if proc.returncode == 0:  # finished before the kill: nothing left to test here
                pytest.fail("the build ended before it was killed; give it more cells")
        else:
            proc = _build(out, kill_at)
            proc.communicate(timeout=900)
        assert proc.returncode == -signal.SIGKILL, kill_at
        assert not out.exists(), kill_at
        kept = _kept(partial)
        assert kept >= seen, kill_at  # never less than before
        if kill_at != "saving:2":
            assert kept > seen, kill_at
        seen = kept
    # The temporary file of the saving killed half way is the only other thing left.
    names = sorted(p.name for p in tmp_path.iterdir())
    assert [n for n in names if n not in ("ref", "atlas.nc.partial")] == [
        n for n in names if n.startswith(".atlas.nc.partial.") and n.endswith(".tmp")]

    last = _build(out)
    _, err = last.communicate(timeout=900)
    assert last.returncode == 0, err
    assert f"resuming from the {seen} edges traced before" in err
    assert not partial.exists()
    assert out.read_bytes() == ref.read_bytes()
    # and what the killed savings left is gone with it
    assert sorted(p.name for p in tmp_path.iterdir()) == ["atlas.nc", "ref"]


def test_a_build_saves_its_traces_as_it_goes_never_over_a_file_it_did_not_make(
        tmp_path, monkeypatch, capsys):
    """In process: with the interval at 0 the partial file follows the build cell by cell; a
    FIFO that appears at its name meanwhile is left exactly as it is (one note), and the build
    still ends with its atlas."""
    import stat

    from cosserat_channel import cli
    from cosserat_channel.cli import _atlas

    monkeypatch.setattr(_atlas, "SAVE_SECONDS", 0.0)
    out, partial = tmp_path / "a.nc", tmp_path / "a.nc.partial"
    sizes = []
    maybe = _atlas._Saver.maybe

    def saving(self):
        maybe(self)
        if len(sizes) < 2 and partial.is_file():
            sizes.append(_kept(partial))
            if len(sizes) == 2:  # someone else's from now on
                partial.unlink()
                os.mkfifo(partial)

    monkeypatch.setattr(_atlas._Saver, "maybe", saving)
    assert cli.main([*ARGS, "-o", str(out)]) == 0
    err = capsys.readouterr().err
    assert len(sizes) == 2 and 0 < sizes[0] < sizes[1]
    assert out.is_file()
    assert stat.S_ISFIFO(partial.lstat().st_mode)  # left alone, not removed
    notes = [line for line in err.splitlines() if "appeared meanwhile" in line]
    assert len(notes) == 1 and "a FIFO" in notes[0] and "Traceback" not in err
