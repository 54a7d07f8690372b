"""Safe selection and filtering of result files (the ``query`` and ``info`` commands).

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

The module is long (~580 lines) because parsing, selecting, rendering (table, CSV, JSON, NetCDF)
and describing a result share the :class:`Selection` and its row iterator; it stays one piece so
that every output format sees exactly the same points.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
import re
from dataclasses import dataclass, field

from typing import TYPE_CHECKING

import numpy as np

from ..files import atomic_output, netcdf_output
from ..parameters import ParameterError

if TYPE_CHECKING:  # imported where used: a small query never imports xarray (LightFile)
    import xarray as xr

RANGE_SLACK = 1e-9
# --sel: |grid - value| <= SEL_RTOL * max(|grid|, |value|), or <= SEL_RTOL * 1e-3 * max|coordinate|
# for values at or next to 0 (a linspace through 0 gives ~1e-16 there instead of 0).
SEL_RTOL = 1e-9
ROW_BLOCK = 1_000_000
TABLE_ROWS = 200
SWEEP_TEXT_LINES = 12
PROVENANCE = ("cosserat_channel_version", "created", "rtol", "atol", "sweep_sha256", "Conventions")

_NAME = r"[A-Za-z_][A-Za-z0-9_]*"
_SEL_RE = re.compile(rf"^\s*({_NAME})\s*=\s*(\S+)\s*$")
_RANGE_RE = re.compile(rf"^\s*({_NAME})\s*=\s*([^:\s]*)\s*:\s*([^:\s]*)\s*$")
_WHERE_RE = re.compile(rf"^\s*({_NAME})\s*(==|!=|<=|>=|<|>)\s*(\S+)\s*$")
_OPS = {
    "==": np.equal, "!=": np.not_equal, "<": np.less,
    "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal,
}


class QueryError(ParameterError):
    """A query the file cannot answer (unknown name, malformed clause, unreadable file)."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


# ---------------------------------------------------------------------------------------------
# Opening
# ---------------------------------------------------------------------------------------------
def open_results(path) -> xr.Dataset:
    """Open a result file lazily (dask-backed); QueryError unless it is one of our result files."""
    path = os.fspath(path)
    if not os.path.exists(path):
        raise QueryError(f"{path}: no such file")
    if os.path.isdir(path):
        raise QueryError(f"{path}: is a directory, not a result file")
    import xarray as xr

    try:
        ds = xr.open_dataset(path, chunks={})
    # Any file can arrive here; the backends raise several types for "not NetCDF".
    except (OSError, ValueError, RuntimeError, TypeError, KeyError) as exc:
        reason = (isinstance(exc, OSError) and exc.strerror) or (
            "damaged, or not NetCDF" if type(exc) is RuntimeError else "not NetCDF")
        raise QueryError(f"{path}: cannot open as a NetCDF result file ({reason})") from None
    if "status" not in ds.data_vars or not _is_flag(ds["status"]):
        ds.close()
        raise QueryError(
            f"{path}: not a cosserat-channel result file (no 'status' variable with "
            "flag_values/flag_meanings)"
        )
    return ds


def read_problem(ds: xr.Dataset) -> str | None:
    """Read every variable of ``ds`` through (in chunks) and say which one cannot be read, if any.

    Result files carry HDF5 Fletcher-32 checksums (:func:`sweep.dataset.encoding`): a damaged
    chunk fails to read (netCDF4: ``RuntimeError: NetCDF: HDF error``) instead of returning
    changed numbers. Used to tell such a file from a failure to write the output.
    """
    for name in [*ds.coords, *ds.data_vars]:
        try:
            ds[name].count().compute()
        except (OSError, RuntimeError, ValueError) as exc:
            reason = " ".join(str(exc).split()) or type(exc).__name__
            return (f"the file is damaged: variable {name!r} cannot be read ({reason}; its "
                    "checksum or the HDF5 structure does not match); write it again")
    return None


def _is_flag(da: xr.DataArray) -> bool:
    return "flag_values" in da.attrs and "flag_meanings" in da.attrs


def flag_names(da: xr.DataArray) -> dict[str, int]:
    """``{flag name: value}`` of a CF flag variable."""
    values = np.atleast_1d(np.asarray(da.attrs["flag_values"])).tolist()
    names = str(da.attrs["flag_meanings"]).split()
    return dict(zip(names, (int(v) for v in values)))


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


