"""Sensitivities of a solved point's outputs to its parameters (``solve_point(sensitivities=True)``).

The derivatives of the marched quantities by ``(eta, A, N)`` come from the adjoint march of
:mod:`.adjoint` (or, at ``A = -1``, the closed form, :func:`a_minus_one`); here they are taken to
every differentiable output (``Output.differentiable``) by ``eps, L, K, A, N`` and the material's
inputs, for one point (:func:`point_sensitivities`) and whole arrays alike (:func:`assemble`).
Where the march leaves a derivative short of the tolerance it is computed by differences
(:func:`differences`) or is NaN, with a flag (:data:`FLAGS`) that says which; the solve's status
is never touched. Imported only when sensitivities are asked for: its kernels are compiled only
then.
"""

from __future__ import annotations

import math

import numpy as np

from .. import outputs as out_
from .. import status as st
from ..physics import closure, model
from .adjoint import (N_PS, N_S, PS_J, PS_LOGW, S_DELTA_WALL, S_J_AXIS, S_MU_WALL, S_ONE_MINUS,
                      S_SIGMA_YX_WALL, S_STATUS, S_UNRESOLVED, sensitivity_batch,
                      sensitivity_kernel)
from .layout import R_J_AXIS, R_MU_WALL, R_SIGMA_YX_WALL

__all__ = ["point_sensitivities", "profile_sensitivities", "chain_rule", "a_minus_one",
           "material_sensitivities", "assemble", "differences", "differentiable",
           "sensitivity_batch", "PARAMETERS", "PROFILE_OUTPUTS", "FLAGS", "N_S"]

# The parameters of a point (the outputs that have sensitivities are marked in the registry,
# ``Output.differentiable``).
PARAMETERS = ("eps", "L", "K", "A", "N")
# The profiles that have sensitivities (by eps, L, K, A, N).
PROFILE_OUTPUTS = ("u_over_u0", "omega_hat")
_NO_PROFILE = np.empty(0)
_NO_PROF = np.empty((N_PS, 1))
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


# How each derivative was computed, or why it is NaN (``PointResult.sensitivity_flags`` and the
# ``sensitivity_flags`` variable of ``solve(..., sensitivities=True)``); the status is the solve's.
FLAG_ADJOINT = 0  # the adjoint quadrature, or the closed form at A = -1
FLAG_DIFFERENCES = 1  # central differences of tighter solves, within the tolerance
FLAG_UNRESOLVED = 2  # NaN: neither the quadrature nor the differences reached the tolerance
FLAG_NO_SOLUTION = 3  # NaN: the point has no solution
FLAG_UNDEFINED = 4  # NaN: by A at A = -1, where the closed form holds alone
FLAGS = ("adjoint", "differences", "unresolved", "no_solution", "undefined")
# The raw derivative each output's derivatives are made of (chain_rule; None: a closed form in
# the material alone), and the rows (eta, A, N, eps K) of the raw derivatives per parameter.
_RAW = {"Delta": "om", "xi_p": "om", "slip": "J", "u_axis": "J", "m_wall": "mu",
        "sigma_yx_wall": "sig", "nu": None, "sigma_xx_wall_Pa": None, "sigma_xy_wall_Pa": None,
        "sigma_yx_wall_Pa": "sig", "m_wall_Pa_m": "mu"}
_ROWS = {"eps": (0, 3), "L": (0,), "K": (3,), "A": (1,), "N": (2,)}
_SLOTS = {"mu": S_MU_WALL, "sig": S_SIGMA_YX_WALL, "J": S_J_AXIS, "om": S_ONE_MINUS}
# The differences: solves at this rtol, steps of this size relative to the parameter (a fifth
# root of the solves' error balances it against Richardson's h^4), and a difference taken when
# its error estimate is below this many rtol of the derivative's scale.
DIFF_RTOL = 1e-13
DIFF_STEP = 2e-3
DIFF_ACCEPT = 10.0


