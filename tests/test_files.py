"""Writing files safely: what is at an output path decides how it is written, or whether at all.

Faults made on purpose with private device nodes (``os.mknod``; the tests run as root where the
nodes can be made, and are skipped elsewhere) and FIFOs, all in a temporary directory: a
character device or a FIFO receives the output as a stream and is never renamed over; a
directory, a socket or a block device is refused in one line and left as it was.
"""

from __future__ import annotations

import os
import socket
import stat
import threading

import pytest

from cosserat_channel import cli, files
from cosserat_channel.sweep import run_sweep
from support import SMALL_SWEEP as SMALL

QUERY = ("--sel", "K=0.5", "--format", "csv")
PLOT = ("--x", "eps", "--y", "Delta", "--hue", "K")


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    """A small result file of 'run'."""
    d = tmp_path_factory.mktemp("result")
    (d / "s.toml").write_text(SMALL)
    out = d / "s.nc"
    run_sweep(str(d / "s.toml"), str(out), workers=1).close()
    return out


def char_device(path):
    """A private node of the null device (major 1, minor 3) at ``path``; skip where it cannot be
    made (not root)."""
    return _device_node(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))


def block_device(path):
    """A private block-device node at ``path`` (never opened: it must be refused)."""
    return _device_node(path, 0o600 | stat.S_IFBLK, os.makedev(7, 250))


def _device_node(path, mode, device):
    try:
        os.mknod(path, mode, device)
    except PermissionError:
        pytest.skip("making a device node needs root")
    return path


def identity(path):
    """What must not change about a node the program did not make: inode, type, device."""
    st = os.lstat(path)
    return st.st_ino, stat.S_IFMT(st.st_mode), st.st_rdev


class FifoReader:
    """Reads everything written into a FIFO, in a thread (opening a FIFO waits for both ends)."""

    def __init__(self, path):
        self.data = None
        self.thread = threading.Thread(target=self._read, args=(path,), daemon=True)
        self.thread.start()

    def _read(self, path):
        with open(path, "rb") as f:
            self.data = f.read()

    def result(self, timeout=60.0) -> bytes | None:
        self.thread.join(timeout)
        return self.data


def one_line_error(capsys, *words):
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and err.startswith("cosserat-channel: error:"), err
    for w in words:
        assert w in err, err
    return err


# ---------------------------------------------------------------------------------------------
# files.atomic_output
# ---------------------------------------------------------------------------------------------
def write_text(text):
    def write(tmp):
        with open(tmp, "w") as f:
            f.write(text)
    return write


def test_atomic_output_streams_into_a_fifo_and_keeps_it(tmp_path):
    """A FIFO receives the complete file and stays the FIFO it was; no temporary file is left."""
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    before = identity(fifo)
    reader = FifoReader(fifo)
    files.atomic_output(fifo, write_text("a,b\n1,2\n"))
    assert reader.result() == b"a,b\n1,2\n"
    assert identity(fifo) == before
    assert os.listdir(tmp_path) == ["pipe"]


def test_atomic_output_writes_into_a_character_device_and_keeps_it(tmp_path):
    node = char_device(tmp_path / "null")
    before = identity(node)
    files.atomic_output(node, write_text("x" * 100_000))
    assert identity(node) == before
    assert os.listdir(tmp_path) == ["null"]


def test_atomic_output_refuses_what_is_not_a_file(tmp_path):
    """A directory, a socket, a block device, and a device or FIFO where a file is needed
    (stream=False): WriteError naming the path, nothing written, the node unchanged."""
    (tmp_path / "dir").mkdir()
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(tmp_path / "sock"))
    os.mkfifo(tmp_path / "pipe")
    cases = [(tmp_path / "dir", True), (tmp_path / "sock", True), (tmp_path / "pipe", False)]
    try:
        cases.append((block_device(tmp_path / "blk"), True))
        cases.append((char_device(tmp_path / "null"), False))
    finally:
        names = sorted(os.listdir(tmp_path))
        for path, stream in cases:
            before = identity(path)
            with pytest.raises(files.WriteError, match="not a file") as err:
                files.atomic_output(path, write_text("x"), stream=stream)
            assert str(path) in str(err.value) and "\n" not in str(err.value)
            assert identity(path) == before
            assert files.output_problem(path, stream=stream) == str(err.value)
        assert sorted(os.listdir(tmp_path)) == names
        sock.close()


