"""A writer killed inside a save (SIGKILL, out of memory) leaves its temporary file beside the
output; the next save of that output removes it, and nothing else: not another output's, not a
live process's, not a FIFO, directory or link that bears such a name."""

from __future__ import annotations

import os
import pathlib
import stat
import signal
import subprocess
import sys
import textwrap

import pytest

from cosserat_channel import files

# A child that starts writing OUT and is killed (SIGKILL) before the rename.
KILLED_IN_A_SAVE = textwrap.dedent("""
    import os, signal, sys
    from cosserat_channel import files

    def write(f):
        f.write("half")
        f.flush()
        os.kill(os.getpid(), signal.SIGKILL)

    files.write_text(sys.argv[1], write)
""")


def _dead_pid() -> int:
    proc = subprocess.Popen([sys.executable, "-c", "pass"])
    proc.wait()
    return proc.pid


def test_the_next_save_removes_what_a_killed_save_left_and_nothing_else(tmp_path):
    out = tmp_path / "fit.json"
    proc = subprocess.run([sys.executable, "-c", KILLED_IN_A_SAVE, str(out)], timeout=120)
    assert proc.returncode == -signal.SIGKILL
    left = [p.name for p in tmp_path.iterdir()]
    assert len(left) == 1 and not out.exists()
    # The leftover says what it is: the output's name, the tool's, its writer's pid.
    assert left[0].startswith(".fit.json.cosserat-channel.") and left[0].endswith(".tmp")
    assert (tmp_path / left[0]).read_text() == "half"

    # Beside it, what must stay: another output's leftover, a live process's temporary file,
    # names of a dead writer that are a FIFO, a directory and a link, a file of the pattern
    # with a word for the tag, and a file of the former pattern (no tool, no machine).
    dead = _dead_pid()
    prefix = files._temp_prefix(out)
    keep = {
        files.temp_path(tmp_path, tmp_path / "other.json").replace(
            f".{os.getpid()}.", f".{dead}."): "file",
        os.path.basename(files.temp_path(tmp_path, out)): "file",  # this process: alive
        f"{prefix}{dead}.0123abcd.tmp.bak": "file",
        f"{prefix}{dead}.fifo0000.tmp": "file",
        f"{prefix}{dead}.aaaaaaaa.tmp": "fifo",
        f"{prefix}{dead}.bbbbbbbb.tmp": "dir",
        f"{prefix}{dead}.cccccccc.tmp": "link",
        f".fit.json.{dead}.dddddddd.tmp": "file",
    }
    target = tmp_path / "target"
    target.write_text("the link's target")
    for name, kind in keep.items():
        p = tmp_path / os.path.basename(name)
        if kind == "file":
            p.write_text("keep")
        elif kind == "fifo":
            os.mkfifo(p)
        elif kind == "dir":
            p.mkdir()
        else:
            p.symlink_to(target)
    stale_too = tmp_path / f"{prefix}{dead}.0123abcd.tmp"
    stale_too.write_text("also left by a dead writer")
    before = sorted(p.name for p in tmp_path.iterdir())

    files.write_text(out, "{}\n", replace=False)
    assert out.read_text() == "{}\n"
    after = sorted(p.name for p in tmp_path.iterdir())
    assert set(before) - set(after) == {left[0], stale_too.name}
    assert set(after) - set(before) == {"fit.json"}
    assert target.read_text() == "the link's target"


@pytest.mark.parametrize("pid", ["this process", 9_999_999_999])
def test_a_temporary_of_a_live_or_impossible_pid_is_left_alone(tmp_path, pid):
    # (the live pid is taken inside the test: parallel test workers must collect the same ids)
    pid = os.getpid() if pid == "this process" else pid
    out = tmp_path / "a.nc"
    tmp = tmp_path / f"{files._temp_prefix(out)}{pid}.0123abcd.tmp"
    tmp.write_text("x")
    assert files.remove_stale_temporaries(tmp_path, out) == []
    assert tmp.read_text() == "x"


# A child that streams OUT (a FIFO) through a private directory in TMP and is killed (SIGKILL)
# while it writes there, before anything reaches the FIFO.
KILLED_IN_A_STREAM = textwrap.dedent("""
    import os, signal, sys
    from cosserat_channel import files

    def write(tmp):
        with open(tmp, "w") as f:
            f.write("half")
        os.kill(os.getpid(), signal.SIGKILL)

    files.atomic_output(sys.argv[1], write, tmp_dir=sys.argv[2])
""")


def _read_fifo(path, got):
    import threading

    def read():
        with open(path, "rb") as f:
            got.append(f.read())

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    return reader


def test_the_next_stream_removes_the_private_directory_a_killed_stream_left_and_nothing_else(
        tmp_path):
    fifo, tmp = tmp_path / "out.nc", tmp_path / "tmp"
    os.mkfifo(fifo)
    tmp.mkdir()
    proc = subprocess.run([sys.executable, "-c", KILLED_IN_A_STREAM, str(fifo), str(tmp)],
                          timeout=120)
    assert proc.returncode == -signal.SIGKILL
    left = [p.name for p in tmp.iterdir()]
    assert len(left) == 1 and left[0].startswith(files._temp_prefix(fifo))
    assert [p.read_text() for p in (tmp / left[0]).iterdir()] == ["half"]

    # Beside it, what must stay: a live process's private directory, a dead writer's that holds
    # a directory or a link (not what the tool leaves), another output's, and a plain file.
    dead, prefix = _dead_pid(), files._temp_prefix(fifo)
    live = tmp / os.path.basename(files.temp_path(tmp, fifo))
    nested = tmp / f"{prefix}{dead}.0000aaaa.tmp"
    linked = tmp / f"{prefix}{dead}.0000bbbb.tmp"
    other = tmp / os.path.basename(files.temp_path(tmp, tmp_path / "other.nc")).replace(
        f".{os.getpid()}.", f".{dead}.")
    for d in (live, nested, linked, other):
        d.mkdir()
        (d / "x").write_text("keep")
    (nested / "sub").mkdir()
    (linked / "to").symlink_to(tmp_path / "out.nc")
    plain = tmp / f"{prefix}{dead}.0000cccc.tmp"
    plain.write_text("keep")
    before = sorted(p.name for p in tmp.iterdir())

    got = []
    reader = _read_fifo(fifo, got)
    files.atomic_output(fifo, lambda t: pathlib.Path(t).write_bytes(b"whole"), tmp_dir=tmp)
    reader.join(60)
    assert got == [b"whole"]
    after = sorted(p.name for p in tmp.iterdir())
    assert set(before) - set(after) == {left[0]} and not set(after) - set(before)
    assert all((d / "x").read_text() == "keep" for d in (live, nested, linked, other))
    assert plain.read_text() == "keep" and stat.S_ISFIFO(os.lstat(fifo).st_mode)