def differentiable(names) -> list:
    """The outputs among ``names`` that have derivatives (``Output.differentiable``); a
    ``ValueError`` for one marked so that this module has no chain rule for."""
    names = [n for n in names if n in out_.OUTPUTS and out_.OUTPUTS[n].differentiable]
    for n in names:
        if n not in _RAW:
            raise ValueError(f"output {n!r} is marked differentiable, but the sensitivities have "
                             "no chain rule for it (cosserat_channel.solver.sensitivity)")
    return names


def point_sensitivities(code, eps, L, K, A, N, rtol, atol, ws, one_minus, values, material,
                        profile=None):
    """``({output: {parameter: derivative}}, {output: {parameter: flag name}}, profile
    sensitivities)`` for a point ``solve_point`` just solved in workspace ``ws`` (``one_minus``:
    its ``1 - xi_p``, NaN when not computed; ``profile``: its profiles, or None, then the last
    item is None too, else :func:`profile_sensitivities`'s).

    The computed outputs that are differentiable get derivatives by ``eps, L, K, A, N`` and, for
    those that need a material, by each of its inputs, through :func:`assemble` (the same as a
    whole array's); where the adjoint quadrature misses the tolerance they come from
    differences, or are NaN with a flag that says why. The solve's status is not touched.
    """
    names = differentiable(values)
    eta, eps_K = eps * L, eps * K
    want_plug = not math.isnan(one_minus)
    out = np.full((1, N_S), math.nan)
    if code == st.OK and A != -1.0:
        sensitivity_kernel(eta, A, N, eps_K, one_minus if want_plug else math.nan, rtol, atol,
                           ws.ax, ws.res, ws.T1, ws.Q1, out[0], _NO_PROFILE,
                           out[0, S_DELTA_WALL:S_DELTA_WALL + 3], _NO_PROF)
    one = {k: np.array([v]) for k, v in dict(
        eps=eps, L=L, K=K, A=A, N=N, J0=ws.res[R_J_AXIS], mu=ws.res[R_MU_WALL],
        sig=ws.res[R_SIGMA_YX_WALL], one_minus=one_minus).items()}
    result, flags = assemble(names, out, np.array([code]), one, material, rtol, atol)
    sens = {n: {p: float(v[0]) for p, v in d.items()} for n, d in result.items()}
    names_of = {n: {p: FLAGS[int(f[0])] for p, f in d.items()} for n, d in flags.items()}
    prof_sens = None
    if profile is not None:
        prof_sens = _profile_nan(profile)
        ok = code == st.OK and (A == -1.0 or (out[0, S_STATUS] == st.OK
                                              and not out[0, S_UNRESOLVED:].any()))
        if ok:
            F0 = None if A == -1.0 else (out[0, S_DELTA_WALL:S_DELTA_WALL + 3].copy(),
                                          out[0, S_J_AXIS:S_J_AXIS + 3].copy())
            prof_sens = profile_sensitivities(eps, L, K, A, N, rtol, atol, ws, profile, F0)
    return sens, names_of, prof_sens


