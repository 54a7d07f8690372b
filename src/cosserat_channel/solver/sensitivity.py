"""Sensitivities of a solved point's outputs to its parameters (``solve_point(sensitivities=True)``).

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
:func:`chain_rule` takes both to ``eps, L, K``. Imported only when sensitivities are asked for:
its kernels are compiled only then.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .._jit import EPS as _EPS, JIT as _JIT
from .. import status as st
from ..integrate import panels
from ..physics import closure, model
from ..physics import derivatives as dv
from ..integrate import stepping
from .batch import solve_eta
from .layout import METHOD_AUTO, N_R, R_J_AXIS, R_MU_WALL, R_N1, R_SIGMA_YX_WALL
from .stage1 import stage1_arrays
from .stage2 import (FIRST_PANEL, MAX_STEPS_STAGE2, STAGE2_TOL, TAIL_FRACTION, XI_FLOOR, _h_axis,
                     stage2_arrays)
from .stress_path import _delta_wall, _wall_increments, delta_D_at, xi_of_log

__all__ = ["sensitivity_kernel", "sensitivity_batch", "point_sensitivities", "profile_sensitivities",
           "chain_rule", "a_minus_one", "material_sensitivities", "PARAMETERS", "OUTPUTS", "PROFILE_OUTPUTS"]

# Slots of the kernel's result vector; derivatives with respect to (eta, A, N) in three slots each.
S_STATUS = 0
S_MU_WALL = 1  # d(m(1)/(nu L))/d(eta, A, N)
S_SIGMA_YX_WALL = 4  # d(sigma_yx(1)/nu)/d(eta, A, N)
S_J_AXIS = 7  # dJ(0)/d(eta, A, N)
S_ONE_MINUS = 10  # d(1 - xi_p)/d(eta, A, N, eps K): four slots
S_PANELS = 14  # accepted panels
S_DELTA_WALL = 15  # d delta(1)/d(eta, A, N): the input ``F0`` of a profile call
N_S = 18
# Rows of a profile call's ``prof`` (each by eta, A, N): dJ(xi), d log omega_hat(xi).
PS_J = 0
PS_LOGW = 3
N_PS = 6

# The parameters of a point, and the outputs that have sensitivities.
PARAMETERS = ("eps", "L", "K", "A", "N")
OUTPUTS = ("Delta", "xi_p", "slip", "u_axis", "m_wall", "sigma_yx_wall", "nu", "sigma_xx_wall_Pa",
           "sigma_xy_wall_Pa", "sigma_yx_wall_Pa", "m_wall_Pa_m")
# The profiles that have sensitivities (by eps, L, K, A, N).
PROFILE_OUTPUTS = ("u_over_u0", "omega_hat")
_NO_PROFILE = np.empty(0)
_NO_PROF = np.empty((N_PS, 1))
# Rows of the accumulated integrals: d delta(1), dJ(0), dJ(xi_p) at fixed xi_p, three each.
_N_ACC = 9
# J(0) - J(xi) below this many ulps of J(0) is rounding noise (see sensitivity_kernel).
I_NOISE = 256.0


@njit(**_JIT)
def sensitivity_kernel(eta, A, N, eps_K, one_minus, rtol, atol, ax, res, T1, Q1, out, xis, F0,
                       prof):
    """Derivatives of a solved ``(eta, A, N)`` (``A > -1``) into ``out[N_S]`` (slots ``S_*``).

    ``ax``, ``res`` and ``(T1, Q1)`` are those the solve left (status ok, stage 2 run);
    ``one_minus`` is ``1 - xi_p`` at ``eps_K`` (NaN: no plug-edge derivatives). The panels follow
    stage 1's steps and resolve the integrands to ``STAGE2_TOL * rtol`` (relative to the sum of
    their magnitudes), and stop once what is left down to the axis is below
    ``TAIL_FRACTION * rtol`` of it, as stage 2 does.

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
    X = panels.X
    P = np.empty((dv.N_Q, nn))
    xs = np.empty(nn)
    w = np.empty(nn)
    Jn = np.empty(nn)
    I0 = np.empty(nn)
    beta = ax[model.AX_BETA]
    psi0 = np.empty(nn)
    psip = np.empty(nn)
    v = np.empty(nn)
    cum = np.empty(nn)
    acc = np.zeros(_N_ACC)
    acc_abs = np.zeros(_N_ACC)
    pan = np.empty(_N_ACC)
    pan_abs = np.empty(_N_ACC)
    pan_err = np.empty(_N_ACC)
    low = np.empty(_N_ACC)
    t_floor = math.log(XI_FLOOR)
    n_pro = xis.size
    t_pro = np.empty(n_pro)
    todo = np.ones(n_pro, dtype=np.bool_)
    for i in range(n_pro):
        t_pro[i] = math.log(xis[i]) if xis[i] > 0.0 else -math.inf
    vF = np.empty((3, nn))
    vB = np.empty((3, nn))
    vJ = np.empty((3, nn))
    Sn = np.empty(nn)
    Ln = np.empty(nn)
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
    for _ in range(MAX_STEPS_STAGE2):
        lo_eff = t_p if (have_p and b > t_p > lo) else lo
        a = b - length
        if a < lo_eff + 0.25 * length:
            a = lo_eff
        r = 0.5 * (b - a)
        mid = 0.5 * (a + b)
        good = True
        for j in range(nn):
            t = b if j == 0 else (a if j == last else mid + r * X[j])
            xi, s = xi_of_log(t)
            xs[j] = xi
            delta, D, _ = delta_D_at(xi, s, k, T1, Q1, C, A, N, ax, delta1, D1)
            if not D > 0.0:
                good = False
                break
            dv.rate_partials(xi, delta, D, eta, A, N, P, j)
        err = math.nan
        y_drop = 0.0
        if good:
            # log omega_hat and J, as stage 2 (d log omega_hat/dt = xi B, dJ/dt = -xi h omega_hat)
            for j in range(nn):
                v[j] = xs[j] * P[dv.Q_B, j]
            _, err_y = panels.cumulative(v, r, cum)
            y_drop = cum[last]
            for j in range(nn):
                w[j] = math.exp(y_b - cum[j])
                v[j] = xs[j] * P[dv.Q_H, j] * w[j]
            _, err_J = panels.cumulative(v, r, cum)
            for j in range(nn):
                Jn[j] = J_b + cum[j]
            err = max(err_y / qtol, err_J / (qtol * J0 + atol_J))
            # the adjoints psi of J(0) and of J(xi_p)
            above = have_p and a >= t_p
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
                    v[j] = xs[j] * (P[dv.Q_H_DELTA, j]
                                    - (target - Jn[j]) / w[j] * P[dv.Q_B_DELTA, j])
                tot, e = panels.cumulative(v, r, cum)
                err = max(err, e * fall / (qtol * (abs(psip_b) + abs(tot)) + 1e-300))
                for j in range(nn):
                    psip[j] = psip_b + cum[j]
            else:
                for j in range(nn):
                    psip[j] = psip_b
            for c in range(_N_ACC):
                row = c % 3
                kind = c // 3
                for j in range(nn):
                    wf = w[j] * P[dv.Q_F + row, j]
                    if kind == 0:
                        g = wf
                    elif kind == 1:
                        g = (w[j] * P[dv.Q_HP + row, j] - I0[j] * P[dv.Q_BP + row, j]
                             + psi0[j] * wf)
                    else:
                        g = psip[j] * wf
                        if above:
                            g += (w[j] * P[dv.Q_HP + row, j]
                                  - (target - Jn[j]) * P[dv.Q_BP + row, j])
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
                    err = max(err, pan_err[c] / (qtol * scale))
        if not err <= 1.0:  # also NaN: a node outside the admissible region within round-off
            length = (b - a) * (min(0.5, panels.panel_error_factor(err, 1.0))
                                if math.isfinite(err) else 0.25)
            if length < 1e-15:
                return
            continue
        accepted += 1
        if n_pro > 0:
            for row in range(3):
                for j in range(nn):
                    vF[row, j] = xs[j] * (w[j] * P[dv.Q_F + row, j])
                panels.cumulative(vF[row], r, cum)
                for j in range(nn):
                    Sn[j] = (F0[row] - (Fb[row] + cum[j])) / w[j]
                    vB[row, j] = xs[j] * (P[dv.Q_BP + row, j] + P[dv.Q_B_DELTA, j] * Sn[j])
                panels.cumulative(vB[row], r, cum)
                for j in range(nn):
                    Ln[j] = Lb[row] - cum[j]
                    vJ[row, j] = xs[j] * w[j] * (P[dv.Q_HP + row, j] + P[dv.Q_H_DELTA, j] * Sn[j]
                                                 + P[dv.Q_H, j] * Ln[j])
                dJ_pan, _ = panels.cumulative(vJ[row], r, cum)
                slope[row] = vB[row, last]
                for i in range(n_pro):
                    if todo[i] and a <= t_pro[i] <= b:
                        u = min(2.0, max(0.0, (b - t_pro[i]) / r))
                        prof[PS_J + row, i] = dJb[row] + panels.partial(vJ[row], r, u)
                        prof[PS_LOGW + row, i] = Lb[row] - panels.partial(vB[row], r, u)
                Fb[row] += pan[row]
                Lb[row] = Ln[last]
                dJb[row] += dJ_pan
            for i in range(n_pro):
                if a <= t_pro[i] <= b:
                    todo[i] = False
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
        passed = not have_p or b <= t_p
        tail = passed and 2.0 * max(xs[last] * P[dv.Q_H, last] * w[last],
                                    h_axis * xs[last] * w[last]) < tail_tol * J_b
        for c in range(_N_ACC):
            tail = tail and 2.0 * low[c] <= tail_tol * acc_abs[c]
        if tail or b <= t_floor:
            break
        length = 2.0 * r * panels.panel_error_factor(err, 1.0)
        if a == lo and k >= 0:
            k -= 1
            lo = math.log(T1[k]) if k >= 0 else t_floor
    else:
        return
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
    out[S_STATUS] = st.OK