def _show(x, limit: int = 24) -> str:
    s = str(x)
    return s if len(s) <= limit else s[: limit - 1] + "…"


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
        if self._mask is None and isinstance(self.ds, LightBox):
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
    sub = ds.isel(index) if index or isinstance(ds, LightFile) else ds

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


# ---------------------------------------------------------------------------------------------
# Rows
# ---------------------------------------------------------------------------------------------
def header(selection: Selection) -> list[str]:
    return [*selection.row_dims, *selection.columns]


def iter_rows(selection: Selection, limit: int | None = None):
    """Yield rows (lists of Python values: floats, ints, flag names) in C order of ``row_dims``."""
    if isinstance(selection.ds, LightBox):
        yield from selection.ds.rows(selection, limit)
        return
    import xarray as xr

    mask = selection.mask()
    shape = selection.shape
    total = selection.count()
    n = total if limit is None else min(limit, total)
    if n == 0:
        return
    flat = np.flatnonzero(mask)[:n] if mask is not None else None
    sub = selection.ds[list(selection.columns)]
    if math.prod(shape) <= ROW_BLOCK:
        sub = _load_box(selection, list(selection.columns))
    flags = {v: {c: k for k, c in flag_names(sub[v]).items()}
             for v in selection.columns if _is_flag(sub[v])}
    for start in range(0, n, ROW_BLOCK):
        stop = min(n, start + ROW_BLOCK)
        block = flat[start:stop] if flat is not None else np.arange(start, stop)
        idx = np.unravel_index(block, shape)
        indexers = {d: xr.DataArray(i, dims="row") for d, i in zip(selection.row_dims, idx)}
        pts = sub.isel(indexers).compute()
        cols = [np.asarray(pts[d].values) for d in selection.row_dims]
        for v in selection.columns:
            values = pts[v].values
            if v in flags:
                values = np.array([flags[v].get(int(c), str(int(c))) for c in values], dtype=object)
            cols.append(values)
        for k in range(stop - start):
            yield [_python(c[k]) for c in cols]


def _load_box(selection: Selection, names: list[str]) -> xr.Dataset:
    """The selected box of ``names``, in memory: read straight from the file when it is at hand.

    For a box this small (a slice, a curve) dask's task graph costs more than the read itself
    (~1 s against ~0.1 s for 10^4 points of a 10^8-point file); the file is read only where the
    box lies either way.
    """
    import xarray as xr

    source = selection.ds.encoding.get("source")
    if source and os.path.isfile(source):
        with xr.open_dataset(source) as f:
            return f[names].isel(selection.index).load()
    return selection.ds[names].compute()


def _python(x):
    if isinstance(x, (np.floating, float)):
        return float(x)
    if isinstance(x, (np.integer, int)):
        return int(x)
    return x


def _text(x) -> str:
    return f"{x:.10g}" if isinstance(x, float) else str(x)


def format_table(selection: Selection, max_rows: int | None = None) -> str:
    """Aligned columns, at most ``max_rows`` rows (default ``TABLE_ROWS``), then a count."""
    max_rows = TABLE_ROWS if max_rows is None else max_rows
    head = header(selection)
    rows = [[_text(x) for x in r] for r in iter_rows(selection, limit=max_rows)]
    widths = [max([len(h), *(len(r[i]) for r in rows)]) for i, h in enumerate(head)]
    lines = ["  ".join(h.rjust(w) for h, w in zip(head, widths))]
    lines += ["  ".join(x.rjust(w) for x, w in zip(r, widths)) for r in rows]
    rest = selection.count() - len(rows)
    if rest > 0:
        lines.append(f"… {rest} more rows (use --format csv -o FILE)")
    return "\n".join(lines) + "\n"


def write_csv(selection: Selection, f) -> None:
    """CSV with a header row; floats in full precision (``repr``), NaN as ``nan``."""
    w = csv.writer(f, lineterminator="\n")
    w.writerow(header(selection))
    for r in iter_rows(selection):
        w.writerow([repr(x) if isinstance(x, float) else x for x in r])


