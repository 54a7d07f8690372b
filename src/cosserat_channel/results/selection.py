"""Safe selection and filtering of result files: parsing the clauses and selecting the points.

A selection is three kinds of clause, each parsed with a regular expression and ``float()`` only
(never ``eval``): ``--sel NAME=VALUE`` (a coordinate value, see below), ``--range NAME=LO:HI``
(inclusive, either bound may be empty) and ``--where "NAME OP VALUE"`` with ``OP`` one of
``== != < <= > >=`` on a variable or a coordinate. A flag variable (``status``) is compared by
its flag name: ``status == ok``. Several ``--where`` clauses are ANDed. Comparisons follow IEEE:
a NaN value fails every comparison except ``!=``.

Choices worth knowing:

* ``--sel`` matches a coordinate value exactly, up to round-off (:data:`SEL_RTOL`, so a value
  typed from a printed coordinate with 10 significant digits matches); a value between grid values
  is an error that names the nearest ones, unless ``nearest=True`` (``--nearest``) asks for the
  nearest value, and then :attr:`Selection.snapped` says what was taken.
* ``--sel`` and ``--range`` index by position (matching value / inclusive mask on the coordinate),
  so they work on coordinates in any order, not only sorted ones. A ``--sel`` keeps its dimension
  with length one: the rows carry the selected value as a column, and a NetCDF subset stays a
  result file of the same five-dimensional layout.
* ``--range`` bounds have a relative slack of ``RANGE_SLACK`` so that a bound typed from a
  printed coordinate value (10 significant digits) includes that value.
* A NetCDF subset with ``--where`` is the smallest sub-grid holding every matching point; where
  the match is not a whole sub-grid, float variables are NaN at the points that failed and an
  int8 flag variable ``selected`` marks the matches (``status`` keeps its values: it still says
  why a point has or has no solution).

The file is opened lazily (dask-backed through ``xr.open_dataset(chunks={})``); a selection reads
only what it needs, and rows are extracted in blocks of ``ROW_BLOCK`` points. A small query of a
result file written by ``run`` (a slice, a curve: at most ``ROW_BLOCK`` points selected) is
answered with the ``netCDF4`` library alone (:func:`open_light`): importing xarray and dask
takes longer than such a query's own work.

Rendering the selected points is :mod:`.render`'s, describing a file :mod:`.describe`'s.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from .flags import QueryError, _is_flag, check_flags, flag_names

if TYPE_CHECKING:  # imported where used: a small query never imports xarray (LightFile)
    import xarray as xr

RANGE_SLACK = 1e-9
# --sel: |grid - value| <= SEL_RTOL * max(|grid|, |value|), or <= SEL_RTOL * 1e-3 * max|coordinate|
# for values at or next to 0 (a linspace through 0 gives ~1e-16 there instead of 0).
SEL_RTOL = 1e-9
ROW_BLOCK = 1_000_000
TABLE_ROWS = 200

_NAME = r"[A-Za-z_][A-Za-z0-9_]*"
_SEL_RE = re.compile(rf"^\s*({_NAME})\s*=\s*(\S+)\s*$")
_RANGE_RE = re.compile(rf"^\s*({_NAME})\s*=\s*([^:\s]*)\s*:\s*([^:\s]*)\s*$")
_WHERE_RE = re.compile(rf"^\s*({_NAME})\s*(==|!=|<=|>=|<|>)\s*(\S+)\s*$")
_OPS = {
    "==": np.equal, "!=": np.not_equal, "<": np.less,
    "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal,
}


# ---------------------------------------------------------------------------------------------
# Opening
# ---------------------------------------------------------------------------------------------
# What a file's metadata may declare before anything is read (see storage_problem): the pieces a
# variable is read in (HDF5 chunks, or the whole of a contiguous variable) and their size. A
# result of 'run' has 1 MiB chunks, about 10^5 per variable at the largest grid a sweep allows.
MAX_PIECES = 1_000_000
MAX_PIECE_BYTES = 64 << 20
# Bytes a written HDF5 chunk takes at the least (its index entry and one byte of data): a file
# holds at least this much per chunk of every variable, and a contiguous variable whole.
MIN_CHUNK_BYTES = 8


def storage_problem(nc, path: str) -> str | None:
    """Why the sizes that the open ``netCDF4.Dataset`` ``nc`` declares cannot be read, from its
    metadata alone (None when they can).

    A reader trusts the declared shapes: a crafted file of a few hundred kB declaring a 10^13-point
    grid made counting its statuses allocate gigabytes. Refused: a grid (``status``) of more
    points than a sweep may hold (:data:`~cosserat_channel.parameters.MAX_GRID_POINTS`), a
    variable that would be read in more than :data:`MAX_PIECES` pieces or in a piece above
    :data:`MAX_PIECE_BYTES`, and a file smaller than its variables take once written (unwritten
    chunks take no space).
    """
    from ..parameters import MAX_GRID_POINTS

    status = nc.variables.get("status")
    if status is not None and math.prod(status.shape) > MAX_GRID_POINTS:
        return (f"'status' declares {math.prod(status.shape):,} points, more than the "
                f"{MAX_GRID_POINTS:,} a sweep may hold: not a result of 'run'; nothing read")
    least, size = 0, os.path.getsize(path)
    for name, var in nc.variables.items():
        n = math.prod(var.shape)
        if n == 0:
            continue
        itemsize = getattr(var.dtype, "itemsize", 0) or 8
        chunks = var.chunking()
        if chunks == "contiguous":
            pieces, piece = 1, n * itemsize
            least += piece
        else:
            pieces = math.prod(-(-d // c) for d, c in zip(var.shape, chunks))
            piece = math.prod(chunks) * itemsize
            least += pieces * MIN_CHUNK_BYTES
        shape = " x ".join(map(str, var.shape))
        if pieces > MAX_PIECES:
            return (f"variable {name!r} ({shape}) is stored in {pieces:,} chunks, more than "
                    f"{MAX_PIECES:,}: not a result of 'run'; nothing read")
        if piece > MAX_PIECE_BYTES:
            return (f"variable {name!r} ({shape}) would be read in pieces of {piece:,} bytes, "
                    f"more than {MAX_PIECE_BYTES:,}: not a result of 'run'; nothing read")
    if least > size:
        return (f"the file is {size:,} bytes but its variables take at least {least:,} once "
                "written (their shapes are larger than what it holds): truncated, damaged or "
                "crafted; nothing read")
    return None


def check_storage(path) -> None:
    """QueryError (naming ``path``) when :func:`storage_problem` finds one; a file that netCDF4
    cannot open passes (its opener says what is wrong with it)."""
    import netCDF4

    path = os.fspath(path)
    try:
        nc = netCDF4.Dataset(path)
    except OPEN_ERRORS:
        return
    try:
        problem = storage_problem(nc, path)
    except OPEN_ERRORS:
        problem = None
    finally:
        nc.close()
    if problem:
        raise QueryError(f"{path}: {problem}")


def open_netcdf(path) -> xr.Dataset:
    """Open any NetCDF file lazily (dask-backed); QueryError (one line) when it cannot be, or
    when its declared sizes cannot be read (:func:`storage_problem`)."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise QueryError(f"{path}: no such file")
    if os.path.isdir(path):
        raise QueryError(f"{path}: is a directory, not a result file")
    check_storage(path)  # closed again before xarray opens the file: one reader at a time
    import xarray as xr

    try:
        return xr.open_dataset(path, chunks={})
    # Any file can arrive here; the backends raise several types for "not NetCDF", and netCDF4
    # an AttributeError for an attribute HDF5 cannot read (a damaged header).
    except OPEN_ERRORS as exc:
        reason = (isinstance(exc, OSError) and exc.strerror) or (
            "damaged, or not NetCDF" if type(exc) in (RuntimeError, AttributeError)
            else "not NetCDF")
        raise QueryError(f"{path}: cannot open as a NetCDF result file ({reason})") from None


