"""Test isolation from the user's cache directory, and the order the tests run in.

``plot --regime`` reads a cached atlas from the package's cache directory when one exists, so a
developer's own atlas would change what the plot tests exercise. Every test gets an empty cache
home instead. The package is imported first, so Numba's kernel cache (whose directory is fixed at
import) stays where it is and the tests do not recompile every kernel.

``make test`` runs the tests in two processes (pytest-xdist, ``-n 2``). Each process has its own
temporary directories and cache home; the kernel cache is one directory, which Numba keeps safe
for several processes (a kernel is written to a temporary file and renamed into place). The
tests marked ``slow`` run first, so that the processes share the long ones and the run does not
end with one process still in a long test while the other waits. In one process (``-n 0``, a
single test) the order is the same set of tests.
"""

import pytest

import cosserat_channel  # noqa: F401  (fixes NUMBA_CACHE_DIR before the cache home moves)


@pytest.fixture(autouse=True)
def _empty_cache_home(monkeypatch, tmp_path_factory):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path_factory.getbasetemp() / "cache-home"))


def pytest_collection_modifyitems(config, items):
    items.sort(key=lambda item: item.get_closest_marker("slow") is None)  # stable: slow first
