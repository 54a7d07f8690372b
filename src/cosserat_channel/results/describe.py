"""What ``info`` says of a result file: its grid, variables, statuses and provenance."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np


if TYPE_CHECKING:  # imported where used: a small query never imports xarray (LightFile)
    import xarray as xr

from ..files import format_size
from .render import _python, _text
from .selection import _show, flag_names, printable, read_problem

SWEEP_TEXT_LINES = 12
PROVENANCE = ("cosserat_channel_version", "created", "rtol", "atol", "sweep_sha256", "Conventions")
# Uncompressed bytes of values that info reads to verify a file (a few seconds); the variables
# beyond it are named as not checked.
CHECK_BYTES = 1 << 30

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


def verify(ds: xr.Dataset, budget: int | None = CHECK_BYTES) -> tuple[str | None, list[str]]:
    """Read what ``info`` describes through (checksums included), ``status`` and the
    coordinates first, then the variables in file order while their values fit ``budget`` bytes
    (None: all of them).

    Returns ``(problem, skipped)``: :func:`.selection.read_problem`'s one line for the first
    variable that cannot be read (None if all can) and the variables not read for the budget.
    """
    names = list(dict.fromkeys(["status", *ds.coords, *ds.data_vars]))
    read, skipped, spent = [], [], 0
    for name in names:
        nbytes = int(ds[name].size) * ds[name].dtype.itemsize
        if name == "status" or name in ds.coords or budget is None or spent + nbytes <= budget:
            read.append(name)
            spent += nbytes
        else:
            skipped.append(name)
    return read_problem(ds, read), skipped


def describe(ds: xr.Dataset, path: str = "", skipped=None) -> str:
    """The ``info`` report: dimensions, variables, status counts, provenance, and with
    ``skipped`` (from :func:`verify`) what was read to check the file.

    Text from the file is shown with :func:`.selection.printable`: a file's attributes never
    reach the terminal as control sequences.
    """
    lines = [f"file  {printable(path)}"] if path else []
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
            text = printable(ds[d].attrs.get("long_name", ""))
            lines.append(f"  {name:<8} {n:>8}  {rng:<30} {unit:<10} {text}".rstrip())
        else:
            lines.append(f"  {name:<8} {n:>8}")
    lines.append("variables")
    for v in ds.data_vars:
        da = ds[v]
        unit = printable(da.attrs.get("units", ""))
        text = printable(da.attrs.get("long_name", ""))
        dims = printable("(" + ", ".join(map(str, da.dims)) + ")")
        lines.append(f"  {printable(v):<18} {str(da.dtype):<8} {unit:<18} {text}  {dims}".rstrip())
    counts = status_counts(ds)
    total = max(1, int(ds["status"].size))
    lines.append(f"status ({int(ds['status'].size)} points)")
    for name, n in counts.items():
        lines.append(f"  {printable(name):<22} {n:>12}  {100.0 * n / total:6.2f} %")
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
    for key in PROVENANCE:
        if key in a:
            lines.append(f"  {key:<24} {printable(_text(_python(a[key])))}")
    if "query" in a:
        lines.append(f"  {'query':<24} {printable(a['query'])}")
    text = str(a.get("sweep_toml", ""))
    if text:
        sweep_lines = text.splitlines()
        shown = min(SWEEP_TEXT_LINES, len(sweep_lines))
        lines.append(f"  sweep (first {shown} of {len(sweep_lines)} lines)")
        lines += ["    " + printable(s.expandtabs()) for s in sweep_lines[:SWEEP_TEXT_LINES]]
    return "\n".join(lines) + "\n"
