"""The adjoint march: derivatives of a solved ``(eta, A, N)``'s marched quantities, in Numba.

Through the exact similarity (docs/model.md, section 7) the marches depend on ``(eta, A, N)`` only,
so only those need derivatives of integrals; ``eps``, ``L`` and ``K`` enter through ``eta = eps L``,
``eps K`` and the outputs' own formulas (chain rule, :func:`point_sensitivities`). The derivatives
of the marched quantities are adjoint quadratures over the solved point (docs/model.md, section
10): the linearised stage 1, ``S' = -B S + df/dp`` with ``S(0) = 0``, has ``omega_hat`` as its
integrating factor, so

    d delta(1)/dp = int_0^1 omega_hat df/dp,
    dJ(xi_0)/dp   = int_xi0^1 (omega_hat dh/dp - I dB/dp) + int_0^1 omega_hat psi df/dp,
    psi(xi)       = int_max(xi, xi0)^1 (dh/d delta - (I/omega_hat) dB/d delta),

with ``I(xi) = J(xi_0) - J(xi)`` for ``xi > xi_0`` (``xi_0 = 0`` for ``J(0)``, ``xi_p`` for the plug
edge). :func:`sensitivity_kernel` marches them from the wall to the axis on Chebyshev panels
(:func:`panels.cumulative`) together with ``log omega_hat`` and ``J``, reading stage 1's solution
as stage 2 does. The plug edge follows by the implicit function theorem on
``J(xi_p) = 0.95 J(0) - 0.05 eps K``. With profile points the same march also carries the
forward sensitivities (:func:`profile_sensitivities`); :func:`sensitivity_batch` runs the
kernel over the triples of an array (``solve(..., sensitivities=True)``), and
:mod:`.sensitivity` takes both to the outputs by ``eps, L, K, A, N``. Imported only when
sensitivities are asked for: its kernels are compiled only then.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import EPS as _EPS, JIT as _JIT
from .. import status as st
from ..integrate import panels
from ..physics import model
from ..physics import derivatives as dv
from ..integrate import stepping
from .batch import solve_eta
from .layout import METHOD_AUTO, N_R, R_J_AXIS, R_N1
from .stage1 import stage1_arrays
from .stage2 import (FIRST_PANEL, MAX_STEPS_STAGE2, STAGE2_TOL, TAIL_FRACTION, XI_FLOOR, _h_axis,
                     stage2_arrays)
from .stress_path import _delta_wall, _wall_increments, delta_D_at, xi_of_log

__all__ = ["sensitivity_kernel", "sensitivity_batch", "N_S", "N_PS"]

# Slots of the kernel's result vector; derivatives with respect to (eta, A, N) in three slots each.
S_STATUS = 0
S_MU_WALL = 1  # d(m(1)/(nu L))/d(eta, A, N)
S_SIGMA_YX_WALL = 4  # d(sigma_yx(1)/nu)/d(eta, A, N)
S_J_AXIS = 7  # dJ(0)/d(eta, A, N)
S_ONE_MINUS = 10  # d(1 - xi_p)/d(eta, A, N, eps K): four slots
S_PANELS = 14  # accepted panels
S_DELTA_WALL = 15  # d delta(1)/d(eta, A, N): the input ``F0`` of a profile call
S_UNRESOLVED = 18  # 1 where the derivatives by (eta, A, N) missed the tolerance (see the kernel)
N_S = 21
# Rows of a profile call's ``prof`` (each by eta, A, N): dJ(xi), d log omega_hat(xi).
PS_J = 0
PS_LOGW = 3
N_PS = 6

# Rows of the accumulated integrals: d delta(1), dJ(0), dJ(xi_p) at fixed xi_p, three each.
_N_ACC = 9
# J(0) - J(xi) below this many ulps of J(0) is rounding noise (see sensitivity_kernel).
I_NOISE = 256.0
# A panel rejected this many times in a row, each time at most half as long, whose error is
# then still that of the derivatives alone, meets their integrands' rounding noise (a smooth
# integrand's error would have fallen 2^(9 k)): it is taken, and the parameters whose
# derivatives it leaves above the solve's rtol are marked unresolved (computed another way by
# the caller).
NOISE_REJECTIONS = 8


@njit(**_JIT)
def sensitivity_kernel(eta, A, N, eps_K, one_minus, rtol, atol, ax, res, T1, Q1, out, xis, F0,
                       prof):
    """Derivatives of a solved ``(eta, A, N)`` (``A > -1``) into ``out[N_S]`` (slots ``S_*``).

    ``ax``, ``res`` and ``(T1, Q1)`` are those the solve left (status ok, stage 2 run);
    ``one_minus`` is ``1 - xi_p`` at ``eps_K`` (NaN: no plug-edge derivatives). The panels follow
    stage 1's steps and resolve the integrands to ``STAGE2_TOL * rtol`` (relative to the sum of
    their magnitudes), and stop once what is left down to the axis is below
    ``TAIL_FRACTION * rtol`` of it, as stage 2 does. Each panel: its nodes
    (:func:`_panel_nodes`), ``log omega_hat`` and ``J`` (:func:`_omega_J`), the adjoints
    (:func:`_adjoints`), the derivative integrals (:func:`_derivative_integrals`) and, with
    profile points, the forward sensitivities (:func:`_profile_panel`).

    With profile points ``xis`` (not empty) and ``F0 = d delta(1)/d(eta, A, N)`` from a first call
    (slots ``S_DELTA_WALL``), the same panels also carry the forward sensitivities, column ``i``
    of ``prof[N_PS, xis.size + 1]`` receiving those at ``xis[i]`` (rows ``PS_*``; ``dJ`` NaN
    below the march's end) and the last column the march's own ``dJ`` at its end: with
    ``S = d delta/dp = (F0 - int_xi^1 omega_hat df/dp) / omega_hat``,
    ``d log omega_hat/dp = -int_xi^1 (dB/dp + B_delta S)`` and ``dJ/dp = int_xi^1 omega_hat
    (dh/dp + h_delta S + h d log omega_hat/dp)``, each cumulative from the wall. ``S`` carries
    the whole integral's quadrature error divided by ``omega_hat``, but enters ``J`` weighted by
    ``omega_hat`` and ``omega_hat``'s derivative as ``omega_hat`` times it, so both keep the
    accuracy of the solve (``S`` itself, hence ``m`` and ``sigma_yx``, would not near the axis).
    Points below the march's end continue its last slope (``log omega_hat`` linear in
    ``ln xi``, as ``xi^beta``). The panels and every ``out`` slot are those of a call without
    profile points, bit for bit.

    A panel whose derivative integrals stay above the tolerance after ``NOISE_REJECTIONS``
    rejections (their integrands' rounding, while ``log omega_hat``, ``J`` and the adjoints are
    resolved) is taken, and ``out[S_UNRESOLVED + i]`` is 1 for each parameter ``(eta, A,
    N)[i]`` whose derivatives it left above rtol (0 elsewhere). ``out[S_STATUS]`` is
    ``integration_failed`` where the march itself gives up.
    """
    for i in range(N_S):
        out[i] = math.nan
    out[S_STATUS] = st.INTEGRATION_FAILED
    n1 = int(res[R_N1])
    J0 = res[R_J_AXIS]
    target = model.plug_target(J0, eps_K)
    have_p = target > 0.0 and one_minus > 0.0
    t_p = math.log1p(-one_minus) if have_p else -math.inf
    qtol = STAGE2_TOL * rtol
    tail_tol = TAIL_FRACTION * rtol
    atol_J = atol * min(1.0, eta)
    C = _wall_increments(T1, Q1, n1)
    delta1 = _delta_wall(T1, Q1, n1, np.empty(1))
    D1 = model.yield_D(1.0, delta1, A, N, ax)
    h_axis = _h_axis(A, ax)
    nn = panels.N_NODES
    last = nn - 1
    # the nodes' xi, the rates' partials, omega_hat, J, I = J(0) - J, the two adjoints, scratch
    P = np.empty((dv.N_Q, nn))
    xs = np.empty(nn)
    w = np.empty(nn)
    Jn = np.empty(nn)
    I0 = np.empty(nn)
    psi0 = np.empty(nn)
    psip = np.empty(nn)
    v = np.empty(nn)
    cum = np.empty(nn)
    beta = ax[model.AX_BETA]
    # per integral (_N_ACC): the sums so far and of magnitudes, the panel's, its error and
    # magnitude, and a bound on what is left below
    acc = np.zeros(_N_ACC)
    acc_abs = np.zeros(_N_ACC)
    pan = np.empty(_N_ACC)
    pan_abs = np.empty(_N_ACC)
    pan_err = np.empty(_N_ACC)
    low = np.empty(_N_ACC)
    t_floor = math.log(XI_FLOOR)
    n_pro = xis.size
    t_pro = _log_points(xis)
    todo = np.ones(n_pro, dtype=np.bool_)
    # the forward sensitivities' integrands (of F, log omega_hat, J) and running values
    fwd = np.empty((3, 3, nn))
    Fb = np.zeros(3)
    Lb = np.zeros(3)
    dJb = np.zeros(3)
    slope = np.zeros(3)
    k = n1 - 1
    b = 0.0
    y_b = 0.0
    J_b = 0.0
    psi0_b = 0.0
    psip_b = 0.0
    hw_p = math.nan
    B1 = model.spin_rate_B(delta1, 1.0 / math.sqrt(D1), eta, A, N)
    length = min(-math.log(T1[k]) if k >= 0 else 1.0, FIRST_PANEL / abs(B1))
    lo = math.log(T1[k]) if k >= 0 else t_floor
    accepted = 0
    rejected = 0
    unresolved = np.zeros(3, dtype=np.bool_)
    row_err = np.empty(3)
    for _ in range(MAX_STEPS_STAGE2):
        lo_eff = t_p if (have_p and b > t_p > lo) else lo
        a = b - length
        if a < lo_eff + 0.25 * length:
            a = lo_eff
        r = 0.5 * (b - a)
        good = _panel_nodes(a, b, r, k, eta, A, N, ax, T1, Q1, C, delta1, D1, xs, P)
        err = math.nan
        y_drop = 0.0
        for row in range(3):
            row_err[row] = 0.0
        above = have_p and a >= t_p
        if good:
            err_y, err_J, y_drop = _omega_J(xs, P, r, y_b, J_b, w, Jn, v, cum)
            err = max(err_y / qtol, err_J / (qtol * J0 + atol_J))
            err = _adjoints(err, xs, P, w, Jn, r, J0, J_b, beta, h_axis, qtol, above, target,
                            psi0_b, psip_b, I0, psi0, psip, v, cum)
            _derivative_integrals(xs, P, w, Jn, I0, psi0, psip, r, h_axis, qtol, above, target,
                                  acc_abs, pan, pan_err, pan_abs, low, row_err, v, cum)
        err_all = err
        for row in range(3):
            err_all = max(err_all, row_err[row])
        if not err_all <= 1.0:  # also NaN: a node outside the admissible region within round-off
            rejected += 1
            if not (rejected >= NOISE_REJECTIONS and err <= 1.0):
                length = (b - a) * (min(0.5, panels.panel_error_factor(err_all, 1.0))
                                    if math.isfinite(err_all) else 0.25)
                if length < 1e-15:
                    return
                continue
            _mark_unresolved(row_err, unresolved)
        else:
            err = err_all
        rejected = 0
        accepted += 1
        if n_pro > 0:
            _profile_panel(xs, P, w, r, a, b, F0, pan, t_pro, todo, Fb, Lb, dJb, slope, fwd, v,
                           cum, prof)
        for c in range(_N_ACC):
            acc[c] += pan[c]
            acc_abs[c] += pan_abs[c]
        y_b = y_b - y_drop
        J_b = Jn[last]
        psi0_b = psi0[last]
        psip_b = psip[last]
        if have_p and a == t_p:
            hw_p = P[dv.Q_H, last] * w[last]
        b = a
        if ((not have_p or b <= t_p) and _tail_reached(xs, P, w, h_axis, tail_tol, J_b, low, acc_abs)
                or b <= t_floor):
            break
        length = 2.0 * r * panels.panel_error_factor(err, 1.0)
        if a == lo and k >= 0:
            k -= 1
            lo = math.log(T1[k]) if k >= 0 else t_floor
    else:
        return
    _profile_below(b, t_pro, todo, Lb, dJb, slope, prof)
    _wall_derivatives(A, N, delta1, D1, acc, have_p, target, hw_p, accepted, unresolved, out)


@njit(**_JIT)
def _panel_nodes(a, b, r, k, eta, A, N, ax, T1, Q1, C, delta1, D1, xs, P):
    """The nodes of the panel ``[a, b]`` in ``t = ln xi`` (half-width ``r``) on stage 1's step
    ``k``: ``xi`` into ``xs`` and the rates' partials (:func:`dv.rate_partials`) into ``P``.
    False at the first node outside the admissible region (``D <= 0`` or NaN)."""
    nn = panels.N_NODES
    last = nn - 1
    mid = 0.5 * (a + b)
    for j in range(nn):
        t = b if j == 0 else (a if j == last else mid + r * panels.X[j])
        xi, s = xi_of_log(t)
        xs[j] = xi
        delta, D, _ = delta_D_at(xi, s, k, T1, Q1, C, A, N, ax, delta1, D1)
        if not D > 0.0:
            return False
        dv.rate_partials(xi, delta, D, eta, A, N, P, j)
    return True


@njit(**_JIT)
def _omega_J(xs, P, r, y_b, J_b, w, Jn, v, cum):
    """``log omega_hat`` and ``J`` on a panel as stage 2 integrates them (``d log omega_hat/dt =
    xi B``, ``dJ/dt = -xi h omega_hat``), from ``y_b`` and ``J_b`` at its upper end: ``omega_hat``
    into ``w`` and ``J`` into ``Jn`` at the nodes. Returns both quadratures' errors and the fall
    of ``log omega_hat`` across the panel."""
    nn = panels.N_NODES
    for j in range(nn):
        v[j] = xs[j] * P[dv.Q_B, j]
    _, err_y = panels.cumulative(v, r, cum)
    y_drop = cum[nn - 1]
    for j in range(nn):
        w[j] = math.exp(y_b - cum[j])
        v[j] = xs[j] * P[dv.Q_H, j] * w[j]
    _, err_J = panels.cumulative(v, r, cum)
    for j in range(nn):
        Jn[j] = J_b + cum[j]
    return err_y, err_J, y_drop


@njit(**_JIT)
def _adjoints(err, xs, P, w, Jn, r, J0, J_b, beta, h_axis, qtol, above, target, psi0_b, psip_b,
              I0, psi0, psip, v, cum):
    """The adjoints on a panel: ``psi`` of ``J(0)`` into ``psi0`` and of ``J(xi_p)`` into ``psip``
    (constant at ``psip_b`` unless the panel lies ``above`` the plug edge), each from its value
    at the panel's upper end, and ``I = J(0) - J`` into ``I0``. Returns ``err`` raised to their
    quadratures' errors."""
    nn = panels.N_NODES
    last = nn - 1
    # I = J(0) - J(xi), which is rounding noise once it falls below a few hundred ulps
    # of J(0) (deep in the tail, where what is left of every integral is below 1e-13),
    # and the difference of two quadratures (stage 2's J(0), this march's J) once what
    # is left of J falls below their tolerance: there the axis asymptotics
    # I = xi h omega_hat / (beta + 1) (omega_hat ~ xi^beta) stands in, and I/omega_hat
    # stays finite (J(0) - J would leave ~qtol J(0) / omega_hat in psi, growing without
    # bound towards the axis while the tail test waits for it to fall).
    asym = (J0 - J_b < I_NOISE * _EPS * J0
            or xs[0] * P[dv.Q_H, 0] * w[0] < qtol * J0 * (beta + 1.0))
    for j in range(nn):
        I0[j] = xs[j] * h_axis * w[j] / (beta + 1.0) if asym else J0 - Jn[j]
    for j in range(nn):
        v[j] = xs[j] * (P[dv.Q_H_DELTA, j] - I0[j] / w[j] * P[dv.Q_B_DELTA, j])
    # an error in psi enters the integrals below weighted by omega_hat, which falls
    # towards the axis (I/omega_hat, and its rounding, grows there)
    fall = w[last]
    tot, e = panels.cumulative(v, r, cum)
    err = max(err, e * fall / (qtol * (abs(psi0_b) + abs(tot)) + 1e-300))
    for j in range(nn):
        psi0[j] = psi0_b + cum[j]
    if above:
        for j in range(nn):
            v[j] = xs[j] * (P[dv.Q_H_DELTA, j] - (target - Jn[j]) / w[j] * P[dv.Q_B_DELTA, j])
        tot, e = panels.cumulative(v, r, cum)
        err = max(err, e * fall / (qtol * (abs(psip_b) + abs(tot)) + 1e-300))
        for j in range(nn):
            psip[j] = psip_b + cum[j]
    else:
        for j in range(nn):
            psip[j] = psip_b
    return err