def write_json(selection: Selection, f) -> None:
    """A JSON array of objects, one per row; NaN as null (strict JSON)."""
    head = header(selection)
    f.write("[")
    first = True
    for r in iter_rows(selection):
        obj = {k: (None if isinstance(x, float) and not math.isfinite(x) else x)
               for k, x in zip(head, r)}
        f.write(("\n" if first else ",\n") + json.dumps(obj, allow_nan=False))
        first = False
    f.write("\n]\n" if not first else "]\n")


# ---------------------------------------------------------------------------------------------
# NetCDF subset
# ---------------------------------------------------------------------------------------------
def subset_dataset(selection: Selection) -> xr.Dataset:
    """The selection as a result Dataset of the same layout (see the module docstring)."""
    import xarray as xr

    keep = list(selection.columns)
    ds = selection.ds[keep]
    mask = selection.mask()
    if mask is not None:
        # Smallest sub-grid holding every match.
        index = {}
        for k, d in enumerate(selection.row_dims):
            other = tuple(j for j in range(mask.ndim) if j != k)
            index[d] = np.flatnonzero(mask.any(axis=other))
        ds = ds.isel(index)
        mask = mask[np.ix_(*index.values())]
        if not mask.all():
            m = xr.DataArray(mask, dims=selection.row_dims)
            for v in ds.data_vars:
                if ds[v].dtype.kind == "f":
                    extra = [d for d in m.dims if d not in ds[v].dims]
                    mv = m.any(dim=extra) if extra else m
                    ds[v] = ds[v].where(mv)
            ds["selected"] = m.astype(np.int8).assign_attrs(
                flag_values=np.array([0, 1], dtype=np.int8),
                flag_meanings="no yes",
                long_name="point matches the query's --where clauses",
            )
    ds.attrs = dict(selection.ds.attrs)
    if selection.description:
        ds.attrs["query"] = selection.description
    return ds


def _encoding(ds: xr.Dataset) -> dict:
    enc = {}
    for name, v in ds.variables.items():
        if v.dtype.kind == "f":
            e = {"_FillValue": np.nan} if name in ds.data_vars else {"_FillValue": None}
        else:
            e = {"_FillValue": None}  # status and counters: every value is a real code/count
        if name in ds.data_vars and v.ndim > 0:
            e.update(zlib=True, complevel=1)
        if v.ndim > 0 and v.dtype.kind in "fiub":
            e["fletcher32"] = True  # as sweep.dataset.encoding: damage fails to read
        enc[name] = e
    return enc


def write_netcdf(selection: Selection, path: str) -> None:
    """Write :func:`subset_dataset` atomically (temporary file + ``os.replace``)."""
    ds = subset_dataset(selection)
    for v in ds.variables.values():
        v.encoding = {}
    import dask

    # One thread: with dask's threaded scheduler a failed read (a damaged chunk) raises while
    # other threads still write, and xarray's file manager reopens the temporary file after
    # atomic_output has removed it, leaving it behind.
    with dask.config.set(scheduler="synchronous"):
        netcdf_output(path, lambda tmp: ds.to_netcdf(tmp, encoding=_encoding(ds)))


def write_text(path: str, writer) -> None:
    """Run ``writer(file)`` into a temporary file next to ``path``, then rename it over ``path``."""

    def run(tmp):
        with open(tmp, "w", encoding="utf-8", newline="") as f:
            writer(f)

    atomic_output(path, run)




def render(selection: Selection, fmt: str) -> str:
    """table/csv/json as one string (for stdout)."""
    if fmt == "table":
        return format_table(selection)
    buf = io.StringIO()
    (write_csv if fmt == "csv" else write_json)(selection, buf)
    return buf.getvalue()


# ---------------------------------------------------------------------------------------------
# info
# ---------------------------------------------------------------------------------------------
def status_counts(ds: xr.Dataset) -> dict[str, int]:
    """Points per status name (lazy reduction; codes outside the flags count as 'other')."""
    import xarray as xr

    flags = flag_names(ds["status"])
    sums = xr.Dataset({n: (ds["status"] == v).sum() for n, v in flags.items()}).compute()
    counts = {n: int(sums[n]) for n in flags}
    other = int(ds["status"].size) - sum(counts.values())
    if other:
        counts["other"] = other
    return counts


