"""Sweep files: a TOML file (or a mapping of the same shape) -> a validated :class:`SweepSpec`.

A sweep file has four tables; only ``[grid]`` is required::

    [grid]                      # all five, in any form below (W for eps, delta_w for N: below)
    eps = {logspace = [-3, -1, 12]}     # 10**linspace(-3, -1, 12)
    L = [2, 5, 10, 20]                  # a list, kept in file order
    K = {linspace = [0, 300, 301]}      # numpy.linspace(0, 300, 301)
    A = 0.3333333333333333              # one number
    N = 1.0
    # W = [0.06, 0.1, 0.155]            # channel half-width in m instead of eps: eps = d_p/W
    # delta_w = [8, 12]                 # wall friction angle in degrees instead of N:
                                        #   N = sin(phi)/tan(delta_w); both need [material]

    [material]                  # optional: adds nu and the wall stresses in Pa
    d_p = 0.002                 # m
    rho_p = 2940                # kg/m^3
    phi = 25                    # degrees
                                # optional: g, Lambda, nu_min, nu_max, p, q

    [solver]                    # optional
    rtol = 1e-8
    atol = 1e-12

    [output]                    # optional
    path = "demo/quickstart.nc"
    variables = ["Delta", "slip"]
    profile_points = 201        # xi = linspace(0, 1, profile_points)
    compress = "zlib"           # the file's codec: zlib (default), zstd or none

Everything is checked here, before any solve, and every rejection is a :class:`SweepError` with a
one-line message that names the key (``grid.eps: ...``). The ranges are the solver's own
(:mod:`cosserat_channel.parameters`), so the sweep file, the API and the ``point`` command accept
exactly the same values; the variables are those of :mod:`cosserat_channel.outputs`.

Pure Python plus numpy: no numba and no dask here (the engine is the only importer of dask).
"""

from __future__ import annotations

import hashlib
import json
import math
import numbers
import os
import tomllib
from dataclasses import dataclass
from typing import Mapping

import numpy as np

from .. import outputs as out_
from ..netcdf_policy import CODECS, DEFAULT_CODEC
from ..parameters import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    DIMS,
    MATERIAL,
    MAX_GRID_POINTS,
    ParameterError,
    N_from_friction,
    check_material,
    check_eta,
    check_tolerances,
    check_values,
    eps_from_width,
)

# A guard against a typo in ``num``, not a memory limit: results are written in tiles (see
# .writer), so memory does not grow with the grid, and the real limit is the free disk space,
# which :func:`.engine.run_sweep` checks before computing. Beyond this the plan's per-triple
# arrays (one entry per distinct (eps L, A, N)) would outgrow a single machine's memory.
MAX_POINTS = MAX_GRID_POINTS
# The most values on one axis, checked before any is made. Every value of eps, L, A or N is at
# least one integration, and every value of K an entry of each block, and a run keeps some 100
# bytes per integration and per entry of a block (:func:`.budget.memory_needed`): an axis beyond
# this needs tens of GB whatever the rest of the grid (10^10 values, within MAX_POINTS, were a
# 74.5 GiB allocation before anything was checked).
MAX_AXIS_POINTS = 100_000_000
PROFILE_POINTS_RANGE = (2, 10001)

TABLES = ("grid", "material", "solver", "output")
SOLVER_KEYS = ("rtol", "atol")
OUTPUT_KEYS = ("path", "variables", "profile_points", "compress")
GRID_FORMS = ("linspace", "logspace")
# The first bytes of a NetCDF-4 (HDF5) and a classic NetCDF file: a result given where a sweep
# file belongs.
NETCDF_SIGNATURES = (b"\x89HDF\r\n\x1a\n", b"CDF\x01", b"CDF\x02", b"CDF\x05")


def examples() -> dict[str, str]:
    """The sweep files that come with the package: ``{name: text}``, by name.

    They are package data (``cosserat_channel/examples/*.toml``, also ``sweeps/`` in a clone),
    so an installed package without a clone has them too (``cosserat-channel example``).
    """
    return {name[:-5]: text for name, text in _shipped(".toml").items()}


def example_measurements() -> dict[str, str]:
    """The example measurements of ``cosserat-channel fit`` that come with the package:
    ``{file name: text}`` (``fit_profile.csv`` ...), package data beside the sweep files."""
    return _shipped(".csv")