def flags_checked(ds, path) -> xr.Dataset:
    """``ds`` (opened from ``path``) once its flag variables are usable (:func:`.flags.check_flags`);
    otherwise it is closed and the QueryError names ``path``."""
    try:
        check_flags(ds)
    except QueryError as exc:
        ds.close()
        raise QueryError(f"{os.fspath(path)}: {exc}") from None
    return ds


# The variables that make each kind of file the tool writes, and the one of them that is a CF
# flag (a result's status, a boundary's edge_kind).
KIND_VARIABLES = {"result": ("status",), "boundary": ("eta_max", "edge_kind"),
                  "atlas": ("leaf_coefficients", "sample_A")}
FLAGGED = {"result": "status", "boundary": "edge_kind"}


def is_kind(ds, kind: str) -> bool:
    """Whether ``ds`` has the variables of ``kind`` (:data:`KIND_VARIABLES`), its flag a CF flag."""
    flag = FLAGGED.get(kind)
    return (all(v in ds.data_vars for v in KIND_VARIABLES[kind])
            and (flag is None or _is_flag(ds[flag])))


def is_result(ds) -> bool:
    """Whether ``ds`` is a result of ``run`` (or a subset of one): a CF flag ``status``."""
    return is_kind(ds, "result")


def open_results(path) -> xr.Dataset:
    """Open a result file lazily (dask-backed); QueryError unless it is one of our result files.

    The Dataset has the ``cosserat`` accessor (:mod:`.accessor`).
    """
    ds = open_netcdf(path)
    if not is_result(ds):
        ds.close()
        raise QueryError(
            f"{os.fspath(path)}: not a cosserat-channel result file (no 'status' variable with "
            "flag_values/flag_meanings)"
        )
    flags_checked(ds, path)
    from . import accessor  # noqa: F401 (registers ds.cosserat)

    return ds