@njit(**_JIT)
def _derivative_integrals(xs, P, w, Jn, I0, psi0, psip, r, h_axis, qtol, above, target, acc_abs,
                          pan, pan_err, pan_abs, low, row_err, v, cum):
    """The panel's parts of the ``_N_ACC`` integrals (d delta(1), dJ(0), dJ(xi_p) by eta, A, N)
    into ``pan``, their errors into ``pan_err``, magnitudes into ``pan_abs`` and bounds on what is
    left of each below the panel into ``low``; each parameter's largest error relative to
    ``qtol`` (and to the integral's magnitude so far, ``acc_abs``) into ``row_err``."""
    nn = panels.N_NODES
    last = nn - 1
    for c in range(_N_ACC):
        row = c % 3
        kind = c // 3
        for j in range(nn):
            wf = w[j] * P[dv.Q_F + row, j]
            if kind == 0:
                g = wf
            elif kind == 1:
                g = w[j] * P[dv.Q_HP + row, j] - I0[j] * P[dv.Q_BP + row, j] + psi0[j] * wf
            else:
                g = psip[j] * wf
                if above:
                    g += w[j] * P[dv.Q_HP + row, j] - (target - Jn[j]) * P[dv.Q_BP + row, j]
            v[j] = xs[j] * g
        pan[c], pan_err[c] = panels.cumulative(v, r, cum)
        # What is left below of this integral, bounded as stage 2 bounds J's tail (each
        # term falls at least like xi^(beta+1) towards the axis, and I <= xi max|h|
        # omega_hat there: J(0) - J(xi) itself is rounding noise by then).
        low[c] = abs(v[last])
        if kind == 1:
            h_max = max(abs(P[dv.Q_H, last]), abs(h_axis))
            low[c] = xs[last] * w[last] * (
                abs(P[dv.Q_HP + row, last]) + xs[last] * h_max * abs(P[dv.Q_BP + row, last])
                + abs(psi0[last] * P[dv.Q_F + row, last]))
        size = 0.0
        for j in range(nn):
            size += abs(v[j])
        pan_abs[c] = 2.0 * r * size / nn
        scale = acc_abs[c] + pan_abs[c]
        if scale > 0.0:
            row_err[row] = max(row_err[row], pan_err[c] / (qtol * scale))


