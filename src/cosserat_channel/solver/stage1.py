"""Stage 1: the scaled couple stress ``delta`` from the axis to the wall (or to ``D = 0``).

``w = delta / xi^2`` (see :mod:`cosserat_channel.physics.model`) starts on the axis series as far
out as it is accurate and is marched to the wall with Dormand-Prince 5(4), DOP853 (rtol <=
:data:`DOP853_RTOL`) or RODAS4P2 where what is left is stiff (:func:`use_stiff_path`), stopping
where the stress path leaves the yield-admissible region. Depends on ``(eta = eps L, A, N)`` only.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE
from .. import status as st
from ..integrate import stepping, dense, dop853, rk45, rosenbrock
from ..physics import model
from ..physics.model import AX_BETA, AX_C0
from .layout import (METHOD_AUTO, METHOD_STIFF, PATH_EXPLICIT, PATH_NONE,
                     PATH_STIFF, R_MU_WALL, R_N1, R_PATH, R_RTOL1, R_SIGMA_YX_WALL,
                     R_STATUS, R_XI1, R_XI_STOP, N_R, R_N2)
from .stress_path import _delta_wall

# Work budgets per stage: bounded work per point (a point that needs more is reported as
# integration_failed, never left running).
MAX_STEPS_STAGE1 = 200_000
# Passes that re-march the step where stage 1 met D = 0 (see solve_eta), each within a budget.
EVENT_REFINEMENTS = 4
# Stage 1 ends a step at xi = N (N < 1) unless N is this close to its start or to the wall.
SPLIT_MARGIN = 1e-6
REFINE_MAX_STEPS = 400
# At and below this rtol the explicit path marches with DOP853 instead of Dormand-Prince 5(4).
# On the work-precision set, at the same rtol, it takes about as many evaluations (15 per step
# with its dense output, against 6) and m_wall comes out 2-14x, Delta 1.5-4x more accurate; both
# stages cost the same from 1e-4 to 1e-6 and 4-25 % less from 1e-7 to 1e-10
# (benchmarks/probes/probe_high_order.py, docs/performance.md). Dormand-Prince stays the default where
# the two cost the same.
DOP853_RTOL = 1e-6
# Next to the path edge (the conditioning re-march of solve_stage1) D(1) is small and the
# solution has a near-singularity just beyond the wall: one DOP853 step across the whole stretch
# is good at its end but not inside, where stage 2 reads its interpolant and no error estimate
# controls it (Delta 6e-3 off at rtol 1e-4 at eta = 3.48, A = -0.1, N = 2.29). The re-march caps
# its steps at this fraction of the stretch; capping every march costs 30 % of stage 1 on
# bench_point's grid, where the error does not arise.
EDGE_MAX_STEP = 0.25
# DOP853's error estimate can miss the error of one step across the whole stretch from the
# series start (where the first step's guess, xi1 clipped to the stretch, puts it): on
# bench_point's grid at rtol 1e-6 such a step left J(0) up to 300 rtol off (m_wall 16 rtol),
# half the stretch 0.2 rtol (0.1). A step longer than this fraction of the stretch is kept only
# where its interpolant's defect at the step's middle passes the tolerance (_march_dop853);
# else the stretch is marched again in steps of at most this fraction.
DOP853_MAX_STEP = 0.5
# The defect d = u' - f(u) of a step's interpolant, h d times this, is its error estimate there.
DEFECT_WEIGHT = 0.25
STAGE1_RTOL_FLOOR = 1e-13
# D(1) below this many rtol-sized errors of D is zero within stage 1's resolution (solve_eta).
WALL_D_RESOLUTION = 0.1
# ... and when stage 2 fails with D(1) below this many, the dense output's error decides (see there).
WALL_D_FALLBACK = 1e5
# Stage 1 switches to RODAS4P2 when the stiffness left to march exceeds a threshold (see
# use_stiff_path, benchmarks/probes/probe_stiff_switch.py): against Dormand-Prince (rtol > DOP853_RTOL)
# this times sqrt(1e-6/rtol) ...
STIFF_LAMBDA = 20.0
# ... against DOP853 this times (1e-6/rtol)^(1/4) / max(N - 1, STIFF_N_MARGIN), where the axis is
# far from its edge, and without the N factor next to it.
STIFF_LAMBDA_DOP853 = 4.0
STIFF_N_MARGIN = 5e-3
# Where the wall sits at the end of the slow manifold delta = N - sqrt(N^2 - xi^2) (N close to 1,
# small eta), the outputs read N - delta, not delta: m_wall = L (delta - N), and stage 2's spin
# rate B ~ N - delta. There the stiff path's error in w, controlled relative to w, is amplified
# by kappa = |delta(1)| / |delta(1) - N| (up to ~500), and on top RODAS4P2's embedded estimate
# misses the local error up to ~10x in the last steps of the turn, where h |df/dw| falls through
# 10..4 and the manifold's sqrt(N^2 - xi^2) singularity is within a step: at rtol 1e-6 Delta came
# out 80-2000 rtol off from eta = 1e-8 to 1e-4 (A = 1/3, N = 1). Where kappa exceeds TURN_KAPPA,
# the turn (the steps where |N - delta| is below TURN_SPAN times its wall value) is marched again
# at rtol1 * TURN_COND / kappa; errors made before it are damped on the stiff manifold
# (benchmarks/probes/probe_turn.py: worst output 14 rtol from 2000, at 1.4x the stage-1 steps
# of the points it applies to).
TURN_KAPPA = 8.0
TURN_SPAN = 3.0
TURN_COND = 4.0




@njit(**_JIT)
def stage1_arrays(max_steps):
    """``(T1, Q1)``: room for stage 1's dense output of at most ``max_steps`` steps."""
    return np.empty(max_steps + 1), np.empty((max_steps, dense.N_DENSE, 1))

