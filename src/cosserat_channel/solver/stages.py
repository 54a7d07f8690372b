"""The Numba kernels of one solve: the only module that joins the physics and the integrator.

Stage 1 marches the scaled couple stress ``delta`` (see :mod:`cosserat_channel.physics.model`) from the
axis series to the wall with :func:`rk45.dopri5` (or RODAS4P2 where stiff), stopping at ``D = 0``
if the stress path leaves the yield-admissible region. Stage 2 integrates ``(log omega_hat, J)``
from the wall towards the axis on the dense output of stage 1, as the nested quadrature of
:mod:`.panels` on Chebyshev panels, and stops once what is left of ``J`` is below the tolerance or
the closed form of :func:`model.stage2_series` takes over; near the wall it evaluates ``D`` as
``D(1)`` plus an increment (:func:`_wall_form`), so that ``B ~ 1/sqrt(D)`` stays smooth where
``D(1)`` is tiny, next to the edge of solvability. Both
stages depend on ``(eta = eps L, A, N)`` only (the similarity of model.md); ``eps`` and ``K``
enter afterwards, through ``eps K`` in the plug-edge condition eq:13, so one integration serves a
whole ``K`` axis.

The kernels report through a small float vector per ``(eta, A, N)`` (the ``R_*`` slots) and dense
outputs; :mod:`cosserat_channel.outputs` turns those into what users read, and
:mod:`cosserat_channel.solver.point` is the Python API. This module is long because stage 1, stage 2,
the plug-edge root and the batch kernels share that slot layout and Numba inlines them into one
another; each function is short.
"""

from __future__ import annotations

import math
import numpy as np
from numba import njit
from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE

from ..integrate import dense
from ..integrate import dop853
from ..physics import model
from ..integrate import panels
from ..integrate import rk45
from ..integrate import roots
from ..integrate import rosenbrock
from .. import status as st
from ..physics.model import AX_BETA, AX_C0, N_AX
from ..integrate.stepping import EPS as _EPS

# The stage-2 rates and the lookups in stage 1's dense output are inlined into the stage-2 panels:
# as separate functions, each call passing the dense-output arrays cost reference-count updates.

# Work budgets per stage: bounded work per point (a point that needs more is reported as
# integration_failed, never left running).
MAX_STEPS_STAGE1 = 200_000
MAX_STEPS_STAGE2 = 20_000  # panels
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
# solution has a near-singularity just beyond the wall; there DOP853 crossed the whole stretch
# from the series start to the wall in one step, good at its end but not inside, where stage 2
# reads its interpolant (which the error estimate does not control): Delta 6e-3 off at rtol 1e-4
# (a near-edge point of the work-precision set, eta = 3.48, A = -0.1, N = 2.29). The re-march's
# steps are capped at this fraction of the stretch they march. Capping every march cost 30 % of
# stage 1 on bench_point's grid, where no such error was seen.
EDGE_MAX_STEP = 0.25
# DOP853 marches in at least two steps: one step across the whole stretch from the series start
# (the first step's guess is xi1, clipped to the stretch) was accepted on an error estimate that
# missed its error: on bench_point's grid at rtol 1e-6, 695 of 993 points crossed in one step and
# J(0) came out up to 303 rtol off (m_wall 16 rtol); capped at half the stretch, 0.2 (0.1).
DOP853_MAX_STEP = 0.5
STAGE1_RTOL_FLOOR = 1e-13
# D(1) below this many rtol-sized errors of D is zero within stage 1's resolution (solve_eta).
WALL_D_RESOLUTION = 0.1
# ... and when stage 2 fails with D(1) below this many, the dense output's error decides (see there).
WALL_D_FALLBACK = 1e5
# Stage 2 stops once the rest of J, down to the axis, is below this fraction of rtol * J.
TAIL_FRACTION = 1e-3
# Stage 2's quadrature error, relative to rtol: below the error of the stage-1 interpolant it
# integrates, which sets Delta's (see _march_stage2 and docs/performance.md). On the
# work-precision set Delta's median error is the same at 1e-1 and 1e-2 (rtol 1e-6..1e-9), and
# 1e-1 costs 12-15 % less; at 1 it grows 1.7x (docs/performance.md).
STAGE2_TOL = 1e-1
# ... or, where the integrands are noisy (see _march_stage2), this many times their rounding noise.
NOISE_FLOOR = 10.0
# The first stage-2 panel is at most this many e-folds of omega_hat at the wall long.
FIRST_PANEL = 1.0
# Stage-2 panels may span stage-1 steps where stage 1 ran at below this fraction of its tolerance.
FREE_PANELS = 1e-2
# Evaluations of the plug-edge root (it needs 1-2, ~15 where the series is noisy; the bound only
# guards a loop that cannot end).
ROOT_MAX_ITER = 100
# Below R_XI2, the plug-edge Newton stops on its curvature test only where the series F has a
# condition number at most this (its terms cancel little: log F is good to ~1e-15)
SERIES_QUIET = 16.0
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
# Below XI2 stage 2 is the closed form of model.stage2_series (NaN: marched down to R_T_TAIL)
R_XI2 = 10
R_LOGW2 = 11  # log(omega_hat) at XI2
R_J2 = 12  # J at XI2
R_LOGI2 = 13  # log int_0^XI2 h omega_hat (the plug-edge root below XI2 starts from it)
R_RTOL1 = 14  # the relative tolerance stage 1 finally ran at
N_R = 15
PATH_EXPLICIT = 0.0
PATH_STIFF = 1.0
PATH_NONE = -1.0  # no stage-1 integration: a regime without solution, or A = -1 (exact)
PATH_NAMES = {PATH_EXPLICIT: "explicit", PATH_STIFF: "stiff", PATH_NONE: "none"}