# What opening an arbitrary file with xarray or netCDF4 raises when it is not a readable NetCDF.
OPEN_ERRORS = (OSError, ValueError, RuntimeError, TypeError, KeyError, AttributeError)


def read_problem(ds: xr.Dataset, names=None) -> str | None:
    """Read every variable of ``ds`` (or those in ``names``) through, in chunks, and say which one
    cannot be read, if any.

    Result files carry HDF5 Fletcher-32 checksums (:func:`cosserat_channel.netcdf_policy.encoding`): a damaged
    chunk fails to read (netCDF4: ``RuntimeError: NetCDF: HDF error``) instead of returning
    changed numbers. Used to tell such a file from a failure to write the output, and by
    ``info`` to verify what it describes.
    """
    import xarray as xr

    from . import damage

    for name in [*ds.coords, *ds.data_vars] if names is None else names:
        try:
            # Read once: the count reads every chunk through its checksum, and the damage the
            # checksums do not see (a chunk the index no longer finds reads as fill values) is
            # counted in the same pass.
            bad = damage.dataset_counts(ds, name)
            parts = {"n": ds[name].count(), **({} if bad is None else {"bad": bad})}
            counted = xr.Dataset(parts).compute()
        except (OSError, RuntimeError, ValueError) as exc:
            reason = " ".join(str(exc).split()) or type(exc).__name__
            return (f"the file is damaged: variable {name!r} cannot be read ({reason}; its "
                    "checksum or the HDF5 structure does not match); write it again")
        if bad is not None and int(counted["bad"]):
            return damage.dataset_message(ds, name, int(counted["bad"]))
    return None


# ---------------------------------------------------------------------------------------------
# Parsing the clauses
# ---------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Condition:
    """One ``--where`` clause: ``name op value`` (value a float, or a flag code)."""

    name: str
    op: str
    value: float
    text: str

    def evaluate(self, ds: xr.Dataset) -> xr.DataArray:
        return _OPS[self.op](ds[self.name], self.value)


def _coordinate_names(ds: xr.Dataset) -> list[str]:
    return [d for d in ds.dims if d in ds.coords]


def _check_coordinate(name: str, ds: xr.Dataset, option: str) -> None:
    coords = _coordinate_names(ds)
    if name not in coords:
        raise QueryError(f"{option}: unknown coordinate {name!r}; valid: {', '.join(coords)}")
    if ds[name].dtype.kind not in "iuf":
        raise QueryError(f"{option}: coordinate {name!r} is not numeric ({ds[name].dtype}); "
                         "only numeric coordinates can be selected")


def _float(text: str, what: str) -> float:
    try:
        x = float(text)
    except ValueError:
        raise QueryError(f"{what}: {text!r} is not a number") from None
    if math.isnan(x):
        raise QueryError(f"{what}: nan is not a usable value")
    return x


