"""Writing files safely: check an output path before any work, replace files only when complete.

Every file this package writes (NetCDF results, working-store blocks, figures, query output)
goes through :func:`atomic_output`, so an existing file is never left half-written, and every
command checks its output path with :func:`output_problem` before it computes anything.

What is at an output path decides how it is written (:func:`output_kind`, the one place that
says): nothing or a regular file is written under a temporary name and renamed onto it; a
character device or a FIFO (``/dev/stdout``, a named pipe) receives the complete file as a
stream and is never renamed over; anything else (a directory, a socket, a block device) is
refused in one line.
"""

from __future__ import annotations

import errno
import os
import secrets
import shutil
import stat
import tempfile
from typing import Callable

# What output_kind finds at a path (or, for what may not be written, a description of it).
NEW, FILE, STREAM = "new", "file", "stream"
# Bytes of an output's name kept in its temporary name: with the pid and a random tag that stays
# far below NAME_MAX (255 on every common file system), however long the output's own name.
TMP_STEM = 64
# The tool's name in its temporary names: what makes a leftover recognisably its own.
TMP_TOOL = "cosserat-channel"
# The file that marks a directory as a sweep's working store (see sweep.store): the run that
# made it deletes it with all it holds, so no output may be written inside one.
STORE_MARKER = "cosserat-channel-store"


class WriteError(OSError):
    """A file could not be written; the message is one line that names the file and the reason.

    Raised by :func:`netcdf_output` instead of whatever the writer raised (netCDF4 reports a full
    disk as ``RuntimeError: NetCDF: HDF error``, the operating system as ``OSError``), so callers
    catch one type.
    """


class OutputAppeared(WriteError):
    """A file appeared at an output path while the output was made (another run, another user):
    it is kept, and the new output is kept beside it under the name the message gives."""


def write_failure(path, exc: BaseException) -> WriteError:
    """A :class:`WriteError` for ``exc`` raised while writing ``path``.

    An ``OSError`` says why itself (``No space left on device``); the HDF5 library's errors do
    not, so for those the free space of the file system is added: it is usually the reason.
    """
    path = os.fspath(path)
    if isinstance(exc, OSError) and exc.strerror:
        reason = exc.strerror
    else:
        reason = " ".join(str(exc).split()) or type(exc).__name__
        free = free_space(path)
        if free is not None:
            reason += f" (the file system has {format_size(free)} free; a full disk is the usual cause)"
    err = WriteError(f"cannot write {path!r}: {reason}")
    err.__cause__ = None
    return err


def format_size(n: int) -> str:
    """``n`` bytes for people: ``512 B``, ``1.5 GB``."""
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n} B"


def output_kind(path) -> str:
    """What is at ``path``, following symbolic links: :data:`NEW` (nothing, or a dangling link),
    :data:`FILE` (a regular file), :data:`STREAM` (a character device or a FIFO), or for anything
    else a description of it ("a directory", "a socket", "a block device")."""
    try:
        mode = os.stat(path).st_mode
    except OSError:
        # Missing, or unreachable (a dangling link, a component that is not a directory): the
        # writer meets the same error and reports it.
        return NEW
    if stat.S_ISREG(mode):
        return FILE
    if stat.S_ISCHR(mode) or stat.S_ISFIFO(mode):
        return STREAM
    return describe(mode)


def describe(mode: int) -> str:
    """What a file of mode ``mode`` (``os.lstat(...).st_mode``) is, for a message."""
    for test, what in ((stat.S_ISREG, "a regular file"), (stat.S_ISDIR, "a directory"),
                       (stat.S_ISLNK, "a symbolic link"), (stat.S_ISFIFO, "a FIFO"),
                       (stat.S_ISCHR, "a character device"), (stat.S_ISSOCK, "a socket"),
                       (stat.S_ISBLK, "a block device")):
        if test(mode):
            return what
    return "not a regular file"


def _not_a_file(path: str, kind: str) -> str:
    what = "a character device or a FIFO" if kind == STREAM else kind
    return f"cannot write {path!r}: it is {what}, not a file; give a file name"


