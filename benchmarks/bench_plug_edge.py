"""Cost of the plug-edge root (eq:13) per (eps, K), measured inside the batch kernel.

One triple (eta, A, N) with many eps K values: the CPU time of the thread with the root minus
the time without it, divided by the number of eps K values (best of ``--repeat`` each).
Target: <= 0.15 us per root.

Run: ``.venv/bin/python benchmarks/bench_plug_edge.py [--values 200000] [--json PATH]``.
"""

from __future__ import annotations

import time

import numpy as np

from cosserat_channel.integrate import stepping
from cosserat_channel.measure import harness
from cosserat_channel.solver import batch, layout, stage1, stage2

CASES = ((1 / 3, 1 / 3, 1.0), (0.01, 1 / 3, 1.0), (3.0, 2.0, 2.0))
TARGET_US = 0.15


def run(eta, A, N, eps_K, plug_edge, repeat):
    """Thread CPU seconds of one batch call (best of ``repeat``) and its ``1 - xi_p``."""
    res = np.empty((1, layout.N_R))
    stats = np.zeros((1, 2, stepping.N_STATS), np.int64)
    one_minus = np.empty(eps_K.size)
    eta_, A_, N_ = np.array([eta]), np.array([A]), np.array([N])
    offsets = np.array([0, eps_K.size])
    no_xi, no_prof = np.empty(0), np.empty((1, layout.N_PROF, 0))

    def call():
        batch.solve_batch(eta_, A_, N_, eps_K, offsets, 1e-8, 1e-12, stage1.MAX_STEPS_STAGE1,
                           stage2.MAX_STEPS_STAGE2, res, stats, one_minus, no_xi, no_prof, True,
                           plug_edge)

    return harness.best_of(call, repeat, clock=time.thread_time).seconds, one_minus


def main() -> int:
    ap = harness.parser(__doc__)
    ap.add_argument("--values", type=int, default=200_000, help="eps K values per triple")
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    if args.values < 10:
        ap.error("--values must be at least 10")
    rec = harness.Record("bench_plug_edge", args.json)
    n = args.values
    worst = 0.0
    for eta, A, N in CASES:
        # eps K from 1e-4 to the value where the wall moves at 95 % (Delta = 0): every root is real.
        eps_K = np.geomspace(1e-4, 10.0, n)
        run(eta, A, N, eps_K[:10], True, 1)  # compile or load the kernel outside the timing
        with_root = run(eta, A, N, eps_K, True, args.repeat)[0]
        without = run(eta, A, N, eps_K, False, args.repeat)[0]
        us = 1e6 * (with_root - without) / n
        worst = max(worst, us)
        rec.row("cases", eta=eta, A=A, N=N, values=n, us_per_root=us)
        print(f"eta = {eta:6.3f}, A = {A:5.3f}, N = {N}: {us:6.3f} us per root ({n:,} eps K values)")
    v = rec.check(f"plug-edge root <= {TARGET_US:g} us", worst <= TARGET_US,
                  f"worst case {worst:.3f} us")
    print(v.line())
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