def describe(ds: xr.Dataset, path: str = "") -> str:
    """The ``info`` report: dimensions, variables, status counts, provenance."""
    lines = [f"file  {path}"] if path else []
    lines.append("dimensions")
    for d in ds.dims:
        n = ds.sizes[d]
        if d in ds.coords and n:
            c = np.asarray(ds[d].values)
            unit = ds[d].attrs.get("units", "")
            if c.dtype.kind in "iuf":
                rng = f"{np.min(c):.10g} .. {np.max(c):.10g}"
            else:  # not a file of ours, but describe what is there (strings, dates, ...)
                rng = _show(c[0]) + (f" .. {_show(c[-1])}" if n > 1 else "")
            text = ds[d].attrs.get("long_name", "")
            lines.append(f"  {d:<8} {n:>8}  {rng:<30} {unit:<10} {text}".rstrip())
        else:
            lines.append(f"  {d:<8} {n:>8}")
    lines.append("variables")
    for v in ds.data_vars:
        da = ds[v]
        unit = da.attrs.get("units", "")
        text = da.attrs.get("long_name", "")
        dims = "(" + ", ".join(da.dims) + ")"
        lines.append(f"  {v:<18} {str(da.dtype):<8} {unit:<18} {text}  {dims}".rstrip())
    counts = status_counts(ds)
    total = max(1, int(ds["status"].size))
    lines.append(f"status ({int(ds['status'].size)} points)")
    for name, n in counts.items():
        lines.append(f"  {name:<22} {n:>12}  {100.0 * n / total:6.2f} %")
    lines.append("provenance")
    a = ds.attrs
    for key in PROVENANCE:
        if key in a:
            lines.append(f"  {key:<24} {_text(_python(a[key]))}")
    if "query" in a:
        lines.append(f"  {'query':<24} {a['query']}")
    text = str(a.get("sweep_toml", ""))
    if text:
        sweep_lines = text.splitlines()
        shown = min(SWEEP_TEXT_LINES, len(sweep_lines))
        lines.append(f"  sweep (first {shown} of {len(sweep_lines)} lines)")
        lines += ["    " + s for s in sweep_lines[:SWEEP_TEXT_LINES]]
    return "\n".join(lines) + "\n"


# ---------------------------------------------------------------------------------------------
# Small queries without xarray
# ---------------------------------------------------------------------------------------------
class _LightVariable:
    """What parsing and selecting read of a variable: dims, attrs, dtype, shape, values."""

    def __init__(self, var, dims):
        self._var = var
        self.dims = dims
        self.attrs = {k: var.getncattr(k) for k in var.ncattrs()}
        self.dtype = var.dtype
        self.shape = var.shape

    @property
    def values(self) -> np.ndarray:
        return np.asarray(self._var[...])


