"""The paper's figures 2-12, table 1 and Appendix A's ``eps = 0.33``, computed beside what the
paper prints.

Each function solves what one figure (or the table) of Mohan, Nott & Rao shows, with the
parameters of its caption, and returns a :class:`PaperFigure`: the data to draw
(:mod:`cosserat_channel.plot.paper` draws it and never solves) and the paper's stated numbers
next to ours, each with a sentence where they differ. :func:`paper_figures` computes them all;
``python -m cosserat_channel.paper -o DIR`` (or ``cosserat-channel paper -o DIR``) writes every
figure as a PNG and the comparison as Markdown, without a notebook.

The paper's figure numbers are used (its ``\\label``s differ: ``fig:new`` is figure 9,
``fig:9`` figure 10, ``fig:10`` figure 11 and ``fig:11`` figure 12). Stresses are drawn divided
by ``nu`` (the package's scaled variables; the paper's bars are ``nu`` times them).
"""

from __future__ import annotations

import math
import os
import sys
from dataclasses import dataclass, field

import numpy as np

# Figure 2's caption: A = 1/3, K = 0.5, W = 0.06 m, d_p = 2 mm (eps = 1/30), u(0) = 0.2,
# rho_p = 2940 kg/m^3, phi = 25 deg, fully rough wall (N = 1); L = 10 unless a figure varies it.
A = 1.0 / 3.0
K = 0.5
L = 10.0
N = 1.0
EPS2 = 1.0 / 30.0
EPS4 = 1.0 / 600.0
U0 = 0.2
FIG2_MATERIAL = {"d_p": 0.002, "rho_p": 2940.0, "phi": 25.0}
# Figure 3 (Natarajan et al.): W = 0.0255 m, d_p = 3 mm, phi = 28 deg.
FIG3_MATERIAL = {"d_p": 0.003, "rho_p": 2940.0, "phi": 28.0}
EPS3 = 0.003 / 0.0255
# Table 1 (Tuzun & Nedderman): W = 0.155 m, d_p = 2.29 mm, rho_p = 1180, phi = 30, delta = 8 deg.
TABLE1_MATERIAL = {"d_p": 0.00229, "rho_p": 1180.0, "phi": 30.0}
TABLE1_W = 0.155
TABLE1_DELTA_DEG = 8.0
# Figure 12: nu = 0.603 as its caption prints it.
FIG12_NU = 0.603
# Appendix A: the paper's series start for eq:a2.
PAPER_XI1 = 1e-5
APPENDIX_A_EPS = 0.33

# Table 1 as the paper prints it (kN/m^2; H in m): the experiments of Tuzun & Nedderman.
TABLE1_EXPERIMENTS = (
    ("0.91", "2.7\u20133.6", "4.0\u20135.1", "0.30\u20130.39", "0.29\u20130.35"),
    ("1.07", "2.7\u20132.9", "3.8\u20134.6", "0.30", "0.41\u20130.58"),
    ("1.22", "2.7\u20133.6", "4.6\u20135.7", "0.52\u20130.65", "0.58\u20130.76"),
)
NONE = "\u2014"  # the paper's empty cell
TABLE1_COSSERAT = ("7.97", "1.12")
TABLE1_KINETIC = ("2.51", "1.15")


@dataclass
class Row:
    """One stated value: what, the paper's words or number, ours, and why they differ."""

    what: str
    paper: str
    ours: str
    note: str = ""


