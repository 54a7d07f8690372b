"""Stage 2: ``(log omega_hat, J)`` from the wall towards the axis on stage 1's solution.

The nested quadrature of :mod:`cosserat_channel.integrate.panels` on Chebyshev panels in
``t = ln(xi)`` that follow stage 1's steps, stopping once what is left of ``J`` is below the
tolerance or where the closed form of :func:`model.stage2_series` takes over.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import JIT as _JIT, JIT_INLINE as _JIT_INLINE
from .. import status as st
from ..integrate import stepping, dense, panels
from ..physics import model
from ..physics.model import AX_BETA, AX_C0
from .layout import (R_J2, R_J_AXIS, R_LOGI2, R_LOGW2, R_N2, R_RTOL1, R_STATUS, R_T_TAIL, R_XI2)
from .stage1 import SERIES_TOL
from .stress_path import _delta_wall, _wall_increments, delta_D_at, xi_of_log

MAX_STEPS_STAGE2 = 20_000  # panels: bounded work per point (integration_failed beyond)
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
# Stage 2 never marches below this xi: J's remaining tail there is < XI_FLOOR * max h.
XI_FLOOR = 1e-14



@njit(**_JIT)
def stage2_arrays(max_steps):
    """``(T2, Q2)``: room for stage 2's panels, at most ``max_steps`` of them."""
    return np.empty(max_steps + 1), np.empty((max_steps, panels.N_ROWS, 2))


@njit(**_JIT_INLINE)
def _h_axis(A, ax):
    # h at the axis, where sqrt(D) -> c0 xi (A = -1: h = 2 everywhere).
    if A == -1.0:
        return model.a_minus_one_h()
    return (A + 1.0) * (1.0 - (A - 1.0) / ax[AX_C0])




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
    delta, D, noise = delta_D_at(xi, s, k, T1, Q1, C, A, N, ax, delta1, D1)
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
    # the integrands at the nodes, their rounding, y there; one allocation
    work = np.empty((4, panels.N_NODES))
    f, g, rel_noise, y_nodes = work[0], work[1], work[2], work[3]
    delta1 = math.nan
    D1 = math.nan
    if A != -1.0:
        delta1 = _delta_wall(T1, Q1, n1, y_nodes)
        D1 = model.yield_D(1.0, delta1, A, N, ax)
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
    # (A = -1: xi B = c = 2N/eta exactly, up to ~1e18, and omega_hat = xi^c falls by e within 1/c
    # of the wall; a panel shrinking from 1 to that gave up after 22 rejections.)
    B1 = (model.a_minus_one_xi_B(eta, N) if A == -1.0
          else model.spin_rate_B(delta1, 1.0 / math.sqrt(D1), eta, A, N))
    length = min(length, FIRST_PANEL / abs(B1))
    # A march whose panels shrink this far gives up: in t, below 1e-15 of the wall's scale 1/c
    # at A = -1 (the layer can be far thinner than 1e-15), below 1e-15 otherwise.
    min_length = 1e-15 * length if A == -1.0 else 1e-15
    lo = math.log(T1[k]) if k >= 0 and not free else t_end
    T2[0] = 0.0
    # int64 from the start: Numba types the calls below with a literal 0 first and compiled
    # integrate_panel and panel_value once more for it.
    p = np.int64(0)
    tail = False
    # The rates at the panels' upper end b, shared by every panel tried from b and by the panel
    # above (its lower end): computed once while b stays inside one stage-1 step.
    have_b = False
    f_b = 0.0
    g_b = 0.0
    noise_b = 0.0
    while b > t_end:
        a = b - length
        if a < lo + 0.25 * length:
            a = lo  # no sliver left before the step boundary
        r = 0.5 * (b - a)
        mid = 0.5 * (a + b)
        noise_y = 0.0
        for j in range(panels.N_NODES):
            if j == 0 and have_b:
                # (in free mode k is already the step holding e^b: find_step_from from its own
                # answer returns it)
                f[0] = f_b
                g[0] = g_b
                rel_noise[0] = noise_b
            else:
                t = b if j == 0 else (a if j == last else mid + r * X[j])
                xi, s = xi_of_log(t)
                if free:
                    k = dense.find_step_from(T1, n1, xi, k) if xi > xi1 else -1
                f[j], g[j], rel_noise[j] = _node_rates(xi, s, k, eta, A, N, ax, T1, Q1, C,
                                                       delta1, D1)
                stats2[stepping.STAT_FEV] += 1
            noise_y = max(noise_y, abs(f[j]) * rel_noise[j])
        if not have_b:
            f_b = f[0]
            g_b = g[0]
            noise_b = rel_noise[0]
            have_b = True
        g_a = g[last]  # before integrate_panel weights g by omega_hat
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
            stats2[stepping.STAT_REJECTED] += 1
            length = (b - a) * (min(0.5, panels.panel_error_factor(err, 1.0))
                                if math.isfinite(err) else 0.25)
            if length < min_length:
                res[R_N2] = p
                res[R_STATUS] = st.INTEGRATION_FAILED
                return st.INTEGRATION_FAILED
            continue
        stats2[stepping.STAT_ACCEPTED] += 1
        p += 1
        T2[p] = a
        b = a
        y_b = y_nodes[last]
        J_b = J_a
        f_b = f[last]
        g_b = g_a
        noise_b = rel_noise[last]
        if p >= max_panels:
            res[R_N2] = p
            res[R_STATUS] = st.INTEGRATION_FAILED
            return st.INTEGRATION_FAILED
        # The rest of J, from xi down to the axis, is at most xi max(h) omega_hat(xi) (omega_hat
        # increases with xi near the axis, B > 0 there): stop once that is negligible.
        # (g[last] is xi h omega_hat at xi = e^a; the bound's second term, an exponential, only
        # where the first leaves the test open: 2 max(u, v) < c is 2u < c and 2v < c)
        limit = tail_tol * J_b
        if 2.0 * g[last] < limit and 2.0 * (h_axis * math.exp(a + y_b)) < limit:
            tail = True
            break
        length = 2.0 * r * panels.panel_error_factor(err, 1.0)
        if a == lo and k >= 0 and not free:
            have_b = False  # e^b ends step k: the next panels read step k - 1
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


@njit(**_JIT_INLINE)
def _series_log_I(xi, xi2, logw2, ax):
    """``log int_0^xi h omega_hat`` below ``xi2`` (:func:`model.stage2_series`), with
    ``log omega_hat(xi2) = logw2``: in logs, because ``(xi/xi2)^(beta+1)`` underflows for large beta."""
    return (logw2 - model.series_G(xi2, ax) + math.log(xi2)
            + (ax[AX_BETA] + 1.0) * math.log(xi / xi2) + math.log(model.series_F(xi, ax)))


@njit(**_JIT)
def _series_I(xi, xi2, logw2, ax):
    return math.exp(_series_log_I(xi, xi2, logw2, ax))
