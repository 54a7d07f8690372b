"""Where and with what a measurement ran: CPU model, git revision, versions.

Every report prints these next to its numbers (a time per point means nothing without the
machine and the exact solver that produced it); ``benchmarks/`` prints them too.
"""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
from pathlib import Path

# The package directory: the sources hashed by source_digest, and where git is asked.
PACKAGE_DIR = Path(__file__).resolve().parent.parent


def cpu_model() -> str:
    """The CPU's model name from ``/proc/cpuinfo`` (Linux), else what :mod:`platform` knows."""
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or platform.machine()


def machine() -> str:
    """``"<CPU model>, <n> cores, <OS> <release>"``."""
    return f"{cpu_model()}, {os.cpu_count()} cores, {platform.system()} {platform.release()}"


def git_revision() -> str:
    """Short hash of the checkout the package runs from, flagged when it has uncommitted
    changes; ``"unknown"`` outside a git checkout or without git."""
    try:
        rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=PACKAGE_DIR,
                             capture_output=True, text=True, timeout=5)
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               cwd=PACKAGE_DIR, capture_output=True, text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return "unknown"
    if rev.returncode != 0:
        return "unknown"
    return rev.stdout.strip() + (" (with uncommitted changes)" if dirty.stdout.strip() else "")


def source_digest() -> str:
    """sha256 (12 hex digits) of every source file of the package: which solver exactly ran,
    also for an installed copy that has no git revision."""
    digest = hashlib.sha256()
    for path in sorted(PACKAGE_DIR.rglob("*.py")):
        digest.update(path.relative_to(PACKAGE_DIR).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:12]


def versions(**others) -> str:
    """cosserat-channel (version, git revision, source digest), Python, numba, numpy and scipy,
    then ``name version`` for each keyword, in order (e.g. ``dask=dask.__version__``)."""
    import numba
    import numpy
    import scipy

    from .. import __version__

    text = (f"cosserat-channel {__version__} (git {git_revision()}, package sources sha256 "
            f"{source_digest()}), Python {platform.python_version()}, numba {numba.__version__}, "
            f"numpy {numpy.__version__}, scipy {scipy.__version__}")
    return text + "".join(f", {name} {v}" for name, v in others.items())