# ---------------------------------------------------------------------------------------------
# Right-hand sides and events in the integrator's calling convention
# ---------------------------------------------------------------------------------------------
@njit(**_JIT)
def _stage1_rhs(xi, y, args, out):
    # The state is w = delta / xi^2 (see model.dw_dxi).
    eta, A, N, ax = args
    out[0] = model.dw_dxi(xi, y[0], eta, A, N, ax)


@njit(**_JIT)
def _stage1_jac(xi, y, args):
    eta, A, N, ax = args
    return model.dw_dxi_jacobian(xi, y[0], eta, A, N, ax)


@njit(**_JIT)
def _stage1_event(xi, y, args):
    # D = 0: the stress path leaves the yield-admissible region (Appendix A).
    eta, A, N, ax = args
    return model.yield_D(xi, xi * xi * y[0], A, N, ax)




# ---------------------------------------------------------------------------------------------
# The kernel for one (eta, A, N)
# ---------------------------------------------------------------------------------------------
@njit(**_JIT_INLINE)
def use_stiff_path(eta, A, N, ax, xi1, rtol1):
    """Whether stage 1 should take the stiff path (RODAS4P2, the Jacobian known in closed form).

    The Jacobian is ``-B - 2/xi`` in ``w``: about ``-2/eta`` in the interior and ``-(beta + 2)/xi``
    near the axis, where ``beta`` is large for small eta and next to the axis edge. An explicit
    method is held to ``h < 3.3/|lambda|`` (Dormand-Prince; DOP853 ``6/|lambda|``) by stability,
    so over what is left to march from ``xi1`` it needs about ``x = (1 - xi1) max(2/eta,
    beta/xi1)`` steps (up to that factor) whatever the tolerance, while the steps that accuracy
    asks for grow as rtol shrinks, like ``rtol^(-1/4)`` for RODAS4P2 (order 4), more slowly for
    the explicit pairs. RODAS4P2 is taken where ``x`` exceeds a threshold:

    - rtol > ``DOP853_RTOL`` (explicit path Dormand-Prince): ``STIFF_LAMBDA sqrt(1e-6/rtol1)``.
    - rtol <= ``DOP853_RTOL`` (DOP853): ``STIFF_LAMBDA_DOP853 (1e-6/rtol1)^(1/4) / max(N - 1,
      STIFF_N_MARGIN)``. For small eta the path follows the slow manifold
      ``delta = N - sqrt(N^2 - xi^2)``, which ends at ``xi = N``; the closer N is to 1 (or below
      it, where the path turns there or meets D = 0 just after), the more of the march resolves
      a fast turn rather than a stiff slow manifold, where the 8th-order explicit pair takes
      fewer steps than RODAS4P2, and stage 2 more panels on RODAS4P2's 3rd-order dense output.
      Next to the axis edge (``c0 < (A+1)/2``, i.e. ``beta > 4N/eta``; elsewhere ``beta ~ 2N/eta``
      for small eta) the stiffness sits at the axis, not on the manifold, and the N factor is
      left out.

    The thresholds are calibrated by ``benchmarks/probes/probe_stiff_switch.py`` (both paths
    forced; CPU time of both stages): at rtol 1e-8 the crossover in ``x`` lies at 880-2080 for N
    in (0.9, 1], 110-340 for N in (1.05, 1.1], 21-87 for N in (1.2, 1.5] and 4-25 for N in
    (2, 3], and grows about 10x from rtol 1e-6 to 1e-10. With this rule each probe set costs
    0-6 % more than the better path for every point (docs/performance.md has the table).
    """
    lam = max(2.0 / eta, ax[AX_BETA] / xi1)
    x = (1.0 - xi1) * lam
    if rtol1 > DOP853_RTOL:
        return x > STIFF_LAMBDA * math.sqrt(1e-6 / rtol1)
    threshold = STIFF_LAMBDA_DOP853 * (1e-6 / rtol1) ** 0.25
    if ax[AX_C0] > 0.5 * (A + 1.0):
        threshold /= max(N - 1.0, STIFF_N_MARGIN)
    return x > threshold