@dataclass
class PaperFigure:
    """What one of the paper's figures (or table 1, or Appendix A) needs drawn and said.

    Attributes
    ----------
    key : str
        ``"figure2"`` ... ``"figure12"``, ``"table1"``, ``"appendix_a"``.
    title : str
        The paper's caption, shortened, with its parameters.
    data : dict
        Arrays and numbers the figure draws.
    rows : list of Row
        The paper's stated numbers beside ours.
    """

    key: str
    title: str
    data: dict = field(default_factory=dict)
    rows: list = field(default_factory=list)

    def rows_markdown(self) -> str:
        """The rows as a Markdown table (what, paper, ours, note)."""
        lines = ["| what | paper | ours | note |", "|---|---|---|---|"]
        cell = lambda text: str(text).replace("|", "\\|")  # noqa: E731
        lines += [f"| {cell(r.what)} | {cell(r.paper)} | {cell(r.ours)} | {cell(r.note)} |"
                  for r in self.rows]
        return "\n".join(lines)

    def __str__(self) -> str:
        import textwrap

        lines = textwrap.wrap(self.title, 88)
        for r in self.rows:
            lines.append(f"- {r.what}")
            lines += textwrap.wrap(f"paper: {r.paper}  |  ours: {r.ours}", 88,
                                   initial_indent="    ", subsequent_indent="    ")
            if r.note:
                lines += textwrap.wrap(r.note, 88, initial_indent="    ",
                                       subsequent_indent="    ")
        return "\n".join(lines)


# ---------------------------------------------------------------------------------------------
# Helpers
# ---------------------------------------------------------------------------------------------
def _xi(n):
    return np.linspace(0.0, 1.0, n)


def _profiles(eps, L_, xi, material=FIG2_MATERIAL, K_=K):
    from .solver.point import solve_point

    r = solve_point(eps, L_, K_, A, N, profile=xi, material=material)
    if not r.ok:
        raise RuntimeError(f"no solution at eps = {eps:g}, L = {L_:g}: {r.status.message}")
    return r


def _composite(name, xi, eps, L_=L, K_=K):
    from .physics import asymptotics

    return asymptotics.composite_profile(name, xi, eps, L_, K_)


def _omega_bar(r, xi, eps):
    """omega_bar, -(1/2) du/dxi and the composite's omega_bar, all with u(0) = U0 (figure 2's
    caption): the wall spin is omega_bar_w = u(0) / (u(0)/omega_bar_w), the composite's from its
    own u(0)/omega_bar_w = eps K + J(0)."""
    from .physics import asymptotics

    p = r.profile
    omega_w = U0 / r.u_axis
    half_vorticity = -0.5 * np.gradient(U0 * p["u_over_u0"], xi, edge_order=2)
    omega_w_asym = U0 / (eps * K + asymptotics.composite(np.array([0.0]), eps, L).J[0])
    return (omega_w * p["omega_hat"], half_vorticity,
            omega_w_asym * _composite("omega_hat", xi, eps), omega_w)


def _axis(eps, L_=L, A_=A, N_=N):
    """``(m''(0)/nu, c0)`` of the axis series (eq:20, the paper's root) from the model's
    cancellation-free form: ``m = -N L nu + m''(0) xi^2/2`` and ``sqrt(D) = c0 nu xi`` there."""
    from .physics import model

    ax = np.zeros(model.N_AX)
    model.axis_constants(eps * L_, A_, N_, ax)
    return L_ * ax[model.AX_Y], ax[model.AX_C0]


def _max_abs(a, b):
    return float(np.nanmax(np.abs(np.asarray(a) - np.asarray(b))))


def _delta_sweep(grid):
    from .sweep import run_sweep

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
    from .physics import asymptotics

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
    from .physics import asymptotics

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
    from .physics import asymptotics

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
    from .physics import asymptotics

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
    from . import regimes

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


