"""Test isolation from the user's cache directory.

``plot --regime`` reads a cached atlas from the package's cache directory when one exists, so a
developer's own atlas would change what the plot tests exercise. Every test gets an empty cache
home instead. The package is imported first, so Numba's kernel cache (whose directory is fixed at
import) stays where it is and the tests do not recompile every kernel.
"""

import pytest

import cosserat_channel  # noqa: F401  (fixes NUMBA_CACHE_DIR before the cache home moves)


@pytest.fixture(autouse=True)
def _empty_cache_home(monkeypatch, tmp_path_factory):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path_factory.getbasetemp() / "cache-home"))
