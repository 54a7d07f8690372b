"""Writing files safely: check an output path before any work, replace files only when complete.

Every file this package writes (NetCDF results, working-store blocks, figures, query output)
goes through :func:`atomic_output`, so an existing file is never left half-written, and every
command checks its output path with :func:`output_problem` before it computes anything.
"""

from __future__ import annotations

import os
import secrets
import shutil
from typing import Callable


class WriteError(OSError):
    """A file could not be written; the message is one line that names the file and the reason.

    Raised by :func:`netcdf_output` instead of whatever the writer raised (netCDF4 reports a full
    disk as ``RuntimeError: NetCDF: HDF error``, the operating system as ``OSError``), so callers
    catch one type.
    """


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


def output_problem(path) -> str | None:
    """Why a file cannot be created at ``path`` (one line), or None when it can."""
    path = os.fspath(path)
    if not path.strip():
        return "the output file name is empty"
    directory = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        return f"cannot write {path!r}: it is a directory; give a file name"
    if not os.path.isdir(directory):
        return f"cannot write {path!r}: directory {directory!r} does not exist"
    if not os.access(directory, os.W_OK | os.X_OK):
        return f"cannot write {path!r}: directory {directory!r} is not writable"
    return None


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


def atomic_output(path, write: Callable[[str], None], tmp_dir=None) -> None:
    """Call ``write(tmp)`` for a fresh temporary path, then rename it onto ``path``.

    ``tmp`` lies in ``tmp_dir`` (default: the directory of ``path``), which must be on the same
    file system so that ``os.replace`` is atomic. The temporary file is removed if ``write``
    fails or the process is interrupted, and ``path`` keeps whatever it held before.
    """
    path = os.fspath(path)
    directory, name = os.path.split(os.path.abspath(path))
    tmp = os.path.join(tmp_dir or directory, f".{name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise


def netcdf_output(path, write: Callable[[str], None], tmp_dir=None) -> None:
    """:func:`atomic_output` for a NetCDF writer: a failure to write is a :class:`WriteError`.

    netCDF4 reports a full disk (or any failed write of the HDF5 library) as a plain
    ``RuntimeError: NetCDF: HDF error``, not as an ``OSError``; both become one
    :class:`WriteError` (an ``OSError``) that names the file. Other errors pass unchanged.
    """
    try:
        atomic_output(path, write, tmp_dir)
    except WriteError:
        raise
    except (OSError, RuntimeError) as exc:
        if not isinstance(exc, OSError) and type(exc) is not RuntimeError:
            raise  # RecursionError, NotImplementedError: bugs, not write failures
        raise write_failure(path, exc) from None