@njit(**_JIT_INLINE)
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


# Each integrator's march is a kernel of its own, and the kernels above them take two flags,
# each None or True, that leave integrators out of what they compile (Numba drops a branch on
# ``flag is None`` when it compiles): ``tight=True`` for a run whose rtol never exceeds
# DOP853_RTOL (stage 1 only tightens it), which never marches with Dormand-Prince, and
# ``explicit=True`` for a kernel without RODAS4P2, which returns STIFF_NOT_COMPILED instead of
# marching a point that takes the stiff path (batch.solve_eta_auto then calls one with it).
STIFF_NOT_COMPILED = -1


@njit(**_JIT)
def _march_dopri5(xi0, y0, xi_end, h0, h_max, args1, rtol, atol1, T1, Q1, stats1):
    # The explicit pairs check their first step against the exact |df/dw| at the start (later
    # steps against their own estimate): a first step of xi1, or half the stretch, is often far
    # beyond their stability boundary, where their error estimate can vanish (stepping's
    # beyond_stability).
    rho0 = abs(_stage1_jac(xi0, y0, args1)[0])
    return rk45.dopri5(_stage1_rhs, _stage1_event, xi0, y0, xi_end, args1, rtol, atol1, h0, h_max,
                       T1, Q1, stats1, rho0)


@njit(**_JIT_INLINE)
def _long_step_defect(xi0, xi_end, args1, rtol, atol1, T1, Q1, n):
    # (evaluations, whether a step longer than DOP853_MAX_STEP of the stretch has an
    # interpolant whose defect at its middle exceeds the tolerance): one evaluation of the
    # right-hand side per such step.
    evals = 0
    cap = DOP853_MAX_STEP * (xi_end - xi0)
    f = np.empty(1)
    y = np.empty(1)
    for k in range(n):
        h = T1[k + 1] - T1[k]
        if not h > cap:
            continue
        mid = T1[k] + 0.5 * h
        y[0] = dense.step_value(T1, Q1, k, 0, mid)
        _stage1_rhs(mid, y, args1, f)
        evals += 1
        err = DEFECT_WEIGHT * h * abs(dense.step_slope(T1, Q1, k, 0, mid) - f[0])
        if not err <= atol1[0] + rtol * abs(y[0]):
            return evals, True
    return evals, False


@njit(**_JIT)
def _dop853_run(xi0, y0, xi_end, h0, h_max, args1, rtol, atol1, T1, Q1, stats1, rho0):
    # One DOP853 run of stage 1. A kernel of its own, called (not inlined) by _march_dop853's
    # three runs: each inlined copy of the integrator is typed and optimised again, about a
    # third of the first point's compilation each.
    return dop853.dop853(_stage1_rhs, _stage1_event, xi0, y0, xi_end, args1, rtol, atol1, h0,
                         h_max, T1, Q1, stats1, rho0)


