"""What the Fletcher-32 checksums on result files cost: write time, read time and size.

Writes the same Dataset with the sweep's NetCDF encoding and with that encoding less
``fletcher32``, best of ``--repeat`` each: the quickstart sweep (576 points) and a 10^6-point
sweep (reduced, so it solves in seconds). Run:
``.venv/bin/python benchmarks/bench_checksums.py [--repeat 5] [--json PATH]``.
"""

from __future__ import annotations

import os
import tempfile
import tomllib
from pathlib import Path

import xarray as xr

from cosserat_channel import run_sweep
from cosserat_channel.measure import harness
from cosserat_channel.netcdf_policy import encoding

ROOT = Path(__file__).resolve().parent.parent
BIG = {"grid": {"eps": {"logspace": [-3, -1, 100]}, "L": {"linspace": [2, 20, 100]},
                "K": {"linspace": [0.1, 10, 25]}, "A": [1 / 3, 1.0], "N": [1.0, 1.5]}}


def measure(ds, directory, repeat):
    """``{"with": (write s, read s, bytes), "without": ...}``: best of ``repeat`` each."""
    with_sum = encoding(ds)
    without = {k: {kk: vv for kk, vv in v.items() if kk != "fletcher32"} for k, v in with_sum.items()}
    out = {}
    for label, enc in (("with", with_sum), ("without", without)):
        path = os.path.join(directory, f"{label}.nc")

        def read(path=path):
            with xr.open_dataset(path) as f:
                f.load()

        w = harness.best_of(lambda path=path, enc=enc: ds.to_netcdf(path, encoding=enc), repeat)
        r = harness.best_of(read, repeat)
        out[label] = (w.seconds, r.seconds, os.path.getsize(path))
    return out


def main() -> int:
    ap = harness.parser(__doc__)
    ap.add_argument("--repeat", type=int, default=5)
    args = ap.parse_args()
    rec = harness.Record("bench_checksums", args.json)
    quick = tomllib.loads((ROOT / "sweeps" / "quickstart.toml").read_text())
    quick["output"].pop("path", None)
    cases = (("quickstart (576 points)", quick), ("10^6 points", BIG))
    print("| sweep | write with / without | read with / without | size with / without |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as d:
        for name, mapping in cases:
            ds = run_sweep(mapping, progress=False)
            m = measure(ds, d, args.repeat)
            (w1, r1, s1), (w0, r0, s0) = m["with"], m["without"]
            print(f"| {name} | {w1:.3f} s / {w0:.3f} s ({w1 / w0 - 1:+.0%}) | {r1:.3f} s / {r0:.3f} s "
                  f"({r1 / r0 - 1:+.0%}) | {s1:,} / {s0:,} B ({s1 / s0 - 1:+.2%}) |")
            rec.row("sweeps", sweep=name, write_s_with=w1, write_s_without=w0, read_s_with=r1,
                    read_s_without=r0, bytes_with=s1, bytes_without=s0)
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