def _shipped(suffix: str) -> dict[str, str]:
    from importlib import resources

    here = resources.files("cosserat_channel") / "examples"
    return {f.name: f.read_text(encoding="utf-8")
            for f in sorted(here.iterdir(), key=lambda f: f.name) if f.name.endswith(suffix)}


def example_copy(name: str, text: str, target: str) -> str:
    """The text of the shipped sweep ``name`` for a copy at ``target``, runnable where it is.

    A shipped sweep writes into ``demo/`` (``make demo``'s directory in a clone) and its header
    names ``sweeps/<name>.toml``; outside a clone neither exists. The copy writes
    ``<target's stem>.nc`` (beside where it is run, as ``run`` does for a sweep without an
    output path) and its header's commands name the copy and that file.
    """
    stem = os.path.splitext(os.path.basename(target))[0]
    return (text.replace(f"demo/{name}.nc", f"{stem}.nc")
            .replace(f"sweeps/{name}.toml", target))



def allowed_variables(has_material: bool) -> tuple[str, ...]:
    """Every variable a sweep may ask for: the registry's outputs, then the work counters."""
    return tuple(n for n, o in out_.OUTPUTS.items() if has_material or not o.material) + tuple(
        out_.COUNTERS)


def default_variables(has_material: bool) -> tuple[str, ...]:
    """What a sweep stores when it names no variables: every output, the material's last."""
    plain = tuple(n for n, o in out_.OUTPUTS.items() if not o.material)
    return plain + (out_.material_outputs() if has_material else ())


