"""The one set of Numba compile options of the package's kernels, and where their cache lives.

``error_model="numpy"``: a division by zero gives inf/NaN, which the integrators handle as a
non-finite trial step, instead of a branch and a Python exception around every division.
``JIT_INLINE`` adds Numba-IR inlining: kernels that receive ``fun``/``jac``/``event`` stay
cacheable that way (see :mod:`cosserat_channel.integrate.rk45`), and small helpers that pass arrays
avoid the reference-count updates of a call (see :mod:`cosserat_channel.solver.stress_path`). An
inlined kernel is compiled with the error model of the caller it is inlined into.
``no_cfunc_wrapper``: Numba otherwise builds, optimises and compiles a C-ABI wrapper beside every
kernel, used only where a kernel is passed as a first-class function (a ``cfunc`` address), which
the package never does; it was about a tenth of a first run's compilation.
``cache`` is off only where no directory keyed on the sources is writable (see
:func:`cosserat_channel._numba_cache_enabled`).

Numba files a cached kernel under a hash of its source file's absolute directory, so the same
sources installed at another path (a second clone, a wheel in another environment) would compile
again. :class:`SourcesLocator` files them under the module's path inside the package instead:
the cache directory is already keyed on a hash of every source file, so the same sources share
one cache wherever they are installed.
"""

import hashlib
import os
import sys
from functools import lru_cache
from pathlib import Path

from . import _numba_cache_enabled

PACKAGE = Path(__file__).resolve().parent
# Machine epsilon, for the rounding bounds of the kernels (integrators and physics alike).
EPS = sys.float_info.epsilon


def _install_locator() -> None:
    from numba.core import caching, config

    # Numba 0.60 dropped the underscore of both names.
    base = getattr(caching, "UserProvidedCacheLocator", None) or caching._UserProvidedCacheLocator
    impl = getattr(caching, "CacheImpl", None) or caching._CacheImpl

    class SourcesLocator(base):
        """Numba's locator for ``NUMBA_CACHE_DIR``, with paths relative to the package.

        The cache path is ``NUMBA_CACHE_DIR/cosserat_channel/<subpackage>`` and the source
        stamp the file's SHA-256 (what recent Numba uses too; older ones used its mtime, which
        a copy changes). Functions outside the package are left to Numba's own locators.
        """

        def __init__(self, py_func, py_file):
            super().__init__(py_func, py_file)
            inside = Path(py_file).resolve().parent.relative_to(PACKAGE)
            self._cache_path = os.path.join(config.CACHE_DIR, PACKAGE.name, *inside.parts)

        def get_source_stamp(self):
            return _sha256(os.path.realpath(self._py_file))

        @classmethod
        def from_function(cls, py_func, py_file):
            if not Path(py_file).resolve().is_relative_to(PACKAGE):
                return None
            return super().from_function(py_func, py_file)

    locators = impl._locator_classes
    if not any(c.__name__ == "SourcesLocator" for c in locators):
        locators.insert(0, SourcesLocator)
    _lock_saves(caching.IndexDataCacheFile)


def _lock_saves(index_file) -> None:
    """Numba saves a cache entry by reading the function's index, adding the entry and writing
    the index and the data file back (each replaced at once). Two processes saving entries of
    one function at the same time (a parallel first run's child and its parent, or a sweep's
    workers) could both pick the same data file's name, and the index would name the other's
    code for a signature. A save holds an exclusive lock on its directory."""
    try:
        import fcntl
    except ImportError:  # Windows: no parallel first run (solver.ahead), saves unlocked
        return
    save = index_file.save
    if getattr(save, "locked", False):
        return

    def locked_save(self, key, data):
        # Numba's private attribute; a version without it saves unlocked, as Numba itself does.
        path = getattr(self, "_cache_path", None)
        try:
            fd = os.open(path, os.O_RDONLY)
        except (OSError, TypeError):
            return save(self, key, data)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            return save(self, key, data)
        finally:
            os.close(fd)  # releases the lock

    locked_save.locked = True
    index_file.save = locked_save


@lru_cache(maxsize=None)
def _sha256(path: str) -> str:
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


_CACHE = _numba_cache_enabled()
if _CACHE:
    _install_locator()

JIT = dict(nogil=True, cache=_CACHE, error_model="numpy", no_cfunc_wrapper=True)
JIT_INLINE = dict(JIT, inline="always")