# ---------------------------------------------------------------------------------------------
# The commands: query -o, plot -o, run -o
# ---------------------------------------------------------------------------------------------
def test_query_and_plot_stream_into_a_fifo(result, tmp_path, capsys):
    """query -o FIFO gives the reader what stdout gives; plot -o FIFO a PNG; the FIFO stays."""
    assert cli.main(["query", str(result), *QUERY]) == 0
    expected = capsys.readouterr().out.encode()
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    before = identity(fifo)
    reader = FifoReader(fifo)
    assert cli.main(["query", str(result), *QUERY, "-o", str(fifo)]) == 0
    assert reader.result() == expected
    reader = FifoReader(fifo)
    assert cli.main(["plot", str(result), *PLOT, "-o", str(fifo)]) == 0  # no suffix: PNG
    assert reader.result()[:8] == b"\x89PNG\r\n\x1a\n"
    assert identity(fifo) == before
    assert os.listdir(tmp_path) == ["pipe"]


def test_query_and_plot_write_into_a_character_device_and_keep_it(result, tmp_path):
    node = char_device(tmp_path / "null.png")
    before = identity(node)
    assert cli.main(["query", str(result), *QUERY, "-o", str(node)]) == 0
    assert cli.main(["query", str(result), "--sel", "K=0.5", "--format", "netcdf",
                     "-o", str(node)]) == 0
    assert cli.main(["plot", str(result), *PLOT, "-o", str(node)]) == 0
    assert identity(node) == before
    assert os.listdir(tmp_path) == ["null.png"]


def test_commands_refuse_a_directory_socket_or_block_device(result, tmp_path, capsys):
    """Exit 2, one line naming the path, before any work; the node is left as it was."""
    (tmp_path / "dir.png").mkdir()
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(tmp_path / "sock.png"))
    try:
        targets = [tmp_path / "dir.png", tmp_path / "sock.png", block_device(tmp_path / "blk.png")]
        toml = result.with_name("s.toml")
        for target in targets:
            before = identity(target)
            for argv in (["query", str(result), *QUERY, "-o", str(target)],
                         ["plot", str(result), *PLOT, "-o", str(target)],
                         ["run", str(toml), "-o", str(target)]):
                assert cli.main(argv) == 2
                one_line_error(capsys, str(target), "not a file")
            assert identity(target) == before
    finally:
        sock.close()
    assert sorted(os.listdir(tmp_path)) == ["blk.png", "dir.png", "sock.png"]


def test_run_refuses_a_fifo_or_character_device(result, tmp_path, capsys):
    """run renames its result onto the output from the store beside it: a FIFO or a device is
    refused (exit 2, one line) and no store is made."""
    toml = result.with_name("s.toml")
    os.mkfifo(tmp_path / "pipe.nc")
    for target in (tmp_path / "pipe.nc", char_device(tmp_path / "null.nc")):
        before = identity(target)
        assert cli.main(["run", str(toml), "-o", str(target)]) == 2
        one_line_error(capsys, str(target), "not a file")
        assert identity(target) == before
    assert sorted(os.listdir(tmp_path)) == ["null.nc", "pipe.nc"]


# ---------------------------------------------------------------------------------------------
# Long names
# ---------------------------------------------------------------------------------------------
def test_long_output_names_are_written_or_refused_before_any_work(result, tmp_path, capsys,
                                                                    monkeypatch):
    """A name the file system holds is written, however long (the temporary name is not much
    longer than a short one's); a longer one, or one whose working store's name would be, is
    refused in one line before any work."""
    from cosserat_channel.solver import point
    from cosserat_channel.sweep import block

    fits = tmp_path / ("q" * 251 + ".csv")  # 255 bytes, NAME_MAX on common file systems
    assert cli.main(["query", str(result), *QUERY, "-o", str(fits)]) == 0
    png = tmp_path / ("p" * 251 + ".png")
    assert cli.main(["point", "--eps", "0.0333", "--L", "10", "--K", "0.5", "--A", "0.333",
                     "--N", "1", "--plot", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(os.listdir(tmp_path)) == sorted([fits.name, png.name])
    capsys.readouterr()

    monkeypatch.setattr(point, "solve_point", lambda *a, **k: pytest.fail("solved anyway"))
    # (every caller imports warm_up from the block module when it needs it)
    monkeypatch.setattr(block, "warm_up", lambda *a, **k: pytest.fail("loaded the solver"))
    too_long = str(tmp_path / ("x" * 252 + ".csv"))
    store_too_long = str(tmp_path / ("r" * 245 + ".nc"))  # its store: 256 bytes
    for argv, name in (
            (["query", str(result), *QUERY, "-o", too_long], too_long),
            (["point", "--eps", "0.0333", "--L", "10", "--K", "0.5", "--A", "0.333", "--N", "1",
              "--plot", too_long + ".png"], too_long + ".png"),
            (["run", str(result.with_name("s.toml")), "-o", store_too_long],
             store_too_long + ".partial")):
        assert cli.main(argv) == 2
        one_line_error(capsys, name, "bytes long")
    assert sorted(os.listdir(tmp_path)) == sorted([fits.name, png.name])
