"""Writing files safely: check an output path before any work, replace files only when complete.

Every file this package writes (NetCDF results, working-store blocks, figures, query output)
goes through :func:`atomic_output`, so an existing file is never left half-written, and every
command checks its output path with :func:`output_problem` before it computes anything.
"""

from __future__ import annotations

import os
import secrets
from typing import Callable


def output_problem(path) -> str | None:
    """Why a file cannot be created at ``path`` (one line), or None when it can."""
    path = os.fspath(path)
    directory = os.path.dirname(os.path.abspath(path))
    if os.path.isdir(path):
        return f"cannot write {path!r}: it is a directory; give a file name"
    if not os.path.isdir(directory):
        return f"cannot write {path!r}: directory {directory!r} does not exist"
    if not os.access(directory, os.W_OK | os.X_OK):
        return f"cannot write {path!r}: directory {directory!r} is not writable"
    return None


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
        except FileNotFoundError:
            pass
        raise
