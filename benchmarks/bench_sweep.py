"""The sweep engine end to end, and the kernel's parallel scaling, measured side by side.

(a) ``cosserat-channel run sweeps/large_5d.toml`` (10,000,000 points, 200,000 integrations after
    the similarity reduction) on 2 workers, in a fresh process, NetCDF written: wall time, the
    engine's own split (solve / assemble / write) and the process's peak RSS.
(b) The unreduced kernel (one integration per point) on 20,000 random points of the same grid
    (fixed seed), run through the engine's blocks on dask's threaded scheduler with 1 and 2
    workers; and per-point throughput reduced (a) against unreduced (b).

Targets: (a) under 60 s with peak RSS under 4 GiB on 2 cores; (b) 2 workers >= 1.8x one worker.
Everything runs in one invocation so the ratios hold on a noisy shared machine.

Run:  .venv/bin/python benchmarks/bench_sweep.py [--points 20000] [--repeat 2]
"""

from __future__ import annotations

import argparse
import platform
import re
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import dask
import numpy as np

from cosserat_channel.measure import machine
from cosserat_channel.sweep import engine
from cosserat_channel.sweep.plan import COST_FIXED, COST_PER_INV_ETA, BlockInputs, block_plan
from cosserat_channel.sweep.spec import load_sweep

ROOT = Path(__file__).resolve().parent.parent
LARGE = ROOT / "sweeps" / "large_5d.toml"
TIMES = re.compile(r"solve ([\d.]+) s .* assemble ([\d.]+) s, write ([\d.]+) s, total ([\d.]+) s")
GiB = 1024**3


def cli(*args) -> list[str]:
    return [sys.executable, "-m", "cosserat_channel.cli", "run", *map(str, args)]


def run_large(tmp: Path, workers: int) -> dict:
    """(a): the CLI in a child process; wall time, the engine's split, the child's peak RSS."""
    out = tmp / "large_5d.nc"
    cmd = cli(LARGE, "-o", out, "--workers", workers)
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if proc.returncode != 0:
        sys.exit(f"large run failed:\n{proc.stderr}")
    # ru_maxrss of the largest waited-for child, in KiB on Linux; this is the first big child.
    rss = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss * 1024
    solve_s, assemble_s, write_s, total_s = map(float, TIMES.search(proc.stderr).groups())
    return dict(cmd=" ".join(map(str, cmd)), wall=wall, solve=solve_s, assemble=assemble_s,
                write=write_s, engine_total=total_s, rss=rss, size=out.stat().st_size,
                log=proc.stderr.strip())


def subsample(n: int, seed: int = 0):
    """``n`` random grid points of large_5d as one-point triples, dealt into blocks by cost."""
    spec = load_sweep(LARGE)
    rng = np.random.default_rng(seed)
    flat = rng.choice(spec.size, size=n, replace=False)
    e, l, k, a, nn = np.unravel_index(flat, spec.shape)
    eta = spec.eps[e] * spec.L[l]
    eps_K = spec.eps[e] * spec.K[k]
    A, N = spec.A[a], spec.N[nn]
    cost = COST_FIXED + COST_PER_INV_ETA / eta
    blocks = block_plan(cost, max(1, n // 128))
    inputs = [BlockInputs(eta[b], A[b], N[b], eps_K[b], np.arange(b.size + 1), b) for b in blocks]
    return spec, inputs


def run_unreduced(inputs, rtol, atol, workers: int) -> float:
    """(b): the engine's block function on dask's threaded scheduler; seconds."""
    tasks = [dask.delayed(engine.solve_block)(inp, rtol, atol) for inp in inputs]
    t0 = time.perf_counter()
    dask.compute(*tasks, scheduler="threads", num_workers=workers)
    return time.perf_counter() - t0


def verdict(ok: bool) -> str:
    return "PASS" if ok else "FAIL"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, default=20_000, help="subsample size for (b)")
    ap.add_argument("--repeat", type=int, default=2, help="best of this many timings in (b)")
    ap.add_argument("--workers", type=int, default=2,
                    help="workers for (a) and the 'N workers' of (b)")
    args = ap.parse_args()

    print("command:  " + " ".join([sys.executable, *sys.argv]))
    print(f"machine:  {platform.node()}: {machine.machine()}")
    print(f"versions: {machine.versions(dask=dask.__version__)}")
    engine.warm_up()  # compile (or load) the kernels here, not inside a timing
    with tempfile.TemporaryDirectory(dir=ROOT / "benchmarks") as tmp:
        # A tiny run first so that (a) measures a warm Numba cache, as every run but the first does.
        subprocess.run(cli(ROOT / "sweeps" / "quickstart.toml", "-o", Path(tmp) / "q.nc"),
                       check=True, capture_output=True)
        a = run_large(Path(tmp), args.workers)

    spec, inputs = subsample(args.points)
    run_unreduced(inputs[:2], spec.rtol, spec.atol, 1)
    t1 = min(run_unreduced(inputs, spec.rtol, spec.atol, 1) for _ in range(args.repeat))
    tw = min(run_unreduced(inputs, spec.rtol, spec.atol, args.workers) for _ in range(args.repeat))

    n_large = spec.size
    reduced_pps = n_large / a["wall"]
    reduced_solve_pps = n_large / a["solve"]
    unreduced_pps = args.points / tw
    speedup = t1 / tw
    ok_time = a["wall"] < 60.0
    ok_rss = a["rss"] < 4 * GiB
    ok_speedup = speedup >= 1.8

    print()
    print(f"(a) {a['cmd']}")
    print("    " + a["log"].replace("\n", "\n    "))
    rows = [
        ("(a) large_5d, reduced, end to end", f"{a['wall']:.2f} s", f"{reduced_pps:,.0f} points/s",
         f"< 60 s: {verdict(ok_time)}"),
        ("    of which solve", f"{a['solve']:.2f} s", f"{reduced_solve_pps:,.0f} points/s",
         f"{a['solve'] / a['wall']:.0%}"),
        ("    of which assemble", f"{a['assemble']:.2f} s", "", f"{a['assemble'] / a['wall']:.0%}"),
        ("    of which NetCDF write", f"{a['write']:.2f} s", f"{a['size'] / 1e6:.0f} MB file",
         f"{a['write'] / a['wall']:.0%}"),
        ("    startup, plan, store", f"{a['wall'] - a['solve'] - a['assemble'] - a['write']:.2f} s",
         "", ""),
        ("(a) peak RSS", f"{a['rss'] / GiB:.2f} GiB", "", f"< 4 GiB: {verdict(ok_rss)}"),
        (f"(b) unreduced, {args.points:,} points, 1 worker", f"{t1:.2f} s",
         f"{args.points / t1:,.0f} points/s", ""),
        (f"(b) unreduced, {args.points:,} points, {args.workers} workers", f"{tw:.2f} s",
         f"{unreduced_pps:,.0f} points/s",
         f"{speedup:.2f}x one worker, >= 1.8x: {verdict(ok_speedup)}"),
        ("reduced (a) / unreduced (b), per point", "", "",
         f"{reduced_pps / unreduced_pps:,.0f}x end to end "
         f"({reduced_solve_pps / unreduced_pps:,.0f}x solve only)"),
    ]
    w0 = max(len(r[0]) for r in rows)
    print()
    print(f"{'measurement':<{w0}}  {'time':>10}  {'throughput':>20}  target / ratio")
    print("-" * (w0 + 70))
    for name, t, thr, note in rows:
        print(f"{name:<{w0}}  {t:>10}  {thr:>20}  {note}")


if __name__ == "__main__":
    main()
