"""A dask worker that runs other package sources than the client: a second source tree that
differs by one line (``PYTHONPATH=other/src dask worker ...``), on a scheduler of its own on the
loopback address. Its blocks would silently differ; the run refuses it in one line, at connect
or when it joins mid-run, and nothing finished is lost."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

import cosserat_channel
from cosserat_channel import cli
from cosserat_channel.sweep import engine, sources
from cosserat_channel.sweep.store import partial_dir
from support import SCHEDULER_HTTP
from test_faults import SWEEP, one_line_error, package_env

pytest.importorskip("dask.distributed")


def other_tree(tmp_path) -> Path:
    """A copy of the package's sources with one line changed; returns its ``src``."""
    here = Path(cosserat_channel.__file__).resolve().parent
    src = tmp_path / "other" / "src"
    shutil.copytree(here, src / here.name, ignore=shutil.ignore_patterns("__pycache__", "*.nc"))
    block = src / here.name / "sweep" / "block.py"
    text = block.read_text()
    block.write_text(text.replace("from __future__ import annotations\n",
                                  "from __future__ import annotations  # a local change\n", 1))
    assert block.read_text() != text
    return src


class Cluster:
    """A dask scheduler and workers, each a process of its own, with the environment each is
    given: the test's package, or another source tree."""

    def __init__(self, tmp_path):
        file = tmp_path / "scheduler.json"
        self.procs = []
        self.scheduler = self._start(
            ["distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0",
             *SCHEDULER_HTTP, "--scheduler-file", str(file)], package_env())
        deadline = time.monotonic() + 60
        while not (file.exists() and file.stat().st_size):
            assert time.monotonic() < deadline, "the scheduler did not start"
            time.sleep(0.1)
        self.address = json.loads(file.read_text())["address"]

    def _start(self, argv, env):
        self.procs.append(subprocess.Popen([sys.executable, "-m", *argv], env=env,
                                           stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        return self.procs[-1]

    def worker(self, pythonpath=None):
        """Start a worker (no nanny) importing the package from ``pythonpath`` (default: the
        package under test)."""
        env = package_env()
        if pythonpath is not None:
            env["PYTHONPATH"] = str(pythonpath)
        self._start(["distributed.cli.dask_worker", self.address, "--host", "127.0.0.1",
                     "--nthreads", "1", "--no-dashboard", "--no-nanny"], env)

    def wait_for_workers(self, n):
        from dask.distributed import Client

        with Client(self.address, timeout=30) as client:
            client.wait_for_workers(n, timeout=120)
            return client.run(cosserat_channel.source_digest)

    def close(self):
        for proc in self.procs:
            proc.kill()
            proc.wait()


@pytest.fixture
def cluster(tmp_path):
    c = Cluster(tmp_path)
    yield c
    c.close()


@pytest.fixture
def sweep_file(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text(SWEEP)
    return path


def test_a_foreign_worker_is_refused_at_connect_before_anything_is_written(
        tmp_path, sweep_file, cluster, capsys):
    """One worker of these sources, one of a tree that differs by one line: the run refuses the
    cluster in one line, exit 2, and creates nothing."""
    cluster.worker()
    cluster.worker(other_tree(tmp_path))
    digests = cluster.wait_for_workers(2)
    assert sorted(d == sources.digest() for d in digests.values()) == [False, True]
    out = tmp_path / "out.nc"
    assert cli.main(["run", str(sweep_file), "-o", str(out), "--scheduler",
                     cluster.address]) == 2
    line = one_line_error(capsys.readouterr().err)
    assert "runs other cosserat_channel sources" in line and "start every worker" in line
    assert not out.exists() and not Path(partial_dir(out)).exists()


def test_a_foreign_worker_that_joins_mid_run_is_refused_and_nothing_is_lost(
        tmp_path, sweep_file, cluster, monkeypatch, capsys):
    """No worker at connect; a worker of other sources joins once the store is open. Its
    blocks are never stored: the run ends in one line, exit 1, the store kept for a rerun."""
    other = other_tree(tmp_path)
    orig = engine.WorkStore.open.__func__

    def open_(cls, *a, **k):
        store = orig(cls, *a, **k)
        cluster.worker(other)
        return store

    monkeypatch.setattr(engine.WorkStore, "open", classmethod(open_))
    out = tmp_path / "out.nc"
    t0 = time.perf_counter()
    code = cli.main(["run", str(sweep_file), "-o", str(out), "--scheduler", cluster.address,
                     "--no-workers-timeout", "120", "--block-size", "4"])
    line = one_line_error(capsys.readouterr().err)
    assert code == 1, line
    assert "runs other cosserat_channel sources" in line and "its block was not used" in line
    assert "rerun the same command to resume" in line
    assert time.perf_counter() - t0 < 120  # refused on its first block, nothing solved there
    assert not out.exists() and Path(partial_dir(out)).is_dir()
    assert not list(Path(partial_dir(out)).glob("block_*.npz"))


def test_a_block_without_a_digest_is_foreign():
    """An older worker's block (no digest), or one of other sources, is named; ours passes."""
    assert sources.foreign_block(sources.stamp({}), "tcp://w") is None
    assert "carries no digest" in sources.foreign_block({}, "tcp://w")
    assert "runs other" in sources.foreign_block({"sources": "0" * 64}, "tcp://w")
