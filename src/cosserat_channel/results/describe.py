"""What ``info`` says of a result file: its grid, variables, statuses and provenance."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np


if TYPE_CHECKING:  # imported where used: a small query never imports xarray (LightFile)
    import xarray as xr

from .render import _python, _text
from .selection import _show, flag_names

SWEEP_TEXT_LINES = 12
PROVENANCE = ("cosserat_channel_version", "created", "rtol", "atol", "sweep_sha256", "Conventions")

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


