"""Cost of the plug-edge root (eq:13) per (eps, K), measured inside the batch kernel.

One triple (eta, A, N) with many eps K values: the time with the root minus the time without it,
divided by the number of eps K values. Run: ``.venv/bin/python benchmarks/bench_plug_edge.py``.
Target (issue "one solve ..."): <= 0.15 us per root.
"""

from __future__ import annotations

import time

import numpy as np

from cosserat_channel.integrate import stepping
from cosserat_channel.solver import batch, layout, stage1, stage2

CASES = ((1 / 3, 1 / 3, 1.0), (0.01, 1 / 3, 1.0), (3.0, 2.0, 2.0))


def run(eta, A, N, eps_K, plug_edge):
    res = np.empty((1, layout.N_R))
    stats = np.zeros((1, 2, stepping.N_STATS), np.int64)
    one_minus = np.empty(eps_K.size)
    t0 = time.thread_time()
    batch.solve_batch(np.array([eta]), np.array([A]), np.array([N]), eps_K,
                       np.array([0, eps_K.size]), 1e-8, 1e-12, stage1.MAX_STEPS_STAGE1,
                       stage2.MAX_STEPS_STAGE2, res, stats, one_minus, np.empty(0),
                       np.empty((1, layout.N_PROF, 0)), True, plug_edge)
    return time.thread_time() - t0, one_minus


def main() -> int:
    n = 200_000
    for eta, A, N in CASES:
        # eps K from 1e-4 to the value where the wall moves at 95 % (Delta = 0): every root is real.
        eps_K = np.geomspace(1e-4, 10.0, n)
        run(eta, A, N, eps_K[:10], True)
        with_root = min(run(eta, A, N, eps_K, True)[0] for _ in range(3))
        without = min(run(eta, A, N, eps_K, False)[0] for _ in range(3))
        print(f"eta = {eta:6.3f}, A = {A:5.3f}, N = {N}: {1e6 * (with_root - without) / n:6.3f} us "
              f"per root ({n:,} eps K values)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