class LightFile:
    """A result file written by ``run`` (or a NetCDF subset of one) read with ``netCDF4`` alone:
    the part of an xarray Dataset that :func:`parse_sel`, :func:`parse_range`,
    :func:`parse_where`, :func:`parse_vars` and :func:`select` use. Open with :func:`open_light`.
    """

    def __init__(self, nc, path: str):
        self.nc = nc
        self.path = path
        self.dims = tuple(nc.dimensions)
        self.sizes = {d: len(nc.dimensions[d]) for d in self.dims}
        self.coords = tuple(d for d in self.dims if d in nc.variables)
        self.data_vars = tuple(v for v in nc.variables if v not in self.coords)

    def __getitem__(self, name: str) -> _LightVariable:
        if name not in self.nc.variables:
            raise KeyError(name)
        return _LightVariable(self.nc[name], tuple(self.nc[name].dimensions))

    def isel(self, index: dict) -> "LightBox":
        return LightBox(self, index)

    def close(self) -> None:
        self.nc.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class LightBox(LightFile):
    """The box of a :class:`LightFile` that ``--sel`` and ``--range`` select (positions per
    dimension); it reads only that box, and gives the rows :func:`iter_rows` gives."""

    def __init__(self, parent: LightFile, index: dict):
        super().__init__(parent.nc, parent.path)
        self.index = {d: np.asarray(i, dtype=np.int64) for d, i in index.items()}
        self.sizes = {d: int(self.index[d].size) if d in self.index else n
                      for d, n in self.sizes.items()}

    def read(self, name: str, row_dims: tuple) -> np.ndarray:
        """Variable or coordinate ``name`` on the box, broadcast over ``row_dims``."""
        var = self.nc[name]
        shape = tuple(self.sizes[d] for d in row_dims)
        if 0 in shape:
            return np.empty(shape, dtype=var.dtype)
        key = tuple(_slice_or_positions(self.index.get(d)) for d in var.dimensions)
        values = np.asarray(var[key]) if key else np.asarray(var[...])
        values = values.reshape(tuple(self.sizes[d] if d in var.dimensions else 1
                                      for d in row_dims))
        return np.broadcast_to(values, shape)

    def mask(self, conditions, row_dims) -> np.ndarray:
        """The ``--where`` clauses ANDed, over ``row_dims`` (as :meth:`Selection.mask`)."""
        m = np.ones(tuple(self.sizes[d] for d in row_dims), dtype=bool)
        for c in conditions:
            m &= _OPS[c.op](self.read(c.name, row_dims), c.value)
        return m

    def rows(self, selection: "Selection", limit: int | None):
        """:func:`iter_rows` of a selection of this box (at most ``ROW_BLOCK`` points)."""
        mask = selection.mask()
        total = selection.count()
        n = total if limit is None else min(limit, total)
        if n == 0:
            return
        flat = np.flatnonzero(mask)[:n] if mask is not None else np.arange(n)
        idx = np.unravel_index(flat, selection.shape)
        cols = [self.read(d, (d,))[i] for d, i in zip(selection.row_dims, idx)]
        for v in selection.columns:
            values = self.read(v, selection.row_dims)[idx]
            da = self[v]
            if _is_flag(da):
                names = {c: k for k, c in flag_names(da).items()}
                values = np.array([names.get(int(c), str(int(c))) for c in values], dtype=object)
            cols.append(values)
        for k in range(n):
            yield [_python(c[k]) for c in cols]


def _slice_or_positions(positions):
    """A netCDF4 index for one dimension: all, a slice for consecutive positions, or them."""
    if positions is None:
        return slice(None)
    if positions.size and np.array_equal(positions, np.arange(positions[0],
                                                              positions[0] + positions.size)):
        return slice(int(positions[0]), int(positions[0]) + positions.size)
    return positions


# Attributes that make xarray's decoding change values; a file with any is read through xarray.
_DECODED = ("scale_factor", "add_offset", "missing_value", "calendar")


def open_light(path) -> LightFile | None:
    """``path`` as a :class:`LightFile` when it is a result file of ours that needs none of
    xarray's decoding (else None: read it with :func:`open_results`, which also says what is
    wrong with a file it cannot read).

    The values are then those xarray gives: our float variables' fill value is NaN (masking
    NaN with NaN changes nothing), integer ones have none, and no variable is scaled.
    """
    import netCDF4

    path = os.fspath(path)
    if not os.path.isfile(path):
        return None
    try:
        nc = netCDF4.Dataset(path)
    except (OSError, RuntimeError, ValueError):
        return None
    try:
        nc.set_auto_maskandscale(False)
        f = LightFile(nc, path)
        if getattr(nc, "source", None) != "cosserat-channel run" or nc.groups or \
                "status" not in f.data_vars or not _is_flag(f["status"]):
            raise LookupError
        order = {d: i for i, d in enumerate(f.dims)}
        for var in nc.variables.values():
            attrs = var.ncattrs()
            dims = var.dimensions
            fill = var.getncattr("_FillValue") if "_FillValue" in attrs else None
            if any(a in attrs for a in _DECODED) or var.dtype.kind not in "fiu" or \
                    "since" in str(getattr(var, "units", "")) or \
                    [order[d] for d in dims] != sorted(order[d] for d in dims) or \
                    (fill is not None and not (var.dtype.kind == "f" and np.isnan(fill))):
                raise LookupError
        if any(d not in f.coords or nc[d].dimensions != (d,) for d in f.dims):
            raise LookupError
    except (LookupError, OSError, RuntimeError, ValueError):
        nc.close()
        return None
    return f