class SweepError(ParameterError):
    """A sweep file (or mapping) that cannot be run; the one-line message names the key."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


@dataclass(frozen=True, eq=False)
class SweepSpec:
    """A validated sweep: five axes, material, tolerances and what to store.

    The axis arrays are 1-D float64, read-only, in file order, without duplicates. ``text`` is
    the sweep file's text (a canonical JSON dump for a mapping) and ``sha256`` its hash, for the
    result file's provenance attributes.
    """

    eps: np.ndarray
    L: np.ndarray
    K: np.ndarray
    A: np.ndarray
    N: np.ndarray
    material: dict | None
    rtol: float
    atol: float
    output_path: str | None
    variables: tuple[str, ...]
    profile_points: int | None
    text: str
    sha256: str
    source: str | None
    compress: str = DEFAULT_CODEC

    def coords(self) -> dict[str, np.ndarray]:
        """``{dim: values}`` in :data:`DIMS` order."""
        return {d: getattr(self, d) for d in DIMS}

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(getattr(self, d).size for d in DIMS)

    @property
    def size(self) -> int:
        return math.prod(self.shape)


def load_sweep(path_or_mapping) -> SweepSpec:
    """Read and validate a sweep file (path) or an already parsed mapping of the same shape.

    Raises
    ------
    SweepError
        (a :class:`parameters.ParameterError`, so a ``ValueError``) with a one-line message naming the
        offending key, for anything :func:`~cosserat_channel.solver.point.solve_point` would
        reject and for malformed files.
    """
    if isinstance(path_or_mapping, Mapping):
        data = path_or_mapping
        try:
            text = json.dumps(data, sort_keys=True, default=_json_default)
        except (TypeError, ValueError) as exc:
            raise SweepError(f"sweep mapping cannot be serialised: {exc}") from None
        source = None
    elif isinstance(path_or_mapping, (str, os.PathLike)):
        source = os.fspath(path_or_mapping)
        text = _read_text(source)
        try:
            data = tomllib.loads(text)
        except tomllib.TOMLDecodeError as exc:
            raise SweepError(f"{source}: invalid TOML: {exc}") from None
    else:
        raise SweepError(
            f"load_sweep needs a path or a mapping; got {type(path_or_mapping).__name__}"
        )
    sha = hashlib.sha256(text.encode("utf-8")).hexdigest()
    prefix = f"{source}: " if source is not None else ""
    try:
        fields = _validate(data)
    except SweepError as exc:
        raise SweepError(prefix + str(exc)) from None
    return SweepSpec(**fields, text=text, sha256=sha, source=source)


# ---------------------------------------------------------------------------------------------
# Validation, table by table
# ---------------------------------------------------------------------------------------------
def _validate(data: Mapping) -> dict:
    _check_keys(data, TABLES, "sweep", required=("grid",))
    for table in TABLES:
        if table in data and not isinstance(data[table], Mapping):
            raise SweepError(f"{table}: must be a table; got {_show(data[table])}")
    material = _material(data.get("material"))
    axes = _grid(data["grid"], material)
    rtol, atol = _solver(data.get("solver", {}))
    output = data.get("output", {})
    path, variables, profile_points = _output(output, material is not None)
    return dict(
        **axes, material=material, rtol=rtol, atol=atol, output_path=path,
        variables=variables, profile_points=profile_points, compress=_compress(output),
    )


def _compress(output: Mapping) -> str:
    value = output.get("compress", DEFAULT_CODEC)
    if not isinstance(value, str) or value not in CODECS:
        raise SweepError(f"output.compress: must be one of {', '.join(map(repr, CODECS))}; "
                         f"got {_show(value)}")
    return value


# The engineers' axes a grid may give instead of eps and N, and the material input each needs
# (parameters.eps_from_width, N_from_friction).
GRID_PHYSICAL = {"W": ("eps", "d_p"), "delta_w": ("N", "phi")}


def _grid(grid: Mapping, material: dict | None = None) -> dict[str, np.ndarray]:
    _check_keys(grid, DIMS + tuple(GRID_PHYSICAL), "grid")
    grid = dict(grid)
    given = {}  # eps or N: the key that gives it, its values made on the way below
    for key, (gives, needs) in GRID_PHYSICAL.items():
        if key in grid:
            if gives in grid:
                raise SweepError(f"grid: {gives} and {key} both give {gives}: give one")
            if material is None:
                raise SweepError(f"grid.{key}: needs a [material] table (its {needs})")
            given[gives] = key
            grid[gives] = grid.pop(key)
    instead = {gives: key for key, (gives, _) in GRID_PHYSICAL.items()}
    missing = [d + (f" (or {instead[d]})" if d in instead else "") for d in DIMS if d not in grid]
    if missing:
        raise SweepError(f"grid: missing required key(s) {', '.join(missing)}")
    # Count first, build afterwards: a huge `num` fails the size guard without allocating.
    counts = {d: _axis_count(grid[d], f"grid.{given.get(d, d)}") for d in DIMS}
    size = math.prod(counts.values())
    if size > MAX_POINTS:
        shape = " x ".join(str(counts[d]) for d in DIMS)
        raise SweepError(
            f"grid: {size:,} points ({shape}) exceeds the limit of {MAX_POINTS:,}; split the sweep"
        )
    for d, n in counts.items():
        if n > MAX_AXIS_POINTS:
            raise SweepError(f"grid.{d}: {n:,} values exceed the limit of {MAX_AXIS_POINTS:,} "
                             "on one axis; split the sweep along it")
    axes = {}
    for d in DIMS:
        key = f"grid.{given.get(d, d)}"
        values = _axis_values(grid[d], key)
        try:
            if d in given:  # W or delta_w: eps or N from them, each value checked
                values = np.ascontiguousarray(
                    eps_from_width(material["d_p"], values) if d == "eps"
                    else N_from_friction(material["phi"], values))
            check_values(d, values)
        except ParameterError as exc:
            raise SweepError(f"{key}: {exc}{_logspace_hint(grid[d])}") from None
        dup = _duplicates(values)
        if dup:
            raise SweepError(f"{key}: duplicate value(s) {dup}; coordinate values must be unique")
        values.setflags(write=False)
        axes[d] = values
    # The extreme products are those of the extreme values (both axes are positive).
    try:
        for pick in (np.min, np.max):
            check_eta(float(pick(axes["eps"])), float(pick(axes["L"])), label="grid: eps L")
    except ParameterError as exc:
        hint = _logspace_hint(grid["L"]) or _logspace_hint(grid["eps"])
        raise SweepError(f"{exc}{hint}") from None
    return axes


def _logspace_hint(value) -> str:
    """For an axis that failed its range check: a hint when it is a ``logspace`` with two
    positive ends (values where exponents of 10 belong, e.g. ``[0.001, 0.1, 12]`` for eps, or
    ``[1, 30, 5]`` for L), else ''."""
    if not (isinstance(value, Mapping) and "logspace" in value):
        return ""
    start, stop = (float(x) for x in value["logspace"][:2])
    if not (start > 0 and stop > 0):
        return ""
    return (f" (logspace takes exponents of 10: [{start:g}, {stop:g}] gives "
            f"{10 ** min(start, 300):.3g} to {10 ** min(stop, 300):.3g}; for values from "
            f"{start:g} to {stop:g} write {{logspace = [{math.log10(start):.6g}, "
            f"{math.log10(stop):.6g}, num]}})")


def _axis_count(value, key: str) -> int:
    """How many values the axis form ``value`` gives (its shape is checked here too)."""
    if _is_number(value):
        return 1
    if isinstance(value, (list, tuple, np.ndarray)):
        if len(value) == 0:
            raise SweepError(f"{key}: an empty list gives no values; need at least one number")
        for i, v in enumerate(value):
            if not _is_number(v):
                raise SweepError(f"{key}[{i}]: must be a number; got {_show(v)}")
        return len(value)
    if isinstance(value, Mapping):
        if len(value) != 1 or next(iter(value)) not in GRID_FORMS:
            raise SweepError(
                f"{key}: a table must have exactly one key, linspace or logspace; got "
                f"{', '.join(map(repr, value)) or 'no key'}"
            )
        form, args = next(iter(value.items()))
        what = {"linspace": "[start, stop, num]",
                "logspace": "[start_exponent, stop_exponent, num]"}[form]
        ok = (
            isinstance(args, (list, tuple))
            and len(args) == 3
            and _is_number(args[0])
            and _is_number(args[1])
            and isinstance(args[2], numbers.Integral)
            and not isinstance(args[2], (bool, np.bool_))
            and int(args[2]) >= 1
        )
        if not ok:
            raise SweepError(
                f"{key}: {form} needs {what} with num an integer >= 1; got {_show(args)}"
            )
        return int(args[2])
    raise SweepError(
        f"{key}: must be a number, a list of numbers, {{linspace = [start, stop, num]}} or "
        f"{{logspace = [start_exponent, stop_exponent, num]}}; got {_show(value)}"
    )


def _axis_values(value, key: str) -> np.ndarray:
    """The axis as float64 in file order (shape already checked by :func:`_axis_count`)."""
    if _is_number(value):
        out = np.array([_float(value, key)])
    elif isinstance(value, Mapping):
        form, (start, stop, num) = next(iter(value.items()))
        for name, x in (("start", start), ("stop", stop)):
            if not math.isfinite(_float(x, f"{key}: {form} {name}")):
                raise SweepError(f"{key}: {form} {name} must be finite; got {_show(x)}")
        with np.errstate(over="ignore"):
            out = np.linspace(float(start), float(stop), int(num))
            if form == "logspace":  # np.logspace's values, without its second axis-sized array
                np.power(10.0, out, out=out)
    else:
        out = np.array([_float(v, f"{key}[{i}]") for i, v in enumerate(value)], dtype=np.float64)
    return np.ascontiguousarray(out, dtype=np.float64)


def _duplicates(values: np.ndarray) -> str:
    """The first few values that ``values`` holds twice, as text ('' when none): a strictly
    monotonic axis (every linspace and logspace of distinct ends) is known free of them without
    a sorted copy of it."""
    if values.size < 2 or bool(np.all(values[1:] > values[:-1])) or \
            bool(np.all(values[1:] < values[:-1])):
        return ""
    ordered = np.sort(values)
    repeated = ordered[1:][ordered[1:] == ordered[:-1]]
    return ", ".join(f"{v!r}" for v in np.unique(repeated)[:5].tolist())


def _float(x, key: str) -> float:
    """``float(x)``; SweepError for an integer beyond the largest float (TOML integers are
    unbounded; float() raises OverflowError above about 1.8e308)."""
    try:
        return float(x)
    except OverflowError:
        raise SweepError(f"{key}: {_show(x, 24)} is beyond the largest float (about "
                         "1.8e308)") from None


def _material(material: Mapping | None) -> dict | None:
    if material is None:
        return None
    _check_keys(material, tuple(MATERIAL), "material")
    for k, v in material.items():
        if not _is_number(v):
            raise SweepError(f"material.{k}: must be a number; got {_show(v)}")
    try:
        return check_material(dict(material))
    except ParameterError as exc:
        msg = str(exc)
        raise SweepError(msg if msg.startswith("material") else f"material: {msg}") from None


def _solver(solver: Mapping) -> tuple[float, float]:
    _check_keys(solver, SOLVER_KEYS, "solver")
    for k, v in solver.items():
        if not _is_number(v):
            raise SweepError(f"solver.{k}: must be a number; got {_show(v)}")
    rtol = solver.get("rtol", DEFAULT_RTOL)
    atol = solver.get("atol", DEFAULT_ATOL)
    try:
        return check_tolerances(rtol, atol)
    except ParameterError as exc:
        name = str(exc).split()[0]
        raise SweepError(f"solver.{name}: {exc}") from None


def _output(output: Mapping, has_material: bool):
    _check_keys(output, OUTPUT_KEYS, "output")
    path = output.get("path")
    if path is not None and (not isinstance(path, str) or not path.strip()):
        raise SweepError(f"output.path: must be a non-empty string; got {_show(path)}")

    allowed = allowed_variables(has_material)
    if "variables" in output:
        names = output["variables"]
        if not isinstance(names, (list, tuple)) or not names:
            raise SweepError(
                f"output.variables: must be a non-empty list of names; got {_show(names)}"
            )
        for i, name in enumerate(names):
            if not isinstance(name, str):
                raise SweepError(f"output.variables[{i}]: must be a string; got {_show(name)}")
            if name in out_.OUTPUTS and out_.OUTPUTS[name].material and not has_material:
                raise SweepError(
                    f"output.variables: {name!r} needs a [material] table (d_p, rho_p, phi)"
                )
            if name not in allowed:
                raise SweepError(
                    f"output.variables: unknown variable {name!r}; valid: {', '.join(allowed)}"
                )
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise SweepError(f"output.variables: listed twice: {', '.join(dup)}")
        chosen = tuple(names)
    else:
        chosen = default_variables(has_material)

    profile_points = output.get("profile_points")
    if profile_points is not None:
        lo, hi = PROFILE_POINTS_RANGE
        if (
            not isinstance(profile_points, numbers.Integral)
            or isinstance(profile_points, (bool, np.bool_))
            or not lo <= int(profile_points) <= hi
        ):
            raise SweepError(
                f"output.profile_points: must be an integer in [{lo}, {hi}]; "
                f"got {_show(profile_points)}"
            )
        profile_points = int(profile_points)
    return path, chosen, profile_points


# ---------------------------------------------------------------------------------------------
# Small helpers
# ---------------------------------------------------------------------------------------------
def _check_keys(table: Mapping, allowed: tuple, where: str, required: tuple = ()) -> None:
    unknown = [k for k in table if k not in allowed]
    if unknown:
        raise SweepError(
            f"{where}: unknown key(s) {', '.join(map(repr, unknown))}; "
            f"allowed: {', '.join(allowed)}"
        )
    missing = [k for k in required if k not in table]
    if missing:
        raise SweepError(f"{where}: missing required key(s) {', '.join(missing)}")


def _is_number(x) -> bool:
    """A finite or non-finite real number, never a bool or a string (ranges are checked later)."""
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_))


def _show(x, limit: int = 60) -> str:
    s = " ".join(repr(x).split())
    return s if len(s) <= limit else s[: limit - 1] + "…"


def _read_text(path: str) -> str:
    try:
        with open(path, "rb") as f:
            raw = f.read()
    except FileNotFoundError:
        raise SweepError(f"{path}: no such sweep file ('cosserat-channel example' lists and copies "
                         "the ones that come with the package)") from None
    except IsADirectoryError:
        raise SweepError(f"{path}: is a directory, not a sweep file") from None
    except OSError as exc:
        raise SweepError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if raw.startswith(NETCDF_SIGNATURES):
        raise SweepError(f"{path}: is a NetCDF file (a result?), not a sweep file; "
                         f"'cosserat-channel info {path}' describes a result, 'cosserat-channel "
                         "example' lists the sweep files that come with the package")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SweepError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    # A byte-order mark (Windows editors write one) is not TOML: tomllib calls it an "Invalid
    # statement" at line 1, column 1.
    return text[1:] if text.startswith("\ufeff") else text


def _json_default(x):
    if isinstance(x, (np.ndarray, np.generic)):
        return x.tolist()
    raise TypeError(f"{type(x).__name__} is not JSON serialisable")
