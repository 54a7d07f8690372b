"""What ``info`` says of a file the tool wrote: its grid, variables, flags and provenance.

Three kinds of file: a result of ``run`` (or a NetCDF subset of one from ``query``), a traced
edge of solvability (``boundary``, from :func:`cosserat_channel.regimes.trace_boundary` or drawn
from an atlas) and a solvability atlas (``atlas``). Each is recognised by its variables, so
reading one imports neither the solver nor the module that wrote it.
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np


if TYPE_CHECKING:  # imported where used: a small query never imports xarray (LightFile)
    import xarray as xr

from ..files import format_size
from .render import _python, _text
from .flags import (QueryError, _show, flag_counts, printable,
                    status_counts)
from .selection import (FLAGGED, KIND_VARIABLES, flags_checked, is_kind, open_netcdf,
                        read_problem)

SWEEP_TEXT_LINES = 12
PROVENANCE = ("cosserat_channel_version", "created", "rtol", "atol", "sweep_sha256", "Conventions")
KINDS = tuple(KIND_VARIABLES)  # ("result", "boundary", "atlas")
# Uncompressed bytes of values that info reads to verify a file (a few seconds); the variables
# beyond it are named as not checked.
CHECK_BYTES = 1 << 30


def file_kind(ds: xr.Dataset) -> str | None:
    """``"result"``, ``"boundary"`` or ``"atlas"`` by the variables of ``ds``; None for any
    other file."""
    return next((k for k in KINDS if is_kind(ds, k)), None)


def open_described(path) -> xr.Dataset:
    """Open any file the tool writes (:data:`KINDS`) lazily; QueryError (one line) for others,
    saying what the file is and why it is refused (:func:`unrecognised`)."""
    ds = open_netcdf(path)
    if file_kind(ds) is None:
        try:
            text = unrecognised(ds)
        finally:
            ds.close()
        raise QueryError(f"{os.fspath(path)}: not a cosserat-channel result file (nor a "
                         f"boundary or atlas file of the tool): {text}")
    return flags_checked(ds, path)  # the counts it reports need usable flags


def unrecognised(ds: xr.Dataset, shown: int = 6) -> str:
    """What a NetCDF file that is none of :data:`KINDS` is (its title, dimensions and
    variables) and why it is none of them: what it lacks of the kinds it comes near (a
    variable of theirs, or their name in its title), else that it has none of theirs."""
    title = ds.attrs.get("title")
    dims = [f"{printable(k)} ({v:,})" for k, v in ds.sizes.items()]
    names = [printable(v) for v in ds.data_vars]

    def listed(items):
        more = f" and {len(items) - shown} more" if len(items) > shown else ""
        return ", ".join(items[:shown]) + more

    def article(kind):
        return f"{'an' if kind[0] in 'aeiou' else 'a'} {kind}"

    titled = "" if title is None else f" titled '{printable(title)}'"
    what = (f"a NetCDF file{titled} "
            f"with {'dimensions ' + listed(dims) if dims else 'no dimensions'} and "
            f"{'variables ' + listed(names) if names else 'no variables'}")
    heading = str(title or "").lower()
    near = [k for k, need in KIND_VARIABLES.items()
            if any(v in ds.data_vars for v in need) or k in heading]
    why = []
    for kind in near:
        missing = [v for v in KIND_VARIABLES[kind] if v not in ds.data_vars]
        if missing:
            why.append(f"as {article(kind)} it lacks {' and '.join(missing)}")
        elif kind in FLAGGED:
            why.append(f"its {FLAGGED[kind]} is not a flag variable (flag_values and "
                       "flag_meanings)")
    if not why:
        kinds = [f"{article(k)} ({', '.join(v)})" for k, v in KIND_VARIABLES.items()]
        why.append(f"it has none of the variables of {', '.join(kinds[:-1])} or {kinds[-1]}")
    return f"{what}; {'; '.join(why)} (damaged, or not written by the tool)"


# ---------------------------------------------------------------------------------------------
# info
# ---------------------------------------------------------------------------------------------
def _counts(title: str, counts: dict[str, int], total: int) -> list[str]:
    lines = [title]
    for name, n in counts.items():
        lines.append(f"  {printable(name):<22} {n:>12}  {100.0 * n / max(1, total):6.2f} %")
    return lines


def verify(ds: xr.Dataset, budget: int | None = CHECK_BYTES) -> tuple[str | None, list[str]]:
    """Read what ``info`` describes through (checksums included), ``status`` (where there is
    one) and the coordinates first, then the variables in file order while their values fit
    ``budget`` bytes (None: all of them).

    Returns ``(problem, skipped)``: :func:`.selection.read_problem`'s one line for the first
    variable that cannot be read (None if all can) and the variables not read for the budget.
    """
    first = ["status"] if "status" in ds.variables else []
    names = list(dict.fromkeys([*first, *ds.coords, *ds.data_vars]))
    read, skipped, spent = [], [], 0
    for name in names:
        nbytes = int(ds[name].size) * ds[name].dtype.itemsize
        if name in first or name in ds.coords or budget is None or spent + nbytes <= budget:
            read.append(name)
            spent += nbytes
        else:
            skipped.append(name)
    return read_problem(ds, read), skipped


def describe(ds: xr.Dataset, path: str = "", skipped=None) -> str:
    """The ``info`` report: kind, dimensions, variables, flag counts, provenance, and with
    ``skipped`` (from :func:`verify`) what was read to check the file.

    Text from the file is shown with :func:`.flags.printable`: a file's attributes never
    reach the terminal as control sequences.
    """
    kind = file_kind(ds)
    lines = [f"file  {printable(path)}"] if path else []
    if kind is not None:
        title = f": {printable(ds.attrs['title'])}" if "title" in ds.attrs else ""
        lines.append(f"kind  {kind}{title}")
    lines.append("dimensions")
    for d in ds.dims:
        n = ds.sizes[d]
        name = printable(d)
        if d in ds.coords and n:
            c = np.asarray(ds[d].values)
            unit = printable(ds[d].attrs.get("units", ""))
            if c.dtype.kind in "iuf":
                rng = f"{np.min(c):.10g} .. {np.max(c):.10g}"
            else:  # not a file of ours, but describe what is there (strings, dates, ...)
                rng = _show(c[0]) + (f" .. {_show(c[-1])}" if n > 1 else "")
            text = printable(_text_of(ds[d]))
            lines.append(f"  {name:<8} {n:>8}  {rng:<30} {unit:<10} {text}".rstrip())
        else:
            lines.append(f"  {name:<8} {n:>8}")
    lines.append("variables")
    for v in ds.data_vars:
        da = ds[v]
        unit = printable(da.attrs.get("units", ""))
        dims = printable("(" + ", ".join(map(str, da.dims)) + ")")
        lines.append(f"  {printable(v):<18} {str(da.dtype):<8} {unit:<18} "
                     f"{printable(_text_of(da))}  {dims}".rstrip())
    if kind == "result" or (kind is None and "status" in ds):
        total = int(ds["status"].size)
        lines += _counts(f"status ({total} points)", status_counts(ds), total)
    elif kind == "boundary":
        total = int(ds["edge_kind"].size)
        lines += _counts(f"edges ({total} (A, N) pairs)", flag_counts(ds["edge_kind"]), total)
        if "resolved" in ds:
            lines.append(f"  {'decided by the atlas':<22} {int(ds['resolved'].sum()):>12}")
    elif kind == "atlas":
        n_leaf = int(ds.sizes.get("leaf", 0))
        unresolved = int((ds["leaf_n"] < 0).sum()) if "leaf_n" in ds else 0
        lines.append(f"cells ({n_leaf} leaves, {unresolved} unresolved; "
                     f"{int(ds.sizes.get('sample', 0))} traced edges)")
    if skipped is not None:
        if not skipped:
            lines.append("checked  every variable read through without error")
        else:
            size = sum(int(ds[v].size) * ds[v].dtype.itemsize for v in skipped)
            lines.append(f"checked  all but {printable(', '.join(map(str, skipped)))} "
                         f"({format_size(size)}, beyond the {format_size(CHECK_BYTES)} info reads; "
                         "--check-all reads them)")
    lines.append("provenance")
    a = ds.attrs
    keys = PROVENANCE if kind == "result" else [k for k in a if k != "title"]
    for key in keys:
        if key in a:
            lines.append(f"  {key:<24} {printable(_text(_python(a[key])))}")
    if "query" in a and "query" not in keys:
        lines.append(f"  {'query':<24} {printable(a['query'])}")
    text = str(a.get("sweep_toml", ""))
    if text:
        sweep_lines = text.splitlines()
        shown = min(SWEEP_TEXT_LINES, len(sweep_lines))
        lines.append(f"  sweep (first {shown} of {len(sweep_lines)} lines)")
        lines += ["    " + printable(s.expandtabs()) for s in sweep_lines[:SWEEP_TEXT_LINES]]
    return "\n".join(lines) + "\n"


def _text_of(da) -> str:
    """What a variable is, in words: its description, else its long name."""
    return str(da.attrs.get("description") or da.attrs.get("long_name", ""))