@njit(**_JIT)
def _profile_panel(xs, P, w, r, a, b, F0, pan, t_pro, todo, Fb, Lb, dJb, slope, fwd, Sn, cum,
                   prof):
    """The forward sensitivities across an accepted panel ``[a, b]``, into ``prof`` at the profile
    points ``t_pro`` on it (their ``todo`` cleared), and the running values at its upper end moved
    to its lower end: ``Fb`` (the integral of ``omega_hat df/dp`` from the wall), ``Lb`` (``d log
    omega_hat/dp``), ``dJb`` and ``slope`` (that of ``d log omega_hat/dp`` in ``ln xi``)."""
    nn = panels.N_NODES
    last = nn - 1
    vF, vB, vJ = fwd[0], fwd[1], fwd[2]
    for row in range(3):
        for j in range(nn):
            vF[row, j] = xs[j] * (w[j] * P[dv.Q_F + row, j])
        panels.cumulative(vF[row], r, cum)
        for j in range(nn):
            Sn[j] = (F0[row] - (Fb[row] + cum[j])) / w[j]
            vB[row, j] = xs[j] * (P[dv.Q_BP + row, j] + P[dv.Q_B_DELTA, j] * Sn[j])
        panels.cumulative(vB[row], r, cum)
        for j in range(nn):
            vJ[row, j] = xs[j] * w[j] * (P[dv.Q_HP + row, j] + P[dv.Q_H_DELTA, j] * Sn[j]
                                         + P[dv.Q_H, j] * (Lb[row] - cum[j]))
        L_end = Lb[row] - cum[last]
        dJ_pan, _ = panels.cumulative(vJ[row], r, cum)
        slope[row] = vB[row, last]
        for i in range(t_pro.size):
            if todo[i] and a <= t_pro[i] <= b:
                u = min(2.0, max(0.0, (b - t_pro[i]) / r))
                prof[PS_J + row, i] = dJb[row] + panels.partial(vJ[row], r, u)
                prof[PS_LOGW + row, i] = Lb[row] - panels.partial(vB[row], r, u)
        Fb[row] += pan[row]
        Lb[row] = L_end
        dJb[row] += dJ_pan
    for i in range(t_pro.size):
        if a <= t_pro[i] <= b:
            todo[i] = False


