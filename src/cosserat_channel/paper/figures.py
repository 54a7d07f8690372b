"""Figures 2-12 of the paper, each computed with its caption's parameters (see :mod:`.record`)."""

from __future__ import annotations

import math

import numpy as np
from .record import (A, EPS2, EPS3, EPS4, FIG12_NU, FIG2_MATERIAL, FIG3_MATERIAL, K, L, N,
                     PaperFigure, Row, U0)


# ---------------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------------
def _xi(n):
    return np.linspace(0.0, 1.0, n)


def _profiles(eps, L_, xi, material=FIG2_MATERIAL, K_=K):
    from ..solver.point import solve_point

    r = solve_point(eps, L_, K_, A, N, profile=xi, material=material)
    if not r.ok:
        raise RuntimeError(f"no solution at eps = {eps:g}, L = {L_:g}: {r.status.message}")
    return r


def _composite(name, xi, eps, L_=L, K_=K):
    from ..physics import asymptotics

    return asymptotics.composite_profile(name, xi, eps, L_, K_)


def _omega_bar(r, xi, eps):
    """omega_bar, -(1/2) du/dxi and the composite's omega_bar, all with u(0) = U0 (figure 2's
    caption): the wall spin is omega_bar_w = u(0) / (u(0)/omega_bar_w), the composite's from its
    own u(0)/omega_bar_w = eps K + J(0)."""
    from ..physics import asymptotics

    p = r.profile
    omega_w = U0 / r.u_axis
    half_vorticity = -0.5 * np.gradient(U0 * p["u_over_u0"], xi, edge_order=2)
    omega_w_asym = U0 / (eps * K + asymptotics.composite(np.array([0.0]), eps, L).J[0])
    return (omega_w * p["omega_hat"], half_vorticity,
            omega_w_asym * _composite("omega_hat", xi, eps), omega_w)


def _axis(eps, L_=L, A_=A, N_=N):
    """``(m''(0)/nu, c0)`` of the axis series (eq:20, the paper's root) from the model's
    cancellation-free form: ``m = -N L nu + m''(0) xi^2/2`` and ``sqrt(D) = c0 nu xi`` there."""
    from ..physics import model

    ax = np.zeros(model.N_AX)
    model.axis_constants(eps * L_, A_, N_, ax)
    return L_ * ax[model.AX_Y], ax[model.AX_C0]


def _max_abs(a, b):
    return float(np.nanmax(np.abs(np.asarray(a) - np.asarray(b))))


def _delta_sweep(grid):
    from ..sweep import run_sweep

    ds = run_sweep({"grid": grid, "output": {"variables": ["Delta"]}}, workers=1, progress=False)
    return ds["Delta"].squeeze()


# ---------------------------------------------------------------------------------------------
# Figures 2-6: velocity and spin profiles
# ---------------------------------------------------------------------------------------------
def figure2(n_xi=401) -> PaperFigure:
    """Figure 2: u/u(0) at eps = 1/30 for L = 2, 10 and 20, the asymptote at L = 10."""
    xi = _xi(n_xi)
    results = {L_: _profiles(EPS2, L_, xi) for L_ in (2.0, 10.0, 20.0)}
    r = results[10.0]
    asym = _composite("u_over_u0", xi, EPS2)
    return PaperFigure(
        "figure2", "Figure 2: u/u(0), eps = 1/30 (W = 0.06 m, d_p = 2 mm), A = 1/3, K = 0.5, "
        "phi = 25 deg; L = 2, 10, 20",
        {"xi": xi, "u": {L_: res.profile["u_over_u0"] for L_, res in results.items()},
         "asymptotic": asym},
        [Row("shear-layer thickness Delta at L = 10", "about 10.5", f"{r.Delta:.2f}",
             "ours is 2 % thinner; the paper gives one digit after the point, 'about'"),
         Row("solids fraction nu", "0.60", f"{r.nu:.4f}"),
         Row("asymptote (circles) against L = 10", "smaller deviation than in figure 3",
             f"max abs difference {_max_abs(r.profile['u_over_u0'], asym):.3f} of u(0)",
             "the composite is the eps -> 0 limit: at eps = 1/30 its shear layer is 14.6 "
             "particle diameters, not 10.3"),
         Row("glass-bead data (squares)", "Nedderman & Laohakul", "not drawn",
             "the measured points are not in the paper's text")])


