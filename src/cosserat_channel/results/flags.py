"""CF flag variables of the tool's files (``status``, ``edge_kind``): their names and counts,
the error of a query, and text from a file made safe to print.

The lowest module of :mod:`cosserat_channel.results`: every other one, and the ``cosserat``
accessor, read flags through it.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ..parameters import ParameterError

if TYPE_CHECKING:
    import xarray as xr


class QueryError(ParameterError):
    """A query the file cannot answer (unknown name, malformed clause, unreadable file)."""

    def __init__(self, message: str):
        super().__init__(" ".join(str(message).split()))


def _is_flag(da: xr.DataArray) -> bool:
    return "flag_values" in da.attrs and "flag_meanings" in da.attrs


def flag_names(da: xr.DataArray) -> dict[str, int]:
    """``{flag name: value}`` of a CF flag variable; QueryError unless its ``flag_values`` are
    integers, one per name of its ``flag_meanings``."""
    values = np.atleast_1d(np.asarray(da.attrs["flag_values"]))
    names = str(da.attrs["flag_meanings"]).split()
    whole = values.dtype.kind in "iu" or (
        values.dtype.kind == "f" and bool(np.all(np.isfinite(values)))
        and bool(np.all(values == np.round(values))))
    if values.ndim != 1 or not whole or values.size != len(names):
        raise QueryError(f"variable {da.name!r}: flag_values "
                         f"{_show(values.tolist(), 40)} are not {len(names)} integers, one per "
                         "name of flag_meanings (a damaged or foreign file)")
    return dict(zip(names, (int(v) for v in values.tolist())))


def check_flags(ds: xr.Dataset) -> None:
    """QueryError naming the first flag variable of ``ds`` whose flags are unusable."""
    for name in ds.data_vars:
        if _is_flag(ds[name]):
            flag_names(ds[name])


def flag_counts(da: xr.DataArray) -> dict[str, int]:
    """Points per flag name of a CF flag variable (lazy reduction; values outside the flags
    count as 'other')."""
    import xarray as xr

    flags = flag_names(da)
    sums = xr.Dataset({n: (da == v).sum() for n, v in flags.items()}).compute()
    counts = {n: int(sums[n]) for n in flags}
    other = int(da.size) - sum(counts.values())
    if other:
        counts["other"] = other
    return counts


def status_counts(ds: xr.Dataset) -> dict[str, int]:
    """Points per status name of a result (:func:`flag_counts` of its ``status``)."""
    return flag_counts(ds["status"])


def _show(x, limit: int = 24) -> str:
    s = printable(str(x))
    return s if len(s) <= limit else s[: limit - 1] + "…"


def printable(text: str) -> str:
    """``text`` with every character a terminal would act on (escape sequences, carriage
    returns, bidirectional overrides, ...) written as its escape, e.g. ``\\x1b``: text read
    from a file is shown, never obeyed."""
    text = str(text)
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else c.encode("unicode_escape").decode("ascii")
                   for c in text)