def output_problem(path, stream: bool = True, overwrite: bool = False) -> str | None:
    """Why a file cannot be written at ``path`` (one line), or None when it can.

    ``stream``: whether a character device or a FIFO at ``path`` may receive the file as a
    stream (:func:`atomic_output`); a writer that needs a real file beside others (a sweep's
    result and its working store) passes False and such a path is refused.
    ``overwrite``: whether a file already at ``path`` (or a symbolic link) may be replaced;
    without it the file is kept and the output refused.
    """
    path = os.fspath(path)
    if not path.strip():
        return "the output file name is empty"
    kind = output_kind(path)
    if kind == STREAM and stream:
        if not os.access(path, os.W_OK):
            return f"cannot write {path!r}: it is not writable"
        return None
    if kind not in (NEW, FILE):
        return _not_a_file(path, kind)
    if not overwrite and (kind == FILE or os.path.lexists(path)):
        return f"{path!r} exists; kept: add --overwrite to replace it, or choose another name"
    store = working_store_around(path)
    if store is not None:
        return (f"cannot write {path!r}: it is inside {store!r}, the working store of a run, "
                "which is deleted with all it holds when that run finishes; write elsewhere")
    directory = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(directory):
        return f"cannot write {path!r}: directory {directory!r} does not exist"
    if not os.access(directory, os.W_OK | os.X_OK):
        return f"cannot write {path!r}: directory {directory!r} is not writable"
    return name_problem(path)


def name_problem(path) -> str | None:
    """Why the file system of ``path``'s directory (which exists) cannot hold a file of its name
    (one line), or None when it can."""
    path = os.fspath(path)
    directory, name = os.path.split(os.path.abspath(path))
    try:
        limit = os.pathconf(directory, "PC_NAME_MAX")
    except (OSError, ValueError):
        limit = 255
    n = len(os.fsencode(name))
    if n > limit:
        return (f"cannot write {path!r}: its name is {n} bytes long, more than the {limit} the file "
                "system allows; choose a shorter name")
    return None


def _temp_prefix(path) -> str:
    """What every temporary name of ``path`` begins with: a dot, the first :data:`TMP_STEM`
    bytes of its name, the tool's name and this machine's tag (``.out.nc.cosserat-channel.
    1a2b3c.``); the writer's pid, a random tag and ``.tmp`` follow."""
    import hashlib
    import socket

    name = os.fsencode(os.path.basename(os.path.abspath(os.fspath(path))))
    host = hashlib.sha256(socket.gethostname().encode(errors="replace")).hexdigest()[:6]
    return f".{os.fsdecode(name[:TMP_STEM])}.{TMP_TOOL}.{host}."


def temp_path(directory, path) -> str:
    """A fresh temporary name in ``directory`` for a file that becomes ``path``: a hidden name
    ending in ``.tmp`` that says which tool, machine and process writes it, short enough for
    any file system whatever the length of ``path``'s."""
    return os.path.join(directory,
                        f"{_temp_prefix(path)}{os.getpid()}.{secrets.token_hex(4)}.tmp")