@njit(**_JIT)
def _profile_below(b, t_pro, todo, Lb, dJb, slope, prof):
    """The forward sensitivities at the profile points below the march's end ``b`` (``todo``),
    and the march's own ``dJ`` at its end in ``prof``'s last column."""
    n_pro = t_pro.size
    for row in range(3):
        for i in range(n_pro):
            if todo[i]:
                # below the march: log omega_hat ~ beta ln xi (slope: xi (B_p + B_delta S) ->
                # dbeta/dp); dJ is the caller's dJ(0) (NaN here: the tail test bounds what is
                # left of the adjoint integrals, not of this one)
                prof[PS_J + row, i] = math.nan
                prof[PS_LOGW + row, i] = Lb[row] + slope[row] * (t_pro[i] - b)
        prof[PS_J + row, n_pro] = dJb[row]
        prof[PS_LOGW + row, n_pro] = math.nan


@njit(**_JIT)
def _wall_derivatives(A, N, delta1, D1, acc, have_p, target, hw_p, accepted, unresolved, out):
    """The outputs' derivatives from the accumulated integrals ``acc``: the wall's ``delta``,
    ``mu`` and ``sigma_yx``, ``J(0)``, and ``1 - xi_p`` (``hw_p``: ``h omega_hat`` at the plug
    edge), into ``out``'s ``S_*`` slots, with the march's panels and unresolved flags; status ok."""
    sq = math.sqrt(D1)
    D_d, D_A, D_N = dv.yield_D_partials(1.0, delta1, A, N)
    for i in range(3):
        out[S_DELTA_WALL + i] = acc[i]
        out[S_MU_WALL + i] = acc[i]
        out[S_J_AXIS + i] = acc[3 + i]
        out[S_SIGMA_YX_WALL + i] = -D_d * acc[i] / (2.0 * sq)
    out[S_MU_WALL + 2] -= 1.0  # mu = delta - N
    out[S_SIGMA_YX_WALL + 1] += 1.0 - D_A / (2.0 * sq)  # sigma_yx(1) = A - sqrt(D(1))
    out[S_SIGMA_YX_WALL + 2] -= D_N / (2.0 * sq)
    if have_p:
        # J(xi_p) - 0.95 J(0) + 0.05 eps K = 0, and dJ/dxi = -h omega_hat
        for i in range(3):
            out[S_ONE_MINUS + i] = -(acc[6 + i] - 0.95 * acc[3 + i]) / hw_p
        out[S_ONE_MINUS + 3] = -0.05 / hw_p
    elif target <= 0.0:
        for i in range(4):
            out[S_ONE_MINUS + i] = 0.0  # Delta = 0 on a neighbourhood (eq:13's target < 0)
    out[S_PANELS] = accepted
    for i in range(3):
        out[S_UNRESOLVED + i] = 1.0 if unresolved[i] else 0.0
    out[S_STATUS] = st.OK


