"""Where and with what a measurement ran: CPU model, git revision, versions.

Every report prints these next to its numbers (a time per point means nothing without the
machine and the exact solver that produced it); ``benchmarks/`` prints them too.
"""

from __future__ import annotations

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


def os_name() -> str:
    """``"<OS> <release>"``, e.g. ``Linux 6.1.0``."""
    return f"{platform.system()} {platform.release()}"


def machine() -> str:
    """``"<CPU model>, <n> cores, <OS> <release>"``."""
    return f"{cpu_model()}, {os.cpu_count()} cores, {os_name()}"


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
    """The package's source digest (:func:`cosserat_channel.source_digest`) to 12 hex digits, as
    reports print it."""
    from .. import source_digest as digest

    return digest()[:12]


def version_table(**others) -> dict:
    """``{name: version}``: cosserat-channel, its git revision and source digest, Python, numba,
    numpy and scipy, then each keyword in order (e.g. ``dask=dask.__version__``)."""
    import numba
    import numpy
    import scipy

    from .. import __version__

    table = {"cosserat-channel": __version__, "git": git_revision(),
             "package sources sha256": source_digest(), "Python": platform.python_version(),
             "numba": numba.__version__, "numpy": numpy.__version__, "scipy": scipy.__version__}
    table.update(others)
    return table


def versions(**others) -> str:
    """:func:`version_table` as one line (:func:`format_versions`)."""
    return format_versions(version_table(**others))


def format_versions(table: dict) -> str:
    """``cosserat-channel 0.1.0 (git 1a2b3c4, package sources sha256 ...), Python ..., numba ...,
    numpy ..., scipy ...`` and ``, name version`` for each further entry, in order."""
    t = dict(table)
    head = (f"cosserat-channel {t.pop('cosserat-channel')} (git {t.pop('git')}, package sources "
            f"sha256 {t.pop('package sources sha256')})")
    return ", ".join([head] + [f"{name} {v}" for name, v in t.items()])