# ---------------------------------------------------------------------------------------------
# Table 1 and Appendix A
# ---------------------------------------------------------------------------------------------
def table1() -> PaperFigure:
    """Table 1: wall stresses against Tuzun & Nedderman's measurements (kN/m^2)."""
    from .solver.point import solve_point

    from .parameters import N_from_friction, eps_from_width

    N_t = float(N_from_friction(TABLE1_MATERIAL["phi"], TABLE1_DELTA_DEG))
    eps_t = float(eps_from_width(TABLE1_MATERIAL["d_p"], TABLE1_W))
    r = solve_point(eps_t, L, K, A, N_t, material=TABLE1_MATERIAL)
    normal, shear = r.sigma_xx_wall_Pa / 1e3, -r.sigma_xy_wall_Pa / 1e3
    header = ("", "H", "normal stress,\nstatic", "normal stress,\nflowing", "shear stress,\nstatic",
              "shear stress,\nflowing")
    rows = [("Experiments", *TABLE1_EXPERIMENTS[0])]
    rows += [("", *e) for e in TABLE1_EXPERIMENTS[1:]]
    rows += [("Cosserat model (paper)", NONE, NONE, TABLE1_COSSERAT[0], NONE, TABLE1_COSSERAT[1]),
             ("Cosserat model (ours)", NONE, NONE, f"{normal:.2f}", NONE, f"{shear:.2f}"),
             ("Kinetic model (paper)", NONE, NONE, TABLE1_KINETIC[0], NONE, TABLE1_KINETIC[1]),
             ("Kinetic model (ours)", NONE, NONE, "not computed", NONE, "not computed")]
    return PaperFigure(
        "table1", "Table 1: wall stresses (kN/m^2; H, depth below the top, in m); W = 0.155 m, "
        f"d_p = 2.29 mm, rho_p = 1180 kg/m^3, phi = 30 deg, delta = 8 deg (N = {N_t:.4f})",
        {"header": header, "rows": rows, "nu": r.nu, "N": N_t},
        [Row("wall normal stress, flowing", TABLE1_COSSERAT[0], f"{normal:.2f}",
             "the paper's numbers are rho_p g W nu / tan(delta) and rho_p g W nu with nu = 0.625; "
             "the closure eq:24 as printed gives the nu below"),
         Row("wall shear stress, flowing", TABLE1_COSSERAT[1], f"{shear:.2f}"),
         Row("solids fraction nu", "0.625", f"{r.nu:.4f}"),
         Row("kinetic model", " / ".join(TABLE1_KINETIC), "not computed",
             "the kinetic model (Mohan et al. 1997) is not part of this package")])


def printed_march(eps, rtol, *, L_=L, A_=A, N_=N, nu=FIG12_NU, xi1=PAPER_XI1):
    """Stage 1 as the paper describes it: eq:a2 for ``m`` itself (not ``m + N L nu``), ``D`` in
    the printed form eq:a3, from the two-term series at ``xi1 = 1e-5``, with LSODA (the paper's
    integrator, here scipy's) at ``rtol`` (``atol = 1e-3 rtol``).

    A negative ``D`` is taken as what it is in that formulation, no real solution (the paper's
    "could not be constructed"). Not the package's solver, which carries ``delta = m/L + N`` and
    evaluates ``D`` without subtracting nearly equal numbers (docs/model.md): this reproduces how
    the printed formulation loses ``D``'s digits near the axis.

    Returns
    -------
    (bool, float)
        Whether the march reached the wall, and ``D(1)/nu^2`` there or the ``xi`` where ``D < 0``.
    """
    from scipy.integrate import solve_ivp

    m1 = -N_ * L_ * nu + 0.5 * _axis(eps, L_, A_, N_)[0] * nu * xi1 * xi1

    def D(xi, m):  # eq:a3 as printed
        return ((A_ * A_ - 1.0) * nu * nu * xi * xi
                + 2.0 * (A_ + 1.0) * (N_ * N_ * nu * nu - m * m / (L_ * L_)))

    class _Negative(Exception):
        pass

    where = []

    def rhs(xi, z):
        d = D(xi, z[0])
        if d < 0.0:
            where.append(xi)
            raise _Negative
        return [((A_ + 1.0) * nu * xi - math.sqrt(d)) / eps]

    try:
        sol = solve_ivp(rhs, (xi1, 1.0), [m1], method="LSODA", rtol=rtol, atol=1e-3 * rtol)
    except _Negative:
        return False, float(where[-1])
    return True, float(D(1.0, sol.y[0, -1]) / (nu * nu))


