"""The result files' deflate, variable by variable: zlib level 1 (the HDF5 library's) against
ISA-L's levels and the tool's choice (``chunk_filters.deflate``), on chunks of a real result file.

Samples ``--chunks`` chunks of each deflated variable of FILE (their bytes before deflate: the
checksum and the shuffle applied, as the file's pipeline runs them), deflates each with every
method in this thread's CPU time, and extrapolates size and time to the variable's whole chunk
count. The target: the tool's choice within 2 % of zlib level 1 on the whole file. It is at
level 1's size on the variables that vary along every axis; on those constant along one (their
rows repeat), ISA-L's level that finds the repeats at speed writes 1.3x zlib's bytes, which the
tool accepts for a tenth of the CPU of its lazy level, the one level at zlib's size there.

Run:  .venv/bin/python benchmarks/bench_deflate.py FILE.nc [--chunks 64]
(FILE: a result of ``cosserat-channel run``, e.g. bench_sweep.py's (c) grid written with
``--compress zlib``; any deflated netCDF-4 file will do.)
"""

from __future__ import annotations

import time
import zlib

import numpy as np

from cosserat_channel import chunk_filters
from cosserat_channel.measure import harness

TARGET = 1.02  # the tool's file / zlib level 1's


def methods() -> dict:
    """``{name: compress(bytes) -> bytes}``: zlib 1, the tool's, and ISA-L's levels if loaded."""
    found = {"zlib 1": lambda b: zlib.compress(b, 1),
             f"tool ({chunk_filters.DEFLATE})": lambda b: chunk_filters.deflate(b, 1)}
    try:
        from isal import igzip_lib as ig
    except ImportError:  # pragma: no cover (depends on the installation)
        return found
    small = ig.MEM_LEVEL_SMALL
    found["ISA-L 0"] = lambda b: ig.compress(b, 0, ig.COMP_ZLIB)
    found["ISA-L 1"] = lambda b: ig.compress(b, 1, ig.COMP_ZLIB)
    found["ISA-L 2 small"] = lambda b: ig.compress(b, 2, ig.COMP_ZLIB, small)
    found["ISA-L 3"] = lambda b: ig.compress(b, 3, ig.COMP_ZLIB)
    return found


def sample(path: str, n: int, seed: int = 2) -> dict:
    """``{variable: (chunk count, [bytes before deflate, ...])}`` for up to ``n`` random chunks of
    each chunked variable of ``path`` whose last filter is deflate."""
    import h5py

    rng = np.random.default_rng(seed)
    out = {}
    with h5py.File(path, "r") as f:
        for name, ds in f.items():
            if not isinstance(ds, h5py.Dataset) or ds.chunks is None or ds.compression != "gzip":
                continue
            grid = [-(-m // c) for m, c in zip(ds.shape, ds.chunks)]
            count = int(np.prod(grid))
            raws = []
            for i in rng.choice(count, min(n, count), replace=False):
                offset = tuple(int(a * c) for a, c in zip(np.unravel_index(i, grid), ds.chunks))
                raws.append(zlib.decompress(ds.id.read_direct_chunk(offset)[1]))
            out[name] = (count, raws)
    return out


def main() -> int:
    ap = harness.parser(__doc__)
    ap.add_argument("file", help="a deflated result file (netCDF-4)")
    ap.add_argument("--chunks", type=int, default=64, help="chunks sampled per variable")
    args = ap.parse_args()
    if args.chunks < 1:
        ap.error("--chunks must be at least 1")
    rec = harness.Record("bench_deflate", args.json)
    found = methods()
    chunks = sample(args.file, args.chunks)
    if not chunks:
        ap.error(f"{args.file}: no deflated chunked variable")
    total = {m: [0.0, 0.0] for m in found}
    print(f"{'variable':<16}" + "".join(f"{m:>26}" for m in found))
    for name, (count, raws) in chunks.items():
        scale = count / len(raws)
        cells = []
        for m, compress in found.items():
            c0 = time.thread_time()
            size = sum(len(compress(r)) for r in raws)
            cpu = time.thread_time() - c0
            total[m][0] += size * scale
            total[m][1] += cpu * scale
            rec.row("variables", variable=name, method=m, mb=size * scale / 1e6,
                    cpu_s=cpu * scale)
            cells.append(f"{size * scale / 1e6:>12.1f} MB {cpu * scale:>7.2f} s")
        print(f"{name:<16}" + "".join(f"{c:>26}" for c in cells))
    zlib1 = total["zlib 1"][0]
    print(f"{'whole file':<16}" + "".join(
        f"{s / 1e6:>9.1f} MB {s / zlib1 - 1:>+6.1%} {t:>5.1f} s" for s, t in total.values()))
    for m, (s, t) in total.items():
        rec.row("file", method=m, mb=s / 1e6, vs_zlib1=s / zlib1, cpu_s=t)
    tool = next(m for m in found if m.startswith("tool"))
    ratio = total[tool][0] / zlib1
    print(rec.check(f"the tool's deflate within {TARGET - 1:.0%} of zlib level 1 on the file "
                    f"(sampled, {args.chunks} chunks a variable)", ratio <= TARGET,
                    f"{ratio:.4f} x").line())
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
