"""An independent reference solution with scipy ``solve_ivp`` at tight tolerance (for tests,
reports and benchmarks; the solver never uses it).

Written from model.md directly and deliberately *differently* from the package: it keeps ``eps``
and ``L`` separate (no similarity), carries the unscaled ``delta = m + N L``, evaluates ``D`` in the
paper's form eq:a3, and marches stage 2 in ``t = ln(xi)`` instead of ``xi``. Agreement with the
package therefore checks the equations, the similarity and the numerics at once.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

RTOL = 1e-12
XI1 = 1e-6  # series start, as the paper does (it used 1e-5)


def classify(eps, L, A, N):
    """Status name from Appendix A and the eq:20 root condition, or None when stage 1 must run."""
    if A < 1 - 2 * N * N:
        return "wall_inadmissible"
    if A < -1:
        return "axis_spin_unbounded"
    if A == -1:
        return None
    # eq:20: eps^2 x^2 - 2(A+1)(eps + N/L) x + 2(A+1) = 0, smaller root with eps x <= A+1.
    a, b, c = eps * eps, -2 * (A + 1) * (eps + N / L), 2 * (A + 1)
    disc = b * b - 4 * a * c
    if disc < 0:
        return "eps_too_large_axis"
    x = (-b - math.sqrt(disc)) / (2 * a)
    if eps * x > A + 1:
        return "eps_too_large_axis"
    return None


def reference(eps, L, K, A, N, method="DOP853", rtol=RTOL, status_only=False):
    """Reference outputs (dict) for one point; ``status`` by name.

    With ``status_only`` the status alone, from stage 1 (next to an edge, where D(1) is tiny,
    stage 2's ``B ~ 1/sqrt(D)`` makes its march long, and the status does not need it).
    """
    out = {"status": classify(eps, L, A, N)}
    if out["status"] is not None:
        return out
    if A == -1:
        raise ValueError("reference() covers A > -1; A = -1 has a closed form")
    a, b = eps * eps, -2 * (A + 1) * (eps + N / L)
    x = (-b - math.sqrt(b * b - 8 * (A + 1) * a)) / (2 * a)  # eq:20, the root classify() accepted

    def D(xi, delta):
        return (A * A - 1) * xi * xi + 2 * (A + 1) * delta * (2 * N * L - delta) / (L * L)

    def f(xi, z):
        return [((A + 1) * xi - math.sqrt(max(D(xi, z[0]), 0.0))) / eps]

    def jac(xi, z):  # d/d(delta) of f: -B (model.md)
        d = max(D(xi, z[0]), 1e-300)
        return [[-2 * (A + 1) * (N * L - z[0]) / (L * L * eps * math.sqrt(d))]]

    def hit(xi, z):
        return D(xi, z[0])

    hit.terminal = True
    hit.direction = -1
    kw = {"jac": jac} if method in ("Radau", "BDF", "LSODA") else {}
    # Radau's step-size predictor divides by the previous error norm, which is exactly 0 on
    # smooth stretches (scipy radau.py, "divide by zero encountered in scalar divide"); it then
    # takes the largest step, as intended. The warning says nothing about the answer.
    with np.errstate(divide="ignore"):
        s1 = solve_ivp(f, [XI1, 1.0], [0.5 * x * XI1 * XI1], method=method, rtol=rtol,
                       atol=1e-24, events=hit, dense_output=True, **kw)
    if s1.status == 1:
        out["status"] = "eps_too_large_path"
        out["xi_stop"] = float(s1.t_events[0][0])
        return out
    assert s1.status == 0, s1.message
    delta_w = float(s1.y[0, -1])
    Dw = D(1.0, delta_w)
    if Dw <= 0:
        out["status"] = "eps_too_large_path"
        out["xi_stop"] = 1.0
        return out
    if status_only:
        out["status"] = "ok"
        return out

    def delta_at(xi):
        return 0.5 * x * xi * xi if xi < XI1 else float(s1.sol(xi)[0])

    def g(t, z):  # t = ln xi; z = [ln omega_hat, J]
        xi = math.exp(t)
        dl = delta_at(xi)
        d = D(xi, dl)
        sq = math.sqrt(d)
        B = 2 * (A + 1) * (N * L - dl) / (L * L * eps * sq)  # e-60
        h = (A + 1) * (1 - (A - 1) * xi / sq)  # e-59
        return [xi * B, -xi * h * math.exp(z[0])]

    def gone(t, z):  # omega_hat below exp(-700): nothing left to add to J
        return z[0] + 700.0

    gone.terminal = True
    s2 = solve_ivp(g, [0.0, math.log(1e-13)], [0.0, 0.0], method="DOP853", rtol=rtol,
                   atol=[1e-12, 1e-16], dense_output=True, events=gone)
    assert s2.status in (0, 1), s2.message
    J0 = float(s2.y[1, -1])
    epsK = eps * K
    target = 0.95 * J0 - 0.05 * epsK
    if target <= 0:
        xi_p = 1.0
    else:
        tp = brentq(lambda t: s2.sol(t)[1] - target, s2.t[-1], 0.0, xtol=1e-15, rtol=1e-15)
        xi_p = math.exp(tp)
    out.update(
        status="ok",
        xi_p=xi_p,
        Delta=(1 - xi_p) / eps,
        u_axis=epsK + J0,
        slip=epsK / (epsK + J0),
        m_wall=delta_w - N * L,
        sigma_yx_wall=A - math.sqrt(Dw),
        J_axis=J0,
        stage1=s1,
        stage2=s2,
    )
    return out


def profile(ref, xi, eps, L, K, A, N):
    """u/u(0), omega_hat, m, sigma_yx of a reference solution at ``xi`` (array, xi >= XI1)."""
    s1, s2 = ref["stage1"], ref["stage2"]
    xi = np.asarray(xi, float)
    z = s2.sol(np.log(xi))
    delta = s1.sol(xi)[0]
    Dv = (A * A - 1) * xi * xi + 2 * (A + 1) * delta * (2 * N * L - delta) / (L * L)
    epsK = eps * K
    return {
        "u_over_u0": (epsK + z[1]) / (epsK + ref["J_axis"]),
        "omega_hat": np.exp(z[0]),
        "m": delta - N * L,
        "sigma_yx": A * xi - np.sqrt(Dv),
    }
