"""Table 1 (wall stresses against Tuzun & Nedderman) and Appendix A (the paper's printed march
at eps = 0.33)."""

from __future__ import annotations

import math

import numpy as np
from .figures import _axis
from .record import (A, APPENDIX_A_EPS, EPS2, FIG12_NU, K, L, N, NONE, PAPER_XI1,
                     PaperFigure, Row, TABLE1_COSSERAT, TABLE1_DELTA_DEG,
                     TABLE1_EXPERIMENTS, TABLE1_KINETIC, TABLE1_MATERIAL,
                     TABLE1_W)


# ---------------------------------------------------------------------------------------------
# Table 1 and Appendix A
# ---------------------------------------------------------------------------------------------
def table1() -> PaperFigure:
    """Table 1: wall stresses against Tuzun & Nedderman's measurements (kN/m^2)."""
    from ..solver.point import solve_point

    from ..parameters import N_from_friction, eps_from_width

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
    from .. import regimes
    from ..physics import reference
    from ..solver.point import solve_point

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
