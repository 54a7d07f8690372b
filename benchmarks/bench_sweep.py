"""The sweep engine end to end, at scale, and the kernel's parallel scaling, measured side by side.

(a) ``cosserat-channel run sweeps/large_5d.toml`` (10,000,000 points, 200,000 integrations after
    the similarity reduction) on 2 workers, in a fresh process, NetCDF written: wall time, the
    engine's own split (solve / assemble and write) and the child process's peak RSS.
(b) The unreduced kernel (one integration per point) on 80,000 random points of the same grid
    (fixed seed), run through the engine's blocks on a pool of 1 and of 2 threads (as the engine
    runs them); and per-point throughput reduced (a) against unreduced (b). The pool's handling
    of the same 128 blocks without work is timed too: a fixed cost that both runs pay, which on
    20,000 points (0.5 s of work on two workers) hid the kernel's scaling. In a fresh process
    of its own, before the other sections: inside the process that had started (e)'s cluster and
    waited on the children of (a) and (c), two workers measured 1.76-1.80x one, in a fresh
    process 1.95x, with the same blocks.
(c) A 10^8-point sweep end to end to its file, default settings, in a fresh process: eps 50
    log-spaced values in [1e-3, 0.2], L 50 in [1, 31.6], K 200 in [0.1, 100], A 10 in [-0.5, 3],
    N 20 in [0.7, 3] (50 x 50 x 200 x 10 x 20), the four outputs of large_5d: 10^8 plug-edge
    roots (one per grid point: the reduction does not apply to them) and 10^8 points of every
    output derived, encoded and written. Wall time against the solving threads' CPU time over
    the workers (what the solve alone takes on free cores), and the deflate file's size.
(d) ``cosserat-channel query`` of an 8,000-point slice (one eps, one L, 40 K values, all A and N)
    from the file of (c), to CSV, in a fresh process: wall time and peak RSS.
(e) (a)'s sweep with ``--scheduler`` on a ``dask.distributed`` cluster of 2 local worker
    processes of 1 thread (started here, with its scheduler, in this process): the ``run``
    process's CPU time from the start of the solve to the complete file (the engine's log; and
    all of it, start-up included, from its rusage) against the workers' (the solve, as each task
    measured it, and the tiles' deriving and encoding).

Targets: (a) peak RSS < 1 GiB, (b) 2 workers >= 1.8x one worker; (c) peak RSS < 2 GiB and wall
time <= 1.4x the solving threads' CPU over the workers; (d) < 2 s and < 1 GiB; (e) the ``run``
process's CPU <= 25 % of the workers' solve CPU.

"solve" and "assemble and write" are the engine's own split (its log): the file is written while
the blocks are solved, so "solve" is the solving threads' CPU time (block inputs, kernels,
storing the blocks) over the workers, what the solve alone takes on free cores, and "assemble
and write" the rest of the wall time from the start of the solve to the finished file. On a
loaded machine the time spent waiting for a core lands in the second: it is a bound from above.
Peak RSS is each child's own (``os.wait4``). Everything runs in one invocation so the ratios hold
on a noisy shared machine; the load average before and after is printed.

Run:  .venv/bin/python benchmarks/bench_sweep.py [--only c,e] [--points 20000] [--repeat 3]
      [--json PATH]
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import dask
import numpy as np

from cosserat_channel.measure import harness
from cosserat_channel import chunk_filters
from cosserat_channel.sweep.spec import load_sweep

ROOT = Path(__file__).resolve().parent.parent
LARGE = ROOT / "sweeps" / "large_5d.toml"
TIMES = re.compile(r"solve ([\d.]+) s .* assemble and write ([\d.]+) s, total ([\d.]+) s")
PHASE = re.compile(r"solving threads ([\d.]+) s CPU on (\d+) workers; the process ([\d.]+) s CPU"
                   r".*\), (\d+) of (\d+) tiles written during it; tiles derived and encoded "
                   r"(where solved|by the writer) in ([\d.]+) s CPU.*, ([\d.]+) s after the solve")
GiB = 1024**3
# (c): a 10^8-point grid, large_5d's outputs: 2,500 (eps, L) pairs x 200 K x 200 (A, N).
HUGE = LARGE.read_text().split("[grid]")[0] + """[grid]
eps = {logspace = [-3, -0.7, 50]}
L = {logspace = [0, 1.5, 50]}
K = {logspace = [-1, 2, 200]}
A = {linspace = [-0.5, 3, 10]}
N = {linspace = [0.7, 3, 20]}