def appendix_a(eps_values=None, rtols=None) -> PaperFigure:
    """Appendix A: "solutions could not be constructed for eps = 0.33", against exact arithmetic.

    Our solver and scipy's reference (rtol 1e-12) find the solution at ``eps = 0.33``; the march
    in the printed formulation (:func:`printed_march`) decides it by the digits it keeps.
    """
    from . import regimes
    from .physics import reference
    from .solver.point import solve_point

    if eps_values is None:
        eps_values = np.r_[np.linspace(0.01, 0.30, 30), 0.305, 0.31, 0.315, 0.32, 0.325, 0.33,
                           0.3305, 0.3308, 0.331, 0.332]
    if rtols is None:
        rtols = np.array([1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13])
    eps_values, rtols = np.asarray(eps_values, float), np.asarray(rtols, float)
    reached = np.zeros((rtols.size, eps_values.size), dtype=bool)
    for i, rtol in enumerate(rtols):
        for j, eps in enumerate(eps_values):
            reached[i, j] = printed_march(eps, rtol)[0]
    ours = solve_point(APPENDIX_A_EPS, L, K, A, N, profile=np.array([1.0]))
    D1 = float((A - ours.profile["sigma_yx"][0]) ** 2)  # sqrt(D) = A xi - sigma_yx
    ref = reference.reference(APPENDIX_A_EPS, L, K, A, N)
    D1_ref = (A - ref["sigma_yx_wall"]) ** 2 if ref["status"] == "ok" else math.nan
    eps_max = regimes.trace_edge(A, N).eta_max / L
    c0, c0_fig2 = _axis(APPENDIX_A_EPS)[1], _axis(EPS2)[1]
    i11 = int(np.argmin(np.abs(np.log(rtols / 1e-11))))
    fails = ~reached[i11]
    if fails.any():
        first = float(eps_values[fails].min())
        split = np.all(fails[eps_values >= first])
        verdict = (f"solves every eps below {first:.3f}, fails at every eps from {first:.3f} on"
                   if split else "fails at eps = " + ", ".join(f"{e:.4g}" for e in eps_values[fails]))
    else:
        verdict = "solves every eps tried"
    return PaperFigure(
        "appendix_a", "Appendix A: 'for the parameters used in figure 12, solutions could not be "
        "constructed for eps = 0.33' (L = 10, A = 1/3, N = 1)",
        {"eps": eps_values, "rtol": rtols, "reached": reached, "eps_max": eps_max,
         "eps_paper": APPENDIX_A_EPS},
        [Row("solution at eps = 0.33", "none", f"{ours.status.name}, D(1) = {D1:.2e} nu^2",
             f"scipy's reference at rtol 1e-12 agrees: {ref['status']}, D(1) = {D1_ref:.2e} nu^2;"
             f" the edge is eps = {eps_max:.6f}"),
         Row("D near the axis in the printed form", "-",
             f"D = {c0 ** 2 * PAPER_XI1 ** 2:.1e} nu^2 at xi_1 = 1e-5",
             f"the difference of two numbers of size {2 * (A + 1) * N * N:.2f} nu^2 (eq:a3), "
             f"{c0_fig2 ** 2 / c0 ** 2:.0f} times smaller than at "
             "eps = 1/30: its sign is in the 12th digit of m"),
         Row(f"printed march at rtol {rtols[i11]:.0e}", "-", verdict,
             "a model of the paper's verdict (its tolerance is not stated); tighter tolerances "
             "reach the wall at 0.33, as exact arithmetic does; looser ones fail at almost every "
             "eps, 1/30 included")])


