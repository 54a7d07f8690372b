"""Would an 8th-order pair pay on stage 1? A plain DOP853 march against ours, on the same points.

A probe for issue 9's fourth direction, not a solver: scipy's DOP853 tableau (Hairer's error
estimate, step-size exponent 1/8) in a Numba loop on stage 1 from the same axis-series start,
with the same right-hand side, the same split at xi = N, no events and no dense output. It runs on
the work-precision set's points where our stage 1 takes the explicit path without a re-march, and
prints the mean right-hand-side evaluations of both and the median m_wall error against the
set's references. Run after ``cosserat-channel bench -o DIR`` (which caches the references):
``PYTHONPATH=src .venv/bin/python benchmarks/probe_high_order.py DIR/reference_cache.npz``.
"""

from __future__ import annotations

import math
import sys

import numpy as np
import scipy.integrate._ivp.dop853_coefficients as dop  # private module: a probe, not the product
from numba import njit

from cosserat_channel import dense, model, rk45, stages

ATOL = 1e-12
_A = np.ascontiguousarray(dop.A[:12, :12])
_B = dop.B.copy()
_C = dop.C[:12].copy()
_E3 = dop.E3.copy()
_E5 = dop.E5.copy()


@njit
def dop853_stage1(x0, w0, x1, h, eta, A, N, ax, rtol, atol):
    """``(w(x1), evaluations)`` of a DOP853 march of stage 1 (NaN when the step size collapses)."""
    k = np.empty(13)
    nfev = 1
    x = x0
    w = w0
    k[0] = model.dw_dxi(x, w, eta, A, N, ax)
    while x < x1:
        h = min(h, x1 - x)
        for s in range(1, 12):
            dy = 0.0
            for j in range(s):
                dy += _A[s, j] * k[j]
            k[s] = model.dw_dxi(x + _C[s] * h, w + h * dy, eta, A, N, ax)
        dy = 0.0
        for j in range(12):
            dy += _B[j] * k[j]
        w_new = w + h * dy
        k[12] = model.dw_dxi(x + h, w_new, eta, A, N, ax)
        nfev += 12
        scale = atol + rtol * max(abs(w), abs(w_new))
        e5 = 0.0
        e3 = 0.0
        for j in range(13):
            e5 += _E5[j] * k[j]
            e3 += _E3[j] * k[j]
        e5 /= scale
        e3 /= scale
        den = e5 * e5 + 0.01 * e3 * e3
        err = abs(h) * e5 * e5 / math.sqrt(den) if den > 0.0 else 0.0
        if err < 1.0 and math.isfinite(w_new):
            x += h
            w = w_new
            k[0] = k[12]
            h *= 10.0 if err == 0.0 else min(10.0, 0.9 * err ** (-1.0 / 8.0))
        else:
            h *= max(0.2, 0.9 * err ** (-1.0 / 8.0)) if math.isfinite(err) else 0.25
            if h < 1e-14:
                return math.nan, nfev
    return w, nfev


@njit
def ours(eta, A, N, rtol):
    ax = np.empty(model.N_AX)
    T1 = np.empty(stages.MAX_STEPS_STAGE1 + 1)
    Q1 = np.empty((stages.MAX_STEPS_STAGE1, dense.N_DENSE, 1))
    res = np.empty(stages.N_R)
    stats = np.zeros(rk45.N_STATS, np.int64)
    code, _ = stages.solve_stage1(eta, A, N, rtol, ATOL, ax, T1, Q1, stats, res, 0)
    return code, res[stages.R_MU_WALL], res[stages.R_RTOL1], res[stages.R_PATH], stats[rk45.STAT_FEV]


def main(path):
    d = np.load(path)
    eps, L, A, N, ref = (d[k] for k in ("eps", "L", "A", "N", "ref_m_wall"))
    eta = eps * L
    for rtol in (1e-6, 1e-8, 1e-10):
        fev_ours, fev_dop, err_ours, err_dop = [], [], [], []
        for i in range(eta.size):
            code, mu, rtol1, path, fev = ours(eta[i], A[i], N[i], rtol)
            if code != 0 or path != stages.PATH_EXPLICIT or rtol1 != rtol:
                continue
            ax = np.empty(model.N_AX)
            model.axis_constants(eta[i], A[i], N[i], ax)
            xi1, w1 = stages.stage1_start(ax, rtol)
            split = xi1 + stages.SPLIT_MARGIN < N[i] < 1.0 - stages.SPLIT_MARGIN
            w, nfev = dop853_stage1(xi1, w1, N[i] if split else 1.0, xi1, eta[i], A[i], N[i], ax,
                                    rtol, ATOL)
            if split:
                w, more = dop853_stage1(N[i], w, 1.0, 1e-3 * (1.0 - N[i]), eta[i], A[i], N[i], ax,
                                        rtol, ATOL)
                nfev += more
            fev_ours.append(fev)
            fev_dop.append(nfev)
            err_ours.append(abs(L[i] * mu / ref[i] - 1.0))
            err_dop.append(abs(L[i] * (w - N[i]) / ref[i] - 1.0))
        print(f"rtol {rtol:g}: {len(fev_ours)} explicit points; evaluations per point: "
              f"ours (RK45) {np.mean(fev_ours):.0f}, DOP853 {np.mean(fev_dop):.0f} "
              f"({np.mean(fev_dop) / np.mean(fev_ours):.2f}x); median m_wall error: "
              f"ours {np.nanmedian(err_ours):.1e}, DOP853 {np.nanmedian(err_dop):.1e}")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print("usage: probe_high_order.py DIR/reference_cache.npz", file=sys.stderr)
        raise SystemExit(2)
    raise SystemExit(main(sys.argv[1]))