METHOD_AUTO = 0
METHOD_EXPLICIT = 1
METHOD_STIFF = 2
# Stage 1 switches to RODAS4P2 when the stiffness left to march exceeds a threshold (see
# use_stiff_path, benchmarks/probes/probe_stiff_switch.py): against Dormand-Prince (rtol > DOP853_RTOL)
# this times sqrt(1e-6/rtol) ...
STIFF_LAMBDA = 20.0
# ... against DOP853 this times (1e-6/rtol)^(1/4) / max(N - 1, STIFF_N_MARGIN), where the axis is
# far from its edge, and without the N factor next to it.
STIFF_LAMBDA_DOP853 = 4.0
STIFF_N_MARGIN = 5e-3

# Rows of a triple's profile array (see profile_kernel).
P_J = 0  # J(xi) = u(xi)/omega_w - eps K
P_OMEGA_HAT = 1  # omega(xi)/omega_w
P_DELTA = 2  # (m/nu + N L)/L
P_SIGMA_YX = 3  # sigma_yx/nu
N_PROF = 4


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


# Slots of the small work vector kept about the stage-1 solution while reading it in order.
W_STEP = 0  # the stage-1 step of the last lookup
N_W = 1
# Above this xi stage 2 evaluates D as D(1) + [D(xi) - D(1)] (see _wall_form).
XI_WALL_FORM = 0.5


@njit(**_JIT_INLINE)
def _stage1_step(xi, T1, n1, work):
    """The stage-1 step that holds ``xi``; stage 2 asks for nearby, mostly decreasing xi, so the
    search starts at the step of the previous lookup (kept in ``work``)."""
    k = dense.find_step_from(T1, n1, xi, int(work[W_STEP]))
    work[W_STEP] = k
    return k


@njit(**_JIT_INLINE)
def _delta_at(xi, xi1, ax, T1, Q1, n1, buf, work):
    """Stage-1 solution anywhere in [0, 1]: the axis series below ``xi1``, the dense output above."""
    if xi <= xi1:
        return model.delta_axis_series(xi, ax)
    k = _stage1_step(xi, T1, n1, work)
    dense.dense_eval_step(T1, Q1, k, xi, buf)
    return xi * xi * buf[0]


@njit(**_JIT)
def _delta_wall(T1, Q1, n1, buf):
    """``delta(1)``: the wall ends the last stage-1 step, so no search and no axis series."""
    dense.dense_eval_step(T1, Q1, max(n1 - 1, 0), 1.0, buf)
    return buf[0]


@njit(**_JIT)
def _stage1_work(n1):
    work = np.empty(N_W)
    work[W_STEP] = n1 - 1
    return work


@njit(**_JIT)
def _wall_increments(T1, Q1, n1):
    """``C[k] = w(T1[k+1]) - w(1)`` for the stage-1 steps that reach above ``XI_WALL_FORM``.

    Summed from the wall over the steps' own increments (the second dense-output row), so that
    :func:`_wall_form` gets ``w(xi) - w(1)`` without subtracting two O(1) values. Entries below
    are not filled.
    """
    C = np.empty(max(n1, 1))
    acc = 0.0
    for k in range(n1 - 1, -1, -1):
        C[k] = acc
        if T1[k] < XI_WALL_FORM:
            break
        acc -= Q1[k, 1, 0]
    return C