def figure3(n_xi=401, fig2: PaperFigure | None = None) -> PaperFigure:
    """Figure 3: u/u(0) for Natarajan et al.'s channel (eps = 0.1176, phi = 28 deg), L = 10."""
    xi = _xi(n_xi)
    r = _profiles(EPS3, L, xi, FIG3_MATERIAL)
    asym = _composite("u_over_u0", xi, EPS3)
    dev3 = _max_abs(r.profile["u_over_u0"], asym)
    fig2 = fig2 or figure2(n_xi)
    dev2 = _max_abs(fig2.data["u"][10.0], fig2.data["asymptotic"])
    return PaperFigure(
        "figure3", "Figure 3: u/u(0), W = 0.0255 m, d_p = 3 mm (eps = 0.1176), phi = 28 deg, "
        "L = 10, rest as in figure 2",
        {"xi": xi, "u": r.profile["u_over_u0"], "asymptotic": asym},
        [Row("solids fraction nu", "0.59", f"{r.nu:.4f}"),
         Row("asymptote's deviation, larger than in figure 2", "yes (eps larger)",
             f"max abs difference {dev3:.3f} of u(0) here, {dev2:.3f} in figure 2"),
         Row("mass flow rate int u nu dxi", "0.15", "-",
             "it sets omega_w only; u/u(0) does not depend on it"),
         Row("glass-bead data (squares)", "Natarajan et al.", "not drawn",
             "the measured points are not in the paper's text")])


def figure4(n_xi=401) -> PaperFigure:
    """Figure 4: u/u(0) at eps = 1/600 (W = 1.2 m), L = 10, numerical and asymptotic."""
    from ..physics import asymptotics

    xi = _xi(n_xi)
    r = _profiles(EPS4, L, xi)
    asym = _composite("u_over_u0", xi, EPS4)
    lim = asymptotics.Delta_asymptotic(EPS4, L)
    finite = asymptotics.Delta_asymptotic(EPS4, L, finite=True, K=K)
    dev = _max_abs(r.profile["u_over_u0"], asym)
    where = float(xi[np.nanargmax(np.abs(r.profile["u_over_u0"] - asym))])
    return PaperFigure(
        "figure4", "Figure 4: u/u(0), W = 1.2 m (eps = 1/600), L = 10, rest as in figure 2",
        {"xi": xi, "u": r.profile["u_over_u0"], "asymptotic": asym},
        [Row("numerical vs asymptotic profile", "indistinguishable",
             f"max abs difference {dev:.3f} of u(0)",
             f"{100 * dev:.1f} % of u(0) at most, at xi = {where:.3f} "
             f"({'inside' if where > r.xi_p else 'outside'} the shear layer): the composite is "
             "the first term of an expansion in powers of eps^(1/3) (Appendix C)"),
         Row("Delta numerical vs asymptotic", "-",
             f"{r.Delta:.2f} vs {lim:.2f} (limit), {finite:.2f} (finite eps, with slip)",
             f"the limit drops the wall slip eps K ({lim - finite:.2f}) and the higher-order "
             f"terms ({finite - r.Delta:.2f}); the gap closes like eps^(2/3): "
             "0.9 % at eps = 1e-4 (docs/model.md, section 8)")])


def figure5(n_xi=401) -> PaperFigure:
    """Figure 5: omega_bar and half the vorticity at eps = 1/30, L = 10, the asymptotic omega_bar."""
    xi = _xi(n_xi)
    r = _profiles(EPS2, L, xi)
    omega, half_vort, omega_asym, omega_w = _omega_bar(r, xi, EPS2)
    layer = xi >= r.xi_p
    return PaperFigure(
        "figure5", "Figure 5: omega_bar and half the vorticity, eps = 1/30, L = 10, u(0) = 0.2",
        {"xi": xi, "omega": omega, "half_vorticity": half_vort, "asymptotic": omega_asym,
         "xi_p": r.xi_p},
        [Row("omega_bar vs half the vorticity", "differ slightly, more in the shear layer",
             f"max difference {_max_abs(omega[~layer], half_vort[~layer]):.4f} in the plug, "
             f"{_max_abs(omega[layer], half_vort[layer]):.4f} in the shear layer"),
         Row("sign of the vorticity curve", "(1/2) du/dxi", "-(1/2) du/dxi",
             "u = -v_y/(g W)^(1/2) is positive downwards, so the classical rotation rate is "
             "-(1/2) du/dxi: positive, like omega_bar; the paper's label drops the sign"),
         Row("asymptotic omega_bar at eps = 1/30", "deviates significantly",
             f"max abs difference {_max_abs(omega, omega_asym):.4f} "
             f"(omega_bar_w = {omega_w:.4f})")])


def figure6(n_xi=401) -> PaperFigure:
    """Figure 6: omega_bar at eps = 1/600, L = 10, numerical and asymptotic."""
    xi = _xi(n_xi)
    r = _profiles(EPS4, L, xi)
    omega, _, omega_asym, omega_w = _omega_bar(r, xi, EPS4)
    return PaperFigure(
        "figure6", "Figure 6: omega_bar, W = 1.2 m (eps = 1/600), L = 10, u(0) = 0.2",
        {"xi": xi, "omega": omega, "asymptotic": omega_asym},
        [Row("asymptotic omega_bar at eps = 1/600", "agree well",
             f"max abs difference {_max_abs(omega, omega_asym):.4f} of omega_bar_w = "
             f"{omega_w:.4f}")])