@njit(**_JIT)
def _march_dop853(xi0, y0, xi_end, h0, h_max, args1, rtol, atol1, T1, Q1, stats1):
    rho0 = abs(_stage1_jac(xi0, y0, args1)[0])  # as in _march_dopri5
    cap = DOP853_MAX_STEP * (xi_end - xi0)
    if 0.0 < h_max < cap:
        return _dop853_run(xi0, y0, xi_end, h0, h_max, args1, rtol, atol1, T1, Q1, stats1, rho0)
    s, n, t = _dop853_run(xi0, y0, xi_end, h0, h_max, args1, rtol, atol1, T1, Q1, stats1, rho0)
    if not (s == stepping.SUCCESS or s == stepping.EVENT):
        return s, n, t
    evals, bad = _long_step_defect(xi0, xi_end, args1, rtol, atol1, T1, Q1, n)
    stats1[stepping.STAT_FEV] += evals
    if not bad:
        return s, n, t
    spent = stats1.copy()
    s, n, t = _dop853_run(xi0, y0, xi_end, h0, cap, args1, rtol, atol1, T1, Q1, stats1, rho0)
    for i in range(stepping.STAT_STIFF):
        stats1[i] += spent[i]
    return s, n, t


@njit(**_JIT)
def _march_rodas(xi0, y0, xi_end, h0, h_max, args1, rtol, atol1, T1, Q1, stats1):
    return rosenbrock.rodas4(_stage1_rhs, _stage1_jac, _stage1_event, xi0, y0, xi_end, args1,
                             rtol, atol1, h0, h_max, T1, Q1, stats1)


@njit(**_JIT)
def _turn_remarch(args1, rtol1, rtol, atol, T1, Q1, n1, kappa, mu_wall, stats1):
    """The stiff path's turn onto the wall marched again (see ``TURN_KAPPA``): from the last
    step start where ``|N - delta|`` is at least ``TURN_SPAN`` times ``mu_wall = |delta(1) - N|``,
    at ``rtol1 * TURN_COND / kappa``, into the same dense output. Returns what
    :func:`_stage1_pass` does."""
    N = args1[2]
    k0 = n1 - 1
    while k0 > 0 and abs(N - T1[k0] * T1[k0] * Q1[k0, 0, 0]) < TURN_SPAN * mu_wall:
        k0 -= 1
    rtol_leg = max(STAGE1_RTOL_FLOOR, rtol1 * TURN_COND / kappa)
    atol_leg = np.empty(1)
    atol_leg[0] = atol * min(1.0, rtol_leg / rtol)
    y0 = np.empty(1)
    y0[0] = Q1[k0, 0, 0]
    stats_r = np.zeros_like(stats1)
    s, nb, t = _march_rodas(T1[k0], y0, 1.0, 0.0, 0.0, args1, rtol_leg, atol_leg, T1[k0:],
                            Q1[k0:], stats_r)
    _add_stats(stats1, stats_r)
    return s, k0 + nb, t


@njit(**_JIT_INLINE)
def _march_stage1(tight, explicit, stiff, xi0, y0, xi_end, h0, h_max, args1, rtol, atol1, T1, Q1,
                  stats1):
    # The only place that picks stage 1's integrator; all write the same dense-output layout.
    # (With explicit=True, stiff is False here: solve_stage1_with returned before.)
    if explicit is None and stiff:
        return _march_rodas(xi0, y0, xi_end, h0, h_max, args1, rtol, atol1, T1, Q1, stats1)
    if tight is None and not rtol <= DOP853_RTOL:
        return _march_dopri5(xi0, y0, xi_end, h0, h_max, args1, rtol, atol1, T1, Q1, stats1)
    return _march_dop853(xi0, y0, xi_end, h0, h_max, args1, rtol, atol1, T1, Q1, stats1)


@njit(**_JIT_INLINE)
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


@njit(**_JIT_INLINE)
def start_xi(ax):
    """Next to the axis, where two terms of the axis series are exact to round-off: the neglected
    O(xi^6) term is far below it, scaled with ``c0`` because the series' radius shrinks at the axis
    edge. The floor of :func:`stage1_start`."""
    return 1e-3 * min(1.0, ax[AX_C0])


@njit(**_JIT)
def ivp_start(ax):
    """Stage 1 as a plain initial value problem: ``(xi1, w(xi1))`` next to the axis (:func:`start_xi`).

    ``ax`` holds :func:`model.axis_constants` of the point. The set-up the benchmarks give every
    peer ODE solver, and the scipy references of the tests: they march the whole of stage 1,
    where our own solve starts from the series as far out as it is accurate (:func:`stage1_start`).
    """
    xi1 = start_xi(ax)
    return xi1, model.w_axis_series(xi1, ax)


