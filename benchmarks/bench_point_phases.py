"""Where a point's time goes: bench_point's grid split into stage 1, stage 2 and the plug edge.

Each phase is timed as the difference of two kernels over the whole grid that share everything
before it: stage 1 alone; stage 1 and stage 2's panels (``_march_stage2``); the same with the
panels marched twice (their own cost, without stage 1's cache effects); with the plug-edge
constants of the triple (``_plug_constants``); with the root for its one ``eps K``. The kernels
run in interleaved rounds, timed in this thread's CPU time, and the table gives each kernel's
fastest round. Counters: stage-2 panels per point and the share of points whose panels reach
the closed form below them. No target: it shows which phase of bench_point's time to cut.

Run:  .venv/bin/python benchmarks/bench_point_phases.py [--repeat 7] [--json PATH]
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

from cosserat_channel.integrate import stepping
from cosserat_channel.measure import harness
from cosserat_channel.physics.model import N_AX
from cosserat_channel.solver import stage1, stage2
from cosserat_channel.solver.layout import METHOD_AUTO, N_R, R_N1, R_XI1, R_XI2
from cosserat_channel.solver.plug_edge import _one_minus_xi_p, _plug_constants

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_point import grid  # noqa: E402

PHASES = ("stage 1", "stage 1 + panels", "stage 1 + panels x2", "+ plug constants",
          "+ plug root")


@njit(cache=False)
def _run(phase, eta, A, N, eps_K, rtol, atol, out, counts):
    ax = np.empty(N_AX)
    T1, Q1 = stage1.stage1_arrays(stage1.MAX_STEPS_STAGE1)
    T2, Q2 = stage2.stage2_arrays(stage2.MAX_STEPS_STAGE2)
    stats1 = np.zeros(stepping.N_STATS, dtype=np.int64)
    stats2 = np.zeros(stepping.N_STATS, dtype=np.int64)
    res = np.empty(N_R)
    acc = 0.0
    for i in range(eta.size):
        code, _ = stage1.solve_stage1(eta[i], A[i], N[i], rtol, atol, ax, T1, Q1, stats1, res,
                                      METHOD_AUTO)
        if code != 0 or phase == 0:
            continue
        for _ in range(2 if phase == 2 else 1):
            stats2[:] = 0
            code = stage2._march_stage2(eta[i], A[i], N[i], rtol, atol, ax, res[R_XI1], T1, Q1,
                                        int(res[R_N1]), T2, Q2, stats2, res)
        counts[0] += stats2[stepping.STAT_ACCEPTED]
        counts[1] += stats2[stepping.STAT_REJECTED]
        counts[2] += res[R_XI2] > 0.0
        counts[3] += 1
        if code != 0 or phase < 3:
            continue
        consts = _plug_constants(res, ax)
        acc += consts[8]
        if phase == 4:
            out[i] = _one_minus_xi_p(eps_K[i], res, ax, T2, Q2, consts)[0]
    return acc


def main():
    ap = harness.parser(__doc__)
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    rec = harness.Record("bench_point_phases", args.json)
    eps, L = grid()
    n = eps.size
    eta, A, N, eps_K = eps * L, np.full(n, 1 / 3), np.ones(n), eps * 0.5
    out = np.empty(n)
    print(f"{n} points (bench_point's grid), {os.cpu_count()} cores, load average "
          f"{os.getloadavg()[0]:.2f} before")
    for rtol, atol in ((1e-6, 1e-8), (1e-8, 1e-10)):
        counts = np.zeros(4)
        for phase in range(len(PHASES)):
            _run(phase, eta, A, N, eps_K, rtol, atol, out, counts)  # compile, warm
        best = [np.inf] * len(PHASES)
        for _ in range(args.repeat):
            for phase in range(len(PHASES)):
                t0 = time.thread_time()
                _run(phase, eta, A, N, eps_K, rtol, atol, out, np.zeros(4))
                best[phase] = min(best[phase], (time.thread_time() - t0) / n * 1e6)
        counts = np.zeros(4)
        _run(1, eta, A, N, eps_K, rtol, atol, out, counts)
        solved = max(counts[3], 1)
        print(f"\nrtol {rtol:g}: {counts[0] / solved:.2f} accepted + {counts[1] / solved:.2f} "
              f"rejected panels per point; {counts[2] / solved:.0%} reach the closed form")
        print(f"| {'kernel':<22} | {'us/point':>8} | {'phase':<16} | {'us/point':>8} |")
        print(f"|{'-' * 24}|{'-' * 10}|{'-' * 18}|{'-' * 10}|")
        names = ("stage 1", "stage 2", "(panels alone)", "plug constants", "plug root")
        deltas = (best[0], best[1] - best[0], best[2] - best[1], best[3] - best[1],
                  best[4] - best[3])
        for k in range(len(PHASES)):
            print(f"| {PHASES[k]:<22} | {best[k]:>8.2f} | {names[k]:<16} | {deltas[k]:>8.2f} |")
            rec.row("phases", rtol=rtol, kernel=PHASES[k], us_per_point=best[k], phase=names[k],
                    phase_us_per_point=deltas[k])
    print(f"\nload average after: {os.getloadavg()[0]:.2f}")
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