@njit(**_JIT_INLINE)
def _wall_form(xi, s, k, T1, Q1, C, A, N, ax, delta1, D1):
    """``(delta, D, noise)`` at ``xi = 1 - s`` (in stage-1 step ``k``, ``xi >= XI_WALL_FORM``), with
    ``D`` as ``D(1)`` plus an increment computed from increments, and a bound on the rounding noise
    of that increment.

    Next to the edge of solvability ``D`` is tiny at the wall (down to ~1e-14) and is the difference
    of O(1) terms: evaluated directly its rounding noise is ~1e-16, so near the wall
    ``B ~ 1/sqrt(D)`` became a noisy function of xi and stage 2 spent its whole budget (20,000 steps)
    on it. Here ``D(xi) - D(1)`` is built from ``delta(xi) - delta(1)`` and ``xi^2 - 1 = -s(2 - s)``,
    each with a relative error of a few ulps: the rounding of ``D(1)`` itself is then a constant,
    and ``D`` is smooth in xi down to the wall.
    """
    s_end = 1.0 - T1[k + 1]  # exact (Sterbenz): T1[k + 1] >= 1/2
    om = (s - s_end) / (T1[k + 1] - T1[k])  # 1 - theta in the step
    th = 1.0 - om
    # w(xi) - w(T1[k+1]) on the step's polynomial (dense.dense_eval_step's layout), as a multiple
    # of 1 - theta: no cancellation at the step's end.
    dw = C[k] - om * (Q1[k, 1, 0] - th * (Q1[k, 2, 0] + th * (Q1[k, 3, 0] + om * (
        Q1[k, 4, 0] + th * (Q1[k, 5, 0] + om * (Q1[k, 6, 0] + th * Q1[k, 7, 0]))))))
    x2m1 = -s * (2.0 - s)  # xi^2 - 1
    ddelta = x2m1 * (delta1 + dw) + dw  # xi^2 w(xi) - w(1)
    delta = delta1 + ddelta
    c0 = ax[AX_C0]
    a2 = 2.0 * (A + 1.0)
    half_yx = 0.5 * ax[model.AX_Y] * x2m1
    dD = c0 * c0 * x2m1 + a2 * (2.0 * N * (ddelta - half_yx) - ddelta * (delta + delta1))
    # Rounding of dD (the rounding of D(1) is a constant, not noise): of its terms, and of ddelta
    # carried through dD/d(delta).
    noise_ddelta = _EPS * (abs(x2m1) * (abs(delta1) + abs(dw)) + abs(C[k]) + 2.0 * abs(dw))
    noise = _EPS * (c0 * c0 * abs(x2m1) + abs(a2) * (2.0 * N * (abs(ddelta) + abs(half_yx))
                                                     + abs(ddelta * (delta + delta1)))) \
        + abs(a2) * (2.0 * N + abs(delta + delta1)) * noise_ddelta
    return delta, D1 + dD, noise


@njit(**_JIT)
def _h_axis(A, ax):
    # h at the axis, where sqrt(D) -> c0 xi (A = -1: h = 2 everywhere).
    if A == -1.0:
        return model.a_minus_one_h()
    return (A + 1.0) * (1.0 - (A - 1.0) / ax[AX_C0])