[output]
variables = ["Delta", "slip", "m_wall", "sigma_yx_wall"]
"""
QUERY = ("--sel", "eps=0.01", "--nearest", "--sel", "L=10", "--range", "K=0.1:0.397")  # 40 K
QUERY_ROWS = 40 * 10 * 20


def cli(command, *args) -> list[str]:
    return [sys.executable, "-m", "cosserat_channel.cli", command, *map(str, args)]


def child(cmd: list[str], tmp: Path) -> dict:
    """Run ``cmd``; its wall time, stderr and its own peak RSS (os.wait4's rusage, in bytes)."""
    err_path = tmp / "stderr.txt"
    with open(err_path, "w") as err, open(os.devnull, "w") as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        proc.returncode = os.waitstatus_to_exitcode(status)
    stderr = err_path.read_text()
    if proc.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{stderr}")
    return dict(cmd=" ".join(map(str, cmd)), wall=wall, rss=usage.ru_maxrss * 1024,
                cpu=usage.ru_utime + usage.ru_stime, log=stderr.strip())


def run_sweep_child(sweep: Path, out: Path, workers: int, tmp: Path, *extra) -> dict:
    """(a), (c), (e): ``run`` in a child process; wall time, the engine's split, peak RSS."""
    r = child(cli("run", sweep, "-o", out, "--workers", workers, "--overwrite", *extra), tmp)
    solve_s, write_s, total_s = map(float, TIMES.search(r["log"]).groups())
    (threads_cpu, n, process_cpu, during, tiles, where, encode_cpu,
     after) = PHASE.search(r["log"]).groups()
    return dict(r, solve=solve_s, write=write_s, engine_total=total_s, size=out.stat().st_size,
                threads_cpu=float(threads_cpu), workers=int(n), process_cpu=float(process_cpu),
                tiles_during=int(during), tiles=int(tiles), encoded=where,
                encode_cpu=float(encode_cpu), after=float(after))


def run_distributed(tmp: Path) -> dict:
    """(e): (a)'s sweep on a local dask.distributed cluster of 2 worker processes x 1 thread."""
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:
        return run_sweep_child(LARGE, tmp / "large_5d_cluster.nc", 2, tmp, "--scheduler",
                               cluster.scheduler_address)


def subsample(n: int, seed: int = 0):
    """``n`` random grid points of large_5d as one-point triples, dealt into blocks by cost."""
    from cosserat_channel.sweep.plan import COST_FIXED, COST_PER_INV_ETA, BlockInputs, block_plan

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


def _no_work(inp, rtol, atol):
    return None


def run_unreduced(inputs, rtol, atol, workers: int, function=None) -> float:
    """(b): the engine's block function (or ``function``) on a pool of ``workers`` threads, as
    the engine runs its blocks; seconds, the pool's start included."""
    from concurrent.futures import ThreadPoolExecutor

    from cosserat_channel.sweep import block

    function = block.solve_block if function is None else function
    t0 = time.perf_counter()
    with ThreadPoolExecutor(workers) as pool:
        for fut in [pool.submit(function, inp, rtol, atol) for inp in inputs]:
            fut.result()
    return time.perf_counter() - t0


def scaling(points: int, repeat: int, workers: int) -> dict:
    """(b) in this process: the kernels loaded, then 1 and ``workers`` workers in alternate
    rounds, the fastest of each (what disturbs one round, another job, is not charged to one
    side), and the pool's handling of the blocks without work."""
    from cosserat_channel.sweep import block

    block.warm_up()  # compile (or load) the kernels here, not inside a timing
    spec, inputs = subsample(points)
    run_unreduced(inputs[:2], spec.rtol, spec.atol, workers)
    rounds = [[run_unreduced(inputs, spec.rtol, spec.atol, w) for w in (1, workers)]
              for _ in range(repeat)]
    t1, tw = (min(r[j] for r in rounds) for j in (0, 1))
    t_sched = harness.best_of(lambda: run_unreduced(inputs, spec.rtol, spec.atol, workers,
                                                    _no_work), repeat).seconds
    return {"one_worker_s": t1, "workers_s": tw, "scheduling_s": t_sched, "blocks": len(inputs)}


def scaling_child(points: int, repeat: int, workers: int) -> dict:
    """:func:`scaling` in a fresh process (this script with ``--scaling``): nothing that ran
    before in this one (children waited on, a cluster started and stopped) is in its timing."""
    import json

    cmd = [sys.executable, __file__, "--scaling", "--points", str(points), "--repeat",
           str(repeat), "--workers", str(workers)]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed:\n{done.stderr}")
    return json.loads(done.stdout.strip().splitlines()[-1])


SECTIONS = "abcde"


def sections(text: str) -> str:
    """The sections ``--only`` names (``c,e`` or ``ce``); (d) reads (c)'s file, so it brings (c)."""
    chosen = "".join(ch for ch in text.lower() if ch.isalpha())
    unknown = sorted(set(chosen) - set(SECTIONS))
    if unknown or not chosen:
        sys.exit(f"bench_sweep: --only takes sections among {', '.join(SECTIONS)}; got {text!r}")
    return "".join(ch for ch in SECTIONS if ch in chosen or (ch == "c" and "d" in chosen))


def main() -> int:
    ap = harness.parser(__doc__)
    ap.add_argument("--points", type=int, default=80_000, help="subsample size for (b)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="rounds of (b): 1 and N workers alternately, the fastest of each")
    ap.add_argument("--workers", type=int, default=2,
                    help="workers for (a) and the 'N workers' of (b)")
    ap.add_argument("--only", default=SECTIONS, metavar="SECTIONS",
                    help="run only these sections, e.g. c,e (default: all; d brings c)")
    ap.add_argument("--scaling", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.scaling:  # (b) in the fresh process scaling_child started: one JSON line
        import json

        print(json.dumps(scaling(args.points, args.repeat, args.workers)))
        return 0
    only = sections(args.only)

    rec = harness.Record("bench_sweep", args.json, dask=dask.__version__, sections=only)
    load_before = os.getloadavg()
    a = b = c = d = e = None
    with tempfile.TemporaryDirectory(dir=ROOT / "benchmarks") as tmp_name:
        tmp = Path(tmp_name)
        # A tiny run first so that the runs measure a warm Numba cache, as every run but the
        # first does (the chunk filters' kernels included).
        subprocess.run(cli("run", ROOT / "sweeps" / "quickstart.toml", "-o", tmp / "q.nc"),
                       check=True, capture_output=True)
        if "b" in only:  # first: no page cache writing back (c)'s file meanwhile
            b = scaling_child(args.points, args.repeat, args.workers)
        if "a" in only:
            a = run_sweep_child(LARGE, tmp / "large_5d.nc", args.workers, tmp)
        if "c" in only:
            huge_toml = tmp / "huge_5d.toml"
            huge_toml.write_text(HUGE)
            c = run_sweep_child(huge_toml, tmp / "huge_5d.nc", args.workers, tmp)
        if "d" in only:
            d = child(cli("query", tmp / "huge_5d.nc", *QUERY, "--format", "csv", "-o",
                          tmp / "slice.csv"), tmp)
            d["rows"] = sum(1 for _ in open(tmp / "slice.csv")) - 1
        if "e" in only:
            e = run_distributed(tmp)

    rows = []
    n_large = load_sweep(LARGE).size
    if b is not None:
        t1, tw, t_sched = b["one_worker_s"], b["workers_s"], b["scheduling_s"]
        unreduced_pps = args.points / tw
        speedup = t1 / tw
    load_after = os.getloadavg()
    if a is not None:
        reduced_pps = n_large / a["wall"]
        reduced_solve_pps = n_large / a["solve"]
        ok_time = rec.check("(a) large_5d end to end < 60 s", a["wall"] < 60.0,
                            f"{a['wall']:.2f} s")
        ok_rss = rec.check("(a) peak RSS < 1 GiB", a["rss"] < 1 * GiB,
                           f"{a['rss'] / GiB:.2f} GiB")
        rec.add("a_large_5d", {k: a[k] for k in ("cmd", "wall", "solve", "write", "rss", "size")})
        rows += [
            ("(a) large_5d, reduced, end to end", f"{a['wall']:.2f} s",
             f"{reduced_pps:,.0f} points/s", f"< 60 s: {ok_time.word}"),
            ("    of which solve", f"{a['solve']:.2f} s", f"{reduced_solve_pps:,.0f} points/s",
             f"{a['solve'] / a['wall']:.0%}"),
            ("    of which assemble and write", f"{a['write']:.2f} s",
             f"{a['size'] / 1e6:.0f} MB file", f"{a['write'] / a['wall']:.0%}"),
            ("    startup, plan, store", f"{a['wall'] - a['solve'] - a['write']:.2f} s", "", ""),
            ("(a) peak RSS", f"{a['rss'] / GiB:.2f} GiB", "", f"< 1 GiB: {ok_rss.word}"),
        ]
    if b is not None:
        ok_speedup = rec.check(f"(b) {args.workers} workers >= 1.8x one worker", speedup >= 1.8,
                               f"{speedup:.2f}x")
        rec.add("b_unreduced", {"points": args.points, "one_worker_s": t1,
                                "workers": args.workers, "workers_s": tw, "speedup": speedup,
                                "blocks": b["blocks"], "scheduling_s": t_sched,
                                "process": "its own, fresh"})
        rows += [
            (f"(b) unreduced, {args.points:,} points, 1 worker", f"{t1:.2f} s",
             f"{args.points / t1:,.0f} points/s", ""),
            (f"(b) unreduced, {args.points:,} points, {args.workers} workers", f"{tw:.2f} s",
             f"{unreduced_pps:,.0f} points/s",
             f"{speedup:.2f}x one worker, >= 1.8x: {ok_speedup.word}"),
            (f"(b) the pool's handling of the {b['blocks']} blocks, no work", f"{t_sched:.2f} s",
             "", "paid by both runs"),
        ]
        if a is not None:
            rows.append(("reduced (a) / unreduced (b), per point", "", "",
                         f"{reduced_pps / unreduced_pps:,.0f}x end to end "
                         f"({reduced_solve_pps / unreduced_pps:,.0f}x solve only)"))
    if c is not None:
        c_ratio = c["wall"] / c["solve"]  # the solve: the solving threads' CPU over the workers
        # On free cores the process cannot take less wall time than its CPU over the cores: a
        # bound that holds whatever else runs on the machine.
        c_bound = c["cpu"] / os.cpu_count() / c["solve"]
        ok_huge_rss = rec.check("(c) peak RSS < 2 GiB", c["rss"] < 2 * GiB,
                                f"{c['rss'] / GiB:.2f} GiB")
        ok_overhead = rec.check("(c) wall <= 1.4x the solving threads' CPU over the workers",
                                c_ratio <= 1.4, f"{c_ratio:.2f}x")
        rec.add("c_1e8_points", {k: c[k] for k in ("cmd", "wall", "solve", "write", "rss", "size",
                                                   "cpu", "threads_cpu", "encode_cpu")})
        rows += [
            ("(c) 10^8 points, reduced, end to end", f"{c['wall']:.2f} s",
             f"{1e8 / c['wall']:,.0f} points/s",
             f"{c_ratio:.2f}x the solve, <= 1.4x: {ok_overhead.word}"),
            ("    of which solve", f"{c['solve']:.2f} s", f"{1e8 / c['solve']:,.0f} points/s",
             f"solving threads {c['threads_cpu']:.1f} s CPU on {c['workers']}"),
            ("    of which assemble and write", f"{c['write']:.2f} s",
             f"{c['size'] / 1e6:.0f} MB file", f"{c['write'] / c['solve']:.0%} of solve"),
            ("    tiles derived and encoded", f"{c['encode_cpu']:.2f} s", "CPU",
             f"{c['encoded']}"),
            ("    the process's CPU, all of it", f"{c['cpu']:.2f} s", "",
             f"over {os.cpu_count()} cores: {c_bound:.2f}x the solve (wall on free cores >=)"),
            ("(c) peak RSS", f"{c['rss'] / GiB:.2f} GiB", "", f"< 2 GiB: {ok_huge_rss.word}"),
        ]
    if d is not None:
        ok_query = rec.check(f"(d) query of {QUERY_ROWS:,} rows < 2 s and < 1 GiB, every row",
                             d["wall"] < 2.0 and d["rss"] < 1 * GiB and d["rows"] == QUERY_ROWS,
                             f"{d['wall']:.2f} s, {d['rss'] / GiB:.2f} GiB, {d['rows']:,} rows")
        rec.add("d_query", {k: d[k] for k in ("cmd", "wall", "rss", "rows")})
        rows.append((f"(d) query, {d['rows']:,} rows to CSV", f"{d['wall']:.2f} s",
                     f"{d['rss'] / GiB:.2f} GiB peak RSS", f"< 2 s, < 1 GiB: {ok_query.word}"))
    if e is not None:
        # The run process's CPU from the start of the solve to the complete file (the engine's
        # log), and all of it (start-up, imports, plan included: os.wait4).
        e_ratio = e["process_cpu"] / e["threads_cpu"]
        e_ratio_all = e["cpu"] / e["threads_cpu"]
        ok_client = rec.check("(e) run process's CPU <= 25 % of the workers' solve CPU",
                              e_ratio <= 0.25, f"{e_ratio:.0%}")
        rec.add("e_distributed", {k: e[k] for k in ("cmd", "wall", "cpu", "process_cpu",
                                                    "threads_cpu", "encode_cpu", "rss", "size",
                                                    "tiles_during", "tiles", "after")})
        rows += [
            ("(e) large_5d on 2 cluster workers, end to end", f"{e['wall']:.2f} s",
             f"{e['size'] / 1e6:.0f} MB file", f"{e['encoded']}"),
            ("    tiles written during the solve", f"{e['tiles_during']} of {e['tiles']}", "",
             f"the file complete {e['after']:.2f} s after the last block"),
            ("    workers' solve CPU", f"{e['threads_cpu']:.2f} s", "", ""),
            ("    workers' deriving and encoding CPU", f"{e['encode_cpu']:.2f} s", "", ""),
            ("    run process's CPU, solve to file", f"{e['process_cpu']:.2f} s", "",
             f"{e_ratio:.0%} of the workers' solve, <= 25 %: {ok_client.word}"),
            ("    run process's CPU, all of it", f"{e['cpu']:.2f} s", "",
             f"{e_ratio_all:.0%} of the workers' solve (start-up included)"),
        ]
    rec.add("load", {"before": load_before, "after": load_after})
    rec.add("deflate", chunk_filters.DEFLATE)

    print()
    for r in (a, c, d, e):
        if r is not None:
            print(r["cmd"])
            print("    " + r["log"].replace("\n", "\n    "))
    w0 = max(len(r[0]) for r in rows) if rows else 10
    print()
    print(f"sections run: {', '.join(only)}")
    print(f"deflate of the encoded chunks: {chunk_filters.DEFLATE}")
    print(f"load average before {load_before[0]:.2f} {load_before[1]:.2f} {load_before[2]:.2f}, "
          f"after {load_after[0]:.2f} {load_after[1]:.2f} {load_after[2]:.2f} "
          f"({os.cpu_count()} cores)")
    print(f"{'measurement':<{w0}}  {'time':>10}  {'throughput':>20}  target / ratio")
    print("-" * (w0 + 70))
    for name, t, thr, note in rows:
        print(f"{name:<{w0}}  {t:>10}  {thr:>20}  {note}")
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