def a_minus_one(eta, N, eps_K, want_plug):
    """The closed form of Appendix A (docs/model.md, section 6) differentiated: ``(mu, sigma_yx,
    J(0), 1 - xi_p)`` derivatives by ``(eta, A, N[, eps K])``; with respect to A they are NaN
    (the closed form holds at A = -1 alone)."""
    nan = math.nan
    c = model.a_minus_one_xi_B(eta, N)  # xi B = c = 2N/eta
    c_eta, c_N = -c / eta, 2.0 / eta
    J_c = -2.0 / (c + 1.0) ** 2  # J(0) = 2/(c+1)
    one_minus = (nan,) * 4
    if want_plug:
        q = 0.05 + 0.025 * eps_K * (c + 1.0)  # xi_p^(c+1) = q
        if q >= 1.0:
            one_minus = (0.0, nan, 0.0, 0.0)
        else:
            xi_p = q ** (1.0 / (c + 1.0))
            lx_c = 0.025 * eps_K / (q * (c + 1.0)) - math.log(q) / (c + 1.0) ** 2
            lx_k = 0.025 / q
            one_minus = (-xi_p * lx_c * c_eta, nan, -xi_p * lx_c * c_N, -xi_p * lx_k)
    return (0.0, nan, -1.0), (0.0, nan, 0.0), (J_c * c_eta, nan, J_c * c_N), one_minus


