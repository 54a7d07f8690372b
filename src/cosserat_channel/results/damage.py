"""A value missing where a result file says there is one: damage that checksums do not see.

HDF5's Fletcher-32 checksums cover the data of each chunk, not the index (the B-tree) that finds
the chunks. A bit flipped there can make a chunk unfindable, and HDF5 then returns the fill value
for all of it without an error: NaN for floats, netCDF's default fill (a large negative number)
for integers. A point whose status is ``ok`` has a value of every output (but those an
:class:`~cosserat_channel.outputs.Output` declares without one there, ``valued_when_ok``) and of
every counter, and every status is one of the file's flags; a blanked chunk breaks one of these.

Pure numpy (and xarray for a Dataset): reading a file never imports numba.
"""

from __future__ import annotations

import numpy as np

from .. import status as st
from ..outputs import COUNTERS, OUTPUTS


class DamagedFile(RuntimeError):
    """Rows read from a result show damage (:func:`rows_problem`); the message is one line."""


# A subset written by ``query --where`` marks the points its clauses chose in this variable and
# has NaN at the others whatever their status: only the chosen ones are held to their status.
SELECTED = "selected"


def check_rows(columns: dict, flag_values, coordinates=None, selected=None) -> None:
    """Raise :class:`DamagedFile` if :func:`rows_problem` finds damage."""
    problem = rows_problem(columns, flag_values, coordinates, selected)
    if problem:
        raise DamagedFile(problem)


def valued_when_ok(name: str) -> bool:
    """Whether variable ``name`` of a result has a value at every point whose status is ok."""
    out = OUTPUTS.get(name)
    return name in COUNTERS or (out is not None and out.valued_when_ok)


# netCDF's default fill of a double (NC_FILL_DOUBLE) and of a float (NC_FILL_FLOAT): what a
# variable without a _FillValue (a coordinate) reads where its chunk is not found.
NC_FILL = (9.9692099683868690e36, float(np.float32(9.96921e36)))


def missing(values):
    """Where ``values`` (numpy or xarray) hold no value: NaN or netCDF's default fill for
    floats, a negative number for integers (counts and codes of ours are never negative)."""
    kind = values.dtype.kind
    if kind == "f":
        # NaN != NaN; works lazily on xarray too.
        return (values != values) | (values == NC_FILL[0]) | (values == NC_FILL[1])
    return values < 0 if kind in "iu" else values != values


def coordinate_message(name: str, n: int) -> str:
    return (f"the file is damaged: coordinate {name!r} has {n} value(s) missing (a part of the "
            "file that HDF5 no longer finds reads as fill values); write it again")


def missing_message(name: str, n: int) -> str:
    return (f"the file is damaged: variable {name!r} has no value at {n} point(s) whose status "
            "is ok (a part of the file that HDF5 no longer finds reads as fill values); write "
            "it again")


def status_message(n: int, example) -> str:
    return (f"the file is damaged: variable 'status' holds {n} value(s) that are no status "
            f"(e.g. {example}; a part of the file that HDF5 no longer finds reads as fill "
            "values); write it again")


def rows_problem(columns: dict, flag_values, coordinates=None, selected=None) -> str | None:
    """One line if the rows ``columns`` (``{name: array}``, ``status`` codes among them, all of
    one shape) or the ``coordinates`` (``{name: values}``) show damage, else None.
    ``flag_values``: the file's status codes; ``selected``: the rows' :data:`SELECTED` values
    in a subset that has them."""
    status = columns.get("status")
    if status is None:
        return None
    for name, values in (coordinates or {}).items():
        n = int(np.count_nonzero(missing(np.asarray(values))))
        if n:
            return coordinate_message(name, n)
    status = np.asarray(status)
    foreign = ~np.isin(status, np.asarray(flag_values))
    if foreign.any():
        return status_message(int(foreign.sum()), int(status[foreign].flat[0]))
    ok = status == st.OK
    if selected is not None:
        ok &= np.asarray(selected) == 1
    for name, values in columns.items():
        if name != "status" and valued_when_ok(name):
            n = int(np.count_nonzero(ok & missing(np.asarray(values))))
            if n:
                return missing_message(name, n)
    return None


def dataset_counts(ds, name: str):
    """The lazy count of damaged points of variable ``name`` of a result Dataset ``ds`` (None
    when it cannot be told for that variable)."""
    if "status" not in ds.variables:
        return None
    if name in ds.dims and name in ds.coords and ds[name].dtype.kind in "fiu":
        return missing(ds[name]).sum()
    if name == "status":
        from .flags import flag_names

        codes = list(flag_names(ds["status"]).values())
        return (~ds["status"].isin(codes)).sum()
    if not valued_when_ok(name) or not set(ds["status"].dims) <= set(ds[name].dims):
        return None
    ok = ds["status"] == st.OK
    if SELECTED in ds.data_vars:
        ok = ok & (ds[SELECTED] == 1)
    return (missing(ds[name]) & ok).sum()


def dataset_message(ds, name: str, n: int) -> str:
    if name in ds.dims and name in ds.coords:
        return coordinate_message(name, n)
    if name == "status":
        from .flags import flag_names

        codes = list(flag_names(ds["status"]).values())
        s = np.asarray(ds["status"].values)
        bad = s[~np.isin(s, codes)]
        return status_message(n, int(bad.flat[0]) if bad.size else "?")
    return missing_message(name, n)