# ---------------------------------------------------------------------------------------------
# Figures 7-9: Delta against W/d_p, L and K
# ---------------------------------------------------------------------------------------------
def figure7(n=120) -> PaperFigure:
    """Figure 7: Delta against W/d_p (L = 10) with the Appendix C asymptote."""
    from ..physics import asymptotics

    W_over_d_p = np.geomspace(5.0, 600.0, n)
    delta = _delta_sweep({"eps": (1.0 / W_over_d_p).tolist(), "L": L, "K": K, "A": A, "N": N})
    delta = delta.sortby("eps", ascending=False).values
    asym = np.array([asymptotics.Delta_asymptotic(1.0 / w, L) for w in W_over_d_p])
    ok = np.isfinite(delta)
    return PaperFigure(
        "figure7", "Figure 7: Delta against W/d_p, L = 10, rest as in figure 2",
        {"W_over_d_p": W_over_d_p, "Delta": delta, "asymptotic": asym},
        [Row("Delta grows with W", "yes", "yes" if np.all(np.diff(delta[ok]) > 0) else "no",
             f"from {delta[ok][0]:.2f} at W/d_p = {W_over_d_p[ok][0]:.0f} to {delta[ok][-1]:.2f} "
             f"at {W_over_d_p[ok][-1]:.0f}"),
         Row("lim xi_bar_p (Appendix C)", "1.275", f"{asymptotics.xi_bar_p_limit():.6f}"),
         Row("kinetic and frictional-kinetic curves", "drawn", "not drawn",
             "those models (Mohan et al. 1997) are not part of this package"),
         Row("Nedderman & Laohakul's estimates (solid symbols)", "drawn", "not drawn",
             "the estimates are not in the paper's text")])


def figure8(n=117) -> PaperFigure:
    """Figure 8: Delta against L at eps = 1/30, with the asymptote."""
    from ..physics import asymptotics

    L_values = np.linspace(1.0, 30.0, n)
    delta = _delta_sweep({"eps": EPS2, "L": L_values.tolist(), "K": K, "A": A, "N": N}).values
    asym = np.array([asymptotics.Delta_asymptotic(EPS2, v) for v in L_values])
    i = int(np.argmin(np.abs(L_values - L)))
    slope = float(np.gradient(np.log(delta), np.log(L_values))[i])
    return PaperFigure(
        "figure8", "Figure 8: Delta against L, eps = 1/30, rest as in figure 2",
        {"L": L_values, "Delta": delta, "asymptotic": asym},
        [Row("Delta against L", "a weak function of L", f"{delta[0]:.2f} at L = {L_values[0]:g} "
             f"to {delta[-1]:.2f} at L = {L_values[-1]:g}"),
         Row("d ln Delta / d ln L", "2/3 as eps -> 0", f"{slope:.3f} at L = 10, eps = 1/30",
             "below 2/3 at finite eps: the asymptote overestimates Delta more at large L")])


def figure9(n=3001) -> PaperFigure:
    """Figure 9 (the paper's fig:new): Delta against K at eps = 1/30, L = 10."""
    from ..physics import asymptotics

    K_values = np.linspace(0.0, 300.0, n)
    delta = _delta_sweep({"eps": EPS2, "L": L, "K": K_values.tolist(), "A": A, "N": N}).values
    zero = K_values[delta == 0.0]
    k_star = float(zero.min()) if zero.size else math.nan
    small = delta[K_values <= 1.0]
    return PaperFigure(
        "figure9", "Figure 9: Delta against K, eps = 1/30, L = 10, rest as in figure 2",
        {"K": K_values, "Delta": delta, "K_star": k_star},
        [Row("Delta at small K", "little variation", f"{small.max() - small.min():.3f} "
             f"from K = 0 to 1 (of {delta[0]:.2f})"),
         Row("Delta = 0 (u(1) > 0.95 u(0))", "for K > 200", f"K >= {k_star:.1f}",
             f"on this grid (spacing {K_values[1] - K_values[0]:g})"),
         Row("asymptotic Delta", "not drawn", "not drawn",
             f"Appendix C's limit is independent of K ({asymptotics.Delta_asymptotic(EPS2, L):.1f}"
             " at eps = 1/30, L = 10): a flat line the paper does not draw")])


# ---------------------------------------------------------------------------------------------
# Figures 10-12: stresses and the phase plane
# ---------------------------------------------------------------------------------------------
def _two_eps(n_xi):
    xi = _xi(n_xi)
    return xi, {eps: _profiles(eps, L, xi) for eps in (EPS2, EPS4)}


