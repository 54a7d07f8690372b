"""The package module: Numba's kernel cache follows the sources wherever it can live.

Each test copies the package into a temporary tree with two probe modules, a cached kernel
``outer`` that inlines ``inner`` from the other module (as ``solve`` inlines ``model``), and runs
it in a fresh interpreter whose cache home cannot be written. Numba checks a cached kernel
against its own file only, so editing ``inner`` serves the old number unless the cache directory
is keyed on all sources. Unwritable places are paths under a regular file: that holds for root,
who can write into any directory whatever its mode.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import cosserat_channel
from cosserat_channel import _usable

PACKAGE = Path(cosserat_channel.__file__).resolve().parent

INNER = """
from numba import njit
from ._jit import JIT_INLINE

@njit(**JIT_INLINE)
def inner():
    return {value}
"""

OUTER = """
from numba import njit
from ._jit import JIT
from ._probe_inner import inner

@njit(**JIT)
def outer():
    return inner()
"""

RUN = """
import json, sys, tempfile
if len(sys.argv) > 1:
    tempfile.tempdir = sys.argv[1]
import cosserat_channel
from cosserat_channel._probe_outer import outer
value = outer()
print(json.dumps(dict(value=value, hits=sum(outer.stats.cache_hits.values()),
                      file=cosserat_channel.__file__)))
"""


@pytest.fixture
def tree(tmp_path):
    """A copy of the package with the probe modules, and a file to put unwritable paths under."""
    src = tmp_path / "src"
    shutil.copytree(PACKAGE, src / "cosserat_channel",
                    ignore=shutil.ignore_patterns("__pycache__"))
    (src / "cosserat_channel" / "_probe_inner.py").write_text(INNER.format(value=1.0))
    (src / "cosserat_channel" / "_probe_outer.py").write_text(OUTER)
    (tmp_path / "tmp").mkdir()
    (tmp_path / "a-file").write_text("not a directory\n")
    return tmp_path


def _run(tree, tempdir=None, **env):
    """Run the probe in a fresh interpreter; HOME and the cache home are unwritable by default."""
    environ = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    environ.update(PYTHONPATH=str(tree / "src"), TMPDIR=str(tree / "tmp"),
                   HOME=str(tree / "a-file" / "home"),
                   XDG_CACHE_HOME=str(tree / "a-file" / "cache"))
    environ.update(env)
    argv = [sys.executable, "-c", RUN] + ([str(tempdir)] if tempdir else [])
    proc = subprocess.run(argv, env=environ, cwd=tree, capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 0, proc.stderr
    out = json.loads(proc.stdout)
    assert Path(out["file"]).resolve().parent == (tree / "src" / "cosserat_channel").resolve()
    return out, proc.stderr


def _edit_inner(tree, value):
    (tree / "src" / "cosserat_channel" / "_probe_inner.py").write_text(INNER.format(value=value))


def _cached_files(root):
    return sorted(root.rglob("*.nbi"))


@pytest.mark.parametrize("where", ["temporary", "given"])
def test_edited_source_is_never_served_stale(tree, where):
    if where == "temporary":
        env = {}
        root = tree / "tmp" / f"cosserat-channel-{os.getuid()}"
    else:
        env = dict(NUMBA_CACHE_DIR=str(tree / "given"))
        root = tree / "given" / "cosserat-channel"

    first, err = _run(tree, **env)
    assert (first["value"], first["hits"], err) == (1.0, 0, "")
    again, _ = _run(tree, **env)
    assert (again["value"], again["hits"]) == (1.0, 1)  # the cache is used at all
    _edit_inner(tree, 2.0)
    edited, _ = _run(tree, **env)
    assert edited["value"] == 2.0

    # Two keyed directories, each with the kernel's index; nothing beside the sources.
    keyed = sorted(p.name for p in root.iterdir())
    assert len(keyed) == 2 and all(name.startswith("numba-") for name in keyed)
    assert all(_cached_files(root / name) for name in keyed)
    assert _cached_files(tree / "src") == []


def test_given_cache_dir_unwritable_falls_back_to_a_private_temporary_one(tree):
    env = dict(NUMBA_CACHE_DIR=str(tree / "a-file" / "numba"))
    assert _run(tree, **env)[0]["value"] == 1.0
    _edit_inner(tree, 3.0)
    assert _run(tree, **env)[0]["value"] == 3.0
    root = tree / "tmp" / f"cosserat-channel-{os.getuid()}"
    assert root.stat().st_mode & 0o077 == 0
    assert len(_cached_files(root)) == 2 and _cached_files(tree / "src") == []


def test_nowhere_to_cache_is_one_warning_line_and_no_cache(tree):
    nowhere = tree / "a-file" / "tmp"
    out, err = _run(tree, tempdir=nowhere)
    assert out["value"] == 1.0
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("cosserat-channel: warning: "), err
    assert "cache" in lines[0] and str(nowhere) in lines[0]
    _edit_inner(tree, 4.0)
    assert _run(tree, tempdir=nowhere)[0]["value"] == 4.0
    assert _cached_files(tree) == []


def test_temporary_directory_others_can_write_is_refused(tmp_path):
    shared = tmp_path / "cosserat-channel-x"
    shared.mkdir()
    shared.chmod(0o777)
    assert not _usable(shared / "numba-key", private=True)
    shared.chmod(0o700)
    assert _usable(shared / "numba-key", private=True)
    link = tmp_path / "link"
    link.symlink_to(shared)
    assert not _usable(link / "numba-key", private=True)
    (tmp_path / "a-file").write_text("")
    assert not _usable(tmp_path / "a-file" / "numba-key", private=False)


def test_the_same_sources_elsewhere_load_the_cached_kernels(tree, tmp_path):
    """A second copy of the same sources at another path (another clone, another environment)
    loads the kernels the first compiled: the cache is keyed on the sources, not on where they
    are."""
    cache = tmp_path / "cache"
    first, _ = _run(tree, NUMBA_CACHE_DIR=str(cache))
    assert (first["value"], first["hits"]) == (1.0, 0)
    other = tmp_path / "elsewhere" / "deeper"
    shutil.copytree(tree, other, symlinks=True)
    again, _ = _run(other, NUMBA_CACHE_DIR=str(cache))
    assert (again["value"], again["hits"]) == (1.0, 1)
    # One keyed directory, the kernels filed under the package's own layout.
    keyed = list((cache / "cosserat-channel").iterdir())
    assert len(keyed) == 1
    assert {p.parent.name for p in _cached_files(keyed[0])} == {"cosserat_channel"}
    # An edit is still seen through the shared cache.
    _edit_inner(other, 5.0)
    assert _run(other, NUMBA_CACHE_DIR=str(cache))[0]["value"] == 5.0
