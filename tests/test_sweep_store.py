"""The working store: kill -9 and resume, refusal of a foreign store, atomic result files."""

from __future__ import annotations

import os
import re
import shutil
import signal
import stat
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from cosserat_channel import cli
from cosserat_channel.sweep import block, engine, run_sweep
from cosserat_channel.sweep.spec import SweepError, load_sweep
from cosserat_channel.sweep.store import WorkStore, partial_dir
from support import assert_identical

# About 3 s on one core: 9,600 integrations at rtol = 1e-10 in 240 blocks of 40.
SLOW = """\
[grid]
eps = {logspace = [-3, -1.5, 60]}
L = {logspace = [0, 1, 20]}
K = [0.5, 5.0]
A = [0.0, 0.3333333333333333, 1.0, 2.0]
N = [1.0, 1.5]
[solver]
rtol = 1e-10
"""
SLOW_BLOCKS = 240
SMALL = """\
[grid]
eps = [0.02, 0.05]
L = [5.0, 10.0]
K = [0.5, 5.0]
A = 0.3333333333333333
N = [1.0, 1.5]
"""
LOG = re.compile(r"(\d+) done before, (\d+) to compute")


def run_cli(*args) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cosserat_channel.cli", "run", *map(str, args)],
                          capture_output=True, text=True, timeout=300)


def snapshot(directory) -> dict:
    return {p.name: p.read_bytes() for p in sorted(Path(directory).iterdir())}


def leave_partial(monkeypatch, toml, out):
    """Run ``toml`` in-process until every block is stored, then fail before the file is written."""

    def crash(*args, **kwargs):
        raise RuntimeError("simulated crash after the solve")

    with monkeypatch.context() as m:
        m.setattr(engine, "assemble", crash)
        with pytest.raises(RuntimeError, match="simulated crash"):
            run_sweep(toml, out, workers=1)
    assert os.path.isdir(partial_dir(out))


def test_kill_9_then_rerun_resumes_to_identical_result(tmp_path):
    """kill -9 mid-run leaves the old file intact; the rerun resumes and matches a clean run."""
    toml = tmp_path / "slow.toml"
    toml.write_text(SLOW)
    out = tmp_path / "out.nc"
    out.write_bytes(b"sentinel: an earlier result")
    store = Path(partial_dir(out))
    cmd = [sys.executable, "-m", "cosserat_channel.cli", "run", str(toml), "-o", str(out),
           "--workers", "1", "--block-size", "40", "--overwrite"]
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while proc.poll() is None and time.monotonic() < deadline:
        if store.is_dir() and len(list(store.glob("block_*.npz"))) >= 3:
            break
        time.sleep(0.005)
    if proc.poll() is not None:
        pytest.fail("the run finished before it could be killed; make SLOW slower")
    os.kill(proc.pid, signal.SIGKILL)
    proc.wait()
    assert out.read_bytes() == b"sentinel: an earlier result"
    finished = len(list(store.glob("block_*.npz")))
    assert 3 <= finished < SLOW_BLOCKS

    again = run_cli(toml, "-o", out, "--workers", "1", "--block-size", "40")
    assert again.returncode == 0, again.stderr
    before, todo = map(int, LOG.search(again.stderr).groups())
    assert before >= finished and before + todo == SLOW_BLOCKS
    assert not store.exists()
    assert_identical(out, run_sweep(load_sweep(toml), workers=2))


