"""Does the 8th-order pair pay on stage 1? Dormand-Prince 5(4) against DOP853, on the same points.

Calibrates: ``cosserat_channel.solver.stage1.DOP853_RTOL`` (the rtol at and below which the
explicit path marches with DOP853).

Both of the package's explicit integrators
(``rk45.dopri5``, ``dop853.dop853``) march stage 1 of the work-precision set's points where the
solver takes the explicit path, from the same axis-series start (``stage1.stage1_start``), with the
same right-hand side, the same split at xi = N (N < 1) and the same first step, no event (these
points reach the wall) and no step cap. It prints the mean right-hand-side evaluations (DOP853's
include the 3 of its dense output per step) and the median m_wall error against the set's
references. Run after ``cosserat-channel bench -o DIR`` (which caches the references):
``PYTHONPATH=src .venv/bin/python benchmarks/probes/probe_high_order.py DIR/reference_cache.npz``.
"""

from __future__ import annotations

import sys

import numpy as np
from numba import njit

from cosserat_channel.integrate import dense, dop853, rk45, stepping
from cosserat_channel.measure import harness
from cosserat_channel.physics import model
from cosserat_channel.solver import stage1

ATOL = 1e-12


@njit
def march(use_dop853, xi1, w1, args, rtol, T, Q, stats, total):
    """Stage 1 from the series start to the wall; ``(status, m(1)/(nu L))``, evaluations in total."""
    eta, A, N, ax = args
    y0 = np.empty(1)
    y0[0] = w1
    atol = np.full(1, ATOL)
    split = xi1 + stage1.SPLIT_MARGIN < N < 1.0 - stage1.SPLIT_MARGIN
    legs = ((xi1, N, xi1), (N, 1.0, 0.0)) if split else ((xi1, 1.0, xi1), (1.0, 1.0, 0.0))
    total[0] = 0
    w = w1
    for start, end, h0 in legs:
        if end == start:
            continue
        y0[0] = w
        if use_dop853:
            s, n, _ = dop853.dop853(stage1._stage1_rhs, stepping.no_event, start, y0, end, args,
                                    rtol, atol, h0, 0.0, T, Q, stats)
        else:
            s, n, _ = rk45.dopri5(stage1._stage1_rhs, stepping.no_event, start, y0, end, args,
                                  rtol, atol, h0, 0.0, T, Q, stats)
        total[0] += stats[stepping.STAT_FEV]
        if s != stepping.SUCCESS:
            return s, np.nan
        w = Q[n - 1, 0, 0] + Q[n - 1, 1, 0]
    return stepping.SUCCESS, w - N


def main(path):
    print("\n".join(harness.header_lines(harness.header())))
    print(f"stage1.DOP853_RTOL is now {stage1.DOP853_RTOL:g}")
    d = np.load(path)
    eps, L, A, N, ref = (d[k] for k in ("eps", "L", "A", "N", "ref_m_wall"))
    eta = eps * L
    T = np.empty(stage1.MAX_STEPS_STAGE1 + 1)
    Q = np.empty((stage1.MAX_STEPS_STAGE1, dense.N_DENSE, 1))
    stats = np.zeros(stepping.N_STATS, np.int64)
    total = np.zeros(1, np.int64)
    ax = np.empty(model.N_AX)
    for rtol in (1e-4, 1e-6, 1e-8, 1e-10):
        rows = {False: ([], []), True: ([], [])}
        for i in range(eta.size):
            if model.classify(eta[i], A[i], N[i]) != 0 or A[i] == -1.0:
                continue
            model.axis_constants(eta[i], A[i], N[i], ax)
            xi1, w1 = stage1.stage1_start(ax, rtol)
            if stage1.use_stiff_path(eta[i], A[i], N[i], ax, xi1, rtol):
                continue
            args = (eta[i], A[i], N[i], ax)
            out = {}
            for method in (False, True):
                s, mu = march(method, xi1, w1, args, rtol, T, Q, stats, total)
                out[method] = (s, mu, total[0])
            if any(o[0] != stepping.SUCCESS for o in out.values()):
                continue  # a path that meets D = 0: not this comparison
            for method, (_, mu, fev) in out.items():
                rows[method][0].append(fev)
                rows[method][1].append(abs(L[i] * mu / ref[i] - 1.0))
        (f5, e5), (f8, e8) = rows[False], rows[True]
        print(f"rtol {rtol:g}: {len(f5)} explicit points; evaluations per point: Dormand-Prince "
              f"{np.mean(f5):.0f}, DOP853 {np.mean(f8):.0f} ({np.mean(f8) / np.mean(f5):.2f}x); "
              f"median m_wall error: Dormand-Prince {np.median(e5):.1e}, DOP853 {np.median(e8):.1e}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print("usage: probe_high_order.py DIR/reference_cache.npz", file=sys.stderr)
        raise SystemExit(2)
    raise SystemExit(main(sys.argv[1]))
