"""What a selection looks like to its reader: a table, CSV, JSON or a NetCDF subset.

Every format reads the same rows of :class:`~cosserat_channel.results.selection.Selection` (in
blocks of ``ROW_BLOCK`` points), so every output of a query holds exactly the same points.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from typing import TYPE_CHECKING

import numpy as np

from ..files import write_dataset

if TYPE_CHECKING:  # imported where used: a small query never imports xarray (LightFile)
    import xarray as xr
from . import damage
from .flags import _is_flag, flag_names, printable
from .selection import ROW_BLOCK, Selection, read_problem

TABLE_ROWS = 200

# ---------------------------------------------------------------------------------------------
# Rows
# ---------------------------------------------------------------------------------------------
def header(selection: Selection) -> list[str]:
    return [*selection.row_dims, *selection.columns]


def iter_rows(selection: Selection, limit: int | None = None):
    """Yield rows (lists of Python values: floats, ints, flag names) in C order of ``row_dims``."""
    if getattr(selection.ds, "light_box", False):
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
    # A subset's own choice of points (query --where) is read with the rows: the damage check
    # holds only those to their status.
    names = list(dict.fromkeys([*selection.columns, *(
        [damage.SELECTED] if damage.SELECTED in selection.ds.data_vars else [])]))
    sub = selection.ds[names]
    if math.prod(shape) <= ROW_BLOCK:
        sub = _load_box(selection, names)
    flags = {v: {c: k for k, c in flag_names(sub[v]).items()}
             for v in selection.columns if _is_flag(sub[v])}
    for start in range(0, n, ROW_BLOCK):
        stop = min(n, start + ROW_BLOCK)
        block = flat[start:stop] if flat is not None else np.arange(start, stop)
        idx = np.unravel_index(block, shape)
        indexers = {d: xr.DataArray(i, dims="row") for d, i in zip(selection.row_dims, idx)}
        pts = sub.isel(indexers).compute()
        cols = [np.asarray(pts[d].values) for d in selection.row_dims]
        if "status" in flags:
            damage.check_rows({v: pts[v].values for v in selection.columns},
                              list(flags["status"]), dict(zip(selection.row_dims, cols)),
                              pts[damage.SELECTED].values if damage.SELECTED in pts else None)
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
    """A value as JSON, CSV and the table take it: float, int, bool or str (a date, bytes or
    anything else of a foreign file as its text)."""
    if isinstance(x, (np.bool_, bool)):
        return bool(x)
    if isinstance(x, (np.floating, float)):
        return float(x)
    if isinstance(x, (np.integer, int)):
        return int(x)
    if isinstance(x, bytes):
        return x.decode("utf-8", "backslashreplace")
    return x if isinstance(x, str) else str(x)


def _text(x) -> str:
    return f"{x:.10g}" if isinstance(x, float) else str(x)


def format_table(selection: Selection, max_rows: int | None = None) -> str:
    """Aligned columns, at most ``max_rows`` rows (default ``TABLE_ROWS``), then a count."""
    max_rows = TABLE_ROWS if max_rows is None else max_rows
    head = [printable(h) for h in header(selection)]
    rows = [[printable(_text(x)) for x in r] for r in iter_rows(selection, limit=max_rows)]
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
                long_name="selected by the query",
                description="point matches the query's --where clauses",
            )
    ds.attrs = dict(selection.ds.attrs)
    if selection.description:
        ds.attrs["query"] = selection.description
    return ds


def write_netcdf(selection: Selection, path: str, replace: bool = True) -> None:
    """Write :func:`subset_dataset` atomically (:func:`..files.atomic_output`: over a file at
    ``path`` only with ``replace``)."""
    ds = subset_dataset(selection)
    for v in ds.variables.values():
        v.encoding = {}
    import dask

    # One thread: with dask's threaded scheduler a failed read (a damaged chunk) raises while
    # other threads still write, and xarray's file manager reopens the temporary file after
    # atomic_output has removed it, leaving it behind.
    with dask.config.set(scheduler="synchronous"):
        # A part of the file that HDF5 no longer finds reads as fill values without an error:
        # never copied into the subset as if they were values.
        problem = read_problem(ds, [*(d for d in ds.dims if d in ds.coords), *(
            v for v in ds.data_vars if damage.valued_when_ok(v) or v == "status")])
        if problem:
            raise damage.DamagedFile(problem)
        write_dataset(path, ds, replace=replace)


def render(selection: Selection, fmt: str) -> str:
    """table/csv/json as one string (for stdout)."""
    if fmt == "table":
        return format_table(selection)
    buf = io.StringIO()
    (write_csv if fmt == "csv" else write_json)(selection, buf)
    return buf.getvalue()


