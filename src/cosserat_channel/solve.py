"""One point through both stages: the only module that joins the physics and the integrator.

Stage 1 marches the scaled couple stress ``delta`` (see :mod:`cosserat_channel.model`) from the
axis to the wall with :func:`rk45.dopri5`, stopping at ``D = 0`` if the stress path leaves the
yield-admissible region. Stage 2 marches ``(log omega_hat, J)`` from the wall towards the axis on
the dense output of stage 1 and stops once what is left of ``J`` is below the tolerance. Both
stages depend on ``(eta = eps L, A, N)`` only (the similarity of model.md); ``eps`` and ``K``
enter afterwards, through ``eps K`` in the plug-edge condition eq:13, so one integration serves a
whole ``K`` axis.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np
from numba import njit

from . import dense
from . import model
from . import rk45
from . import rosenbrock
from . import status as st
from .model import AX_BETA, AX_C0, N_AX

# Work budgets per stage: bounded work per point (a point that needs more is reported as
# integration_failed, never left running).
MAX_STEPS_STAGE1 = 200_000
MAX_STEPS_STAGE2 = 20_000
# Passes that re-march the step where stage 1 met D = 0 (see solve_eta), each within a budget.
EVENT_REFINEMENTS = 4
REFINE_MAX_STEPS = 400
STAGE1_RTOL_FLOOR = 1e-13
# D(1) below this many rtol-sized errors of D is zero within stage 1's resolution (solve_eta).
WALL_D_RESOLUTION = 0.1
# ... and when stage 2 fails with D(1) below this many, the dense output's error decides (see there).
WALL_D_FALLBACK = 1e5
# Stage 2 stops once the rest of J, down to the axis, is below this fraction of rtol * J.
TAIL_FRACTION = 1e-3
# Stage 2 never marches below this xi: J's remaining tail there is < XI_FLOOR * max h.
XI_FLOOR = 1e-14

# Slots of the per-(eta, A, N) result vector of `solve_eta`.
R_STATUS = 0
R_XI_STOP = 1  # where the stress path met D = 0 (eps_too_large_path), NaN otherwise
R_J_AXIS = 2  # J(0) = u(0)/omega_w - eps K
R_MU_WALL = 3  # m(1)/(nu L)
R_SIGMA_YX_WALL = 4  # sigma_yx(1)/nu
R_XI1 = 5  # where stage 1 left the axis series
R_T_TAIL = 6  # ln(xi) where stage 2 stopped
R_N1 = 7  # accepted steps kept in the stage-1 dense output
R_N2 = 8
R_PATH = 9  # stage 1 took the explicit (0) or the stiff (1) path; -1: not integrated
N_R = 10
PATH_EXPLICIT = 0.0
PATH_STIFF = 1.0
PATH_NONE = -1.0  # no stage-1 integration: a regime without solution, or A = -1 (exact)
PATH_NAMES = {PATH_EXPLICIT: "explicit", PATH_STIFF: "stiff", PATH_NONE: "none"}

METHOD_AUTO = 0
METHOD_EXPLICIT = 1
METHOD_STIFF = 2
# Stage 1 switches to RODAS4P2 when its stiffness exceeds this (see use_stiff_path and
# docs/performance.md for the measurement behind it).
STIFF_LAMBDA = 20.0

# Rows of a triple's profile array (see profile_kernel).
P_J = 0  # J(xi) = u(xi)/omega_w - eps K
P_OMEGA_HAT = 1  # omega(xi)/omega_w
P_DELTA = 2  # (m/nu + N L)/L
P_SIGMA_YX = 3  # sigma_yx/nu
N_PROF = 4


# ---------------------------------------------------------------------------------------------
# Right-hand sides and events in the integrator's calling convention
# ---------------------------------------------------------------------------------------------
@njit(nogil=True, cache=True)
def _stage1_rhs(xi, y, args, out):
    # The state is w = delta / xi^2 (see model.dw_dxi).
    eta, A, N, ax = args
    out[0] = model.dw_dxi(xi, y[0], eta, A, N, ax)


@njit(nogil=True, cache=True)
def _stage1_jac(xi, y, args):
    eta, A, N, ax = args
    return model.dw_dxi_jacobian(xi, y[0], eta, A, N, ax)


@njit(nogil=True, cache=True)
def _stage1_event(xi, y, args):
    # D = 0: the stress path leaves the yield-admissible region (Appendix A).
    eta, A, N, ax = args
    return model.yield_D(xi, xi * xi * y[0], A, N, ax)


@njit(nogil=True, cache=True)
def _delta_at(xi, xi1, ax, T1, Q1, n1, buf):
    """Stage-1 solution anywhere in [0, 1]: the axis series below ``xi1``, the dense output above."""
    if xi <= xi1:
        return model.delta_axis_series(xi, ax)
    dense.dense_eval(T1, Q1, n1, xi, buf)
    return xi * xi * buf[0]


@njit(nogil=True, cache=True)
def _stage2_rates(xi, eta, A, N, ax, xi1, T1, Q1, n1, buf):
    """``(xi B, h)`` of e-60 / e-59 at ``xi``, on the stage-1 solution.

    For A = -1 (Appendix A) ``D`` vanishes identically and the general formulas are 0/0; there
    ``m = -N L`` and the limits ``B = c/xi`` (``c = 2N/eta``) and ``h = 2`` are used instead, so
    that A = -1 runs through the same stage-2 march as every other A and the closed form
    (model.a_minus_one_*) stays an independent check of it.
    """
    if A == -1.0:
        return model.a_minus_one_xi_B(eta, N), model.a_minus_one_h()
    delta = _delta_at(xi, xi1, ax, T1, Q1, n1, buf)
    D = model.yield_D(xi, delta, A, N, ax)
    return xi * model.spin_rate_B(delta, D, eta, A, N), model.shear_rate_h(xi, D, A)


@njit(nogil=True, cache=True)
def _stage2_rhs(t, y, args, out):
    # Independent variable t = ln(xi): near the axis B ~ beta/xi, so d log(omega_hat)/dt -> beta
    # is smooth all the way down, where marching in xi would crawl in geometric steps.
    eta, A, N, ax, xi1, T1, Q1, n1, buf, tail_tol = args
    xi = math.exp(t)
    xiB, h = _stage2_rates(xi, eta, A, N, ax, xi1, T1, Q1, n1, buf)
    out[0] = xiB  # d log(omega_hat)/dt   (e-60)
    out[1] = -xi * h * math.exp(y[0])  # dJ/dt   (e-59)


@njit(nogil=True, cache=True)
def _h_axis(A, ax):
    # h at the axis, where sqrt(D) -> c0 xi (A = -1: h = 2 everywhere).
    if A == -1.0:
        return model.a_minus_one_h()
    return (A + 1.0) * (1.0 - (A - 1.0) / ax[AX_C0])


@njit(nogil=True, cache=True)
def _stage2_event(t, y, args):
    # Positive while the rest of J (from xi down to the axis) can still matter: that rest is at
    # most xi * max(h) * omega_hat(xi), because omega_hat increases with xi (B > 0 near the axis).
    eta, A, N, ax, xi1, T1, Q1, n1, buf, tail_tol = args
    J = y[1]
    if J <= 0.0:
        return 1.0
    xi = math.exp(t)
    _, h = _stage2_rates(xi, eta, A, N, ax, xi1, T1, Q1, n1, buf)
    h_bound = 2.0 * max(h, _h_axis(A, ax))
    return y[0] + t + math.log(h_bound) - math.log(tail_tol * J)


# ---------------------------------------------------------------------------------------------
# The kernel for one (eta, A, N)
# ---------------------------------------------------------------------------------------------
@njit(nogil=True, cache=True)
def use_stiff_path(eta, ax):
    """Whether stage 1 should take the stiff path: the Jacobian is known in closed form.

    It is ``-B - 2/xi`` in ``w``: about ``-2/eta`` in the interior. An explicit method needs
    O(1/eta) steps there (stability, and accuracy along the slow manifold) and O(beta) steps per
    decade of xi near the axis, where the Jacobian is ``-(beta + 2)/xi``; RODAS4P2 a number set by
    the smoothness of the solution alone. beta is large for small eta and also next to the axis
    edge, where c0 -> 0.
    """
    return max(2.0 / eta, ax[AX_BETA]) > STIFF_LAMBDA


@njit(nogil=True, cache=True)
def stage1_rtol(rtol, A, N, ax):
    """Stage 1's relative tolerance: the user's, tightened to ``rho/1000`` next to the axis edge.

    ``rho = c0^2 / (2(A+1) N y)`` (:func:`model.axis_relative_margin`) is the relative size of the
    difference ``D/xi^2 -> c0^2`` that decides where such a path meets D = 0; ``rho = c0^2`` up to
    an O(1) factor unless ``A -> -1``. Floored at 1e-13 (double precision); within ~1e-10 relative
    of the axis edge the location xi_stop where such a path fails is therefore only approximate
    (the status is not).
    """
    rho = model.axis_relative_margin(A, N, ax)
    return min(rtol, max(STAGE1_RTOL_FLOOR, 1e-3 * rho))


@njit(nogil=True, cache=True)
def _march_stage1(stiff, xi0, y0, h0, h_max, args1, rtol, atol1, T1, Q1, stats1):
    # The only place that picks stage 1's integrator; both write the same dense-output layout.
    if stiff:
        return rosenbrock.rodas4(_stage1_rhs, _stage1_jac, _stage1_event, xi0, y0, 1.0, args1,
                                 rtol, atol1, h0, h_max, T1, Q1, stats1)
    return rk45.dopri5(_stage1_rhs, _stage1_event, xi0, y0, 1.0, args1, rtol, atol1, h0, h_max,
                       T1, Q1, stats1)


@njit(nogil=True, cache=True)
def axis_crossing_xi2(eta, A, N, ax):
    """``xi^2`` where the two-term axis series ``D = c0^2 xi^2 + 2(A+1)(2Nk - y^2/4) xi^4`` vanishes.

    With ``k`` of :func:`model.axis_constants`, ``2Nk - y^2/4 = -(y^2/4) 4 eta c0 / (4 eta c0 +
    2(A+1)N)`` exactly, so this is ``c0 (4 eta c0 + 2(A+1)N) / (2(A+1) y^2 eta)``, free of
    cancellation. Only meaningful when it is small (the series' own range).
    """
    a1 = A + 1.0
    c0 = ax[AX_C0]
    y = ax[model.AX_Y]
    return c0 * (4.0 * eta * c0 + 2.0 * a1 * N) / (2.0 * a1 * y * y * eta)


@njit(nogil=True, cache=True)
def start_xi(ax):
    """Where stage 1 leaves the axis series: small enough that the neglected O(xi^6) term is far
    below round-off, scaled with ``c0`` because the series' radius shrinks at the axis edge."""
    return 1e-3 * min(1.0, ax[AX_C0])


@njit(nogil=True, cache=True)
def _stage1_pass(stiff, xi1, w1, args1, rtol1, atol1, T1, Q1, stats1):
    """Stage 1 from the axis series to the wall or to D = 0; counters are added to ``stats1``.

    Where the path meets D = 0, sqrt(D) ~ sqrt(xi_stop - xi): the RHS has a kink that the last
    (wide, error-controlled) step glides over, so the dense output locates xi_stop only to ~1e-4.
    That last step is marched again with steps 1/16 as wide, until the location settles.
    """
    y0 = np.empty(1)
    y0[0] = w1
    stats_r = np.zeros_like(stats1)
    # First step = xi1: off the axis the solution varies on the scale of xi itself, and the
    # generic first-step guesses (built on |f|, which is tiny there) jump far too far.
    s1, n1, t1 = _march_stage1(stiff, xi1, y0, xi1, 0.0, args1, rtol1, atol1, T1, Q1, stats_r)
    for i in range(rk45.STAT_STIFF):
        stats1[i] += stats_r[i]
    stats1[rk45.STAT_STIFF] = max(stats1[rk45.STAT_STIFF], stats_r[rk45.STAT_STIFF])
    for _ in range(EVENT_REFINEMENTS):
        if s1 != rk45.EVENT:
            break
        k = n1 - 1
        span = t1 - T1[k]
        if not span > 0.0:
            break
        y0[0] = Q1[k, 0, 0]
        stop = min(Q1.shape[0], k + REFINE_MAX_STEPS)
        s_new, nb, t_new = _march_stage1(stiff, T1[k], y0, span / 16.0, span / 16.0, args1, rtol1,
                                         atol1, T1[k:stop + 1], Q1[k:stop], stats_r)
        for i in range(rk45.STAT_STIFF):
            stats1[i] += stats_r[i]
        n1 = k + nb
        if s_new == rk45.SUCCESS:
            # With finer steps the path reaches the wall: the crossing was the interpolant's.
            s1 = s_new
            t1 = t_new
            break
        if s_new != rk45.EVENT:
            # Budget spent crawling into the sqrt kink (D ~ 0 over a long stretch, next to the
            # axis edge): keep the previous location, good to the last pass's step width.
            break
        settled = abs(t_new - t1) <= rtol1 * t1
        t1 = t_new
        if settled:
            break
    return s1, n1, t1


@njit(nogil=True, cache=True)
def _wall_D_sensitivity(A, N, delta_wall):
    """``|dD/d delta| delta`` at the wall: what a relative error in delta does to D(1)."""
    return 4.0 * (A + 1.0) * abs(N - delta_wall) * abs(delta_wall)


@njit(nogil=True, cache=True)
def solve_stage1(eta, A, N, rtol, atol, ax, T1, Q1, stats1, res, method=METHOD_AUTO):
    """Stage 1 for one ``(eta, A, N)``: the regime, the march from the axis and the wall values.

    Fills ``res`` (all ``R_*`` slots reset; stage 1 sets ``R_STATUS``, ``R_XI_STOP``, ``R_XI1``,
    ``R_N1``, ``R_PATH``, ``R_MU_WALL``, ``R_SIGMA_YX_WALL``), the axis constants ``ax``, the dense
    output (T1, Q1) and ``stats1``. Returns ``(status, near_edge)``: ``near_edge`` says D(1) lies
    within ``WALL_D_FALLBACK`` resolutions of zero, where a stage-2 failure means D(1) = 0 within
    the dense output's resolution (see :func:`solve_eta`).
    """
    for i in range(N_R):
        res[i] = math.nan
    for i in range(stats1.size):
        stats1[i] = 0
    res[R_N1] = 0.0
    res[R_N2] = 0.0
    res[R_PATH] = PATH_NONE
    code = model.classify(eta, A, N)
    res[R_STATUS] = code
    if code != st.OK:
        return code, False
    if A == -1.0:
        # Appendix A: stage 1 is exact (m = -NL, sigma_yx = -xi, delta = 0), no integration and
        # no stage-1 path; stage 2 runs through the same march as every other A, with B = c/xi
        # and h = 2 (see _stage2_rates); beta = c is the exact spin exponent for the profiles.
        ax[model.AX_Y] = 0.0
        ax[AX_C0] = 0.0
        ax[model.AX_K] = 0.0
        ax[AX_BETA] = model.a_minus_one_xi_B(eta, N)
        res[R_XI1] = 0.0
        res[R_MU_WALL] = -N
        res[R_SIGMA_YX_WALL] = -1.0
        return st.OK, False

    model.axis_constants(eta, A, N, ax)
    if (1e-3 * model.axis_relative_margin(A, N, ax) < STAGE1_RTOL_FLOOR
            and axis_crossing_xi2(eta, A, N, ax) < 1e-2):
        # Within ~1e-5 (relative) of the axis edge. The series gives
        # D = c0^2 xi^2 + 2(A+1)(2Nk - y^2/4) xi^4 + ..., with 2Nk - y^2/4 < 0 for every c0 > 0,
        # so the path meets D = 0 at xi ~ sqrt(c0) (axis_crossing_xi2): the status is certain, but
        # where exactly is below double-precision resolution (the margin c0^2 is < 1e-10 of the
        # terms of D), so xi_stop stays NaN rather than a number we cannot stand behind. When
        # A -> -1 that crossing can lie beyond the wall even for a tiny c0; such points are
        # integrated (at the floor tolerance) instead.
        res[R_STATUS] = st.EPS_TOO_LARGE_PATH
        return st.EPS_TOO_LARGE_PATH, False
    xi1 = start_xi(ax)
    res[R_XI1] = xi1
    buf = np.empty(1)
    w1 = model.delta_axis_series(xi1, ax) / (xi1 * xi1)
    atol1 = np.empty(1)
    atol1[0] = atol
    args1 = (eta, A, N, ax)
    # Next to the axis edge D/xi^2 ~ c0^2 is the small difference that decides where the path
    # meets D = 0; an error in w of rtol would swamp it, so stage 1 runs at rtol ~ c0^2/1000 there.
    rtol1 = stage1_rtol(rtol, A, N, ax)
    stiff = use_stiff_path(eta, ax) if method == METHOD_AUTO else method == METHOD_STIFF
    res[R_PATH] = PATH_STIFF if stiff else PATH_EXPLICIT
    s1, n1, t1 = _stage1_pass(stiff, xi1, w1, args1, rtol1, atol1, T1, Q1, stats1)
    if s1 == rk45.SUCCESS:
        delta_wall = _delta_at(1.0, xi1, ax, T1, Q1, n1, buf)
        D_wall = model.yield_D(1.0, delta_wall, A, N, ax)
        sensitivity = _wall_D_sensitivity(A, N, delta_wall)
        # Near the path edge D(1) is small and Delta, sigma_yx(1) and stage 2 (B ~ 1/sqrt(D))
        # depend on D(1) with condition ~ sensitivity / D(1): an error rtol1 in delta is an error
        # rtol1 * sensitivity in D. March stage 1 once more at rtol * D(1)/sensitivity so that
        # D(1), hence Delta, is good to ~rtol (before this, near-edge points at rtol 1e-5 came
        # back with Delta 28 % off; see docs/work_precision.md).
        rtol_cond = rtol * D_wall / sensitivity if sensitivity > 0.0 else rtol1
        if D_wall > 0.0 and rtol_cond < 0.5 * rtol1 and rtol1 > STAGE1_RTOL_FLOOR:
            rtol1 = max(STAGE1_RTOL_FLOOR, rtol_cond)
            s1, n1, t1 = _stage1_pass(stiff, xi1, w1, args1, rtol1, atol1, T1, Q1, stats1)
            if s1 == rk45.SUCCESS:
                delta_wall = _delta_at(1.0, xi1, ax, T1, Q1, n1, buf)
                D_wall = model.yield_D(1.0, delta_wall, A, N, ax)
                sensitivity = _wall_D_sensitivity(A, N, delta_wall)
    res[R_N1] = n1
    if s1 == rk45.EVENT:
        res[R_STATUS] = st.EPS_TOO_LARGE_PATH
        res[R_XI_STOP] = t1
        return st.EPS_TOO_LARGE_PATH, False
    if s1 != rk45.SUCCESS:
        res[R_STATUS] = st.INTEGRATION_FAILED
        return st.INTEGRATION_FAILED, False
    # Stage 1 resolves delta to ~rtol1 |delta|, hence D(1) to ~rtol1 * sensitivity: a D(1) well
    # below that is zero within what stage 1 resolves. Stage 2 there marches B ~ 1/sqrt(D) on
    # noise (20,000 steps, no answer, seen at D(1) ~ 0.1 of it), so such a point is reported as
    # reaching D = 0 at the wall, like D(1) <= 0 itself. The stage-2 fallback in solve_eta catches
    # what this cheap cut lets through; together they move the edge < 1e-5 relative.
    D_resolution = WALL_D_RESOLUTION * rtol1 * sensitivity
    if not D_wall > D_resolution:
        res[R_STATUS] = st.EPS_TOO_LARGE_PATH
        res[R_XI_STOP] = 1.0
        return st.EPS_TOO_LARGE_PATH, False
    res[R_MU_WALL] = delta_wall - N
    res[R_SIGMA_YX_WALL] = model.sigma_yx(1.0, D_wall, A)
    return st.OK, D_wall < WALL_D_FALLBACK * D_resolution


@njit(nogil=True, cache=True)
def solve_eta(eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res, method=METHOD_AUTO):
    """Both stages for one ``(eta, A, N)`` with ``A > -1`` or ``A = -1``.

    ``method`` picks stage 1's integrator: ``METHOD_AUTO`` (by :func:`use_stiff_path`),
    ``METHOD_EXPLICIT`` (Dormand-Prince) or ``METHOD_STIFF`` (RODAS4P2).

    Fills ``res[N_R]`` (slots ``R_*``), the axis constants ``ax``, the dense outputs (T1, Q1) of
    stage 1 and (T2, Q2) of stage 2 and the counters. Returns the status code.
    """
    for i in range(stats2.size):
        stats2[i] = 0
    code, near_edge = solve_stage1(eta, A, N, rtol, atol, ax, T1, Q1, stats1, res, method)
    if code != st.OK:
        return code
    code = _march_stage2(eta, A, N, rtol, atol, ax, res[R_XI1], T1, Q1, int(res[R_N1]), T2, Q2,
                         stats2, res)
    if code == st.INTEGRATION_FAILED and near_edge:
        # Stage 2 failed on B ~ 1/sqrt(D) with D(1) a few decades above stage 1's step error but
        # not above its interpolation error (tight rtol): D(1) is zero within the dense output's
        # resolution, the same verdict as the cut in solve_stage1.
        res[R_STATUS] = st.EPS_TOO_LARGE_PATH
        res[R_XI_STOP] = 1.0
        res[R_J_AXIS] = math.nan
        return st.EPS_TOO_LARGE_PATH
    return code


@njit(nogil=True, cache=True)
def _march_stage2(eta, A, N, rtol, atol, ax, xi1, T1, Q1, n1, T2, Q2, stats2, res):
    """Stage 2: wall -> axis in ``t = ln(xi)``, state ``(log omega_hat, J)``; ``omega_hat(1) = 1``,
    ``J(1) = 0`` (eq:7). Stops once the rest of ``J`` is below ``TAIL_FRACTION * rtol * J``.

    ``d log(omega_hat)/dt = xi B`` does not depend on the state, and ``J`` grows like
    ``exp((beta + 1) t)``: with ``beta = 1e5`` the march takes steps of ~1/beta in t and stops
    after a few tens of them (the tail event), so its cost does not grow with beta.
    """
    buf = np.empty(1)
    y2 = np.zeros(2)
    atol2 = np.empty(2)
    atol2[0] = rtol  # an absolute error in log(omega_hat) is a relative error in omega_hat
    atol2[1] = atol * min(1.0, eta)
    args2 = (eta, A, N, ax, xi1, T1, Q1, n1, buf, TAIL_FRACTION * rtol)
    s2, n2, t2 = rk45.dopri5(
        _stage2_rhs, _stage2_event, 0.0, y2, math.log(XI_FLOOR), args2, rtol, atol2, 0.0, 0.0, T2, Q2,
        stats2,
    )
    res[R_N2] = n2
    if s2 != rk45.SUCCESS and s2 != rk45.EVENT:
        res[R_STATUS] = st.INTEGRATION_FAILED
        return st.INTEGRATION_FAILED
    yb = np.empty(2)
    dense.dense_eval(T2, Q2, n2, t2, yb)
    res[R_T_TAIL] = t2
    res[R_J_AXIS] = yb[1]
    if not (math.isfinite(yb[1]) and yb[1] > 0.0):
        res[R_STATUS] = st.INTEGRATION_FAILED
        return st.INTEGRATION_FAILED
    return st.OK


@njit(nogil=True, cache=True)
def _J_at(T2, Q2, n2, t, yb):
    dense.dense_eval(T2, Q2, n2, t, yb)
    return yb[1]


@njit(nogil=True, cache=True)
def one_minus_xi_p(A, N, eta, eps_K, res, T2, Q2):
    """``1 - xi_p`` from eq:13 on the stage-2 dense output (``J`` decreases monotonically in xi).

    The root is found in ``t = ln(xi_p)`` and returned as ``-expm1(t)``: no cancellation even when
    the shear layer is a tiny fraction of the channel.
    """
    J_axis = res[R_J_AXIS]
    target = model.plug_target(J_axis, eps_K)
    if target <= 0.0:
        return 0.0
    n2 = int(res[R_N2])
    yb = np.empty(2)
    # Bracket on step ends: T2 (= ln xi) runs from 0 down, J from 0 up.
    lo = 0
    hi = n2
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if _J_at(T2, Q2, n2, T2[mid], yb) < target:
            lo = mid
        else:
            hi = mid
    a = T2[lo]  # J(a) < target
    # T2[n2] is the end of the last step, which overshoots where an event stopped stage 2.
    b = T2[hi] if hi < n2 else res[R_T_TAIL]
    fa = _J_at(T2, Q2, n2, a, yb) - target
    fb = _J_at(T2, Q2, n2, b, yb) - target
    # Illinois regula falsi on the interpolant, safeguarded by bisection.
    side = 0
    x = a
    for _ in range(100):
        if fb == fa:
            x = 0.5 * (a + b)
        else:
            x = b - fb * (b - a) / (fb - fa)
            if not (min(a, b) < x < max(a, b)):
                x = 0.5 * (a + b)
        fx = _J_at(T2, Q2, n2, x, yb) - target
        if fx == 0.0 or abs(b - a) <= 4e-16 * abs(x) + 1e-300:
            break
        if (fx < 0.0) == (fa < 0.0):
            a = x
            fa = fx
            if side == -1:
                fb *= 0.5
            side = -1
        else:
            b = x
            fb = fx
            if side == 1:
                fa *= 0.5
            side = 1
    return -math.expm1(x)


@njit(nogil=True, cache=True)
def stage1_batch(eta, A, N, rtol, atol, method, max_steps, mu_wall, stats):
    """Stage 1 alone for many triples (benchmarks), exactly as :func:`solve_eta` runs it:
    ``m(1)/(nu L)`` into ``mu_wall`` (NaN without a solution) and the counters into ``stats[i]``."""
    ax = np.empty(N_AX)
    T1 = np.empty(max_steps + 1)
    Q1 = np.empty((max_steps, 5, 1))
    res = np.empty(N_R)
    for i in range(eta.size):
        solve_stage1(eta[i], A[i], N[i], rtol, atol, ax, T1, Q1, stats[i], res, method)
        mu_wall[i] = res[R_MU_WALL]


@njit(nogil=True, cache=True)
def solve_batch(eta, A, N, eps_K, offsets, rtol, atol, max_steps_stage1, max_steps_stage2,
                res, stats, one_minus, xi_profile, profiles):
    """Many ``(eta, A, N)`` triples, each with its own run of ``eps K`` values, on one core.

    Triple ``i`` owns ``eps_K[offsets[i]:offsets[i+1]]``; ``one_minus`` (same length as ``eps_K``)
    receives ``1 - xi_p`` for each (NaN where the triple has no solution). ``res[i]`` gets the
    triple's ``R_*`` slots and ``stats[i, 0]`` / ``stats[i, 1]`` the counters of the two stages.
    When ``xi_profile`` is not empty, ``profiles[i]`` (shape ``(N_PROF, xi_profile.size)``)
    receives the triple's profiles (slots ``P_*``; NaN without a solution).
    One integration per triple, whatever the number of ``eps K`` values (model.md's similarity).
    The work arrays are allocated once, here, so the kernel releases the GIL for its whole run.
    """
    ax = np.empty(N_AX)
    T1 = np.empty(max_steps_stage1 + 1)
    Q1 = np.empty((max_steps_stage1, 5, 1))
    T2 = np.empty(max_steps_stage2 + 1)
    Q2 = np.empty((max_steps_stage2, 5, 2))
    for i in range(eta.size):
        code = solve_eta(eta[i], A[i], N[i], rtol, atol, ax, T1, Q1, T2, Q2, stats[i, 0],
                         stats[i, 1], res[i])
        for j in range(offsets[i], offsets[i + 1]):
            if code == st.OK:
                one_minus[j] = one_minus_xi_p(A[i], N[i], eta[i], eps_K[j], res[i], T2, Q2)
            else:
                one_minus[j] = math.nan
        if xi_profile.size > 0:
            if code == st.OK:
                profile_kernel(xi_profile, eta[i], A[i], N[i], ax, res[i], T1, Q1, T2, Q2,
                               profiles[i])
            else:
                profiles[i, :, :] = math.nan


# ---------------------------------------------------------------------------------------------
# Python API
# ---------------------------------------------------------------------------------------------
class ParameterError(ValueError):
    """A parameter outside the model's or the solver's domain; the message names it and its range."""


MATERIAL_KEYS = {
    "d_p": ("particle diameter d_p in m", 0.0, math.inf, False),
    "rho_p": ("particle density rho_p in kg/m^3", 0.0, math.inf, False),
    "phi": ("angle of internal friction phi in degrees", 0.0, 90.0, False),
    "g": ("gravity g in m/s^2", 0.0, math.inf, False),
    "Lambda": ("closure constant Lambda in Pa (eq:24)", 0.0, math.inf, False),
    "nu_min": ("closure nu_min (eq:24)", 0.0, 1.0, True),
    "nu_max": ("closure nu_max (eq:24)", 0.0, 1.0, False),
    "p": ("closure exponent p (eq:24)", 1.0, math.inf, True),
    "q": ("closure exponent q (eq:24)", 0.0, math.inf, True),
}
MATERIAL_REQUIRED = ("d_p", "rho_p", "phi")


def _number(name: str, value, lo: float, hi: float, lo_closed: bool, hi_closed: bool, what: str):
    """``float(value)`` checked to lie in the interval; a ParameterError naming it otherwise."""
    lb = "[" if lo_closed else "("
    rb = "]" if hi_closed else ")"
    rng = f"{lb}{lo:g}, {hi:g}{rb}"
    if isinstance(value, bool):
        raise ParameterError(f"{name} must be a number in {rng} ({what}); got {value!r}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a number in {rng} ({what}); got {value!r}") from None
    ok = math.isfinite(x) and (x >= lo if lo_closed else x > lo) and (x <= hi if hi_closed else x < hi)
    if not ok:
        raise ParameterError(f"{name} = {value!r} is outside the allowed range {rng} ({what})")
    return x


def check_point(eps, L, K, A, N):
    """Validate ``(eps, L, K, A, N)``; returns them as floats or raises :class:`ParameterError`."""
    inf = math.inf
    return (
        _number("eps", eps, 0.0, 1.0, False, True, "particle diameter / channel half-width"),
        _number("L", L, 0.0, inf, False, False, "Cosserat length in particle diameters"),
        _number("K", K, 0.0, inf, True, False, "wall roughness in u = eps K omega at the wall"),
        _number("A", A, -inf, inf, False, False, "yield-surface constant a2/a1"),
        _number("N", N, 0.0, inf, False, False, "sin(phi)/tan(delta)"),
    )


def check_tolerances(rtol, atol):
    """Validate the tolerances; returns them as floats or raises :class:`ParameterError`."""
    rtol = _number("rtol", rtol, 1e-13, 1.0, True, False, "relative tolerance")
    atol = _number("atol", atol, 0.0, math.inf, False, False, "absolute tolerance")
    return rtol, atol


def check_material(material: Mapping | None) -> dict | None:
    """Validate a material mapping; fill in the paper's closure constants; None stays None."""
    if material is None:
        return None
    if not isinstance(material, Mapping):
        raise ParameterError("material must be a mapping with keys " + ", ".join(MATERIAL_KEYS))
    unknown = sorted(set(material) - set(MATERIAL_KEYS))
    if unknown:
        raise ParameterError(
            f"material: unknown key(s) {', '.join(map(repr, unknown))}; allowed: "
            + ", ".join(MATERIAL_KEYS)
        )
    missing = [k for k in MATERIAL_REQUIRED if k not in material]
    if missing:
        raise ParameterError(f"material: missing required key(s) {', '.join(missing)}")
    full = {
        "g": model.G_DEFAULT,
        "Lambda": model.LAMBDA_DEFAULT,
        "nu_min": model.NU_MIN_DEFAULT,
        "nu_max": model.NU_MAX_DEFAULT,
        "p": model.P_DEFAULT,
        "q": model.Q_DEFAULT,
    }
    for key, value in material.items():
        what, lo, hi, lo_closed = MATERIAL_KEYS[key]
        full[key] = _number(f"material.{key}", value, lo, hi, lo_closed, False, what)
    if not full["nu_min"] < full["nu_max"]:
        raise ParameterError(
            f"material.nu_min = {full['nu_min']:g} must be below material.nu_max = {full['nu_max']:g}"
        )
    return full


# Every scalar output of a point: (units, description). The single source for the CLI table,
# plot labels and the NetCDF attributes.
OUTPUTS = {
    "Delta": ("particle diameters", "shear-layer thickness (1 - xi_p)/eps"),
    "xi_p": ("1", "plug edge, u(xi_p) = 0.95 u(0) (eq:13)"),
    "slip": ("1", "wall slip u(1)/u(0)"),
    "u_axis": ("1", "centre-line velocity u(0)/omega_w"),
    "m_wall": ("1", "wall couple stress m(1)/nu (rho_p g W d_p units)"),
    "sigma_yx_wall": ("1", "wall shear stress sigma_yx(1)/nu (rho_p g W units)"),
    "xi_stop": ("1", "where the stress path met D = 0"),
    "nu": ("1", "solids fraction (eq:35)"),
    "sigma_xx_wall_Pa": ("Pa", "wall normal stress sigma_xx, compressive positive"),
    "sigma_xy_wall_Pa": ("Pa", "wall shear stress sigma_xy"),
    "sigma_yx_wall_Pa": ("Pa", "wall shear stress sigma_yx"),
    "m_wall_Pa_m": ("Pa m", "wall couple stress m"),
}
# The outputs that need a material (filled by _add_material).
MATERIAL_OUTPUTS = ("nu", "sigma_xx_wall_Pa", "sigma_xy_wall_Pa", "sigma_yx_wall_Pa", "m_wall_Pa_m")


@dataclass
class PointResult:
    """Everything one point yields. Dimensionless values follow model.md's scalings.

    Attributes
    ----------
    status : Status
        Why the point has or has no solution; ``status.message`` explains.
    Delta : float
        Shear-layer thickness ``(1 - xi_p)/eps`` in particle diameters (0 when the wall moves at
        >= 95 % of the centre).
    xi_p : float
        Plug edge, ``u(xi_p) = 0.95 u(0)`` (eq:13).
    slip : float
        ``u(1)/u(0)``.
    u_axis : float
        ``u(0)/omega_w`` (dimensionless, ``eps K + J(0)``).
    m_wall, sigma_yx_wall : float
        ``m(1)/nu`` and ``sigma_yx(1)/nu`` (paper's scalings of eq:54 and eq:56 divided by nu).
    xi_stop : float
        Where the stress path met ``D = 0`` (status ``eps_too_large_path``), NaN otherwise.
    nu : float
        Solids fraction from eq:35 (only with a material).
    sigma_xx_wall_Pa, sigma_xy_wall_Pa, sigma_yx_wall_Pa : float
        Wall stresses in Pa, compressive positive as in the paper (only with a material):
        normal ``sigma_c(nu)``, shear ``-rho_p g W nu`` and ``rho_p g W nu sigma_yx_wall``.
    m_wall_Pa_m : float
        Wall couple stress in Pa m (N/m) (only with a material).
    counters : dict
        Accepted/rejected steps and right-hand-side evaluations of both stages, and whether the
        stage-1 stiffness detector fired.
    profile : dict or None
        With ``profile=xi``: arrays ``xi``, ``u_over_u0``, ``omega_hat``, ``m`` (``m/nu``),
        ``sigma_xy``, ``sigma_yx`` (over nu).
    """

    eps: float
    L: float
    K: float
    A: float
    N: float
    status: st.Status
    Delta: float = math.nan
    xi_p: float = math.nan
    slip: float = math.nan
    u_axis: float = math.nan
    m_wall: float = math.nan
    sigma_yx_wall: float = math.nan
    xi_stop: float = math.nan
    nu: float = math.nan
    sigma_xx_wall_Pa: float = math.nan
    sigma_xy_wall_Pa: float = math.nan
    sigma_yx_wall_Pa: float = math.nan
    m_wall_Pa_m: float = math.nan
    counters: dict = field(default_factory=dict)
    profile: dict | None = None

    SCALARS = tuple(OUTPUTS)

    @property
    def ok(self) -> bool:
        return self.status == st.Status.ok

    def to_dict(self) -> dict:
        """A JSON-ready dict: parameters, status by name and message, outputs (NaN as None)."""

        def clean(x):
            return None if x is None or (isinstance(x, float) and not math.isfinite(x)) else x

        d = {"eps": self.eps, "L": self.L, "K": self.K, "A": self.A, "N": self.N}
        d["status"] = self.status.name
        d["message"] = self.status.message
        for k in self.SCALARS:
            d[k] = clean(float(getattr(self, k)))
        d["counters"] = dict(self.counters)
        if self.profile is not None:
            d["profile"] = {k: [clean(float(v)) for v in a] for k, a in self.profile.items()}
        return d


class Workspace:
    """Preallocated work arrays for :func:`solve_eta` (reuse one across many points)."""

    def __init__(self, max_steps_stage1=MAX_STEPS_STAGE1, max_steps_stage2=MAX_STEPS_STAGE2):
        self.ax = np.empty(N_AX)
        self.T1 = np.empty(max_steps_stage1 + 1)
        self.Q1 = np.empty((max_steps_stage1, 5, 1))
        self.T2 = np.empty(max_steps_stage2 + 1)
        self.Q2 = np.empty((max_steps_stage2, 5, 2))
        self.stats1 = np.zeros(rk45.N_STATS, dtype=np.int64)
        self.stats2 = np.zeros(rk45.N_STATS, dtype=np.int64)
        self.res = np.empty(N_R)

    def run(self, eta, A, N, rtol, atol, method=METHOD_AUTO):
        return solve_eta(
            eta, A, N, rtol, atol, self.ax, self.T1, self.Q1, self.T2, self.Q2,
            self.stats1, self.stats2, self.res, method,
        )


DEFAULT_RTOL = 1e-8
DEFAULT_ATOL = 1e-12


def solve_point(eps, L, K, A, N, *, rtol=DEFAULT_RTOL, atol=DEFAULT_ATOL, material=None, profile=None,
                workspace: Workspace | None = None) -> PointResult:
    """Solve one point ``(eps, L, K, A, N)`` of the channel-flow model through both stages.

    Parameters
    ----------
    eps, L, K, A, N : float
        The model's parameters (model.md): ``eps = d_p/W`` in (0, 1], ``L > 0``, ``K >= 0``,
        ``A`` real, ``N > 0``.
    rtol, atol : float
        Tolerances of both integrations (mixed relative/absolute error per step).
    material : mapping, optional
        ``d_p`` (m), ``rho_p`` (kg/m^3), ``phi`` (degrees), optionally ``g``, ``Lambda`` (Pa),
        ``nu_min``, ``nu_max``, ``p``, ``q``. Adds ``nu`` and the dimensional wall stresses.
    profile : array_like, optional
        ``xi`` values in [0, 1] at which to return u/u(0), omega_hat, m, sigma_xy and sigma_yx.

    Returns
    -------
    PointResult
        Never raises for a point the model has no solution at: the status says why.

    Raises
    ------
    ParameterError
        (a ``ValueError``) for input outside the domain, naming the parameter and its range.
    """
    eps, L, K, A, N = check_point(eps, L, K, A, N)
    rtol, atol = check_tolerances(rtol, atol)
    mat = check_material(material)
    xi_prof = None
    if profile is not None:
        xi_prof = np.atleast_1d(np.asarray(profile, dtype=float))
        if xi_prof.ndim != 1 or not np.all(np.isfinite(xi_prof)) or np.any((xi_prof < 0) | (xi_prof > 1)):
            raise ParameterError("profile must be xi values in [0, 1]")
    ws = workspace or Workspace()
    eta = eps * L
    code = ws.run(eta, A, N, rtol, atol)
    res = ws.res
    out = PointResult(eps=eps, L=L, K=K, A=A, N=N, status=st.Status(code))
    out.counters = _counters(ws)
    if code == st.EPS_TOO_LARGE_PATH:
        out.xi_stop = float(res[R_XI_STOP])
    if code == st.OK:
        eps_K = eps * K
        J_axis = float(res[R_J_AXIS])
        one_minus = float(one_minus_xi_p(A, N, eta, eps_K, res, ws.T2, ws.Q2))
        out.xi_p = 1.0 - one_minus
        out.Delta = one_minus / eps
        out.u_axis = eps_K + J_axis
        out.slip = eps_K / out.u_axis
        out.m_wall = L * float(res[R_MU_WALL])
        out.sigma_yx_wall = float(res[R_SIGMA_YX_WALL])
        if xi_prof is not None:
            out.profile = _profile(xi_prof, eps, L, K, A, N, ws)
    if mat is not None:
        _add_material(out, mat)
    return out


def _counters(ws: Workspace) -> dict:
    s1, s2 = ws.stats1, ws.stats2
    return {
        "stage1_accepted": int(s1[rk45.STAT_ACCEPTED]),
        "stage1_rejected": int(s1[rk45.STAT_REJECTED]),
        "stage1_fev": int(s1[rk45.STAT_FEV]),
        "stage1_stiff": bool(s1[rk45.STAT_STIFF]),
        "stage1_path": PATH_NAMES.get(float(ws.res[R_PATH]), "none"),
        "stage2_accepted": int(s2[rk45.STAT_ACCEPTED]),
        "stage2_rejected": int(s2[rk45.STAT_REJECTED]),
        "stage2_fev": int(s2[rk45.STAT_FEV]),
    }


def _add_material(out: PointResult, mat: dict) -> None:
    """Solids fraction (eq:35) and the dimensional wall stresses."""
    W = mat["d_p"] / out.eps
    tan_delta = math.sin(math.radians(mat["phi"])) / out.N
    rho_g_W = mat["rho_p"] * mat["g"] * W
    nu = model.solids_fraction(
        rho_g_W, tan_delta, mat["Lambda"], mat["nu_min"], mat["nu_max"], mat["p"], mat["q"]
    )
    out.nu = float(nu)
    scale = rho_g_W * nu  # Pa; sigma_bar * nu * rho_p g W
    out.sigma_xx_wall_Pa = scale / tan_delta  # eq:33 with eq:35: sigma_xx = sigma_c(nu)
    out.sigma_xy_wall_Pa = -scale  # eq:19 at the wall
    if out.ok:
        out.sigma_yx_wall_Pa = scale * out.sigma_yx_wall
        out.m_wall_Pa_m = scale * mat["d_p"] * out.m_wall


@njit(nogil=True, cache=True)
def profile_kernel(xis, eta, A, N, ax, res, T1, Q1, T2, Q2, out):
    """Profiles of one solved triple at ``xis``: rows ``P_J``, ``P_OMEGA_HAT``, ``P_DELTA``, ``P_SIGMA_YX``.

    ``u/u(0) = (eps K + J) / (eps K + J(0))`` for any K, so ``J`` is stored, not ``u``.
    A = -1 has no stage-1 output: there ``delta = 0`` and ``sigma_yx = -xi`` exactly (Appendix A),
    while ``J`` and ``omega_hat`` come from the stage-2 march as for every other A.
    """
    buf = np.empty(1)
    yb = np.empty(2)
    xi1 = res[R_XI1]
    n1 = int(res[R_N1])
    n2 = int(res[R_N2])
    t_tail = res[R_T_TAIL]
    J_axis = res[R_J_AXIS]
    # Below where stage 2 stopped, omega_hat ~ xi^beta (Appendix B) and J has converged.
    dense.dense_eval(T2, Q2, n2, t_tail, yb)
    logw_tail = yb[0]
    for i in range(xis.size):
        xi = xis[i]
        t = math.log(xi) if xi > 0.0 else -math.inf
        if t >= t_tail:
            dense.dense_eval(T2, Q2, n2, t, yb)
            logw = yb[0]
            J = yb[1]
        else:
            logw = logw_tail + ax[AX_BETA] * (t - t_tail)
            J = J_axis
        out[P_J, i] = J
        out[P_OMEGA_HAT, i] = math.exp(logw)
        if A == -1.0:
            out[P_DELTA, i] = 0.0  # m = -N L
            out[P_SIGMA_YX, i] = -xi
        else:
            delta = _delta_at(xi, xi1, ax, T1, Q1, n1, buf)
            D = model.yield_D(xi, delta, A, N, ax)
            out[P_DELTA, i] = delta
            out[P_SIGMA_YX, i] = model.sigma_yx(xi, D, A)


def _profile(xi, eps, L, K, A, N, ws: Workspace) -> dict:
    eta = eps * L
    eps_K = eps * K
    out = np.empty((N_PROF, xi.size))
    profile_kernel(xi, eta, A, N, ws.ax, ws.res, ws.T1, ws.Q1, ws.T2, ws.Q2, out)
    J_axis = ws.res[R_J_AXIS]
    return {
        "xi": xi.copy(),
        "u_over_u0": (eps_K + out[P_J]) / (eps_K + J_axis),
        "omega_hat": out[P_OMEGA_HAT],
        "m": L * (out[P_DELTA] - N),
        "sigma_xy": -xi,
        "sigma_yx": out[P_SIGMA_YX],
    }