def point_sensitivities(code, eps, L, K, A, N, rtol, atol, ws, one_minus, values, material,
                        profile=None):
    """``({output: {parameter: derivative}}, profile sensitivities, status code)`` for a point
    ``solve_point`` just solved in workspace ``ws`` (``one_minus``: its ``1 - xi_p``, NaN when not
    computed; ``profile``: its profiles, or None, then the second item is None too, else
    :func:`profile_sensitivities`'s).

    Only outputs in ``values`` that :data:`OUTPUTS` lists get derivatives: by ``eps, L, K, A, N``
    and, for those that need a material, by each of its inputs. NaN where the point has no
    solution; the status turns ``integration_failed`` only where the sensitivity quadrature gives
    up (its panel budget) on a point that solved.
    """
    names = [n for n in OUTPUTS if n in values]
    mat_keys = tuple(material) if material is not None else ()
    nan = math.nan
    if code != st.OK:
        return {n: dict.fromkeys(PARAMETERS + (mat_keys if n in _MATERIAL_OUTPUTS else ()), nan)
                for n in names}, _profile_nan(profile), code
    F0 = None
    eta, eps_K = eps * L, eps * K
    want_plug = not math.isnan(one_minus)
    if A == -1.0:
        d_mu, d_sig, d_J, d_om = a_minus_one(eta, N, eps_K, want_plug)
    else:
        out = np.empty(N_S)
        sensitivity_kernel(eta, A, N, eps_K, one_minus if want_plug else nan, rtol, atol, ws.ax,
                           ws.res, ws.T1, ws.Q1, out, _NO_PROFILE, out[S_DELTA_WALL:], _NO_PROF)
        F0 = (out[S_DELTA_WALL:S_DELTA_WALL + 3].copy(), out[S_J_AXIS:S_J_AXIS + 3].copy())
        if out[S_STATUS] != st.OK:
            code = st.INTEGRATION_FAILED
            return {n: dict.fromkeys(PARAMETERS + (mat_keys if n in _MATERIAL_OUTPUTS else ()), nan)
                    for n in names}, _profile_nan(profile), code
        o = out.tolist()
        d_mu = o[S_MU_WALL:S_MU_WALL + 3]
        d_sig = o[S_SIGMA_YX_WALL:S_SIGMA_YX_WALL + 3]
        d_J = o[S_J_AXIS:S_J_AXIS + 3]
        d_om = o[S_ONE_MINUS:S_ONE_MINUS + 4]

    J0 = float(ws.res[R_J_AXIS])
    mu = float(ws.res[R_MU_WALL])
    result = chain_rule(d_mu, d_sig, d_J, d_om, eps, L, K, J0, mu, one_minus)
    if material is not None and any(n in _MATERIAL_OUTPUTS for n in names):
        sig = float(ws.res[R_SIGMA_YX_WALL])
        result.update(material_sensitivities(names, material, eps, N, L * mu, sig, result))
    prof_sens = None
    if profile is not None:
        prof_sens = profile_sensitivities(eps, L, K, A, N, rtol, atol, ws, profile, F0)
    return {n: result[n] for n in names}, prof_sens, code