@njit(**_JIT)
def _mark_unresolved(row_err, unresolved):
    # the parameters whose derivatives a panel taken unresolved leaves above the solve's rtol
    # (STAGE2_TOL is the march's margin below it)
    for row in range(3):
        if not row_err[row] <= 1.0 / STAGE2_TOL:
            unresolved[row] = True


@njit(**_JIT)
def _log_points(xis):
    """``ln xi`` of the profile points (``-inf`` at the axis)."""
    t_pro = np.empty(xis.size)
    for i in range(xis.size):
        t_pro[i] = math.log(xis[i]) if xis[i] > 0.0 else -math.inf
    return t_pro


@njit(**_JIT)
def _tail_reached(xs, P, w, h_axis, tail_tol, J_b, low, acc_abs):
    """Whether what is left below the last panel's lower end, of ``J`` (bounded as stage 2 bounds
    it) and of each integral (``low``), is below ``tail_tol`` of what they add up to."""
    last = panels.N_NODES - 1
    tail = 2.0 * max(xs[last] * P[dv.Q_H, last] * w[last],
                     h_axis * xs[last] * w[last]) < tail_tol * J_b
    for c in range(_N_ACC):
        tail = tail and 2.0 * low[c] <= tail_tol * acc_abs[c]
    return tail