def parse_sel(text: str, ds: xr.Dataset) -> tuple[str, float]:
    """``NAME=VALUE`` -> ``(name, value)``, NAME a dimension coordinate of ``ds``."""
    m = _SEL_RE.match(text)
    if not m:
        raise QueryError(f"--sel {text!r}: expected NAME=VALUE, e.g. L=10")
    name, value = m.groups()
    _check_coordinate(name, ds, "--sel")
    x = _float(value, f"--sel {name}")
    if not math.isfinite(x):
        raise QueryError(f"--sel {name}: the value must be finite; got {value!r}")
    return name, x


def parse_range(text: str, ds: xr.Dataset) -> tuple[str, float | None, float | None]:
    """``NAME=LO:HI`` (LO or HI may be empty) -> ``(name, lo, hi)``, None for an open end."""
    m = _RANGE_RE.match(text)
    if not m:
        raise QueryError(f"--range {text!r}: expected NAME=LO:HI, e.g. eps=0.001:0.01 or eps=:0.01")
    name, lo, hi = m.groups()
    _check_coordinate(name, ds, "--range")
    lo_x = _float(lo, f"--range {name} LO") if lo else None
    hi_x = _float(hi, f"--range {name} HI") if hi else None
    if lo_x is None and hi_x is None:
        raise QueryError(f"--range {name}: give at least one of LO and HI")
    if lo_x is not None and hi_x is not None and lo_x > hi_x:
        raise QueryError(f"--range {name}: LO = {lo_x:g} is above HI = {hi_x:g}")
    return name, lo_x, hi_x


def parse_where(text: str, ds: xr.Dataset) -> Condition:
    """``NAME OP VALUE`` -> :class:`Condition`; flag variables take a flag name as VALUE."""
    m = _WHERE_RE.match(text)
    if not m:
        raise QueryError(
            f"--where {text!r}: expected NAME OP VALUE with OP one of == != < <= > >= "
            "and VALUE a number (or a status name), e.g. \"Delta > 2\" or \"status == ok\""
        )
    name, op, value = m.groups()
    names = [*_coordinate_names(ds), *ds.data_vars]
    if name not in names:
        raise QueryError(f"--where: unknown name {name!r}; valid: {', '.join(names)}")
    da = ds[name]
    if _is_flag(da):
        flags = flag_names(da)
        if op not in ("==", "!="):
            raise QueryError(f"--where {name}: a flag variable supports only == and !=; got {op}")
        if value not in flags:
            raise QueryError(
                f"--where {name}: unknown {name} name {value!r}; valid: {', '.join(flags)}"
            )
        return Condition(name, op, flags[value], text.strip())
    if da.dtype.kind not in "iuf":
        raise QueryError(f"--where: {name!r} is not numeric ({da.dtype}); it cannot be compared "
                         "with a number")
    return Condition(name, op, _float(value, f"--where {name}"), text.strip())


def parse_vars(text: str | None, ds: xr.Dataset) -> tuple[str, ...] | None:
    """``a,b`` -> the data variables to report (None: the default set)."""
    if text is None:
        return None
    names = [n.strip() for n in text.split(",") if n.strip()]
    if not names:
        raise QueryError("--vars: give at least one variable name")
    valid = list(ds.data_vars)
    unknown = [n for n in names if n not in valid]
    if unknown:
        raise QueryError(
            f"--vars: unknown variable(s) {', '.join(map(repr, unknown))}; "
            f"valid: {', '.join(valid)}"
        )
    return tuple(dict.fromkeys(names))


# ---------------------------------------------------------------------------------------------
# Selecting
# ---------------------------------------------------------------------------------------------
def match_coordinate(values, value: float, name: str, option: str = "--sel",
                     nearest: bool = False) -> tuple[int, bool]:
    """``(index, exact)`` of ``value`` in the coordinate ``values``.

    ``exact``: the value equals the grid value within round-off (:data:`SEL_RTOL`). Without
    ``nearest`` a value between grid values raises :class:`QueryError` naming the nearest grid
    values below and above it; with ``nearest`` the index is that of the nearest value.
    """
    if not math.isfinite(value):  # NaN has no nearest value, and no grid value is infinite
        raise QueryError(f"{option} {name}: the value must be finite; got {value!r}")
    c = np.asarray(values, dtype=float).reshape(-1)
    if c.size == 0:
        raise QueryError(f"{option} {name}: the coordinate {name} is empty")
    dist = np.abs(c - value)
    i = int(np.argmin(dist))
    scale = float(np.max(np.abs(c)))
    tol = SEL_RTOL * max(abs(float(c[i])), abs(value), 1e-3 * scale)
    if dist[i] <= tol or nearest:
        return i, bool(dist[i] <= tol)
    below = c[c < value]
    above = c[c > value]
    near = [f"{v:.10g}" for v in ((below.max(),) if below.size else ())
            + ((above.min(),) if above.size else ())]
    where = "nearest grid values" if len(near) == 2 else "nearest grid value"
    raise QueryError(
        f"{option} {name}={value:.10g}: not a value of {name} ({c.size} values from "
        f"{c.min():.10g} to {c.max():.10g}); {where}: {', '.join(near)}; give "
        f"{'one of them' if len(near) == 2 else 'it'}, or add --nearest to take the nearest"
    )