def assemble(names, out, status, x, material, rtol, atol):
    """``({output: {parameter: array}}, {output: {parameter: flag array}})`` of many points.

    ``out[n, N_S]``: :func:`sensitivity_kernel`'s results per point (NaN rows where it did not
    run: no solution, or ``A = -1``); ``status`` the points' status codes; ``x`` the arrays
    ``eps, L, K, A, N`` and the solved ``J0``, ``mu`` (``m(1)/(nu L)``), ``sig``
    (``sigma_yx(1)/nu``), ``one_minus``. At ``A = -1`` the closed form (:func:`a_minus_one`);
    where the quadrature gave up, or left a parameter unresolved, that parameter's raw
    derivatives by :func:`differences`; then :func:`chain_rule` and, with a material,
    :func:`material_sensitivities`. Values are NaN wherever the flag is not ``adjoint`` or
    ``differences``.
    """
    n = status.size
    ok = status == st.OK
    eps, L, K, A, N = (x[k] for k in PARAMETERS)
    eta, eps_K = eps * L, eps * K
    raw = {q: [out[:, s + c].copy() for c in range(4 if q == "om" else 3)] for q, s in _SLOTS.items()}
    raw_flag = {q: [np.zeros(n, dtype=np.int8) for _ in v] for q, v in raw.items()}
    for i in np.flatnonzero(ok & (A == -1.0)):
        closed = a_minus_one(float(eta[i]), float(N[i]), float(eps_K[i]),
                             not math.isnan(x["one_minus"][i]))
        for q, vals in zip(_SLOTS, closed):
            for c, v in enumerate(vals):
                raw[q][c][i] = v
    kernel_failed = ok & (A != -1.0) & (out[:, S_STATUS] != st.OK)
    for i in np.flatnonzero(ok & (A != -1.0)):
        rows = [c for c in range(3) if kernel_failed[i] or out[i, S_UNRESOLVED + c] != 0.0]
        if kernel_failed[i]:
            rows.append(3)
        if not rows:
            continue
        want_plug = not math.isnan(x["one_minus"][i])
        for q, c, value, flag in differences(float(eta[i]), float(A[i]), float(N[i]),
                                             float(eps_K[i]), rows, want_plug, rtol, atol):
            raw[q][c][i] = value
            raw_flag[q][c][i] = flag
    result = chain_rule(*raw.values(), eps, L, K, x["J0"], x["mu"], x["one_minus"])
    material_names = [o for o in names if out_.OUTPUTS[o].material]
    if material is not None and material_names:
        # the material's derivatives are scalar Python per point (the closure's root)
        mats = {o: {p: np.full(n, math.nan) for p in PARAMETERS + tuple(material)}
                for o in material_names}
        for i in np.flatnonzero(ok):
            point = {o: {p: float(v[i]) for p, v in result[o].items()} for o in result}
            m = material_sensitivities(names, material, float(eps[i]), float(N[i]),
                                       float(L[i] * x["mu"][i]), float(x["sig"][i]), point)
            for o, ds in m.items():
                for p, v in ds.items():
                    mats[o][p][i] = v
        result.update(mats)
    values, flags = {}, {}
    for o in names:
        values[o], flags[o] = {}, {}
        for p, v in result[o].items():
            f = np.zeros(n, dtype=np.int8)
            q = _RAW[o]
            if q is not None and p in _ROWS:
                for c in _ROWS[p]:
                    if c < len(raw_flag[q]):
                        f = np.maximum(f, raw_flag[q][c])
            if p == "A":
                f[ok & (A == -1.0)] = FLAG_UNDEFINED
            f[~ok] = FLAG_NO_SOLUTION
            v = np.asarray(v, dtype=np.float64) * np.ones(n)
            v = np.where(f <= FLAG_DIFFERENCES, v, math.nan)
            f[(f <= FLAG_DIFFERENCES) & np.isnan(v)] = FLAG_UNRESOLVED
            values[o][p], flags[o][p] = v, f
    return values, flags