# The march starts where the axis series is good to this fraction of stage 1's rtol ...
SERIES_TOL = 1e-2
# ... but never beyond this xi: the last stretch, where D(1) may be tiny, is always marched.
XI_SERIES_MAX = 0.9


@njit(**_JIT)
def stage1_start(ax, rtol1):
    """Where and with what value our stage-1 march starts: ``(xi1, w(xi1))`` from the axis series.

    As far out as the series of :func:`model.axis_series` is good to ``SERIES_TOL * rtol1``
    (:func:`model.series_reach`), never beyond ``XI_SERIES_MAX`` nor closer to the axis than
    :func:`start_xi`. Near the axis stage 1 is a regular singular point (Jacobian ``-(beta+2)/xi``)
    where any ODE solver takes geometric steps in xi: 40-60 % of the steps before this start.
    """
    xi1 = max(start_xi(ax), model.series_reach(ax, SERIES_TOL * rtol1, XI_SERIES_MAX))
    return xi1, model.w_axis_series(xi1, ax)


@njit(**_JIT_INLINE)
def _stage1_from_series(tight, explicit, stiff, ax, args1, rtol1, atol1, T1, Q1, stats1, res,
                        max_step):
    """Stage 1 marched again at a tighter ``rtol1``, from where the axis series is good to it
    (:func:`stage1_start`, which moves closer to the axis); records that start in ``res[R_XI1]``.
    Returns what :func:`_stage1_pass` does (``max_step`` as there).

    Inlined, and every call passes ``max_step``: a kernel of its own, or a default left out,
    is one more specialisation whose compilation re-optimises all of stage 1's integrators
    that it links (about 4 s of the first run's compilation)."""
    xi1, w1 = stage1_start(ax, rtol1)
    res[R_XI1] = xi1
    return _stage1_pass(tight, explicit, stiff, xi1, w1, args1, rtol1, atol1, T1, Q1, stats1,
                        max_step)


@njit(**_JIT_INLINE)
def _add_stats(stats, more):
    for i in range(stepping.STAT_STIFF):
        stats[i] += more[i]
    stats[stepping.STAT_STIFF] = max(stats[stepping.STAT_STIFF], more[stepping.STAT_STIFF])


@njit(**_JIT)
def _stage1_pass(tight, explicit, stiff, xi1, w1, args1, rtol1, atol1, T1, Q1, stats1, max_step):
    """Stage 1 from the axis series to the wall or to D = 0; counters are added to ``stats1``.
    ``max_step > 0`` caps each step at that fraction of the stretch it marches.

    Where the path meets D = 0, sqrt(D) ~ sqrt(xi_stop - xi): the RHS has a kink that the last
    (wide, error-controlled) step glides over, so the dense output locates xi_stop only to ~1e-4.
    That last step is marched again with steps 1/16 as wide, until the location settles.
    """
    y0 = np.empty(1)
    y0[0] = w1
    stats_r = np.zeros_like(stats1)
    eta, A, N, ax = args1
    # For N < 1 the slow manifold w ~ sqrt(N^2 - xi^2) ends at xi = N, and a path that survives it
    # turns there on a short scale; at loose rtol a wide step glided over that turn (m_wall 1.3e-2
    # off at rtol 1e-4 for eta = 1.2e-3, A = 3.75, N = 0.993). A step boundary at xi = N, and a
    # fresh step-size start after it, resolve it for two more steps (not within a hair of either
    # end, where a leg would be shorter than a step can be).
    split = xi1 + SPLIT_MARGIN < N < 1.0 - SPLIT_MARGIN
    # First step = xi1: off the axis the solution varies on the scale of xi itself, and the
    # generic first-step guesses (built on |f|, which is tiny there) jump far too far.
    end = N if split else 1.0
    s1, n1, t1 = _march_stage1(tight, explicit, stiff, xi1, y0, end, xi1, max_step * (end - xi1),
                               args1, rtol1, atol1, T1, Q1, stats_r)
    _add_stats(stats1, stats_r)
    if split and s1 == stepping.SUCCESS and n1 > 0:
        y0[0] = Q1[n1 - 1, 0, 0] + Q1[n1 - 1, 1, 0]  # w(N): the last step's end
        s1, n_more, t1 = _march_stage1(tight, explicit, stiff, N, y0, 1.0, 0.0,
                                       max_step * (1.0 - N), args1, rtol1, atol1, T1[n1:], Q1[n1:],
                                       stats_r)
        n1 += n_more
        _add_stats(stats1, stats_r)
    for _ in range(EVENT_REFINEMENTS):
        if s1 != stepping.EVENT:
            break
        k = n1 - 1
        span = t1 - T1[k]
        if not span > 0.0:
            break
        y0[0] = Q1[k, 0, 0]
        stop = min(Q1.shape[0], k + REFINE_MAX_STEPS)
        s_new, nb, t_new = _march_stage1(tight, explicit, stiff, T1[k], y0, 1.0, span / 16.0,
                                         span / 16.0, args1, rtol1, atol1, T1[k:stop + 1],
                                         Q1[k:stop], stats_r)
        _add_stats(stats1, stats_r)
        n1 = k + nb
        if s_new == stepping.SUCCESS:
            # With finer steps the path reaches the wall: the crossing was the interpolant's.
            s1 = s_new
            t1 = t_new
            break
        if s_new != stepping.EVENT:
            # Budget spent crawling into the sqrt kink (D ~ 0 over a long stretch, next to the
            # axis edge): keep the previous location, good to the last pass's step width.
            break
        settled = abs(t_new - t1) <= rtol1 * t1
        t1 = t_new
        if settled:
            break
    return s1, n1, t1