def _alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this machine (another user's counts)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except (PermissionError, OverflowError, ValueError):
        return True  # someone else's, or beyond what a pid can be: not ours to judge dead
    return True


def remove_stale_temporaries(directory, path, private: bool = False) -> list[str]:
    """Remove the temporary files of ``path`` in ``directory`` that a killed writer left: only
    regular files of this user whose whole name is one :func:`temp_path` gives for ``path`` on
    this machine and whose process is gone. Anything else (another output's, a live process's,
    a FIFO or directory of that name, another user's) is left alone. Returns the names removed.

    With ``private``, the same for the private directories of a streamed output
    (:func:`_stream_output`): directories of this user that hold nothing but regular files,
    removed with them.
    """
    import re

    prefix = _temp_prefix(path)
    pattern = re.compile(re.escape(prefix) + r"([0-9]{1,10})\.[0-9a-f]{8}\.tmp")
    removed = []
    try:
        entries = [e.name for e in os.scandir(directory) if e.name.startswith(prefix)]
    except OSError:
        return removed
    for name in entries:
        match = pattern.fullmatch(name)
        if match is None or int(match[1]) == os.getpid() or _alive(int(match[1])):
            continue
        full = os.path.join(directory, name)
        try:
            if not _ours(full, stat.S_ISDIR if private else stat.S_ISREG):
                continue
            if private:
                inside = [os.path.join(full, n) for n in os.listdir(full)]
                if not all(_ours(f, stat.S_ISREG) for f in inside):
                    continue
                for f in inside:
                    os.unlink(f)
                os.rmdir(full)
            else:
                os.unlink(full)
        except OSError:
            continue
        removed.append(name)
    return removed


def _ours(path: str, kind: Callable[[int], bool]) -> bool:
    """Whether ``path`` itself (a link is not followed) is of ``kind`` (``stat.S_ISREG``, ...)
    and belongs to this user."""
    info = os.lstat(path)
    return kind(info.st_mode) and not (hasattr(os, "getuid") and info.st_uid != os.getuid())


def working_store_around(path) -> str | None:
    """The working store (a directory holding :data:`STORE_MARKER`) that ``path`` lies inside,
    symbolic links resolved, or None."""
    d = os.path.realpath(os.path.dirname(os.path.abspath(os.fspath(path))))
    while True:
        if os.path.isfile(os.path.join(d, STORE_MARKER)):
            return d
        parent = os.path.dirname(d)
        if parent == d:
            return None
        d = parent


def free_space(path) -> int | None:
    """Free bytes on the file system that would hold ``path``, or None when it cannot say."""
    try:
        return shutil.disk_usage(os.path.dirname(os.path.abspath(os.fspath(path)))).free
    except OSError:
        return None


def space_problem(path, need: int) -> str | None:
    """Why ``need`` more bytes will not fit beside ``path`` (one line), or None when they will
    (or when the file system cannot say)."""
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    free = free_space(path)
    if free is None or need <= free:
        return None
    return (f"cannot write {path!r}: the run needs about {format_size(need)} of disk space and "
            f"the file system of {directory!r} has {format_size(free)} free; free some space or "
            "write elsewhere")


def atomic_output(path, write: Callable[[str], None], tmp_dir=None, stream: bool = True,
                  replace: bool = True) -> None:
    """Call ``write(tmp)`` for a fresh temporary path, then rename it onto ``path``.

    ``tmp`` lies in ``tmp_dir`` (default: the directory of ``path``), which must be on the same
    file system so that the rename is atomic. The temporary file is removed if ``write``
    fails or the process is interrupted, and ``path`` keeps whatever it held before.

    ``replace``: whether a file at ``path`` may be replaced. Without it the output is published
    without replacing (:func:`publish_new`): a file that appeared at ``path`` while the output
    was made (after the caller checked it was free) is kept, the new output is kept beside it
    (:func:`keep_beside`), and :class:`OutputAppeared` says both in one line.

    A character device or a FIFO at ``path`` (``stream`` True) is not renamed over: the complete
    file is copied into it (opening a FIFO waits for its reader, as a shell's ``>`` does).
    Anything else that is not a regular file (a directory, a socket, a block device; a device
    or a FIFO when ``stream`` is False) is a :class:`WriteError` and nothing is written.
    """
    path = os.fspath(path)
    kind = output_kind(path)
    if kind == STREAM and stream:
        _stream_output(path, write, tmp_dir)
        return
    if kind not in (NEW, FILE):
        raise WriteError(_not_a_file(path, kind))
    directory = tmp_dir or os.path.dirname(os.path.abspath(path))
    # What a writer of this output killed before (SIGKILL, out of memory) left beside it.
    remove_stale_temporaries(directory, path)
    tmp = temp_path(directory, path)
    try:
        write(tmp)
        if replace:
            os.replace(tmp, path)
        else:
            try:
                publish_new(tmp, path)
            except FileExistsError:
                kept = keep_beside(tmp, path)
                raise OutputAppeared(
                    f"{path!r} appeared while the output was made and is kept; the new output "
                    f"is {kept!r} (rename it yourself, or run again with --overwrite)") from None
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


# renameat2's flag that makes the rename fail with EEXIST instead of replacing (Linux >= 3.15).
_RENAME_NOREPLACE = 1
_AT_FDCWD = -100


def _renameat2():
    """libc's ``renameat2``, or None where there is none (another system, an old C library)."""
    try:
        import ctypes

        f = ctypes.CDLL(None, use_errno=True).renameat2
    except (ImportError, OSError, AttributeError):
        return None
    f.argtypes = (ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint)
    f.restype = ctypes.c_int
    return f


def publish_new(src, dst) -> None:
    """Rename ``src`` to ``dst`` only if nothing is at ``dst``, atomically: FileExistsError
    (and ``src`` left as it is) when something is.

    ``renameat2(RENAME_NOREPLACE)`` where the system has it; else a hard link (which never
    replaces) and the unlink of ``src``. On a file system with neither (no hard links) the check
    and the rename are two steps: a file appearing between them is the only one replaced.
    """
    import ctypes

    src, dst = os.fsencode(os.fspath(src)), os.fsencode(os.fspath(dst))
    f = _renameat2()
    if f is not None:
        if f(_AT_FDCWD, src, _AT_FDCWD, dst, _RENAME_NOREPLACE) == 0:
            return
        err = ctypes.get_errno()
        if err not in (errno.ENOSYS, errno.EINVAL, errno.ENOTSUP, errno.EOPNOTSUPP):
            raise OSError(err, os.strerror(err), os.fsdecode(dst))
    try:
        os.link(src, dst)
    except FileExistsError:
        raise
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.ENOSYS):
            raise
        if os.path.lexists(dst):
            raise FileExistsError(errno.EEXIST, os.strerror(errno.EEXIST),
                                  os.fsdecode(dst)) from None
        os.rename(src, dst)
        return
    os.unlink(src)


