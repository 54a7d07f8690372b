"""cosserat-channel: the frictional Cosserat model of granular channel flow, solved fast.

The physics is Mohan, Nott & Rao, "A frictional Cosserat model for the flow of granular
materials through a vertical channel". See ``README.md`` for the set-up commands.
"""

from __future__ import annotations

import hashlib
import os
import re
import stat
import sys
import tempfile
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


def source_digest() -> str:
    """SHA-256 (hex) of every source file of the package, each with its path inside it: which
    solver exactly this is, also for an installed copy that has no git revision."""
    here = Path(__file__).resolve().parent
    digest = hashlib.sha256()
    for path in sorted(here.rglob("*.py")):
        digest.update(path.relative_to(here).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _numba_cache_key() -> str:
    """The name of this source tree's Numba cache directory: ``numba-<version>-<hash>``.

    Numba checks a cached kernel against the source file of the function itself only, so the
    compiled ``solve`` kernels, which inline ``model``, ``rk45`` and ``rosenbrock``, would be
    reloaded unchanged after an edit (or a ``git pull``) of those modules: a silent wrong answer.
    Keying the directory on a hash of every source file makes any change a clean recompile.
    """
    return f"numba-{__version__}-{source_digest()[:16]}"


_KEY_NAME = re.compile(r"numba-.+-[0-9a-f]{16}")


def _numba_cache_candidates() -> list[tuple[Path, bool]]:
    """Where the kernel cache may live, best first, each as ``(directory, private)``.

    A ``NUMBA_CACHE_DIR`` set by the user holds the keyed directory in ``cosserat-channel/``
    (one that already names a key was set by a parent process and is used as the same place);
    then the package's cache directory; then a directory of this user's own under the system's
    temporary directory (``private``: it must be ours and closed to others, since Numba loads
    pickles from it).
    """
    key = _numba_cache_key()
    roots = []
    given = os.environ.get("NUMBA_CACHE_DIR")
    if given:
        given = Path(given)
        roots.append((given.parent if _KEY_NAME.fullmatch(given.name) else
                      given / "cosserat-channel", False))
    roots.append((cache_dir(), False))
    mine = f"cosserat-channel-{os.getuid()}" if hasattr(os, "getuid") else "cosserat-channel"
    roots.append((Path(tempfile.gettempdir()) / mine, True))
    return [(root / key, private) for root, private in roots]


def _usable(path: Path, private: bool) -> bool:
    """Whether Numba can cache in ``path``: Numba's own test (create it, write a file in it).

    A ``private`` directory is also created closed to others and must be a real directory
    owned by this user that no one else can write into.
    """
    try:
        if private:
            path.parent.mkdir(mode=0o700, exist_ok=True)
            info = path.parent.lstat()
            if (not stat.S_ISDIR(info.st_mode) or info.st_mode & 0o022
                    or (hasattr(os, "getuid") and info.st_uid != os.getuid())):
                return False
        path.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=path).close()
    except OSError:
        return False
    return True


def _numba_cache_enabled() -> bool:
    """Point Numba's cache at the first usable candidate; ``False`` (and one warning line) if none.

    Called once, by :mod:`._jit`, before the first cached kernel is defined. Where Numba finds
    its cache directory unusable it falls back to ``__pycache__`` beside each source file, keyed
    per file, which serves stale kernels after an edit of an inlined module; caching is off
    instead when no candidate is usable.
    """
    for path, private in _NUMBA_CACHE_CANDIDATES:
        if _usable(path, private):
            _set_numba_cache_dir(str(path))
            return True
    tried = ", ".join(str(path) for path, _ in _NUMBA_CACHE_CANDIDATES)
    sys.stderr.write(f"cosserat-channel: warning: no writable directory for the Numba kernel "
                     f"cache (tried {tried}); kernels are compiled in every process\n")
    return False


def _set_numba_cache_dir(path: str) -> None:
    # numba reads the variable when it is first imported and its config per decorated function
    # afterwards, so cover both without importing numba here (the CLI stays light).
    os.environ["NUMBA_CACHE_DIR"] = path
    if "numba" in sys.modules:
        sys.modules["numba"].config.CACHE_DIR = path


# Fixed at import, before any submodule defines a cached kernel and before anything (a test
# fixture) can move the cache home; whether it is usable is found when the kernels are defined.
_NUMBA_CACHE_CANDIDATES = _numba_cache_candidates()
_set_numba_cache_dir(str(_NUMBA_CACHE_CANDIDATES[0][0]))


# The public API, imported on first use (PEP 562) so that ``import cosserat_channel`` stays light
# and reading a result file never compiles a kernel. Each name is the real object of its home.
_API = {
    "solve_point": "solver.point",
    "solve": "sweep.arrays",
    "PointResult": "solver.point",
    "Workspace": "solver.point",
    "Status": "status",
    "ParameterError": "parameters",
    "check_point": "parameters",
    "eps_from_width": "parameters",
    "N_from_friction": "parameters",
    "PARAMETERS": "parameters",
    "OUTPUTS": "outputs",
    "Output": "outputs",
    "load_sweep": "sweep.spec",
    "run_sweep": "sweep.engine",
    "open_results": "results.selection",
    "trace_edge": "regimes",
    "trace_boundary": "regimes",
    "phase_plane": "regimes",
    "fit": "calibrate",
    "FitResult": "calibrate",
    "explore": "explorer",
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