def differences(eta, A, N, eps_K, rows, want_plug, rtol, atol):
    """``(quantity, row, value, flag)`` for the raw derivatives by the parameters ``rows``
    (indices into ``(eta, A, N, eps K)``) of ``mu``, ``sig``, ``J`` (``J(0)``) and ``om``
    (``1 - xi_p``, with ``want_plug``): Richardson-extrapolated central differences of solves at
    :data:`DIFF_RTOL` with steps ``h``, ``2h`` and ``4h``; the difference of the extrapolations
    from ``(h, 2h)`` and ``(2h, 4h)`` bounds the first's error (it falls like ``h^4``). Taken
    (``FLAG_DIFFERENCES``) where that bound is below ``DIFF_ACCEPT * rtol`` of the derivative's
    scale (the quantity over the parameter), else NaN and ``FLAG_UNRESOLVED``: also where a
    neighbour has no solution."""
    from .batch import Workspace
    from .plug_edge import one_minus_xi_p

    ws = Workspace()
    base = (eta, A, N, eps_K)

    def raw_at(y, with_plug):
        code = ws.run(y[0], y[1], y[2], DIFF_RTOL, atol * DIFF_RTOL / max(rtol, DIFF_RTOL))
        if code != st.OK:
            return None
        om = (float(one_minus_xi_p(y[3], ws.res, ws.ax, ws.T2, ws.Q2)) if with_plug
              else math.nan)
        return {"mu": ws.res[R_MU_WALL], "sig": ws.res[R_SIGMA_YX_WALL], "J": ws.res[R_J_AXIS],
                "om": om}

    centre = raw_at(base, want_plug)
    found = []
    for c in rows:
        size = max(abs(base[c]), 1e-2)
        h = DIFF_STEP * size
        if c == 1:
            h = min(h, 0.2 * (A + 1.0))  # A - 4h stays above -1
        if c == 0:
            h = min(h, 0.2 * eta)
        vals = {}
        if c == 3 and centre is not None:
            # eps K moves the plug edge alone: the centre's solve, the root at each eps K
            raw_at(base, False)
        for k in (-4, -2, -1, 1, 2, 4):
            y = list(base)
            y[c] += k * h
            if c < 3:
                vals[k] = raw_at(y, want_plug)
            elif centre is not None:
                vals[k] = {"om": float(one_minus_xi_p(y[3], ws.res, ws.ax, ws.T2, ws.Q2))}
        for q in (("om",) if c == 3 else ("mu", "sig", "J", "om")):
            if q == "om" and not want_plug:
                continue
            if centre is None or any(v is None for v in vals.values()):
                found.append((q, c, math.nan, FLAG_UNRESOLVED))
                continue
            d1, d2, d4 = ((vals[k][q] - vals[-k][q]) / (2 * k * h) for k in (1, 2, 4))
            r1, r2 = (4.0 * d1 - d2) / 3.0, (4.0 * d2 - d4) / 3.0
            scale = abs(centre[q]) / size + abs(r1)
            good = abs(r1 - r2) <= DIFF_ACCEPT * rtol * scale and math.isfinite(r1)
            found.append((q, c, r1 if good else math.nan,
                          FLAG_DIFFERENCES if good else FLAG_UNRESOLVED))
    return found


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
    for n in ("Delta", "xi_p", "slip", "u_axis", "m_wall", "sigma_yx_wall"):
        if n == "Delta":
            d = by_point(*d_om)
            d = {p: x / eps for p, x in d.items()}
            d["eps"] -= one_minus / (eps * eps)
        elif n == "xi_p":
            d = {p: -x for p, x in by_point(*d_om).items()}
        elif n == "u_axis":
            d = by_point(*d_J, 1.0)
        elif n == "slip":
            # slip = eps K / u(0), u(0) = eps K + J(0): scaled by 1/u(0) first, since u(0)^2
            # overflows for K beyond ~1e154 (K has no upper bound).
            inv = 1.0 / (eps_K + J0)
            slip = eps_K * inv
            d = by_point(*(-slip * (x * inv) for x in d_J), (J0 * inv) * inv)
        elif n == "m_wall":
            d = by_point(*(L * x for x in d_mu))
            d["L"] += mu
        elif n == "sigma_yx_wall":
            d = by_point(*d_sig)
        else:
            continue
        result[n] = d
    return result


def _profile_nan(profile):
    if profile is None:
        return None
    size = np.asarray(profile["xi"]).size
    return {n: {p: np.full(size, math.nan) for p in PARAMETERS} for n in PROFILE_OUTPUTS}


def material_sensitivities(names, material, eps, N, m_wall, sigma_yx_wall, result):
    """The derivatives of the material outputs among ``names`` (eq:35 through
    :func:`closure.solids_fraction_partials`, the stresses in Pa by the product rule of their
    definitions in :mod:`..outputs`)."""
    rho_g_W = material["rho_p"] * material["g"] * (material["d_p"] / eps)
    phi = math.radians(material["phi"])
    tan_delta = math.sin(phi) / N
    nu = closure.solids_fraction(rho_g_W, tan_delta, material)
    if not math.isfinite(nu):
        keys = PARAMETERS + tuple(material)
        return {n: dict.fromkeys(keys, math.nan) for n in names if out_.OUTPUTS[n].material}
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