@dataclass
class Selection:
    """The selected part of a result file, still lazy.

    ``ds`` is the file reduced by ``--sel``/``--range`` (every dimension kept), ``columns`` the
    reported variables (``status`` first), ``conditions`` the ``--where`` clauses and ``row_dims``
    the dimensions one row runs over.
    """

    ds: xr.Dataset
    columns: tuple[str, ...]
    conditions: tuple[Condition, ...]
    row_dims: tuple[str, ...]
    description: str = ""
    snapped: tuple = ()  # (name, value asked, value taken) of each --sel moved by nearest=True
    index: dict = field(default_factory=dict, repr=False)  # the isel of --sel and --range
    _mask: np.ndarray | None = field(default=None, repr=False)

    def mask(self) -> np.ndarray | None:
        """Boolean array over ``row_dims`` (None when there is no ``--where``); computed once."""
        if not self.conditions:
            return None
        if self._mask is None and getattr(self.ds, "light_box", False):
            self._mask = self.ds.mask(self.conditions, self.row_dims)
        if self._mask is None:
            m = self.conditions[0].evaluate(self.ds)
            for c in self.conditions[1:]:
                m = m & c.evaluate(self.ds)
            m = m.compute()
            missing = {d: self.ds.sizes[d] for d in self.row_dims if d not in m.dims}
            if missing:
                m = m.expand_dims(missing)
            self._mask = np.asarray(m.transpose(*self.row_dims).values, dtype=bool)
        return self._mask

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(self.ds.sizes[d] for d in self.row_dims)

    def count(self) -> int:
        """Number of selected rows."""
        m = self.mask()
        return int(m.sum()) if m is not None else math.prod(self.shape)


def select(ds: xr.Dataset, sel=(), ranges=(), where=(), variables=None,
           description: str = "", nearest: bool = False) -> Selection:
    """Apply parsed clauses (see :func:`parse_sel`, :func:`parse_range`, :func:`parse_where`).

    A ``--sel`` value must be a grid value (within round-off) unless ``nearest``; see
    :func:`match_coordinate`.
    """
    index: dict[str, np.ndarray] = {}
    snapped = []
    for name, value in sel:
        if name in index:
            raise QueryError(f"--sel {name}: {name} is selected twice")
        c = np.asarray(ds[name].values, dtype=float)
        i, exact = match_coordinate(c, value, name, nearest=nearest)
        if not exact:
            snapped.append((name, value, float(c[i])))
        index[name] = np.array([i])
    for name, lo, hi in ranges:
        if name in index:
            raise QueryError(f"--range {name}: {name} is already selected by another --sel/--range")
        c = np.asarray(ds[name].values, dtype=float)
        keep = np.ones(c.shape, bool)
        if lo is not None:
            keep &= c >= lo - RANGE_SLACK * abs(lo)
        if hi is not None:
            keep &= c <= hi + RANGE_SLACK * abs(hi)
        index[name] = np.flatnonzero(keep)
    sub = ds.isel(index) if index or getattr(ds, "light", False) else ds

    if variables is None:
        scalar_dims = set(ds["status"].dims)
        variables = tuple(v for v in ds.data_vars if set(ds[v].dims) <= scalar_dims)
    columns = ("status", *(v for v in variables if v != "status"))
    conditions = tuple(where)
    used = set()
    for name in (*columns, *(c.name for c in conditions)):
        used.update(ds[name].dims)
    row_dims = tuple(d for d in ds.dims if d in used)
    return Selection(sub, columns, conditions, row_dims, description, tuple(snapped), index)


