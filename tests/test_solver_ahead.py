"""A first run's kernels compiled in a child process (solver.ahead) and the cache's locked saves."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from support import run_python

from cosserat_channel.solver import ahead

# Solves the README's point with a profile, then reports, for each part the child was given,
# whether this process loaded it from the cache (a hit, no compilation of its own), and whether
# the entry kernel was compiled here (the cache was cold for it).
POINT = """if True:
    import json
    import numpy as np
    import cosserat_channel as cc
    from cosserat_channel.solver import ahead, batch

    r = cc.solve_point(1 / 30, 10, 0.5, 1 / 3, 1, profile=np.linspace(0.0, 1.0, 5))
    child = ahead._state["child"]
    loaded = {name: [d.stats.cache_hits[sig] == 1 and not d.stats.cache_misses[sig]
                     for d, sig in ahead._signatures(name)] for name in ahead.JOBS}
    entry = batch.solve_eta_dop853.stats
    print(json.dumps({
        "child": None if child is None else child.names,
        "child_exit": None if child is None else child.proc.wait(),
        "loaded": loaded,
        "entry_compiled": sum(entry.cache_misses.values()) > 0,
        "result": r.to_dict(),
    }))
"""


@pytest.mark.slow
def test_a_cold_first_point_loads_what_a_child_compiled_meanwhile(tmp_path, monkeypatch):
    """On an empty kernel cache the first point hands stage 2, the plug edge and the profile to
    a child process; this process compiles stage 1 and the entry and loads the child's kernels
    from the cache (cache hits, no compilation). A second process finds everything cached,
    starts no child and gives the same result."""
    if ahead._usable_cores() < 2:
        pytest.skip("one usable core: no child is started")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path))
    cold = json.loads(run_python(POINT))
    assert cold["child"] == list(ahead.JOBS)
    assert cold["child_exit"] == 0
    assert cold["loaded"] == {name: [True] for name in ahead.JOBS}
    assert cold["entry_compiled"]
    warm = json.loads(run_python(POINT))
    assert warm["child"] is None and not warm["entry_compiled"]
    assert warm["result"] == cold["result"]


def test_no_child_without_a_cache_or_compiler_or_second_core(monkeypatch):
    """No child where it cannot help: Numba's cache off, JIT disabled, one usable core, or in
    the child itself."""
    from numba.core import config

    from cosserat_channel import _jit

    if not _jit.JIT["cache"]:
        pytest.skip("the kernel cache is off here")
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    monkeypatch.delenv(ahead.CHILD_ENV, raising=False)
    assert ahead._eligible()
    monkeypatch.setitem(_jit.JIT, "cache", False)
    assert not ahead._eligible()
    monkeypatch.setitem(_jit.JIT, "cache", True)
    monkeypatch.setattr(config, "DISABLE_JIT", True)
    assert not ahead._eligible()
    monkeypatch.setattr(config, "DISABLE_JIT", False)
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0}, raising=False)
    assert not ahead._eligible()
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    monkeypatch.setenv(ahead.CHILD_ENV, "1")
    assert not ahead._eligible()


def _gone(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return True
    return "\nState:\tZ" in state  # ended, not reaped yet


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads /proc")
def test_the_child_ends_when_its_parent_is_killed(tmp_path):
    """A parent killed with SIGKILL (no exit handler runs) leaves no child compiling: the child
    ends when its standard input closes."""
    if ahead._usable_cores() < 2:
        pytest.skip("one usable core: no child is started")
    code = """if True:
        import os, signal, sys
        from cosserat_channel.solver import ahead
        ahead.start(("stage2",))
        child = ahead._state["child"]
        print(child.proc.pid if child else 0, flush=True)
        os.kill(os.getpid(), signal.SIGKILL)
    """
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path)))
    assert proc.returncode == -signal.SIGKILL
    pid = int(proc.stdout)
    assert pid > 0
    deadline = time.monotonic() + 60
    while not _gone(pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert _gone(pid)


def test_a_cache_save_holds_its_directory_locked(tmp_path, monkeypatch):
    """Numba's save of a cache entry (index read, entry added, index and data written) runs
    under an exclusive lock on the cache directory, so that two processes saving entries of one
    function cannot both take the same data file."""
    import fcntl

    from numba.core import caching

    from cosserat_channel import _jit

    if not _jit.JIT["cache"]:
        pytest.skip("the kernel cache is off here")
    seen = []

    def save(self, key, data):
        fd = os.open(self._cache_path, os.O_RDONLY)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            seen.append("free")
        except BlockingIOError:
            seen.append("locked")
        finally:
            os.close(fd)

    monkeypatch.setattr(caching.IndexDataCacheFile, "save", save)
    _jit._lock_saves(caching.IndexDataCacheFile)
    index = caching.IndexDataCacheFile(str(tmp_path), "f-1.py311", "stamp")
    index.save(("key",), b"data")
    assert seen == ["locked"]
    fd = os.open(tmp_path, os.O_RDONLY)  # released afterwards
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    finally:
        os.close(fd)


def test_reports_that_arrive_together_are_each_seen_at_once(monkeypatch):
    """A child that reports two parts in one write and then works on: the second report is seen
    without waiting for the child's next one or its end."""
    monkeypatch.setattr(ahead, "WAIT_S", 20.0)
    code = ("import sys, time; sys.stdout.write('stage2\\nplug_edge\\n'); sys.stdout.flush(); "
            "time.sleep(60)")
    child = ahead._Child(["stage2", "plug_edge"], code=code)
    try:
        t0 = time.monotonic()
        assert child.wait("stage2")
        assert child.wait("plug_edge")
        assert time.monotonic() - t0 < 15
        assert child.proc.poll() is None  # still working: the reports were read, not its end
    finally:
        child.close()