@njit(**_JIT_INLINE)
def _path_end_bound(xi, eta, A, N):
    """An upper bound on where a stage-1 path that exists at ``xi > N`` meets ``D = 0`` (A > -1).

    Over delta, ``D`` is largest at ``delta = N``: ``D <= (A^2-1) xi^2 + 2(A+1) N^2``, which is
    below ``((A+1) xi)^2`` exactly when ``xi > N``. There ``eta delta' = (A+1) xi - sqrt(D)`` is at
    least ``gap(xi) = (A+1) xi - sqrt((A^2-1) xi^2 + 2(A+1) N^2) > 0`` wherever the path exists,
    and ``gap`` grows with xi; ``D >= 0`` keeps delta in ``N +- sqrt(N^2 + (A-1) xi^2/2)``, a band
    narrower than ``W = 2 sqrt(N^2 + max(A-1, 0)/2)``. So delta crosses the band, i.e. the path
    meets D = 0, before ``xi + eta W / gap(xi)``. Returns inf where ``xi <= N`` (no bound).
    """
    if not xi > N:
        return math.inf
    a1 = A + 1.0
    gap = a1 * xi - math.sqrt(max((A * A - 1.0) * xi * xi + 2.0 * a1 * N * N, 0.0))
    if not gap > 0.0:
        return math.inf
    W = 2.0 * math.sqrt(N * N + 0.5 * max(A - 1.0, 0.0))
    return xi + eta * W / gap


@njit(**_JIT_INLINE)
def path_must_end(xi, eta, A, N):
    """Whether every stage-1 path that reaches ``xi`` meets ``D = 0`` before the wall (A > -1).

    True when :func:`_path_end_bound` is below 1 at ``xi`` or at some ``xi' > max(xi, N)``
    (tried on 16 points up to the wall): a path that reaches ``xi'`` ends before that bound, and
    one that does not reach it has ended already. Needs ``N < 1`` and a small enough eta.
    """
    if not N < 1.0:
        return False
    if _path_end_bound(xi, eta, A, N) < 1.0:
        return True
    lo = max(xi, N)
    for k in range(1, 16):
        if _path_end_bound(lo + (1.0 - lo) * k / 16.0, eta, A, N) < 1.0:
            return True
    return False


@njit(**_JIT_INLINE)
def _wall_D_sensitivity(A, N, delta_wall):
    """``|dD/d delta| delta`` at the wall: what a relative error in delta does to D(1)."""
    return 4.0 * (A + 1.0) * abs(N - delta_wall) * abs(delta_wall)


