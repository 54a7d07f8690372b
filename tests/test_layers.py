"""The package's layers: which part of it may import which.

:data:`LAYERS` is the one statement of the rules; the ``Layer`` paragraphs of the packages'
docstrings say the same in words. Every module under ``src/cosserat_channel`` is read with
``ast`` (imports inside functions included, so a lazy import is held to the same rule), each
import is resolved to the module it names, and an import outside the importer's row fails.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = "cosserat_channel"
SRC = Path(__file__).resolve().parent.parent / "src" / PACKAGE

# Part of the package -> what else of the package it may import (a part always imports itself,
# and every part may import the package's root module: its version, cache directory and source
# digest). A part is a sub-package or a top-level module; an entry names a part or one module
# of it ("physics.analytic"). Keep the packages' docstrings in step with this table.
VOCABULARY = ("parameters", "status", "regime_codes", "outputs", "files", "netcdf_policy")
LAYERS = {
    # The vocabulary: names, codes and file primitives every layer shares.
    "parameters": (),
    "status": (),
    "regime_codes": (),
    "files": ("netcdf_policy",),
    "netcdf_policy": (),
    "outputs": ("physics.closure", "parameters", "status"),
    "_jit": (),
    # HDF5's chunk filters (encoding a sweep file's chunks in parallel); their Numba kernels in
    # a module of their own, imported on first use, so that a cluster's client never loads numba.
    "chunk_filters": ("_chunk_kernels",),
    "_chunk_kernels": ("_jit",),
    # Kernels: the integrators know nothing of the physics, the physics nothing of the
    # integrators; the solver is the only part that imports both.
    "integrate": ("_jit",),
    "physics": ("_jit", "parameters", "status"),
    "solver": ("_jit", "integrate", "physics", "parameters", "status", "outputs"),
    # Reading results and drawing never solve.
    "plot": ("physics.analytic", "physics.asymptotics", "parameters", "status", "regime_codes",
             "outputs", "files"),
    "results": ("plot", "parameters", "status", "outputs", "files", "netcdf_policy"),
    # Above the solver.
    "regimes": ("solver", "physics", "parameters", "status", "regime_codes"),
    "atlas": ("regimes", "solver.point", "physics.analytic", "parameters", "status",
              "regime_codes", "files", "netcdf_policy"),
    "sweep": ("solver", "physics.analytic", "results", "chunk_filters", "parameters", "status",
              "outputs", "files", "netcdf_policy"),
    "calibrate": ("solver", "sweep", "plot", "parameters", "status", "outputs"),
    "measure": ("solver", "regimes", "physics", "plot", "parameters", "status", "files"),
    "paper": ("solver", "regimes", "sweep", "physics", "plot", *VOCABULARY),
    # The explorer's page: the public API (solve_point and solve through the package's root),
    # the atlas's reading functions and the figures; only the command line imports it.
    "explorer": ("atlas", "plot", *VOCABULARY),
    # The top: may import every part; nothing imports it.
    "cli": ("*",),
}
# Third-party modules only some parts may import: numba's kernels stay below the sweeps (reading
# a result, an atlas or a sweep file never compiles), matplotlib stays in the figures.
RESTRICTED = {
    "numba": ("_jit", "_chunk_kernels", "integrate", "physics", "solver", "measure"),
    "matplotlib": ("plot",),
    "dask": ("sweep", "results", "cli"),
    "distributed": ("sweep", "results", "cli"),
}


def module_name(path: Path, root: Path = SRC) -> str:
    parts = [PACKAGE, *path.relative_to(root).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def is_module(name: str, root: Path = SRC) -> bool:
    rel = Path(*name.split(".")[1:])
    return (root / rel).with_suffix(".py").is_file() or (root / rel / "__init__.py").is_file()


def imports(source: str, name: str, is_package: bool, root: Path = SRC):
    """``(line, imported module)`` for every import in ``source``, at any depth, relative ones
    resolved; ``from X import y`` names ``X.y`` where that is a module, else ``X``."""
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".")[:len(name.split(".")) - node.level + is_package]
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                yield node.lineno, sub if base.startswith(PACKAGE) and is_module(sub, root) else base


def part(name: str) -> str:
    """The part of the package a module belongs to (``""`` for the root module)."""
    parts = name.split(".")
    return parts[1] if len(parts) > 1 else ""


def breaks(root: Path = SRC):
    """Every import outside its importer's row of :data:`LAYERS` or :data:`RESTRICTED`."""
    found = []
    for path in sorted(root.rglob("*.py")):
        name = module_name(path, root)
        own = part(name)
        for line, target in imports(path.read_text(), name, path.name == "__init__.py", root):
            where = f"{path.relative_to(root.parent)}:{line}: {name} imports {target}"
            top = target.split(".")[0]
            if top == PACKAGE:
                other = part(target)
                if other in ("", own):
                    continue
                allowed = LAYERS.get(own, ())
                rel = target.split(".", 1)[1]
                if not ("*" in allowed or any(rel == a or rel.startswith(a + ".")
                                              for a in allowed)):
                    found.append(where)
            elif top in RESTRICTED and own not in RESTRICTED[top]:
                found.append(where)
    return found


def test_every_part_has_a_row():
    parts = {part(module_name(p)) for p in SRC.rglob("*.py")} - {""}
    assert parts == set(LAYERS)
    for row in LAYERS.values():
        for entry in row:
            assert entry == "*" or is_module(f"{PACKAGE}.{entry}"), entry


def test_no_import_breaks_a_layer():
    assert breaks() == []


def test_nothing_imports_the_command_line():
    assert not [b for b in breaks() if b.endswith(".cli")]
    users = [p for p in SRC.rglob("*.py") if part(module_name(p)) != "cli"
             for _, t in imports(p.read_text(), module_name(p), p.name == "__init__.py")
             if t.startswith(f"{PACKAGE}.cli")]
    assert users == []


@pytest.mark.parametrize("body, target, caught", [
    ("from ..integrate import rk45\n", "cosserat_channel.integrate.rk45", True),
    ("def f():\n    from .. import sweep\n", "cosserat_channel.sweep", True),
    ("import cosserat_channel.plot.lines\n", "cosserat_channel.plot.lines", True),
    ("from ..solver import batch\n", "cosserat_channel.solver.batch", False),
    ("def f():\n    import numba\n", "numba", True),
    ("from . import wall\n", "cosserat_channel.regimes.wall", False),
])
def test_a_forbidden_import_is_caught(tmp_path, body, target, caught):
    # A copy of the layout with one module of regimes/ changed: the check reads the copy.
    root = tmp_path / PACKAGE
    for sub in ("regimes", "integrate", "sweep", "plot", "solver"):
        (root / sub).mkdir(parents=True)
        (root / sub / "__init__.py").write_text("")
    (root / "__init__.py").write_text("")
    for mod in ("regimes/wall.py", "integrate/rk45.py", "plot/lines.py", "solver/batch.py"):
        (root / mod).write_text("")
    (root / "regimes" / "edge.py").write_text(body)
    got = list(imports(body, f"{PACKAGE}.regimes.edge", False, root))
    assert [t for _, t in got] == [target]
    found = breaks(root)
    assert bool(found) == caught, found
    if caught:
        assert found[0].endswith(f"imports {target}") and "regimes/edge.py:" in found[0]