# ---------------------------------------------------------------------------------------------
# The kernel for one (eta, A, N)
# ---------------------------------------------------------------------------------------------
@njit(**_JIT)
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

    Measured with ``benchmarks/probes/probe_stiff_switch.py`` (both paths forced on bench_point's grid,
    1000 random points and lines in eta at N = 0.9-1.3; CPU time of both stages): at rtol 1e-8
    the crossover in ``x`` (thresholds within 2 % of the best total) lies at 880-2080 for N in
    (0.9, 1], 110-340 for N in (1.05, 1.1], 21-87 for N in (1.2, 1.5] and 4-25 for N in (2, 3];
    from rtol 1e-6 to 1e-10 each grows 4-15x (the rule: 10x). With this rule each set costs
    0-6 % more in total than with the better path for every point, at each rtol from 1e-6 to
    1e-10 (stage 1 alone: 0-11 %), against 0-37 % (0-40 %) with ``STIFF_LAMBDA sqrt(1e-6/rtol)``
    there; the single points that cost more than 2x the better path have ``x < 20`` and meet
    D = 0 (the same under either rule). At rtol 1e-4 and 1e-5 the Dormand-Prince threshold is within
    4-7 % of the better path.
    """
    lam = max(2.0 / eta, ax[AX_BETA] / xi1)
    x = (1.0 - xi1) * lam
    if rtol1 > DOP853_RTOL:
        return x > STIFF_LAMBDA * math.sqrt(1e-6 / rtol1)
    threshold = STIFF_LAMBDA_DOP853 * (1e-6 / rtol1) ** 0.25
    if ax[AX_C0] > 0.5 * (A + 1.0):
        threshold /= max(N - 1.0, STIFF_N_MARGIN)
    return x > threshold


@njit(**_JIT)
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


@njit(**_JIT)
def _march_stage1(stiff, xi0, y0, xi_end, h0, h_max, args1, rtol, atol1, T1, Q1, stats1):
    # The only place that picks stage 1's integrator; all write the same dense-output layout.
    if stiff:
        return rosenbrock.rodas4(_stage1_rhs, _stage1_jac, _stage1_event, xi0, y0, xi_end, args1,
                                 rtol, atol1, h0, h_max, T1, Q1, stats1)
    if rtol <= DOP853_RTOL:
        cap = DOP853_MAX_STEP * (xi_end - xi0)
        return dop853.dop853(_stage1_rhs, _stage1_event, xi0, y0, xi_end, args1, rtol, atol1, h0,
                             cap if not (0.0 < h_max < cap) else h_max, T1, Q1, stats1)
    return rk45.dopri5(_stage1_rhs, _stage1_event, xi0, y0, xi_end, args1, rtol, atol1, h0, h_max,
                       T1, Q1, stats1)


@njit(**_JIT)
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


@njit(**_JIT)
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


@njit(**_JIT)
def _stage1_from_series(stiff, ax, args1, rtol1, atol1, T1, Q1, stats1, res, max_step=0.0):
    """Stage 1 marched again at a tighter ``rtol1``, from where the axis series is good to it
    (:func:`stage1_start`, which moves closer to the axis); records that start in ``res[R_XI1]``.
    Returns what :func:`_stage1_pass` does (``max_step`` as there)."""
    xi1, w1 = stage1_start(ax, rtol1)
    res[R_XI1] = xi1
    return _stage1_pass(stiff, xi1, w1, args1, rtol1, atol1, T1, Q1, stats1, max_step)


@njit(**_JIT_INLINE)
def _add_stats(stats, more):
    for i in range(rk45.STAT_STIFF):
        stats[i] += more[i]
    stats[rk45.STAT_STIFF] = max(stats[rk45.STAT_STIFF], more[rk45.STAT_STIFF])


@njit(**_JIT)
def _stage1_pass(stiff, xi1, w1, args1, rtol1, atol1, T1, Q1, stats1, max_step=0.0):
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
    s1, n1, t1 = _march_stage1(stiff, xi1, y0, end, xi1, max_step * (end - xi1), args1, rtol1,
                               atol1, T1, Q1, stats_r)
    _add_stats(stats1, stats_r)
    if split and s1 == rk45.SUCCESS and n1 > 0:
        y0[0] = Q1[n1 - 1, 0, 0] + Q1[n1 - 1, 1, 0]  # w(N): the last step's end
        s1, n_more, t1 = _march_stage1(stiff, N, y0, 1.0, 0.0, max_step * (1.0 - N), args1, rtol1,
                                       atol1, T1[n1:], Q1[n1:], stats_r)
        n1 += n_more
        _add_stats(stats1, stats_r)
    for _ in range(EVENT_REFINEMENTS):
        if s1 != rk45.EVENT:
            break
        k = n1 - 1
        span = t1 - T1[k]
        if not span > 0.0:
            break
        y0[0] = Q1[k, 0, 0]
        stop = min(Q1.shape[0], k + REFINE_MAX_STEPS)
        s_new, nb, t_new = _march_stage1(stiff, T1[k], y0, 1.0, span / 16.0, span / 16.0, args1,
                                         rtol1, atol1, T1[k:stop + 1], Q1[k:stop], stats_r)
        _add_stats(stats1, stats_r)
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


@njit(**_JIT)
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


@njit(**_JIT)
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


@njit(**_JIT)
def _wall_D_sensitivity(A, N, delta_wall):
    """``|dD/d delta| delta`` at the wall: what a relative error in delta does to D(1)."""
    return 4.0 * (A + 1.0) * abs(N - delta_wall) * abs(delta_wall)


@njit(**_JIT)
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
    res[R_PATH] = PATH_STIFF if stiff else PATH_EXPLICIT
    s1, n1, t1 = _stage1_pass(stiff, xi1, w1, args1, rtol1, atol1, T1, Q1, stats1)
    if s1 == rk45.EVENT and rtol1 > STAGE1_RTOL_FLOOR:
        # Where the path meets D = 0, D often falls to zero nearly tangentially (D ~ (xi_stop -
        # xi)^2 over the last percent), so xi_stop moves by ~sqrt(the error of D): 2.6e-4 at
        # rtol 1e-8 for eps L = 3.8, A = 1/3, N = 1, from the few wide steps of a march that
        # starts on the axis series. The status is certain; for xi_stop, march again 1000x tighter.
        rtol1 = max(STAGE1_RTOL_FLOOR, 1e-3 * rtol1)
        atol1[0] = atol * min(1.0, rtol1 / rtol)
        s1, n1, t1 = _stage1_from_series(stiff, ax, args1, rtol1, atol1, T1, Q1, stats1, res)
    if s1 == rk45.SUCCESS:
        delta_wall = _delta_wall(T1, Q1, n1, buf)
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
            atol1[0] = atol * min(1.0, rtol1 / rtol)
            s1, n1, t1 = _stage1_from_series(stiff, ax, args1, rtol1, atol1, T1, Q1, stats1, res,
                                             EDGE_MAX_STEP)
            if s1 == rk45.SUCCESS:
                delta_wall = _delta_wall(T1, Q1, n1, buf)
                D_wall = model.yield_D(1.0, delta_wall, A, N, ax)
                sensitivity = _wall_D_sensitivity(A, N, delta_wall)
    res[R_N1] = n1
    if s1 == rk45.EVENT:
        res[R_STATUS] = st.EPS_TOO_LARGE_PATH
        res[R_XI_STOP] = t1
        return st.EPS_TOO_LARGE_PATH, False
    if s1 != rk45.SUCCESS:
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


@njit(**_JIT)
def solve_eta(eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res, method=METHOD_AUTO,
              stage2=True):
    """Both stages for one ``(eta, A, N)`` with ``A > -1`` or ``A = -1``, or only what decides.

    ``method`` picks stage 1's integrator: ``METHOD_AUTO`` (by :func:`use_stiff_path`),
    ``METHOD_EXPLICIT`` (Dormand-Prince) or ``METHOD_STIFF`` (RODAS4P2).

    With ``stage2=False`` stage 2 runs only where it can change the status: next to the path
    edge (``near_edge`` of :func:`solve_stage1`), where its failure means D(1) = 0 within
    resolution. Everywhere else a solved stage 1 is the answer for the status and the wall
    values, and ``R_J_AXIS`` stays NaN. The one status this cannot reproduce is a stage-2
    failure away from the edge (``integration_failed``; none is known, see docs/model.md).

    Fills ``res[N_R]`` (slots ``R_*``), the axis constants ``ax``, the dense outputs (T1, Q1) of
    stage 1 and (T2, Q2) of stage 2 and the counters. Returns the status code.
    """
    for i in range(stats2.size):
        stats2[i] = 0
    code, near_edge = solve_stage1(eta, A, N, rtol, atol, ax, T1, Q1, stats1, res, method)
    if code != st.OK or not (stage2 or near_edge):
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


@njit(**_JIT_INLINE)
def _node_rates(xi, s, k, eta, A, N, ax, T1, Q1, C, delta1, D1):
    """``(xi B, xi h, noise)`` of e-60 / e-59 at ``xi = 1 - s`` on the stage-1 solution, in stage-1
    step ``k`` (``k < 0``: below ``R_XI1``, on the axis series); ``noise`` bounds the relative
    rounding error of the two, from that of ``D`` (large only where ``D`` is small).

    Above ``XI_WALL_FORM`` ``delta`` and ``D`` come from :func:`_wall_form` (``C`` from
    :func:`_wall_increments`), below from the step's polynomial or the series directly.
    For A = -1 (Appendix A) ``D`` vanishes identically and the general formulas are 0/0; there
    ``m = -N L`` and the limits ``xi B = 2N/eta`` and ``h = 2`` are used instead, so that A = -1
    runs through the same stage 2 as every other A and the closed form (model.a_minus_one_*)
    stays an independent check of it.
    """
    if A == -1.0:
        return model.a_minus_one_xi_B(eta, N), xi * model.a_minus_one_h(), 0.0
    if k >= 0 and xi >= XI_WALL_FORM:
        delta, D, noise = _wall_form(xi, s, k, T1, Q1, C, A, N, ax, delta1, D1)
    else:
        if k >= 0:
            delta = xi * xi * dense.step_value(T1, Q1, k, 0, xi)
        else:
            delta = model.delta_axis_series(xi, ax)
        D = model.yield_D(xi, delta, A, N, ax)
        noise = model.yield_D_rounding(xi, delta, A, N, ax)
    # B ~ 1/sqrt(D): a relative error e in D is e/2 in B, and at most that in h's 1/sqrt(D) part
    # (D < 0 within round-off gives NaN, which rejects the panel)
    r = 1.0 / math.sqrt(D)
    xiB = xi * model.spin_rate_B(delta, r, eta, A, N)
    return xiB, xi * model.shear_rate_h(xi, r, A), 0.5 * noise * (r * r)


@njit(**_JIT)
def _stage2_series_start(eta, A, N, ax, rtol, xi1):
    """``(xi2, ln xi2)``: where :func:`model.stage2_series` (set up here) is good to
    ``SERIES_TOL * rtol``, at most ``xi1``; ``(0, ln XI_FLOOR)`` without the closed form (A = -1)."""
    if A == -1.0:
        return 0.0, math.log(XI_FLOOR)
    model.stage2_series(eta, A, N, ax)
    xi2 = model.stage2_series_reach(ax, SERIES_TOL * rtol, xi1)
    return xi2, (math.log(xi2) if xi2 > 0.0 else math.log(XI_FLOOR))


@njit(**_JIT)
def _march_stage2(eta, A, N, rtol, atol, ax, xi1, T1, Q1, n1, T2, Q2, stats2, res):
    """Stage 2: ``(log omega_hat, J)`` from the wall towards the axis, as the nested quadrature of
    :mod:`.panels` in ``t = ln(xi)``; ``omega_hat(1) = 1``, ``J(1) = 0`` (eq:7).

    ``d log(omega_hat)/dt = xi B`` and ``dJ/dt = -xi h omega_hat`` are quadratures of known
    functions of the stage-1 solution, so no ODE solver is needed: on Chebyshev panels that never
    straddle a stage-1 step (inside one, ``w`` is a polynomial and the integrands are analytic)
    both are integrated to ``STAGE2_TOL * rtol``, below the error of the stage-1 interpolant they
    read. Panels follow the stage-1 steps down to ``R_XI1`` and go on, on the axis series, to
    where the closed form of :func:`model.stage2_series` takes over (``R_XI2``), or stop once the
    rest of ``J`` is below ``TAIL_FRACTION * rtol * J``: with ``beta = 1e5``, ``J`` grows like
    ``exp((beta + 1) t)`` and the panels stop after a few widths ~1/beta.

    ``T2[p]`` (descending, ``T2[0] = 0``) are the panel ends in ``t`` and ``Q2[p]`` the dense
    output of ``(log omega_hat, J)`` on panel ``p`` (:func:`panels.integrate_panel`), evaluated at
    ``u = (T2[p] - t) / r`` by :func:`panels.panel_value`.
    """
    # Where the closed form takes over is needed only once the panels leave the stage-1 steps:
    # most points stop on the tail before, and the series cost ~1/5 of the march.
    qtol = STAGE2_TOL * rtol
    # Panels stop at every stage-1 step boundary, where the dense output has a kink of the size
    # of stage 1's error; where stage 1 ran far tighter than this quadrature (next to the path
    # edge, see solve_stage1) the kinks are below its tolerance and panels may span steps.
    free = res[R_RTOL1] < FREE_PANELS * qtol
    xi2 = 0.0
    t_end = -math.inf
    if n1 == 0 or free:
        xi2, t_end = _stage2_series_start(eta, A, N, ax, rtol, xi1)
    atol_J = atol * min(1.0, eta)
    C = _wall_increments(T1, Q1, n1)
    delta1 = math.nan
    D1 = math.nan
    if A != -1.0:
        delta1 = _delta_wall(T1, Q1, n1, np.empty(1))
        D1 = model.yield_D(1.0, delta1, A, N, ax)
    f = np.empty(panels.N_NODES)
    g = np.empty(panels.N_NODES)
    rel_noise = np.empty(panels.N_NODES)
    y_nodes = np.empty(panels.N_NODES)
    X = panels.X
    last = panels.N_NODES - 1
    h_axis = _h_axis(A, ax)
    tail_tol = TAIL_FRACTION * rtol
    max_panels = T2.size - 1
    k = n1 - 1  # the stage-1 step under the current panel; -1: below xi1
    b = 0.0
    y_b = 0.0
    J_b = 0.0
    # First try: the whole last stage-1 step, or less where omega_hat falls fast at the wall
    # (log omega_hat changes by xi B over a unit of t).
    length = -math.log(T1[k]) if k >= 0 else 1.0
    if A != -1.0:
        B1 = model.spin_rate_B(delta1, 1.0 / math.sqrt(D1), eta, A, N)
        length = min(length, FIRST_PANEL / abs(B1))
    lo = math.log(T1[k]) if k >= 0 and not free else t_end
    T2[0] = 0.0
    p = 0
    tail = False
    while b > t_end:
        a = b - length
        if a < lo + 0.25 * length:
            a = lo  # no sliver left before the step boundary
        r = 0.5 * (b - a)
        mid = 0.5 * (a + b)
        noise_y = 0.0
        for j in range(panels.N_NODES):
            t = b if j == 0 else (a if j == last else mid + r * X[j])
            # one exponential: s = 1 - xi to full relative precision where the wall form needs it
            if t > -0.5:
                s = -math.expm1(t)
                xi = 1.0 - s
            else:
                xi = math.exp(t)
                s = 1.0 - xi
            if free:
                k = dense.find_step_from(T1, n1, xi, k) if xi > xi1 else -1
            f[j], g[j], rel_noise[j] = _node_rates(xi, s, k, eta, A, N, ax, T1, Q1, C, delta1, D1)
            noise_y = max(noise_y, abs(f[j]) * rel_noise[j])
        stats2[rk45.STAT_FEV] += panels.N_NODES
        err_y, err_J = panels.integrate_panel(f, g, y_b, J_b, r, Q2, p, y_nodes)
        noise_J = 0.0
        for j in range(panels.N_NODES):
            noise_J = max(noise_J, abs(g[j]) * rel_noise[j])
        J_a = panels.panel_value(Q2, p, 1, 2.0)
        # Next to the edge of solvability D is tiny near the wall and the integrands carry the
        # rounding noise of D: no panel can resolve below it, so the tolerance never goes below a
        # multiple of the noise's integral over the panel (an error of the data, not of the
        # quadrature).
        floor_y = NOISE_FLOOR * 2.0 * r * noise_y
        floor_J = NOISE_FLOOR * 2.0 * r * noise_J + floor_y * abs(J_a - J_b)
        err = max(err_y / (qtol + floor_y), err_J / (qtol * abs(J_a) + atol_J + floor_J))
        if not err <= 1.0:  # also NaN: a node where D < 0 within round-off
            stats2[rk45.STAT_REJECTED] += 1
            length = (b - a) * (min(0.5, panels.panel_error_factor(err, 1.0))
                                if math.isfinite(err) else 0.25)
            if length < 1e-15:
                res[R_N2] = p
                res[R_STATUS] = st.INTEGRATION_FAILED
                return st.INTEGRATION_FAILED
            continue
        stats2[rk45.STAT_ACCEPTED] += 1
        p += 1
        T2[p] = a
        b = a
        y_b = y_nodes[last]
        J_b = J_a
        if p >= max_panels:
            res[R_N2] = p
            res[R_STATUS] = st.INTEGRATION_FAILED
            return st.INTEGRATION_FAILED
        # The rest of J, from xi down to the axis, is at most xi max(h) omega_hat(xi) (omega_hat
        # increases with xi near the axis, B > 0 there): stop once that is negligible.
        # (g[last] is xi h omega_hat at xi = e^a)
        if 2.0 * max(g[last], h_axis * math.exp(a + y_b)) < tail_tol * J_b:
            tail = True
            break
        length = 2.0 * r * panels.panel_error_factor(err, 1.0)
        if a == lo and k >= 0 and not free:
            k -= 1
            if k < 0:
                xi2, t_end = _stage2_series_start(eta, A, N, ax, rtol, xi1)
            lo = math.log(T1[k]) if k >= 0 else t_end
    res[R_N2] = p
    res[R_T_TAIL] = b
    res[R_J_AXIS] = J_b
    if not tail and xi2 > 0.0:
        # J(0) = J(xi2) + int_0^xi2 h omega_hat
        res[R_XI2] = xi2
        res[R_LOGW2] = y_b
        res[R_J2] = J_b
        res[R_LOGI2] = _series_log_I(xi2, xi2, y_b, ax)
        res[R_J_AXIS] = J_b + math.exp(res[R_LOGI2])
    if not (math.isfinite(res[R_J_AXIS]) and res[R_J_AXIS] > 0.0):
        res[R_STATUS] = st.INTEGRATION_FAILED
        return st.INTEGRATION_FAILED
    return st.OK


@njit(**_JIT)
def _series_log_I(xi, xi2, logw2, ax):
    """``log int_0^xi h omega_hat`` below ``xi2`` (:func:`model.stage2_series`), with
    ``log omega_hat(xi2) = logw2``: in logs, because ``(xi/xi2)^(beta+1)`` underflows for large beta."""
    return (logw2 - model.series_G(xi2, ax) + math.log(xi2)
            + (ax[AX_BETA] + 1.0) * math.log(xi / xi2) + math.log(model.series_F(xi, ax)))


@njit(**_JIT)
def _series_I(xi, xi2, logw2, ax):
    return math.exp(_series_log_I(xi, xi2, logw2, ax))


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


@njit(**_JIT_INLINE)
def _series_root(fb, consts, ax, t0):
    # the root of _series_plug_level for log I(xi2) - log(level) = fb > 0, from t0
    t2, log_F2, slope, fa0, slope2, quiet = consts[:6]
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
    x, _ = roots.newton_root_d2(_series_plug_level, (c, t2, slope, ax), a, t2, fa, fb, t0,
                                -1e-16 * t0, ROOT_MAX_ITER, quiet)
    return x


@njit(**_JIT_INLINE)
def _plug_constants(res, ax):
    """What the plug-edge root below ``R_XI2`` needs of a triple whatever ``eps K``: ``(t2,
    log F(x2), beta + 1, the part of f(ln XI_FLOOR) that does not depend on the level, the slope
    at t2)``, then the quintic Hermite of ``t_p`` as a function of ``log(level)`` between the
    levels of ``eps K = 0`` (``J(0)/20``, a root found here) and of ``xi2``: ``(log level there,
    1/range, t_p there, dt/d(log level) at both ends times the range, second derivatives at both
    ends times the range squared)``. NaN without a closed form below the panels."""
    nan = math.nan
    xi2 = res[R_XI2]
    if not xi2 > 0.0:
        return nan, nan, nan, nan, nan, False, nan, nan, nan, nan, nan, nan, nan
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
              slope + 2.0 * x2 * dF2 / F2, size <= SERIES_QUIET * abs(F2))
    _, d1_top, d2_top = _series_plug_level(t2, (-log_F2, t2, slope, ax))
    L_min = math.log(0.05 * res[R_J_AXIS])
    H = res[R_LOGI2] - L_min
    t_min = _series_root(H, consts, ax, nan)
    _, d1_min, d2_min = _series_plug_level(t_min, (H - log_F2, t2, slope, ax))
    # t(L) has t' = 1/f' and t'' = -f''/f'^3 (f = log I - L in t)
    return consts + (L_min, 1.0 / H, t_min, H / d1_min, H / d1_top,
                     -d2_min / d1_min ** 3 * H * H, -d2_top / d1_top ** 3 * H * H)


@njit(**_JIT_INLINE)
def _series_start(L, consts):
    # the quintic Hermite of t_p(log level) of _plug_constants; NaN outside its range
    L_min, inv_H, t_min, m0, m1, a0, a1 = consts[6:]
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
    return _series_root(fb, consts, ax, _series_start(L, consts))


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
    target = model.plug_target(res[R_J_AXIS], eps_K)
    if target <= 0.0:
        return 0.0
    if target > res[R_J2]:  # False when R_J2 is NaN: no closed form below the panels
        return -math.expm1(_series_plug_edge(target, res, ax, consts))
    return _panel_plug_edge(target, T2, Q2, int(res[R_N2]))


@njit(**_JIT)
def one_minus_xi_p(eps_K, res, ax, T2, Q2):
    """``1 - xi_p`` from eq:13: on the stage-2 panels (``J`` increases monotonically towards the
    axis, :func:`_panel_plug_edge`), or below ``R_XI2`` on stage 2's closed form
    (:func:`_series_plug_edge`).

    The root is found in ``t = ln(xi_p)`` and returned as ``-expm1(t)``: no cancellation even
    when the shear layer is a tiny fraction of the channel. :func:`solve_batch` computes the
    triple's constants once for all its ``eps K`` (same bits).
    """
    return _one_minus_xi_p(eps_K, res, ax, T2, Q2, _plug_constants(res, ax))


@njit(**_JIT_INLINE)
def _panel_level(u, packed):
    Q2, p, target = packed
    J, dJ, d2J = panels.panel_value_d2(Q2, p, 1, u)
    return J - target, dJ, d2J


@njit(**_JIT)
def stage1_batch(eta, A, N, rtol, atol, method, max_steps, mu_wall, stats):
    """Stage 1 alone for many triples (benchmarks), exactly as :func:`solve_eta` runs it:
    ``m(1)/(nu L)`` into ``mu_wall`` (NaN without a solution) and the counters into ``stats[i]``."""
    ax = np.empty(N_AX)
    T1 = np.empty(max_steps + 1)
    Q1 = np.empty((max_steps, dense.N_DENSE, 1))
    res = np.empty(N_R)
    for i in range(eta.size):
        solve_stage1(eta[i], A[i], N[i], rtol, atol, ax, T1, Q1, stats[i], res, method)
        mu_wall[i] = res[R_MU_WALL]


@njit(**_JIT)
def solve_batch(eta, A, N, eps_K, offsets, rtol, atol, max_steps_stage1, max_steps_stage2,
                res, stats, one_minus, xi_profile, profiles, stage2=True, plug_edge=True):
    """Many ``(eta, A, N)`` triples, each with its own run of ``eps K`` values, on one core.

    Triple ``i`` owns ``eps_K[offsets[i]:offsets[i+1]]``; ``one_minus`` (same length as ``eps_K``)
    receives ``1 - xi_p`` for each (NaN where the triple has no solution). ``res[i]`` gets the
    triple's ``R_*`` slots and ``stats[i, 0]`` / ``stats[i, 1]`` the counters of the two stages.
    When ``xi_profile`` is not empty, ``profiles[i]`` (shape ``(N_PROF, xi_profile.size)``)
    receives the triple's profiles (slots ``P_*``; NaN without a solution).
    One integration per triple, whatever the number of ``eps K`` values (model.md's similarity).
    The work arrays are allocated once, here, so the kernel releases the GIL for its whole run.

    Only what is asked for is computed: ``stage2=False`` runs stage 2 only where it decides the
    status (:func:`solve_eta`), ``plug_edge=False`` skips the eq:13 root (``one_minus`` is NaN).
    Profiles need both.
    """
    ax = np.empty(N_AX)
    T1 = np.empty(max_steps_stage1 + 1)
    Q1 = np.empty((max_steps_stage1, dense.N_DENSE, 1))
    T2 = np.empty(max_steps_stage2 + 1)
    Q2 = np.empty((max_steps_stage2, panels.N_ROWS, 2))
    for i in range(eta.size):
        code = solve_eta(eta[i], A[i], N[i], rtol, atol, ax, T1, Q1, T2, Q2, stats[i, 0],
                         stats[i, 1], res[i], METHOD_AUTO, stage2 or plug_edge or xi_profile.size > 0)
        if code == st.OK and plug_edge:
            r = res[i]
            consts = _plug_constants(r, ax)
            for j in range(offsets[i], offsets[i + 1]):
                one_minus[j] = _one_minus_xi_p(eps_K[j], r, ax, T2, Q2, consts)
        else:
            one_minus[offsets[i]:offsets[i + 1]] = math.nan
        if xi_profile.size > 0:
            if code == st.OK:
                profile_kernel(xi_profile, eta[i], A[i], N[i], ax, res[i], T1, Q1, T2, Q2,
                               profiles[i])
            else:
                profiles[i, :, :] = math.nan



@njit(**_JIT)
def profile_kernel(xis, eta, A, N, ax, res, T1, Q1, T2, Q2, out):
    """Profiles of one solved triple at ``xis``: rows ``P_J``, ``P_OMEGA_HAT``, ``P_DELTA``, ``P_SIGMA_YX``.

    ``u/u(0) = (eps K + J) / (eps K + J(0))`` for any K, so ``J`` is stored, not ``u``.
    A = -1 has no stage-1 output: there ``delta = 0`` and ``sigma_yx = -xi`` exactly (Appendix A),
    while ``J`` and ``omega_hat`` come from the stage-2 march as for every other A.
    """
    buf = np.empty(1)
    xi1 = res[R_XI1]
    n1 = int(res[R_N1])
    n2 = int(res[R_N2])
    t_tail = res[R_T_TAIL]
    J_axis = res[R_J_AXIS]
    work = _stage1_work(n1)
    # Below where stage 2 stopped, omega_hat ~ xi^beta (Appendix B) and J has converged.
    logw_tail = panels.panel_value(Q2, n2 - 1, 0, 2.0) if n2 > 0 else 0.0
    for i in range(xis.size):
        xi = xis[i]
        t = math.log(xi) if xi > 0.0 else -math.inf
        if t >= t_tail:
            p = dense.find_step(T2, n2, t)  # the panel holding t (T2 descends)
            u = max(0.0, min(2.0, 2.0 * (T2[p] - t) / (T2[p] - T2[p + 1])))
            logw = panels.panel_value(Q2, p, 0, u)
            J = panels.panel_value(Q2, p, 1, u)
        elif res[R_XI2] > 0.0:
            logw = res[R_LOGW2] + ax[AX_BETA] * (t - t_tail) + model.series_G(xi, ax) \
                - model.series_G(res[R_XI2], ax)
            J = J_axis - (_series_I(xi, res[R_XI2], res[R_LOGW2], ax) if xi > 0.0 else 0.0)
        else:
            logw = logw_tail + ax[AX_BETA] * (t - t_tail)
            J = J_axis
        out[P_J, i] = J
        out[P_OMEGA_HAT, i] = math.exp(logw)
        if A == -1.0:
            out[P_DELTA, i] = 0.0  # m = -N L
            out[P_SIGMA_YX, i] = -xi
        else:
            delta = _delta_at(xi, xi1, ax, T1, Q1, n1, buf, work)
            D = model.yield_D(xi, delta, A, N, ax)
            out[P_DELTA, i] = delta
            out[P_SIGMA_YX, i] = model.sigma_yx(xi, D, A)