@njit(**_JIT_INLINE)
def _wall_values(T1, Q1, n1, A, N, ax, buf):
    """``(delta(1), D(1), sensitivity)`` of a march that reached the wall: what decides its
    status and its conditioning (``sensitivity``: :func:`_wall_D_sensitivity`)."""
    delta_wall = _delta_wall(T1, Q1, n1, buf)
    return (delta_wall, model.yield_D(1.0, delta_wall, A, N, ax),
            _wall_D_sensitivity(A, N, delta_wall))


@njit(**_JIT_INLINE)
def solve_stage1(eta, A, N, rtol, atol, ax, T1, Q1, stats1, res, method=METHOD_AUTO):
    """Stage 1 for one ``(eta, A, N)``: the regime, the march from the axis and the wall values.

    Fills ``res`` (all ``R_*`` slots reset; stage 1 sets ``R_STATUS``, ``R_XI_STOP``, ``R_XI1``,
    ``R_N1``, ``R_PATH``, ``R_MU_WALL``, ``R_SIGMA_YX_WALL``), the axis constants ``ax``, the dense
    output (T1, Q1) and ``stats1``. Returns ``(status, near_edge)``: ``near_edge`` says D(1) lies
    within ``WALL_D_FALLBACK`` resolutions of zero, where a stage-2 failure means D(1) = 0 within
    the dense output's resolution (see :func:`solve_eta`).
    """
    return solve_stage1_with(None, None, eta, A, N, rtol, atol, ax, T1, Q1, stats1, res, method)