# ---------------------------------------------------------------------------------------------
# All of them
# ---------------------------------------------------------------------------------------------
KEYS = tuple(f"figure{n}" for n in range(2, 13)) + ("table1", "appendix_a")


def paper_figures(coarse: bool = False, keys=KEYS, progress=None) -> dict[str, PaperFigure]:
    """Every figure of :data:`KEYS` (``coarse``: small grids, the same code paths);
    ``progress(key)``, if given, is called before each."""
    n_xi = 101 if coarse else 401
    out = {}
    for key in keys:
        if progress is not None:
            progress(key)
        if key == "figure2":
            out[key] = figure2(n_xi)
        elif key == "figure3":
            out[key] = figure3(n_xi, out.get("figure2"))
        elif key in ("figure4", "figure5", "figure6", "figure10", "figure11"):
            out[key] = globals()[key](n_xi)
        elif key == "figure7":
            out[key] = figure7(15 if coarse else 120)
        elif key == "figure8":
            out[key] = figure8(12 if coarse else 117)
        elif key == "figure9":
            out[key] = figure9(301 if coarse else 3001)
        elif key == "figure12":
            out[key] = figure12(*((61, 81) if coarse else (301, 401)))
        elif key == "table1":
            out[key] = table1()
        elif key == "appendix_a":
            out[key] = (appendix_a(np.r_[1 / 30, 0.2, 0.31, 0.32, 0.33, 0.332],
                                   np.array([1e-8, 1e-11, 1e-13])) if coarse else appendix_a())
        else:
            raise ValueError(f"unknown paper figure {key!r}; have {', '.join(KEYS)}")
    return out


def write_paper_figures(directory, *, coarse=False, overwrite=False, keys=KEYS,
                        progress=None) -> list[str]:
    """Compute and draw every figure into ``directory`` (created if missing): ``<key>.png`` and
    ``comparison.md``. Existing files are kept (ValueError before any work) unless
    ``overwrite``. Returns the paths written."""
    from .files import output_problem
    from .plot import paper as plot_paper
    from .plot import save_figure

    directory = os.fspath(directory)
    if os.path.lexists(directory) and not os.path.isdir(directory):
        raise ValueError(f"{directory}: exists and is not a directory")
    targets = [os.path.join(directory, n) for n in [f"{k}.png" for k in keys] + ["comparison.md"]]
    for t in targets:
        if os.path.lexists(t) and not (overwrite and os.path.isfile(t) and not os.path.islink(t)):
            what = "exists" if os.path.isfile(t) else "exists and is not a regular file"
            raise ValueError(f"{t} {what}; kept" + (": give --overwrite or another directory"
                                                    if os.path.isfile(t) else ""))
    if not os.path.isdir(directory):
        parent = os.path.dirname(os.path.abspath(directory))
        if not os.path.isdir(parent):
            raise ValueError(f"cannot create {directory!r}: directory {parent!r} does not exist")
        os.mkdir(directory)  # one level, as -o FILE needs its directory to exist
    for t in targets:
        problem = output_problem(t)
        if problem:
            raise ValueError(problem)
    figures = paper_figures(coarse, keys, progress)
    written = []
    for key, pf in figures.items():
        path = os.path.join(directory, f"{key}.png")
        save_figure(plot_paper.draw(pf), path)
        written.append(path)
    text = ["# The paper's figures and table 1 beside ours", ""]
    for pf in figures.values():
        text += [f"## {pf.title}", "", f"![{pf.key}]({pf.key}.png)", "", pf.rows_markdown(), ""]
    path = os.path.join(directory, "comparison.md")
    from .files import atomic_output

    def write(tmp):
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write("\n".join(text))

    atomic_output(path, write)
    written.append(path)
    return written


def main(argv=None) -> int:
    """``python -m cosserat_channel.paper -o DIR [--coarse] [--overwrite]``: the command line's
    ``paper`` command."""
    from .cli import main as cli_main

    return cli_main(["paper", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