def keep_beside(src, path) -> str:
    """Move ``src`` to a fresh name beside ``path`` (``fit.json`` -> ``fit.new.json``,
    ``fit.new-2.json``, ...) without replacing anything; returns that name, or ``src`` itself
    when it cannot be moved (it is then left where it is)."""
    root, ext = os.path.splitext(os.fspath(path))
    for n in range(1, 100):
        candidate = f"{root}.new{'' if n == 1 else f'-{n}'}{ext}"
        try:
            publish_new(src, candidate)
            return candidate
        except FileExistsError:
            continue
        except OSError:
            break
    return os.fspath(src)


def write_text(path, text, replace: bool = True) -> None:
    """Write a text file atomically (:func:`atomic_output`, which says what ``replace`` does):
    UTF-8, line ends as given.

    ``text`` is a string, or a callable that writes into the open text file.
    """

    def write(tmp):
        # newline="": the text's own line ends on every platform (a CSV's "\n" stays "\n").
        with open(tmp, "w", encoding="utf-8", newline="") as f:
            if callable(text):
                text(f)
            else:
                f.write(text)

    atomic_output(path, write, replace=replace)


def _stream_output(path: str, write: Callable[[str], None], tmp_dir) -> None:
    """:func:`atomic_output` into a character device or a FIFO: ``write`` a temporary file in a
    private directory (in ``tmp_dir``, default the system's; named as :func:`temp_path` names
    a temporary file, so that the next streamed output of ``path`` removes it if a killed
    writer left it), then copy it into ``path``."""
    parent = tempfile.gettempdir() if tmp_dir is None else os.fspath(tmp_dir)
    remove_stale_temporaries(parent, path, private=True)
    work = temp_path(parent, path)
    os.mkdir(work, 0o700)
    try:
        tmp = os.path.join(work, os.path.basename(os.path.abspath(path)) or "output")
        write(tmp)
        # No O_CREAT: if the device or FIFO went away meanwhile, nothing is created in its place.
        fd = os.open(path, os.O_WRONLY | os.O_NOCTTY | os.O_CLOEXEC)
        with open(fd, "wb") as dst:
            mode = os.fstat(fd).st_mode
            if not (stat.S_ISCHR(mode) or stat.S_ISFIFO(mode)):  # replaced since it was looked at
                raise WriteError(f"cannot write {path!r}: it changed while the output was made; "
                                 "nothing written, run again")
            with open(tmp, "rb") as src:
                shutil.copyfileobj(src, dst, 1 << 20)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def netcdf_output(path, write: Callable[[str], None], tmp_dir=None, stream: bool = True,
                  replace: bool = True) -> None:
    """:func:`atomic_output` for a NetCDF writer: a failure to write is a :class:`WriteError`.

    netCDF4 reports a full disk (or any failed write of the HDF5 library) as a plain
    ``RuntimeError: NetCDF: HDF error``, not as an ``OSError``; both become one
    :class:`WriteError` (an ``OSError``) that names the file. Other errors pass unchanged.
    """
    try:
        atomic_output(path, write, tmp_dir, stream, replace)
    except WriteError:
        raise
    except (OSError, RuntimeError) as exc:
        if not isinstance(exc, OSError) and type(exc) is not RuntimeError:
            raise  # RecursionError, NotImplementedError: bugs, not write failures
        raise write_failure(path, exc) from None


def save_npz(path, arrays) -> None:
    """``np.savez`` of ``arrays`` (name -> array) at exactly ``path``: through a file object,
    since given a name without ``.npz`` numpy would append it (a temporary name has none)."""
    import numpy as np

    with open(path, "wb") as f:
        np.savez(f, **arrays)


def write_npz(path, arrays, **options) -> None:
    """Write ``arrays`` as an uncompressed ``.npz`` file atomically (:func:`atomic_output`, which
    takes ``options``)."""
    atomic_output(path, lambda tmp: save_npz(tmp, arrays), **options)


def write_dataset(path, ds, **options) -> None:
    """Write an xarray Dataset as NetCDF with the package's encoding
    (:func:`cosserat_channel.netcdf_policy.encoding`: compressed, checksummed) through
    :func:`netcdf_output` (which takes ``options``)."""
    from . import netcdf_policy

    netcdf_output(path, lambda tmp: ds.to_netcdf(tmp, encoding=netcdf_policy.encoding(ds)),
                  **options)
