"""The solver's entry kernels: both stages for one ``(eta, A, N)`` and batches of them.

:func:`solve_eta` runs stage 1 and, where it can matter, stage 2; :func:`solve_batch` solves many
triples and every ``eps K`` of each (the similarity: one integration per ``(eta, A, N)``);
:func:`profile_kernel` evaluates the profiles of a solved triple. The kernels report through the
slots of :mod:`.layout`; :mod:`cosserat_channel.outputs` turns them into what users read.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE
from .. import status as st
from ..integrate import dense, panels, stepping
from ..physics import model
from ..physics.model import AX_BETA, N_AX
from .layout import (METHOD_AUTO, N_R, P_DELTA, P_J, P_OMEGA_HAT, P_SIGMA_YX, R_J_AXIS, R_LOGW2,
                     R_MU_WALL, R_N1, R_N2, R_STATUS, R_T_TAIL, R_XI1, R_XI2, R_XI_STOP)
from .plug_edge import _no_plug_constants, _one_minus_xi_p
from .stage1 import (DOP853_RTOL, MAX_STEPS_STAGE1, STIFF_NOT_COMPILED, solve_stage1,
                     solve_stage1_with, stage1_arrays)
from .stage2 import MAX_STEPS_STAGE2, _march_stage2, _series_I, stage2_arrays
from .stress_path import _delta_at, _stage1_work

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
    return _solve_eta(None, None, eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res,
                      method, stage2)


@njit(**_JIT)
def solve_eta_tight(eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res,
                    method=METHOD_AUTO, stage2=True):
    """:func:`solve_eta` for ``rtol <= stage1.DOP853_RTOL`` (the same bits), compiled without
    Dormand-Prince 5(4), which only a looser tolerance marches with."""
    return _solve_eta(True, None, eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res,
                      method, stage2)


@njit(**_JIT)
def solve_eta_dop853(eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res,
                     method=METHOD_AUTO, stage2=True):
    """:func:`solve_eta_tight` compiled without RODAS4P2 too: DOP853 is its one integrator, and
    a point that takes the stiff path returns ``stage1.STIFF_NOT_COMPILED`` before marching."""
    return _solve_eta(True, True, eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res,
                      method, stage2)


# Whether this process has met a point on the stiff path at rtol <= DOP853_RTOL: from then on
# solve_eta_auto calls the entry with RODAS4P2 at once.
_stiff_met = False


def solve_eta_auto(eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res,
                   method=METHOD_AUTO, stage2=True):
    """:func:`solve_eta` from Python, through the entry that compiles (on an empty kernel cache)
    only the integrators the point can reach: :func:`solve_eta` above ``stage1.DOP853_RTOL``,
    else :func:`solve_eta_dop853` until a point takes the stiff path, then
    :func:`solve_eta_tight`. Every entry gives the same bits."""
    global _stiff_met
    if not rtol <= DOP853_RTOL:
        return solve_eta(eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res, method,
                         stage2)
    if not _stiff_met:
        code = solve_eta_dop853(eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res,
                                method, stage2)
        if code != STIFF_NOT_COMPILED:
            return code
        _stiff_met = True
    return solve_eta_tight(eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res, method,
                           stage2)


@njit(**_JIT_INLINE)
def _solve_eta(tight, explicit, eta, A, N, rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res,
               method, stage2):
    # The body of the entries, with the flags of stage1.solve_stage1_with (inlined: a kernel of
    # its own would be one more level of linked code that each caller's compilation optimises
    # again).
    for i in range(stats2.size):
        stats2[i] = 0
    code, near_edge = solve_stage1_with(tight, explicit, eta, A, N, rtol, atol, ax, T1, Q1,
                                        stats1, res, method)
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


@njit(**_JIT)
def stage1_batch(eta, A, N, rtol, atol, method, max_steps, mu_wall, stats):
    """Stage 1 alone for many triples (benchmarks), exactly as :func:`solve_eta` runs it:
    ``m(1)/(nu L)`` into ``mu_wall`` (NaN without a solution) and the counters into ``stats[i]``."""
    ax = np.empty(N_AX)
    T1, Q1 = stage1_arrays(max_steps)
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
    T1, Q1 = stage1_arrays(max_steps_stage1)
    T2, Q2 = stage2_arrays(max_steps_stage2)
    for i in range(eta.size):
        code = solve_eta(eta[i], A[i], N[i], rtol, atol, ax, T1, Q1, T2, Q2, stats[i, 0],
                         stats[i, 1], res[i], METHOD_AUTO, stage2 or plug_edge or xi_profile.size > 0)
        if code == st.OK and plug_edge:
            r = res[i]
            # the constants of the closed-form root once per triple, if one of its eps K needs it
            consts = _no_plug_constants()
            for j in range(offsets[i], offsets[i + 1]):
                one_minus[j], consts = _one_minus_xi_p(eps_K[j], r, ax, T2, Q2, consts)
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


def new_statistics(*shape):
    """Zeroed counters for the batch kernels: ``shape + (N_STATS,)`` int64 (``(n, 2)`` for
    :func:`solve_batch`'s two stages, ``(n,)`` for :func:`stage1_batch`)."""
    return np.zeros((*shape, stepping.N_STATS), dtype=np.int64)


def accepted_steps(stats):
    """The accepted steps in counters the batch kernels filled (their last axis read out)."""
    return stats[..., stepping.STAT_ACCEPTED].copy()


class Workspace:
    """Preallocated work arrays for :func:`solve_eta` (reuse one across many points)."""

    def __init__(self, max_steps_stage1=MAX_STEPS_STAGE1, max_steps_stage2=MAX_STEPS_STAGE2):
        self.ax = np.empty(N_AX)
        # The kernels' Python originals: compiled, each would be one more kernel to compile for
        # a first point.
        self.T1, self.Q1 = stage1_arrays.py_func(max_steps_stage1)
        self.T2, self.Q2 = stage2_arrays.py_func(max_steps_stage2)
        self.stats1 = np.zeros(stepping.N_STATS, dtype=np.int64)
        self.stats2 = np.zeros(stepping.N_STATS, dtype=np.int64)
        self.res = np.empty(N_R)

    def run(self, eta, A, N, rtol, atol, method=METHOD_AUTO, stage2=True):
        """Both stages for one ``(eta, A, N)``; returns the status code, fills ``self.res``.

        ``stage2=False``: stage 2 only where it decides the status (:func:`solve_eta`).
        """
        return solve_eta_auto(
            eta, A, N, rtol, atol, self.ax, self.T1, self.Q1, self.T2, self.Q2,
            self.stats1, self.stats2, self.res, method, stage2,
        )

    def status(self, eta, A, N, rtol, atol) -> int:
        """The status code of ``(eta, A, N)`` by the cheapest solve that decides it as the full
        solve does: stage 1 to the wall with the same event and edge handling, and stage 2 only
        next to the path edge. For edge tracing, regime maps and the atlas."""
        return self.run(eta, A, N, rtol, atol, METHOD_AUTO, False)