def chain_rule(d_mu, d_sig, d_J, d_om, eps, L, K, J0, mu, one_minus):
    """``{output: {parameter: derivative}}`` of the scalar outputs without a material, from the
    derivatives by ``(eta, A, N)`` of ``mu(1)``, ``sigma_yx(1)`` and ``J(0)`` and by ``(eta, A, N,
    eps K)`` of ``1 - xi_p`` (sequences of three or four); floats or arrays of points alike
    (elementwise, so a point and an array of them get the same bits)."""
    eps_K = eps * K

    def by_point(x_eta, x_A, x_N, x_k=0.0):
        # (eta, A, N, eps K) -> (eps, L, K, A, N)
        return {"eps": L * x_eta + K * x_k, "L": eps * x_eta, "K": eps * x_k, "A": x_A, "N": x_N}

    result = {}
    for n in OUTPUTS[:6]:
        if n == "Delta":
            d = by_point(*d_om)
            d = {p: x / eps for p, x in d.items()}
            d["eps"] -= one_minus / (eps * eps)
        elif n == "xi_p":
            d = {p: -x for p, x in by_point(*d_om).items()}
        elif n == "u_axis":
            d = by_point(*d_J, 1.0)
        elif n == "slip":
            u2 = (eps_K + J0) ** 2
            d = by_point(*(-eps_K * x / u2 for x in d_J), J0 / u2)
        elif n == "m_wall":
            d = by_point(*(L * x for x in d_mu))
            d["L"] += mu
        elif n == "sigma_yx_wall":
            d = by_point(*d_sig)
        else:
            continue
        result[n] = d
    return result


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


def _profile_nan(profile):
    if profile is None:
        return None
    size = np.asarray(profile["xi"]).size
    return {n: {p: np.full(size, math.nan) for p in PARAMETERS} for n in PROFILE_OUTPUTS}


_MATERIAL_OUTPUTS = ("nu", "sigma_xx_wall_Pa", "sigma_xy_wall_Pa", "sigma_yx_wall_Pa", "m_wall_Pa_m")


def material_sensitivities(names, material, eps, N, m_wall, sigma_yx_wall, result):
    """The material outputs' derivatives (eq:35 through :func:`closure.solids_fraction_partials`,
    the stresses in Pa by the product rule of their definitions in :mod:`..outputs`)."""
    rho_g_W = material["rho_p"] * material["g"] * (material["d_p"] / eps)
    phi = math.radians(material["phi"])
    tan_delta = math.sin(phi) / N
    nu = closure.solids_fraction(rho_g_W, tan_delta, material)
    if not math.isfinite(nu):
        keys = PARAMETERS + tuple(material)
        return {n: dict.fromkeys(keys, math.nan) for n in names if n in _MATERIAL_OUTPUTS}
    part = closure.solids_fraction_partials(nu, material)
    S = rho_g_W * nu
    # d ln(rho_p g W) and d ln(tan delta) per parameter (rho_p g W = rho_p g d_p / eps,
    # tan delta = sin(phi) / N)
    d_lnR = {"eps": -1.0 / eps, "d_p": 1.0 / material["d_p"], "rho_p": 1.0 / material["rho_p"],
             "g": 1.0 / material["g"]}
    d_lnT = {"N": -1.0 / N, "phi": math.pi / 180.0 / math.tan(phi)}
    keys = PARAMETERS + tuple(material)
    d_nu = {}
    for p in keys:
        d_nu[p] = (part["ln_rho_g_W"] * d_lnR.get(p, 0.0) + part["ln_tan_delta"] * d_lnT.get(p, 0.0)
                   + part.get(p, 0.0))
    d_lnS = {p: d_lnR.get(p, 0.0) + d_nu[p] / nu for p in keys}  # S = rho_p g W nu
    out = {}
    for n in names:
        if n == "nu":
            out[n] = d_nu
        elif n == "sigma_xx_wall_Pa":
            out[n] = {p: S / tan_delta * (d_lnS[p] - d_lnT.get(p, 0.0)) for p in keys}
        elif n == "sigma_xy_wall_Pa":
            out[n] = {p: -S * d_lnS[p] for p in keys}
        elif n == "sigma_yx_wall_Pa":
            sig = result["sigma_yx_wall"]
            out[n] = {p: S * (sig.get(p, 0.0) + sigma_yx_wall * d_lnS[p]) for p in keys}
        elif n == "m_wall_Pa_m":
            m = result["m_wall"]
            d_p = material["d_p"]
            out[n] = {p: S * d_p * (m.get(p, 0.0) + m_wall * (
                d_lnS[p] + (1.0 / d_p if p == "d_p" else 0.0))) for p in keys}
    return out


