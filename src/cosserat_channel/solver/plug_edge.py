"""The plug edge ``1 - xi_p`` of eq:13: where ``u(xi_p) = 0.95 u(0)``, per ``eps K``.

A root in ``t = ln(xi_p)`` on stage 2's panels (``J`` increases monotonically towards the axis),
or below ``R_XI2`` on stage 2's closed form; returned as ``-expm1(t)``, free of cancellation
even when the shear layer is a tiny fraction of the channel.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import EPS as _EPS, JIT as _JIT, JIT_INLINE as _JIT_INLINE
from ..integrate import panels, roots
from ..physics import model
from ..physics.model import AX_BETA
from .layout import R_J2, R_J_AXIS, R_LOGI2, R_N2, R_XI2
from .stage2 import XI_FLOOR

# guards a loop that cannot end).
ROOT_MAX_ITER = 100
# Below R_XI2, the plug-edge Newton stops on its curvature test only where the series F has a
# condition number at most this (its terms cancel little: log F is good to ~1e-15)
SERIES_QUIET = 16.0



@njit(**_JIT_INLINE)
def _series_plug_level(t, packed):
    # log I(e^t) - log(level) and its first two t-derivatives: I ~ xi^(beta+1) F(x), x = xi^2
    c, t2, slope, ax = packed
    x = math.exp(2.0 * t)
    n = int(ax[model.AX_N2])
    F = ax[model.AX_F + n - 1]
    dF = 0.0
    d2F = 0.0
    for k in range(n - 2, -1, -1):  # Horner for F, F' and F''/2
        d2F = d2F * x + dF
        dF = dF * x + F
        F = F * x + ax[model.AX_F + k]
    q = x * dF / F
    return (c + slope * (t - t2) + math.log(F), slope + 2.0 * q,
            4.0 * q * (1.0 - q) + 8.0 * x * x * d2F / F)


@njit(**_JIT)
def _series_root(fb, consts, ax, t0):
    # the root of _series_plug_level for log I(xi2) - log(level) = fb > 0, from t0; consts are
    # the first seven of _plug_constants. A kernel, not inlined: its two callers share one compiled
    # Newton search, half of the plug edge's compilation (the root costs ~1 % more, bench_plug_edge).
    t2, log_F2, slope, fa0, slope2, quiet, noise_log_F = consts
    c = fb - log_F2  # c + log F(x2) = log I(xi2): c + slope (t - t2) + log F(x) is log I - log(level)
    fa = c + fa0
    a = math.log(XI_FLOOR)
    if fa > 0.0:
        return a
    if not a < t0 < t2:
        t0 = t2 - fb / slope2
        if not t0 > a:
            t0 = t2 - fb / slope
    # 1 - xi_p = -expm1(t) to ~1e-16 relative: dt <= 1e-16 (1 - xi)/xi, and (1 - xi)/xi >= -t
    tol = -1e-16 * t0
    if not quiet:
        # Without the curvature test the search stops on a step below tol; where the level's
        # rounding noise (log F's, and that of its O(fb) terms) is above tol in t, the steps are
        # that noise and never get there: the bracket was bisected down to 1e-16, 25 evaluations
        # on average and 60 at worst. Steps below the noise end the search instead.
        tol = max(tol, (noise_log_F + _EPS * (abs(c) + abs(fb) + abs(log_F2)))
                  / max(slope, slope2))
    x, _ = roots.newton_root_d2(_series_plug_level, (c, t2, slope, ax), a, t2, fa, fb, t0,
                                tol, ROOT_MAX_ITER, quiet)
    return x


@njit(**_JIT_INLINE)
def _no_plug_constants():
    """:func:`_plug_constants` where there is no closed form below the panels (all NaN)."""
    nan = math.nan
    return nan, nan, nan, nan, nan, False, nan, nan, nan, nan, nan, nan, nan, nan


@njit(**_JIT)
def needs_series_root(eps_K, res):
    """Whether the plug edge for ``eps_K`` lies below ``R_XI2``, on stage 2's closed form (the
    root that needs :func:`_plug_constants`): its level is above ``J`` there."""
    return model.plug_target(res[R_J_AXIS], eps_K) > res[R_J2]


@njit(**_JIT)
def _plug_constants(res, ax):
    """What the plug-edge root below ``R_XI2`` needs of a triple whatever ``eps K``: ``(t2,
    log F(x2), beta + 1, the part of f(ln XI_FLOOR) that does not depend on the level, the slope
    at t2, whether F's terms cancel little (the Newton search's curvature test holds), the
    rounding noise of log F)``, then the quintic Hermite of ``t_p`` as a function of ``log(level)`` between the
    levels of ``eps K = 0`` (``J(0)/20``, a root found here) and of ``xi2``: ``(log level there,
    1/range, t_p there, dt/d(log level) at both ends times the range, second derivatives at both
    ends times the range squared)``. NaN without a closed form below the panels."""
    xi2 = res[R_XI2]
    if not xi2 > 0.0:
        return _no_plug_constants()
    t2 = math.log(xi2)
    slope = ax[AX_BETA] + 1.0
    x2 = xi2 * xi2
    F2, dF2 = model.series_F_dF(x2, ax)
    log_F2 = math.log(F2)
    # The condition number of F at x2 (the largest on [0, x2]): where its terms cancel, log F
    # carries rounding noise far above what the curvature test of the Newton steps assumes.
    n = int(ax[model.AX_N2])
    size = 0.0
    for k in range(n - 1, -1, -1):
        size = size * x2 + abs(ax[model.AX_F + k])
    consts = (t2, log_F2, slope, slope * (math.log(XI_FLOOR) - t2) + math.log(ax[model.AX_F]),
              slope + 2.0 * x2 * dF2 / F2, size <= SERIES_QUIET * abs(F2), _EPS * size / abs(F2))
    _, d1_top, d2_top = _series_plug_level(t2, (-log_F2, t2, slope, ax))
    L_min = math.log(0.05 * res[R_J_AXIS])
    H = res[R_LOGI2] - L_min
    if not H > 0.0:
        # eps K = 0's edge lies on the panels: the Hermite's range is empty (eq:13's levels are
        # all at least J(0)/20, above log I(xi2), and a root needs one below)
        nan = math.nan
        return consts + (nan, nan, nan, nan, nan, nan, nan)
    t_min = _series_root(H, consts, ax, math.nan)
    _, d1_min, d2_min = _series_plug_level(t_min, (H - log_F2, t2, slope, ax))
    # t(L) has t' = 1/f' and t'' = -f''/f'^3 (f = log I - L in t)
    return consts + (L_min, 1.0 / H, t_min, H / d1_min, H / d1_top,
                     -d2_min / d1_min ** 3 * H * H, -d2_top / d1_top ** 3 * H * H)


@njit(**_JIT_INLINE)
def _series_start(L, consts):
    # the quintic Hermite of t_p(log level) of _plug_constants; NaN outside its range
    L_min, inv_H, t_min, m0, m1, a0, a1 = consts[7:]
    s = (L - L_min) * inv_H
    if not 0.0 <= s <= 1.0:
        return math.nan
    s2 = s * s
    s3 = s2 * s
    r = 1.0 - s
    r3 = r * r * r
    # quintic Hermite basis (value, slope, curvature at s = 0 and at s = 1)
    return (r3 * (1.0 + 3.0 * s + 6.0 * s2) * t_min + r3 * s * (1.0 + 3.0 * s) * m0
            + 0.5 * r3 * s2 * a0 + s3 * (10.0 - 15.0 * s + 6.0 * s2) * consts[0]
            - s3 * r * (4.0 - 3.0 * s) * m1 + 0.5 * s3 * r * r * a1)


@njit(**_JIT_INLINE)
def _series_plug_edge(target, res, ax, consts):
    """``ln xi_p`` below ``R_XI2``, where ``J = J(0) - I(xi)`` is closed form: ``I(xi_p) = J(0) - target``.

    Safeguarded Newton (:func:`roots.newton_root_d2`) on ``log I - log(J(0) - target)`` in
    ``t = ln xi``, from the quintic Hermite interpolant of the root over the levels that eq:13
    can ask for (``consts``: :func:`_plug_constants`), within ~1e-5: 2 evaluations of one Horner
    pass, an exp and a log. The bracket's ends need no evaluation: ``log I`` at ``xi2`` is kept
    (``R_LOGI2``), and at ``XI_FLOOR`` it is that minus ``(beta+1)`` times the distance, up to
    ``log F(0)/F(x2)``.
    """
    L = math.log(res[R_J_AXIS] - target)
    fb = res[R_LOGI2] - L
    if not fb > 0.0:
        return consts[0]
    return _series_root(fb, consts[:7], ax, _series_start(L, consts))


# T_k(1 - u) - 1 and its u-derivative at the panel's ends u = 0 and u = 2, for k < N_COEF
_K2 = np.array([float(k * k) for k in range(panels.N_COEF)])
_SIGN_K2 = np.array([float((-1) ** k * k * k) for k in range(panels.N_COEF)])
_ODD = np.array([float(k % 2) for k in range(panels.N_COEF)])


@njit(**_JIT_INLINE)
def _panel_plug_edge(target, T2, Q2, n2):
    """``1 - xi_p`` on the stage-2 panels, where ``J`` reaches ``target`` (below ``R_J2``).

    The panel comes from a bisection on ``J`` at the panel ends, the root from
    :func:`roots.newton_root_d2` on that panel's series in ``u``, from the cubic through the
    panel's ends with their slopes, inverted (``u`` as a function of ``J``): 1-2 evaluations.
    """
    lo = 0
    hi = n2
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if Q2[mid, panels.TOP, 1] < target:
            lo = mid
        else:
            hi = mid
    # on panel lo, in u = (T2[lo] - t)/r from its upper end: J - target rises from f_top < 0
    f_top = Q2[lo, panels.TOP, 1] - target
    odd = 0.0
    dJ_top = 0.0
    dJ_bottom = 0.0
    for k in range(1, panels.N_COEF):
        ck = Q2[lo, k, 1]
        odd += _ODD[k] * ck
        dJ_top -= _K2[k] * ck
        dJ_bottom += _SIGN_K2[k] * ck
    rise = -2.0 * odd  # J(u = 2) - J(u = 0)
    f_bottom = f_top + rise
    if not f_bottom > 0.0:
        return -math.expm1(T2[lo + 1])  # J reaches the target only at the panel's end
    s = -f_top / rise
    u0 = 2.0 * s  # linear between the ends
    if dJ_top > 0.0 and dJ_bottom > 0.0:
        # Hermite cubic of u(J) through both ends, in s = (target - J_top)/rise
        uh = s * (1.0 - s) * ((1.0 - s) * rise / dJ_top - s * rise / dJ_bottom) + s * s * (6.0 - 4.0 * s)
        if 0.0 < uh < 2.0:
            u0 = uh
    r = 0.5 * (T2[lo] - T2[lo + 1])
    # 1 - xi_p = -expm1(t) to ~1e-16 relative: du <= 1e-16 (1 - xi)/(xi r), (1 - xi)/xi >= -t
    u, _ = roots.newton_root_d2(_panel_level, (Q2, lo, target), 0.0, 2.0, f_top, f_bottom, u0,
                                1e-16 * (u0 - T2[lo] / r), ROOT_MAX_ITER)
    return -math.expm1(T2[lo] - r * u)


@njit(**_JIT_INLINE)
def _one_minus_xi_p(eps_K, res, ax, T2, Q2, consts):
    """``(1 - xi_p, consts)``: :func:`one_minus_xi_p` with the triple's :func:`_plug_constants`,
    computed here the first time a root needs them (``consts[0]`` NaN until then) and handed back,
    so that a run of ``eps K`` of one triple computes them at most once (:func:`solve_batch`)."""
    target = model.plug_target(res[R_J_AXIS], eps_K)
    if target <= 0.0:
        return 0.0, consts
    if needs_series_root(eps_K, res):  # False when R_J2 is NaN: no closed form below the panels
        if math.isnan(consts[0]):
            consts = _plug_constants(res, ax)
        return -math.expm1(_series_plug_edge(target, res, ax, consts)), consts
    return _panel_plug_edge(target, T2, Q2, int(res[R_N2])), consts


@njit(**_JIT)
def one_minus_xi_p(eps_K, res, ax, T2, Q2):
    """``1 - xi_p`` from eq:13: on the stage-2 panels (``J`` increases monotonically towards the
    axis, :func:`_panel_plug_edge`), or below ``R_XI2`` on stage 2's closed form
    (:func:`_series_plug_edge`).

    The root is found in ``t = ln(xi_p)`` and returned as ``-expm1(t)``: no cancellation even
    when the shear layer is a tiny fraction of the channel. :func:`solve_batch` computes the
    triple's constants once for all its ``eps K`` (same bits).
    """
    return _one_minus_xi_p(eps_K, res, ax, T2, Q2, _no_plug_constants())[0]


@njit(**_JIT_INLINE)
def _panel_level(u, packed):
    Q2, p, target = packed
    J, dJ, d2J = panels.panel_value_d2(Q2, p, 1, u)
    return J - target, dJ, d2J