def test_different_sweep_refused_with_store_untouched(tmp_path, monkeypatch, capsys):
    """Another sweep file for the same -o, with a store present: exit 2, one line, nothing mixed."""
    first = tmp_path / "first.toml"
    first.write_text(SMALL)
    out = tmp_path / "out.nc"
    leave_partial(monkeypatch, str(first), str(out))
    before = snapshot(partial_dir(out))
    second = tmp_path / "second.toml"
    second.write_text(SMALL.replace("K = [0.5, 5.0]", "K = [0.5, 6.0]"))
    assert cli.main(["run", str(second), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert "different sweep file" in err and partial_dir(out) in err and "delete" in err
    assert snapshot(partial_dir(out)) == before
    assert not out.exists()
    # the original sweep resumes from the complete store and finishes
    assert cli.main(["run", str(first), "-o", str(out)]) == 0
    assert "0 to compute" in capsys.readouterr().err
    assert_identical(out, run_sweep(str(first)))


def _crashed_before_assembly(tmp_path, monkeypatch):
    """A run of SMALL in blocks of 3 that crashes after every block is stored, before the file is
    assembled: (sweep file, output path)."""
    toml = tmp_path / "s.toml"
    toml.write_text(SMALL)
    out = tmp_path / "out.nc"
    with monkeypatch.context() as m:
        m.setattr(engine, "assemble", lambda *a, **k: (_ for _ in ()).throw(RuntimeError("crash")))
        with pytest.raises(RuntimeError):
            run_sweep(str(toml), str(out), block_size=3)
    return toml, out


def test_other_block_size_refused_but_plain_rerun_adopts_it(tmp_path, monkeypatch, capsys):
    """An explicit --block-size unlike the store's is refused; without it the store's is used."""
    toml, out = _crashed_before_assembly(tmp_path, monkeypatch)
    assert cli.main(["run", str(toml), "-o", str(out), "--block-size", "2"]) == 2
    assert "--block-size 3" in capsys.readouterr().err
    assert cli.main(["run", str(toml), "-o", str(out), "--no-reduce"]) == 2
    capsys.readouterr()
    assert cli.main(["run", str(toml), "-o", str(out)]) == 0
    assert "0 to compute" in capsys.readouterr().err


def test_unwritable_output_fails_before_any_work(tmp_path, monkeypatch, capsys):
    """A missing output directory or a directory as output: exit 2, one line, nothing planned."""
    toml = tmp_path / "s.toml"
    toml.write_text(SMALL)

    def no_work(*args, **kwargs):
        raise AssertionError("planned work despite an unwritable output")

    monkeypatch.setattr(engine, "Plan", no_work)
    for out in (tmp_path / "missing" / "out.nc", tmp_path):
        assert cli.main(["run", str(toml), "-o", str(out)]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "error:" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_success_replaces_result_and_removes_store(tmp_path, capsys):
    """A finished run replaces an existing file whole and leaves no store or temporary file."""
    toml = tmp_path / "s.toml"
    toml.write_text(SMALL)
    out = tmp_path / "out.nc"
    out.write_bytes(b"old")
    assert cli.main(["run", str(toml), "-o", str(out), "--workers", "2", "--overwrite"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.nc", "s.toml"]
    assert_identical(out, run_sweep(str(toml)))
    assert oct(out.stat().st_mode & 0o777) != oct(0o600)


def test_default_output_is_sweep_name_in_cwd(tmp_path, monkeypatch):
    """Without -o and without [output] path the CLI writes SWEEP.nc in the current directory."""
    (tmp_path / "sub").mkdir()
    toml = tmp_path / "sub" / "mine.toml"
    toml.write_text(SMALL)
    monkeypatch.chdir(tmp_path)
    assert cli.main(["run", str(toml)]) == 0
    assert (tmp_path / "mine.nc").exists()


def test_concurrent_run_on_same_output_refused(tmp_path):
    """While one run holds the store's lock, a second run on the same output is refused."""
    toml = tmp_path / "s.toml"
    toml.write_text(SMALL)
    out = str(tmp_path / "out.nc")
    spec = load_sweep(str(toml))
    plan = engine.Plan(spec.coords())
    holder = WorkStore.open(out, engine._manifest(spec, plan), given_block_size=False)
    try:
        with pytest.raises(SweepError, match="another run"):
            run_sweep(spec, out)
    finally:
        holder.close()
    run_sweep(spec, out)
    assert os.path.exists(out)


def test_run_finished_meanwhile_is_decided_under_the_lock(tmp_path, monkeypatch, capsys):
    """A run of another sweep to the same -o while the first finishes during the second's solver
    warm-up: the second is refused (exit 2, one line) and the first's result stays, the same
    file; a second run of the same sweep keeps it (exit 0, a note, nothing computed)."""
    first = tmp_path / "first.toml"
    first.write_text(SMALL)
    second = tmp_path / "second.toml"
    second.write_text(SMALL.replace("K = [0.5, 5.0]", "K = [0.5, 6.0]"))
    out = tmp_path / "out.nc"
    real_warm_up = block.warm_up
    finished = []

    def first_run_finishes():
        if not finished:  # once: run_sweep warms up too
            finished.append(True)
            run_sweep(str(first), str(out), workers=1).close()
        real_warm_up()

    monkeypatch.setattr(block, "warm_up", first_run_finishes)  # the command's, before the run
    for toml, code, words in ((second, 2, ("another sweep", "--overwrite")),
                              (first, 0, ("already the finished result", "--overwrite"))):
        finished.clear()
        out.unlink(missing_ok=True)
        capsys.readouterr()
        assert cli.main(["run", str(toml), "-o", str(out), "--workers", "1"]) == code
        assert finished
        err = capsys.readouterr().err
        assert all(w in err for w in words) and not LOG.search(err), err
        if code:
            assert len(err.strip().splitlines()) == 1, err
        ino = out.stat().st_ino  # the first run's file, not replaced since
        assert not os.path.exists(partial_dir(out))
        assert_identical(out, run_sweep(str(first), workers=1))
        assert out.stat().st_ino == ino
    assert sorted(p.name for p in tmp_path.iterdir()) == ["first.toml", "out.nc", "second.toml"]


def test_lock_on_a_store_removed_meanwhile_is_taken_again(tmp_path, monkeypatch):
    """A run that finishes removes its store: a run whose lock was taken on the removed store's
    lock file at that moment makes a new store and locks that one."""
    import fcntl
    import shutil

    from cosserat_channel.sweep import store as store_module

    out = str(tmp_path / "out.nc")
    spec = load_sweep_text(tmp_path, SMALL)
    manifest = engine._manifest(spec, engine.Plan(spec.coords()))
    removed = []

    class RemovedAfterLocking:
        LOCK_EX, LOCK_NB = fcntl.LOCK_EX, fcntl.LOCK_NB

        @staticmethod
        def flock(fd, op):
            fcntl.flock(fd, op)
            if not removed:
                removed.append(True)
                shutil.rmtree(partial_dir(out))

    monkeypatch.setattr(store_module, "fcntl", RemovedAfterLocking)
    store = WorkStore.open(out, manifest, given_block_size=False)
    try:
        assert removed and store.created
        lock = os.path.join(partial_dir(out), "lock")
        assert os.path.samestat(os.fstat(store._lock), os.stat(lock))
        assert os.path.isfile(os.path.join(partial_dir(out), "manifest.json"))
    finally:
        store.remove()


def load_sweep_text(tmp_path, text):
    path = tmp_path / "s.toml"
    path.write_text(text)
    return load_sweep(str(path))


def tree(directory) -> dict:
    """Every entry under ``directory`` (links not followed): its kind and, for files, bytes."""
    out = {}
    for root, dirs, names in os.walk(directory):
        for name in dirs + names:
            p = Path(root) / name
            rel = str(p.relative_to(directory))
            mode = p.lstat().st_mode
            out[rel] = ("link", os.readlink(p)) if stat.S_ISLNK(mode) else \
                ("file", p.read_bytes()) if stat.S_ISREG(mode) else (stat.S_IFMT(mode), p.lstat().st_rdev)
    return out


def test_a_partial_directory_that_is_not_a_store_is_left_alone(tmp_path, monkeypatch, capsys):
    """OUT.nc.partial that this program did not make (a directory, empty or not, a symbolic link
    to one, a file) is refused in one line naming it, before any work and by the API too;
    nothing in it or behind it changes, no lock file is made."""
    toml = tmp_path / "s.toml"
    toml.write_text(SMALL)
    out = tmp_path / "out.nc"
    d = Path(partial_dir(out))
    theirs = tmp_path / "theirs"
    theirs.mkdir()
    (theirs / "thesis.txt").write_text("years of work")
    (theirs / "draft.tmp").write_text("also theirs")
    (theirs / "block_00000.npz").write_bytes(b"not a block")
    (theirs / "manifest.json").write_text("{}")

    def plain():
        d.mkdir()
        (d / "thesis.txt").write_text("years of work")

    makers = {"a directory": plain, "an empty directory": d.mkdir,
              "a link to a directory": lambda: d.symlink_to(theirs),
              "a link to a store's look-alike": lambda: d.symlink_to(theirs),
              "a file": lambda: d.write_text("x")}
    monkeypatch.setattr(engine, "_run", lambda *a, **k: pytest.fail("computed anyway"))
    for what, make in makers.items():
        make()
        before, behind = tree(tmp_path), tree(theirs)
        assert cli.main(["run", str(toml), "-o", str(out)]) == 2, what
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and str(d) in err, (what, err)
        with pytest.raises(SweepError, match="left alone"):
            run_sweep(str(toml), str(out))
        with pytest.raises(SweepError, match="left alone"):
            WorkStore.open(str(out), {}, given_block_size=False)
        assert tree(tmp_path) == before and tree(theirs) == behind, what
        if d.is_symlink() or d.is_file():
            d.unlink()
        else:
            shutil.rmtree(d)


def test_outputs_inside_a_working_store_are_refused(tmp_path, monkeypatch, capsys):
    """A store is deleted with all it holds when its run finishes: run, query and plot refuse an
    output inside one (directly, in a folder of it, or through a link to it); the run then
    finishes and nothing written anywhere is lost."""
    first = tmp_path / "first.toml"
    first.write_text(SMALL)
    out = tmp_path / "X.nc"
    leave_partial(monkeypatch, str(first), str(out))
    store = Path(partial_dir(out))
    (store / "folder").mkdir()
    (tmp_path / "link").symlink_to(store)
    other = tmp_path / "other.toml"
    other.write_text(SMALL.replace("K = [0.5, 5.0]", "K = [0.5, 6.0]"))
    result = tmp_path / "done.nc"
    run_sweep(str(other), str(result), workers=1).close()
    before = tree(store)
    for inner in (store / "inner.nc", store / "folder" / "inner.nc", tmp_path / "link" / "i.nc"):
        for argv in (["run", str(other), "-o", str(inner)],
                     ["query", str(result), "--sel", "K=0.5", "--format", "csv", "-o",
                      str(inner)],
                     ["plot", str(result), "--x", "eps", "--y", "Delta", "--hue", "K", "-o",
                      str(inner) + ".png"]):
            assert cli.main(argv) == 2, argv
            err = capsys.readouterr().err
            assert len(err.strip().splitlines()) == 1 and "working store" in err, err
            assert str(store) in err
        with pytest.raises(SweepError, match="working store"):
            run_sweep(str(other), str(inner))
    assert tree(store) == before
    assert cli.main(["run", str(first), "-o", str(out)]) == 0
    assert not store.exists()
    assert_identical(out, run_sweep(str(first)))


def main_or_unblock(argv, fifos=(), seconds=60.0):
    """``cli.main(argv)`` in a thread; if it has not returned within ``seconds`` (reading a FIFO
    waits for a writer), the FIFOs are opened and closed so that it ends, and the test fails."""
    code = []
    thread = threading.Thread(target=lambda: code.append(cli.main(argv)), daemon=True)
    thread.start()
    thread.join(seconds)
    if thread.is_alive():
        for fifo in fifos:
            try:
                os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
            except OSError:
                pass
        thread.join(30)
        pytest.fail(f"{argv} hung on a FIFO")
    return code[0]


def test_what_is_not_a_store_file_is_named_and_left_alone(tmp_path, monkeypatch, capsys):
    """A FIFO, a directory with a file in it, a device node or a link at a block's name, or a
    FIFO as the manifest: the run ends at once, exit 2, one line naming that entry, which is left
    as it was; once it is moved away the same command finishes, the other blocks reused."""
    toml = tmp_path / "s.toml"
    toml.write_text(SMALL)
    out = tmp_path / "out.nc"
    leave_partial(monkeypatch, str(toml), str(out))
    store = Path(partial_dir(out))
    n_blocks = len(list(store.glob("block_*.npz")))
    block, manifest = store / "block_00001.npz", store / "manifest.json"
    saved = manifest.read_bytes()
    block.unlink()

    def directory(p):
        p.mkdir()
        (p / "notes.txt").write_text("not a block")

    def device(p):
        try:
            os.mknod(p, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
        except PermissionError:
            pytest.skip("making a device node needs root")

    cases = [(block, os.mkfifo), (block, directory), (block, lambda p: p.symlink_to(toml)),
             (manifest, os.mkfifo), (block, device)]
    for path, make in cases:
        if path == manifest:
            manifest.unlink()
        make(path)
        before = tree(store)
        argv = ["run", str(toml), "-o", str(out), "--workers", "1"]
        assert main_or_unblock(argv, [path]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and str(path) in err and "move it" in err, err
        assert tree(store) == before
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink()
        if path == manifest:
            manifest.write_bytes(saved)
    assert cli.main(["run", str(toml), "-o", str(out), "--workers", "1"]) == 0
    before, todo = map(int, LOG.search(capsys.readouterr().err).groups())
    assert (before, todo) == (n_blocks - 1, 1)
    assert_identical(out, run_sweep(str(toml)))


@pytest.mark.parametrize("edit", [
    {"plan_sha256": "0" * 64}, {"sweep_sha256": "f" * 64}, {"block_size": 5, "n_blocks": 4},
    {"cosserat_channel_version": "0.0.0"}, {"shape": [1, 1, 1, 1, 1]}])
def test_edited_manifest_resumes_from_the_blocks_its_digests_prove(tmp_path, monkeypatch, capsys,
                                                                   edit):
    """A manifest edited by hand (whatever field): the blocks' digests show they are this run's,
    so the rerun resumes with every block and gives the uninterrupted result; a warning says so."""
    import json

    toml, out = _crashed_before_assembly(tmp_path, monkeypatch)
    path = Path(partial_dir(out)) / "manifest.json"
    manifest = json.loads(path.read_text())
    n_blocks = manifest["n_blocks"]
    path.write_text(json.dumps({**manifest, **edit}))
    capsys.readouterr()
    assert cli.main(["run", str(toml), "-o", str(out), "--workers", "1"]) == 0
    err = capsys.readouterr().err
    assert "digests" in err, err
    assert tuple(map(int, LOG.search(err).groups())) == (n_blocks, 0)
    assert_identical(out, run_sweep(str(toml)))


def test_a_resumed_run_replaces_the_output_only_if_its_first_run_was_asked_to(tmp_path):
    """The store records ``overwrite``: resuming a killed ``--overwrite`` run replaces the earlier
    file (the job it was given), resuming any other run never does."""
    toml = tmp_path / "s.toml"
    toml.write_text(SMALL)
    spec = load_sweep(str(toml))
    manifest = engine._manifest(spec, engine.Plan(spec.coords()))
    for first, again, replaces in ((True, False, True), (False, False, False),
                                   (False, True, True)):
        out = str(tmp_path / f"{first}-{again}.nc")
        store = WorkStore.open(out, manifest, given_block_size=False)
        store.allow_replace(first)
        assert store.replace_output is first
        store.close()
        resumed = WorkStore.open(out, manifest, given_block_size=False)
        assert not resumed.created
        resumed.allow_replace(again)
        assert resumed.replace_output is replaces
        resumed.remove()