def figure10(n_xi=401) -> PaperFigure:
    """Figure 10 (fig:9): sigma_xy and sigma_yx at eps = 1/30 and 1/600, asymptotic sigma_yx."""
    xi, res = _two_eps(n_xi)
    data = {"xi": xi, "sigma_xy": res[EPS2].profile["sigma_xy"],
            "sigma_yx": {e: r.profile["sigma_yx"] for e, r in res.items()},
            "asymptotic": {e: _composite("sigma_yx", xi, e) for e in res}}
    gap = {e: _max_abs(r.profile["sigma_yx"], r.profile["sigma_xy"]) for e, r in res.items()}
    axis = {e: abs(data["asymptotic"][e][0] - data["sigma_yx"][e][0]) for e in res}
    return PaperFigure(
        "figure10", "Figure 10: sigma_xy and sigma_yx (over nu), eps = 1/30 and 1/600, L = 10",
        data,
        [Row("sigma_yx - sigma_xy", "grows with xi", f"{gap[EPS2]:.4f} at the wall (eps = 1/30)"),
         Row("at eps = 1/600", "asymptote indistinguishable, difference very small",
             f"max abs(sigma_yx - sigma_xy) = {gap[EPS4]:.4f}; asymptote off by at most "
             f"{_max_abs(res[EPS4].profile['sigma_yx'], data['asymptotic'][EPS4]):.4f}"),
         Row("asymptote at the axis", "-", f"off by {axis[EPS2]:.3f} (eps = 1/30), "
             f"{axis[EPS4]:.4f} (1/600)", "the composite's error there is proportional to eps "
             "(its Airy term decays only like xi_bar^(-1/2) away from the wall)"),
         Row("scale", "sigma_bar", "sigma_bar / nu",
             f"one sigma_xy = -xi line for both eps; the paper's values are nu times these "
             f"(nu = {res[EPS2].nu:.3f} and {res[EPS4].nu:.3f})")])


def figure11(n_xi=401) -> PaperFigure:
    """Figure 11 (fig:10): the couple stress m at eps = 1/30 and 1/600, and its asymptote."""
    xi, res = _two_eps(n_xi)
    data = {"xi": xi, "m": {e: r.profile["m"] for e, r in res.items()},
            "asymptotic": {e: _composite("m", xi, e) for e in res}}
    axis = {e: abs(data["asymptotic"][e][0] - data["m"][e][0]) for e in res}
    return PaperFigure(
        "figure11", "Figure 11: the couple stress m (over nu), eps = 1/30 and 1/600, L = 10",
        data,
        [Row("m against xi", "increases with xi",
             "increases" if all(np.all(np.diff(v) >= -1e-12) for v in data["m"].values())
             else "not monotone"),
         Row("asymptote at eps = 1/600", "indistinguishable",
             f"max abs difference {_max_abs(data['m'][EPS4], data['asymptotic'][EPS4]):.3f} of "
             f"abs(m(0)) = {L * N:g}; {_max_abs(data['m'][EPS2], data['asymptotic'][EPS2]):.3f} "
             "at eps = 1/30"),
         Row("asymptote at the axis", "-", f"off by {axis[EPS2]:.3f} (eps = 1/30), "
             f"{axis[EPS4]:.3f} (1/600)", "proportional to eps, as for sigma_yx (figure 10)"),
         Row("scale", "m_bar", "m_bar / nu", "the paper's values are nu times these")])


def figure12(n_xi=301, n_m=401) -> PaperFigure:
    """Figure 12 (fig:11): the phase plane of eq:a1/eq:a2 at eps = 1/30, L = 10, A = 1/3, N = 1."""
    from .. import regimes

    pp = regimes.phase_plane(EPS2, L, A, N, n_xi=n_xi, n_m=n_m)
    ends = {tr.root: tr for tr in pp.trajectories if tr.start < 0}
    return PaperFigure(
        "figure12", "Figure 12: phase plane of eq:a1 (E+) and eq:a2 (E-) from m(0) = -N L nu; "
        "N = 1, L = 10, nu = 0.603, A = 1/3, eps = 1/30",
        {"phase_plane": pp, "nu": FIG12_NU},
        [Row("eq:a1 (E+) from -N L nu", "touches the upper D = 0 before the wall",
             f"{ends['+'].end} at xi = {ends['+'].xi[-1]:.3f}"),
         Row("eq:a2 (E-) from -N L nu", "reaches the wall",
             f"{ends['-'].end} at xi = {ends['-'].xi[-1]:.3f}"),
         Row("trajectories from +N L nu", "not drawn", "not drawn",
             "the paper discards that start (the spin is unbounded at the axis)")])
