"""Small queries without xarray: a result file read through the ``netCDF4`` library alone.

Importing xarray and dask takes longer than a small query's own work (a slice, a curve), so a
query of at most ``ROW_BLOCK`` points of a file written by ``run`` is answered from here, through
the same parsing and selecting code as any other (:mod:`.selection`).
"""

from __future__ import annotations

import os

import numpy as np


from .render import _python
from . import damage
from .flags import _is_flag, check_flags, flag_names
from .selection import _OPS, Selection, storage_problem

class _LightVariable:
    """What parsing and selecting read of a variable: dims, attrs, dtype, shape, values."""

    def __init__(self, var, dims):
        self._var = var
        self.name = var.name
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

    # what selection and rendering ask instead of an isinstance test (they do not import this module)
    light = True
    light_box = False

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
        if self.nc.isopen():  # closed early by a caller that reopens the file another way
            self.nc.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


class LightBox(LightFile):
    """The box of a :class:`LightFile` that ``--sel`` and ``--range`` select (positions per
    dimension); it reads only that box, and gives the rows :func:`iter_rows` gives."""

    light_box = True

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
        raw = {v: self.read(v, selection.row_dims)[idx] for v in selection.columns}
        chosen = (self.read(damage.SELECTED, selection.row_dims)[idx]
                  if damage.SELECTED in self.data_vars else None)
        damage.check_rows(raw, list(flag_names(self["status"]).values()),
                          dict(zip(selection.row_dims, cols)), chosen)
        for v in selection.columns:
            values = raw[v]
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
        # A QueryError (a ValueError): open_results then says what is wrong.
        if storage_problem(nc, path):
            raise LookupError
        check_flags(f)
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
    except (LookupError, AttributeError, OSError, RuntimeError, ValueError):
        nc.close()
        return None
    return f