@njit(**_JIT)
def sensitivity_batch(eta, A, N, eps_K, offsets, one_minus, rtol, atol, max_steps_stage1,
                      max_steps_stage2, out):
    """:func:`sensitivity_kernel` for many ``(eta, A, N)`` triples (``A > -1``), each with its run
    of ``eps K`` values ``eps_K[offsets[i]:offsets[i+1]]`` and their ``1 - xi_p`` in
    ``one_minus``: one solve per triple (as ``solve_point`` runs it), one sensitivity march per
    point (the plug edge's split depends on ``eps K``), into ``out[j]``; ``out[j, S_STATUS]``
    is the triple's status where it has no solution or ``A = -1`` (NaN slots: the caller takes
    the closed form, :func:`a_minus_one`). The same numbers as
    :func:`point_sensitivities` per point, bit for bit."""
    ax = np.empty(model.N_AX)
    T1, Q1 = stage1_arrays(max_steps_stage1)
    T2, Q2 = stage2_arrays(max_steps_stage2)
    stats1 = np.zeros(stepping.N_STATS, dtype=np.int64)
    stats2 = np.zeros(stepping.N_STATS, dtype=np.int64)
    res = np.empty(N_R)
    xis = np.empty(0)
    F0 = np.empty(3)
    prof = np.empty((N_PS, 1))
    for i in range(eta.size):
        code = solve_eta(eta[i], A[i], N[i], rtol, atol, ax, T1, Q1, T2, Q2, stats1, stats2, res,
                         METHOD_AUTO, True)
        for j in range(offsets[i], offsets[i + 1]):
            if code == st.OK and A[i] > -1.0:
                sensitivity_kernel(eta[i], A[i], N[i], eps_K[j], one_minus[j], rtol, atol, ax, res,
                                   T1, Q1, out[j], xis, F0, prof)
            else:  # no solution, or A = -1 (the closed form, by the caller)
                out[j, :] = math.nan
                out[j, S_STATUS] = code
