"""cosserat-channel: the frictional Cosserat model of granular channel flow, solved fast.

The physics is Mohan, Nott & Rao, "A frictional Cosserat model for the flow of granular
materials through a vertical channel". See ``README.md`` for the set-up commands.
"""

from __future__ import annotations

import hashlib
import os
import sys
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

try:
    __version__ = version("cosserat-channel")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+unknown"


def cache_dir() -> Path:
    """This package's cache directory: ``$XDG_CACHE_HOME/cosserat-channel`` (``~/.cache`` if unset).

    Read at each call, so a test can point it elsewhere after the package is imported.
    """
    return Path(os.environ.get("XDG_CACHE_HOME", Path.home() / ".cache")) / "cosserat-channel"


def _numba_cache_dir() -> str:
    """A Numba cache directory keyed by a hash of every source file of this package.

    Numba checks a cached kernel against the source file of the function itself only, so the
    compiled ``solve`` kernels, which inline ``model``, ``rk45`` and ``rosenbrock``, would be
    reloaded unchanged after an edit (or a ``git pull``) of those modules: a silent wrong answer.
    Keying the directory on all sources makes any change a clean recompile.
    """
    here = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(here.rglob("*.py")):
        digest.update(path.relative_to(here).as_posix().encode())
        digest.update(path.read_bytes())
    return str(cache_dir() / f"numba-{__version__}-{digest.hexdigest()[:16]}")


if not os.environ.get("NUMBA_CACHE_DIR"):
    # Must happen before any submodule defines a cached kernel. numba reads the variable when it
    # is first imported and its config per decorated function afterwards, so cover both without
    # importing numba here (the CLI stays light).
    os.environ["NUMBA_CACHE_DIR"] = _numba_cache_dir()
    if "numba" in sys.modules:
        sys.modules["numba"].config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]


# The public API, imported on first use (PEP 562) so that ``import cosserat_channel`` stays light
# and reading a result file never compiles a kernel. Each name is the real object of its home.
_API = {
    "solve_point": "solver.point",
    "PointResult": "solver.point",
    "Workspace": "solver.point",
    "Status": "status",
    "ParameterError": "parameters",
    "check_point": "parameters",
    "PARAMETERS": "parameters",
    "OUTPUTS": "outputs",
    "Output": "outputs",
    "load_sweep": "sweep.spec",
    "run_sweep": "sweep.engine",
    "open_results": "results.selection",
    "trace_edge": "regimes",
    "trace_boundary": "regimes",
    "phase_plane": "regimes",
}

__all__ = ["__version__", *_API]


def __getattr__(name):
    if name in _API:
        import importlib

        value = getattr(importlib.import_module(f".{_API[name]}", __name__), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_API))