@njit(**_JIT)
def solve_stage1_with(tight, explicit, eta, A, N, rtol, atol, ax, T1, Q1, stats1, res, method):
    """:func:`solve_stage1` compiled without Dormand-Prince (``tight=True``, for ``rtol <=
    DOP853_RTOL`` only) or RODAS4P2 (``explicit=True``: returns ``(STIFF_NOT_COMPILED, False)``
    for a point that takes the stiff path), with them where the flag is None."""
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
        # and h = 2 (see _node_rates); beta = c is the exact spin exponent for the profiles.
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
    # Next to the axis edge D/xi^2 ~ c0^2 is the small difference that decides where the path
    # meets D = 0; an error in w of rtol would swamp it, so stage 1 runs at rtol ~ c0^2/1000 there.
    rtol1 = stage1_rtol(rtol, A, N, ax)
    buf = np.empty(1)
    atol1 = np.empty(1)
    # Where stage 1 runs tighter than asked (here and in the re-marches below) the reason is a
    # small difference that decides the outputs, so the absolute floor tightens with it: held at
    # the user's atol it capped w's accuracy (1e-12 absolute against 1e-13 asked) and left
    # Delta 2e-7 off next to the path edge (docs/work_precision.md).
    atol1[0] = atol * min(1.0, rtol1 / rtol)
    args1 = (eta, A, N, ax)
    xi1, w1 = stage1_start(ax, rtol1)
    res[R_XI1] = xi1
    stiff = (use_stiff_path(eta, A, N, ax, xi1, rtol1) if method == METHOD_AUTO
             else method == METHOD_STIFF)
    if explicit is not None and stiff:
        return STIFF_NOT_COMPILED, False
    res[R_PATH] = PATH_STIFF if stiff else PATH_EXPLICIT
    s1, n1, t1 = _stage1_pass(tight, explicit, stiff, xi1, w1, args1, rtol1, atol1, T1, Q1, stats1,
                              0.0)
    if s1 == stepping.EVENT and rtol1 > STAGE1_RTOL_FLOOR:
        # Where the path meets D = 0, D often falls to zero nearly tangentially (D ~ (xi_stop -
        # xi)^2 over the last percent), so xi_stop moves by ~sqrt(the error of D): 2.6e-4 at
        # rtol 1e-8 for eps L = 3.8, A = 1/3, N = 1, from the few wide steps of a march that
        # starts on the axis series. The status is certain; for xi_stop, march again 1000x tighter.
        rtol1 = max(STAGE1_RTOL_FLOOR, 1e-3 * rtol1)
        atol1[0] = atol * min(1.0, rtol1 / rtol)
        s1, n1, t1 = _stage1_from_series(tight, explicit, stiff, ax, args1, rtol1, atol1, T1, Q1,
                                         stats1, res, 0.0)
    if s1 == stepping.SUCCESS:
        delta_wall, D_wall, sensitivity = _wall_values(T1, Q1, n1, A, N, ax, buf)
        # Near the path edge D(1) is small and Delta, sigma_yx(1) and stage 2 (B ~ 1/sqrt(D))
        # depend on D(1) with condition ~ sensitivity / D(1): an error rtol1 in delta is an error
        # rtol1 * sensitivity in D. March stage 1 once more at rtol * D(1)/sensitivity so that
        # D(1), hence Delta, is good to ~rtol (a single march leaves near-edge points at rtol
        # 1e-5 up to 28 % off in Delta; see docs/work_precision.md).
        rtol_cond = rtol * D_wall / sensitivity if sensitivity > 0.0 else rtol1
        if D_wall > 0.0 and rtol_cond < 0.5 * rtol1 and rtol1 > STAGE1_RTOL_FLOOR:
            rtol1 = max(STAGE1_RTOL_FLOOR, rtol_cond)
            atol1[0] = atol * min(1.0, rtol1 / rtol)
            s1, n1, t1 = _stage1_from_series(tight, explicit, stiff, ax, args1, rtol1, atol1, T1,
                                             Q1, stats1, res, EDGE_MAX_STEP)
            if s1 == stepping.SUCCESS:
                delta_wall, D_wall, sensitivity = _wall_values(T1, Q1, n1, A, N, ax, buf)
    if explicit is None and stiff and s1 == stepping.SUCCESS and rtol1 > STAGE1_RTOL_FLOOR:
        mu_wall = abs(delta_wall - N)
        kappa = abs(delta_wall) / mu_wall if mu_wall > 0.0 else math.inf
        if kappa > TURN_KAPPA:
            s1, n1, t1 = _turn_remarch(args1, rtol1, rtol, atol, T1, Q1, n1, kappa, mu_wall,
                                       stats1)
            if s1 == stepping.SUCCESS:
                delta_wall, D_wall, sensitivity = _wall_values(T1, Q1, n1, A, N, ax, buf)
    res[R_N1] = n1
    if s1 == stepping.EVENT:
        res[R_STATUS] = st.EPS_TOO_LARGE_PATH
        res[R_XI_STOP] = t1
        return st.EPS_TOO_LARGE_PATH, False
    if s1 != stepping.SUCCESS:
        # The march gave up (step size or budget). For N < 1 and small eta that happens in the
        # fast jump to D = 0 just after xi = N (or crawling along the sqrt(N^2 - xi^2) kink of
        # the slow manifold before it, or at a start inside the series' radius ~N), where the
        # status is certain without the march: see path_must_end.
        xi_s = T1[n1] if n1 > 0 else res[R_XI1]
        if path_must_end(xi_s, eta, A, N):
            res[R_STATUS] = st.EPS_TOO_LARGE_PATH
            # Where: within eta W / gap of xi_s when the march got past N, else not resolved.
            res[R_XI_STOP] = xi_s if _path_end_bound(xi_s, eta, A, N) < 1.0 else math.nan
            return st.EPS_TOO_LARGE_PATH, False
        res[R_STATUS] = st.INTEGRATION_FAILED
        return st.INTEGRATION_FAILED, False
    # Stage 1 resolves delta to ~rtol1 |delta|, hence D(1) to ~rtol1 * sensitivity: a D(1) well
    # below that is zero within what stage 1 resolves (stage 2 would march B ~ 1/sqrt(D) on the
    # integration error of delta), so such a point is reported as reaching D = 0 at the wall, like
    # D(1) <= 0 itself. The stage-2 fallback in solve_eta catches what this cheap cut lets through.
    # Next to a tangential edge D(1) grows like (eta_max - eta)^2, so this band is ~sqrt(D
    # resolution) wide in eta (~5e-7 relative at A = 0, N = 2), where the status flips on
    # isolated points; regimes.trace_edge therefore places such an edge by the closed form of
    # the node it is (regimes.node_edge_eta), not by bisecting the status.
    D_resolution = WALL_D_RESOLUTION * rtol1 * sensitivity
    if not D_wall > D_resolution:
        res[R_STATUS] = st.EPS_TOO_LARGE_PATH
        res[R_XI_STOP] = 1.0
        return st.EPS_TOO_LARGE_PATH, False
    res[R_MU_WALL] = delta_wall - N
    res[R_SIGMA_YX_WALL] = model.sigma_yx(1.0, D_wall, A)
    res[R_RTOL1] = rtol1
    return st.OK, D_wall < WALL_D_FALLBACK * D_resolution