def profile_sensitivities(eps, L, K, A, N, rtol, atol, ws, profile, F0):
    """``{profile: {parameter: ndarray}}`` at ``profile["xi"]`` for a point solved (status ok) in
    workspace ``ws`` (``profile``: its profiles, as :func:`..outputs.derive_profiles` gives them;
    ``F0``: ``d delta(1)/d(eta, A, N)`` and ``dJ(0)/d(eta, A, N)`` from :func:`sensitivity_kernel`,
    None at ``A = -1``).

    ``u_over_u0 = (eps K + J)/(eps K + J(0))`` and ``omega_hat`` by ``eps, L, K, A, N`` through
    the chain rule from the forward sensitivities of :func:`sensitivity_kernel` (a second march
    over the same panels) and the adjoint's ``dJ(0)``. At ``A = -1`` from the closed form of
    docs/model.md section 6 (NaN by ``A``).
    """
    xi = np.asarray(profile["xi"], dtype=np.float64)
    eta, eps_K = eps * L, eps * K
    with np.errstate(divide="ignore", invalid="ignore"):
        if A == -1.0:
            # J = 2 (1 - xi^(c+1))/(c+1), omega_hat = xi^c, c = 2N/eta
            c = model.a_minus_one_xi_B(eta, N)
            c_p = np.array([-c / eta, math.nan, 2.0 / eta])
            lx = np.log(np.where(xi > 0.0, xi, 1.0))
            xc1 = xi ** (c + 1.0)
            J_c = -2.0 * (1.0 - xc1) / (c + 1.0) ** 2 - 2.0 * xc1 * lx / (c + 1.0)
            dJ = J_c[None, :] * c_p[:, None]
            dJ0 = -2.0 / (c + 1.0) ** 2 * c_p
            dlogw = lx[None, :] * c_p[:, None]
        else:
            prof = np.empty((N_PS, xi.size + 1))
            out = np.empty(N_S)
            sensitivity_kernel(eta, A, N, eps_K, math.nan, rtol, atol, ws.ax, ws.res, ws.T1, ws.Q1,
                               out, np.ascontiguousarray(xi), F0[0], prof)
            if out[S_STATUS] != st.OK:
                return _profile_nan(profile)
            # dJ(0) of the adjoint, also below the march's end (whose forward value misses
            # what is left below it): u/u(0) = 1 at the axis exactly
            dJ0 = F0[1]
            dJ = prof[PS_J:PS_J + 3, :-1]
            dJ = np.where(np.isnan(dJ), dJ0[:, None], dJ)
            dlogw = prof[PS_LOGW:PS_LOGW + 3, :-1]
        w = np.asarray(profile["omega_hat"])
        u = np.asarray(profile["u_over_u0"])
        U = eps_K + float(ws.res[R_J_AXIS])
        d_u = (dJ - u[None, :] * dJ0[:, None]) / U
        # omega_hat = 0 at the axis (beta > 0) whatever the parameters
        d_w = np.where(w[None, :] > 0.0, w[None, :] * dlogw, 0.0)
    d_u_k = (1.0 - u) / U  # d u_over_u0 / d(eps K)

    def by_point(x, x_k):
        # (eta, A, N, eps K) -> (eps, L, K, A, N)
        return {"eps": L * x[0] + K * x_k, "L": eps * x[0], "K": eps * x_k, "A": x[1].copy(),
                "N": x[2].copy()}

    return {"u_over_u0": by_point(d_u, d_u_k), "omega_hat": by_point(d_w, np.zeros(xi.size))}
