"""Stage 1's scalars at the wall, the kernels behind :mod:`cosserat_channel.regimes.wall`.

``D(1)`` of a status solve (:func:`wall_D_kernel`), a signed continuation of it through zero
(:func:`wall_scalar_kernel`) and ``D(1)`` marched as a state of its own, smooth in ``eta``
(:func:`smooth_wall_D_kernel`, with its work arrays from :func:`smooth_arrays`). They march stage
1 (:mod:`.stage1`) and read its path (:mod:`.stress_path`); what the scalars mean and how an edge
is located from them is :mod:`cosserat_channel.regimes.wall`'s.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT as _JIT
from .. import status as st
from ..integrate import dense, rk45, stepping
from ..physics import model
from . import layout, stage1, stress_path

# Where the smooth march switches from w = delta/xi^2 (as in stage 1) to the state (delta, D).
SMOOTH_XI_SWITCH = 0.5
SMOOTH_ATOL = 1e-16  # on w and delta
SMOOTH_ATOL_D = 1e-24  # on D: D(1) is wanted to ~1e-18 where the edge is a near-double zero


@njit(**_JIT)
def wall_D_kernel(etas, A, N, rtol, atol, ax, T1, Q1, stats1, res, status, D1, delta1):
    # Stage 1 exactly as the status solve runs it (stage1.solve_stage1: same start, re-marches
    # and floor tolerance), then D(1) from the dense output's wall value, also where stage 1
    # reached the wall but called D(1) zero within its resolution (status eps_too_large_path with
    # xi_stop = 1). NaN where the path met D = 0 before the wall or stage 1 failed.
    buf = np.empty(1)
    for i in range(etas.size):
        code, _ = stage1.solve_stage1(etas[i], A, N, rtol, atol, ax, T1, Q1, stats1, res,
                                      layout.METHOD_AUTO)
        status[i] = code
        n1 = int(res[layout.R_N1])
        if n1 > 0 and (code == st.OK or res[layout.R_XI_STOP] == 1.0):
            delta1[i] = stress_path._delta_wall(T1, Q1, n1, buf)
            D1[i] = model.yield_D(1.0, delta1[i], A, N, ax)
        else:
            delta1[i] = math.nan
            D1[i] = math.nan


@njit(**_JIT)
def wall_scalar_kernel(etas, A, N, atol, ax, T1, Q1, stats1, res, status, G, sens):
    # Stage 1 at its floor tolerance (one march: it never re-marches there), then a signed
    # distance from the edge in D: D(1) where the path reached the wall; F(xi_s) (1 - xi_s) where
    # it met D = 0 at xi_s < 1 (there D' = F, so this continues D(1) through zero to first order);
    # NaN where stage 1 says neither. atol goes with the floor rtol. sens: |dD/d delta| delta,
    # what stage 1's error does to D.
    buf = np.empty(1)
    work = np.zeros(stress_path.N_W)
    rtol = stage1.STAGE1_RTOL_FLOOR
    for i in range(etas.size):
        eta = etas[i]
        code, _ = stage1.solve_stage1(eta, A, N, rtol, atol, ax, T1, Q1, stats1, res,
                                      layout.METHOD_AUTO)
        status[i] = code
        n1 = int(res[layout.R_N1])
        xs = res[layout.R_XI_STOP]
        G[i] = math.nan
        sens[i] = math.nan
        if n1 > 0 and (code == st.OK or xs == 1.0):
            _, G[i], sens[i] = stage1._wall_values(T1, Q1, n1, A, N, ax, buf)
        elif code == st.EPS_TOO_LARGE_PATH and n1 > 0 and xs < 1.0:
            work[0] = 0.0
            d = stress_path._delta_at(xs, res[layout.R_XI1], ax, T1, Q1, n1, buf, work)
            a1 = A + 1.0
            F = 2.0 * a1 * xs * ((A - 1.0) + 2.0 * a1 * (N - d) / eta)
            G[i] = min(F, 0.0) * (1.0 - xs)
            sens[i] = stage1._wall_D_sensitivity(A, N, d)


@njit(**_JIT)
def _delta_D_rhs(xi, y, args, out):
    # (delta, D) along a stage-1 path: eta delta' = (A+1) xi - sqrt(D) and
    # D' = F - (D_delta / eta) sqrt(D), F = 2(A+1) xi [(A-1) + 2(A+1)(N - delta)/eta]
    # (node_edge_eta). D is carried, not recomputed from delta: next to the wall it is a tiny
    # difference of O(1) terms, and carried it keeps a relative error. sqrt(max(D, 0)) continues
    # the path past D = 0 (D' = F < 0 there), so D(1) changes sign at the edge, continuously.
    eta, A, N, ax = args
    a1 = A + 1.0
    s = math.sqrt(max(y[1], 0.0))
    out[0] = (a1 * xi - s) / eta
    out[1] = 2.0 * a1 * xi * ((A - 1.0) + 2.0 * a1 * (N - y[0]) / eta) - 4.0 * a1 * (N - y[0]) * s / eta


@njit(**_JIT)
def smooth_wall_D_kernel(eta, A, N, rtol, ax, T, Qw, Q, stats, out):
    # out: (D(1), delta(1)); returns D(1) (NaN where a march failed)
    out[0] = math.nan
    out[1] = math.nan
    args = (eta, A, N, ax)
    xi1, w1 = stage1.stage1_start(ax, rtol)
    if xi1 < SMOOTH_XI_SWITCH:
        y1 = np.empty(1)
        y1[0] = w1
        atol1 = np.empty(1)
        atol1[0] = SMOOTH_ATOL
        code, n, _ = rk45.dopri5(stage1._stage1_rhs, stepping.no_event, xi1, y1, SMOOTH_XI_SWITCH,
                                 args, rtol, atol1, 0.0, 0.0, T, Qw, stats)
        if code != stepping.SUCCESS:
            return math.nan
        dense.dense_eval_step(T, Qw, n - 1, SMOOTH_XI_SWITCH, y1)
        xi1, w1 = SMOOTH_XI_SWITCH, y1[0]
    y = np.empty(2)
    y[0] = xi1 * xi1 * w1
    y[1] = model.yield_D(xi1, y[0], A, N, ax)
    atol = np.empty(2)
    atol[0] = SMOOTH_ATOL
    atol[1] = SMOOTH_ATOL_D
    code, n, _ = rk45.dopri5(_delta_D_rhs, stepping.no_event, xi1, y, 1.0, args, rtol, atol, 0.0, 0.0,
                             T, Q, stats)
    if code != stepping.SUCCESS:
        return math.nan
    dense.dense_eval_step(T, Q, n - 1, 1.0, y)
    out[0] = y[1]
    out[1] = y[0]
    return y[1]


def smooth_arrays(max_steps):
    """``(T, Qw, Q, stats)``: room for :func:`smooth_wall_D_kernel`'s two marches of at most
    ``max_steps`` steps each (the ``w`` and the ``(delta, D)`` dense output) and their statistics."""
    return (np.empty(max_steps + 1), np.empty((max_steps, dense.N_DENSE, 1)),
            np.empty((max_steps, dense.N_DENSE, 2)), np.zeros(stepping.N_STATS, dtype=np.int64))
