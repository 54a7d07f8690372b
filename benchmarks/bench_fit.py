"""Calibration: coverage of the fit's 95 % intervals, time per fit, and the fit command end to end.

``--datasets`` synthetic data sets (default 200), each the model's u/u(0) at 20 points across
the channel (eps = 1/30, L = 10, K = 0.5, A = 1/3, N = 1, rtol 1e-10) plus Gaussian noise of
sigma 0.002 (numpy.random.default_rng(seed), seeds 0 ...), fitted for L and K from
L = 10, K = 0.5 (the default start) on one thread: the share of data sets whose 95 % interval
(estimate +- 1.96 standard errors) contains the truth, for each parameter, and the wall and
CPU time per fit. Then ``cosserat-channel fit`` on the package's 20-point example profile
(examples/fit_profile.csv), in a fresh process with the kernels cached, best of ``--repeat``
wall times.
Targets: coverage of each parameter in [92 %, 98 %]; the command <= 1 s.

Run: ``.venv/bin/python benchmarks/bench_fit.py [--datasets 200] [--repeat 5] [--json PATH]``.
"""

from __future__ import annotations

import os
import pathlib
import subprocess
import sys
import time

import numpy as np

import cosserat_channel
from cosserat_channel.calibrate import fit
from cosserat_channel.measure import harness
from cosserat_channel.solver.point import solve_point

TRUTH = {"L": 10.0, "K": 0.5}
XI = np.linspace(0.05, 1.0, 20)
SIGMA = 0.002
COVERAGE = (0.92, 0.98)
TARGET_CLI_S = 1.0
EXAMPLE = pathlib.Path(cosserat_channel.__file__).parent / "examples" / "fit_profile.csv"


def coverage(n: int):
    """``({name: share covered}, wall seconds per fit, CPU seconds per fit, evaluations)``."""
    truth = solve_point(1 / 30, TRUTH["L"], TRUTH["K"], 1 / 3, 1.0, profile=XI,
                        rtol=1e-10).profile["u_over_u0"]
    covered = {name: 0 for name in TRUTH}
    evaluations = 0
    wall = cpu = 0.0
    for seed in range(n):
        rng = np.random.default_rng(seed)
        data = {"quantity": ["u_over_u0"] * XI.size,
                "value": truth + SIGMA * rng.standard_normal(XI.size),
                "std_error": np.full(XI.size, SIGMA), "xi": XI, "eps": np.full(XI.size, 1 / 30)}
        t0, c0 = time.perf_counter(), time.process_time()
        r = fit(data, "L,K", {"A": 1 / 3, "N": 1.0})
        wall += time.perf_counter() - t0
        cpu += time.process_time() - c0
        evaluations += r.n_evaluations
        for name in TRUTH:
            covered[name] += abs(r.params[name] - TRUTH[name]) < 1.959964 * r.errors[name]
    return {k: v / n for k, v in covered.items()}, wall / n, cpu / n, evaluations / n


def command_seconds(repeat: int) -> float:
    """Best wall time of ``cosserat-channel fit`` on the example profile, in a fresh process."""
    src = pathlib.Path(cosserat_channel.__file__).resolve().parent.parent
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (str(src), os.environ.get("PYTHONPATH")) if p))
    argv = [sys.executable, "-m", "cosserat_channel.cli", "fit", str(EXAMPLE), "--free", "L,K",
            "--fixed", "A=1/3,N=1"]
    subprocess.run(argv, env=env, check=True, capture_output=True)  # the kernels cached
    times = []
    for _ in range(max(1, repeat)):
        t0 = time.perf_counter()
        subprocess.run(argv, env=env, check=True, capture_output=True)
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> int:
    ap = harness.parser(__doc__)
    ap.add_argument("--datasets", type=int, default=200, help="synthetic data sets to fit")
    ap.add_argument("--repeat", type=int, default=5, help="runs of the command (best is kept)")
    args = ap.parse_args()
    if args.datasets < 1:
        ap.error("--datasets must be at least 1")
    rec = harness.Record("bench_fit", args.json)
    share, wall, cpu, evals = coverage(args.datasets)
    rec.add("coverage", dict(datasets=args.datasets, share=share, wall_s_per_fit=wall,
                             cpu_s_per_fit=cpu, evaluations_per_fit=evals))
    print(f"{args.datasets} data sets: 95 % intervals cover L {share['L']:.1%}, K {share['K']:.1%}; "
          f"{1e3 * wall:.1f} ms wall, {1e3 * cpu:.1f} ms CPU per fit ({evals:.1f} evaluations)")
    cli = command_seconds(args.repeat)
    rec.add("command", dict(seconds=cli, repeat=args.repeat))
    print(f"cosserat-channel fit (20-point profile, L and K): {cli:.2f} s wall, best of "
          f"{args.repeat}")
    lo, hi = COVERAGE
    verdicts = [rec.check(f"coverage of {name} in [{lo:.0%}, {hi:.0%}]", lo <= s <= hi, f"{s:.1%}")
                for name, s in share.items()]
    verdicts.append(rec.check(f"fit command <= {TARGET_CLI_S:g} s", cli <= TARGET_CLI_S,
                              f"{cli:.2f} s"))
    for v in verdicts:
        print(v.line())
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
