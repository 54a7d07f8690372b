"""The phase plane of Appendix A (figure 12): the curves D = 0, the nullcline, the sign regions
of E+- and the four trajectories from m(0) = +-N L, integrated with scipy.

A plotting aid, not the solver (:func:`cosserat_channel.solver.point.solve_point` decides whether a point
has a solution). Imports numpy (scipy when a trajectory is integrated), never numba.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..parameters import ParameterError, check_point
from ..regime_codes import REGION_D_NEGATIVE, REGION_EM_POS, REGION_EP_NEG, REGION_EP_POS_EM_NEG


# ---------------------------------------------------------------------------------------------
# Analytic curves of the (A, N) plane and of the phase plane
# ---------------------------------------------------------------------------------------------
def wall_line_A(N):
    """``A = 1 - 2 N^2``: below it ``D(1, m) < 0`` for every m (Appendix A)."""
    return 1.0 - 2.0 * np.asarray(N, dtype=float) ** 2


def axis_line_N(A, eta):
    """``N`` on the axis condition ``(A-1) eta + 2(A+1) N = 0`` (eq:20), for ``A > -1``; NaN elsewhere."""
    A = np.asarray(A, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        N = (1.0 - A) * eta / (2.0 * (A + 1.0))
    return np.where(A > -1.0, N, np.nan)


def yield_D(xi, m, L, A, N):
    """eq:a3 over nu^2: ``(A^2-1) xi^2 + 2(A+1)(N^2 - m^2/L^2)``, with ``m`` meaning ``m/nu``."""
    xi = np.asarray(xi, dtype=float)
    mu = np.asarray(m, dtype=float) / L
    return (A * A - 1.0) * xi**2 + 2.0 * (A + 1.0) * (N - mu) * (N + mu)


def d_zero_curve(xi, L, A, N):
    """``m/nu`` on ``D = 0``: ``+L sqrt(N^2 + (A-1) xi^2/2)`` (NaN where no real curve; A != -1)."""
    xi = np.asarray(xi, dtype=float)
    arg = N * N + 0.5 * (A - 1.0) * xi**2
    with np.errstate(invalid="ignore"):
        return np.where(arg >= 0.0, L * np.sqrt(np.maximum(arg, 0.0)), np.nan)


def nullcline_curve(xi, L, N):
    """``m/nu`` on the nullcline ``xi^2 + m^2/L^2 = N^2`` (upper half; NaN for ``xi > N``)."""
    xi = np.asarray(xi, dtype=float)
    arg = N * N - xi**2
    return np.where(arg >= 0.0, L * np.sqrt(np.maximum(arg, 0.0)), np.nan)


# ---------------------------------------------------------------------------------------------
# Phase plane
# ---------------------------------------------------------------------------------------------
@dataclass
class Trajectory:
    """One solution of eq:a1 (``root = "+"``) or eq:a2 (``"-"``) from ``m(0) = start`` (m over nu).

    ``end`` says why it stopped: ``"wall"`` (reached xi = 1), ``"D=0"`` (left the admissible
    region at ``xi[-1]``), ``"no_start"`` (no real solution leaves ``m(0)``: the axis series of
    eq:20 for this root and start has no admissible coefficient) or ``"failed"``.
    """

    root: str
    start: float
    xi: np.ndarray
    m: np.ndarray
    end: str

    @property
    def spin_bounded(self) -> bool:
        """Whether ``m < 0`` leaving the axis, i.e. ``B > 0`` there and ``omega_hat -> 0`` (Appendix B).

        With ``m(0) = +NL`` the spin rate ``B = -2(A+1) m/(eps L^2 sqrt(D))`` is negative near the
        axis for A > -1, so the spin grows without bound towards it: the reason the paper discards
        that start even where a trajectory reaches the wall.
        """
        return self.start < 0

    @property
    def label(self) -> str:
        """Legend text: root (E+ is eq:a1, E- is eq:a2, as the figure's title says), start, end."""
        sign = "-" if self.start < 0 else "+"
        end = {"wall": "reaches the wall", "D=0": f"meets $D=0$ at $\\xi$ = {self.xi[-1]:.3g}",
               "no_start": "cannot leave the axis", "failed": "integration failed"}[self.end]
        if self.end == "wall" and not self.spin_bounded:
            end += r", but $\hat\omega\to\infty$ at the axis"
        return rf"$E_{{{self.root}}}$ from $\bar m(0) = {sign}NL$: {end}"


@dataclass
class PhasePlane:
    """Everything figure 12 shows, for one ``(eps, L, A, N)``; ``m`` means ``m/nu`` throughout."""

    eps: float
    L: float
    A: float
    N: float
    xi: np.ndarray  # grid abscissae, [0, 1]
    m: np.ndarray  # grid ordinates
    D: np.ndarray  # (m.size, xi.size)
    E_plus: np.ndarray  # NaN where D < 0
    E_minus: np.ndarray
    region: np.ndarray  # REGION_* codes
    D_zero: np.ndarray  # upper D = 0 curve on xi (the lower one is its negative)
    nullcline: np.ndarray  # upper nullcline on xi (the lower one is its negative)
    trajectories: list = field(default_factory=list)


def _series_coefficient(eps, L, A, N, root, sign):
    """``x`` of ``m = sign N L + x xi^2/2`` near the axis for eq:a1/eq:a2, or None.

    Inserting the series gives ``eps^2 x^2 - 2(A+1)(eps - sign N/L) x + 2(A+1) = 0`` (eq:20 for
    ``sign = -1``); a root is admissible when ``D/xi^2 = A^2-1 - 2 sign (A+1) N x/L >= 0`` and
    ``eps x - (A+1)`` has the sign of the root (``+`` for E+, ``-`` for E-). Of two admissible
    roots the one of smaller magnitude is taken (for eq:a2 from ``-NL`` that is the paper's).
    """
    a1 = A + 1.0
    b = a1 * (eps - sign * N / L)
    disc = b * b - 2.0 * a1 * eps * eps
    if disc < 0.0:
        return None
    s = math.sqrt(disc)
    cands = []
    for x in ((b - s) / eps**2, (b + s) / eps**2):
        c = A * A - 1.0 - 2.0 * sign * a1 * N * x / L
        lhs = eps * x - a1
        tol = 1e-12 * max(1.0, abs(a1))
        if c < -tol:
            continue
        if root == "+" and lhs < -tol:
            continue
        if root == "-" and lhs > tol:
            continue
        cands.append(x)
    if not cands:
        return None
    return min(cands, key=abs)


def phase_trajectory(eps, L, A, N, root="-", start=-1, *, rtol=1e-9, atol=1e-12, n_out=400):
    """Integrate eq:a1 (``root="+"``) or eq:a2 (``"-"``) from ``m(0) = start * N L`` (m over nu).

    Starts on the axis series (see :func:`_series_coefficient`) at a small ``xi``, then
    :func:`scipy.integrate.solve_ivp` (LSODA) with a terminal event at ``D = 0``.
    """
    from scipy.integrate import solve_ivp

    sign = 1.0 if start > 0 else -1.0
    m0 = sign * N * L
    x = _series_coefficient(eps, L, A, N, root, sign)
    if x is None:
        return Trajectory(root, m0, np.array([0.0]), np.array([m0]), "no_start")
    s = 1.0 if root == "+" else -1.0
    xi1 = 1e-4

    def rhs(xi, y):
        D = float(yield_D(xi, y[0], L, A, N))
        return [((A + 1.0) * xi + s * math.sqrt(max(D, 0.0))) / eps]

    def hit(xi, y):
        return float(yield_D(xi, y[0], L, A, N))

    hit.terminal = True
    hit.direction = -1.0
    sol = solve_ivp(rhs, (xi1, 1.0), [m0 + 0.5 * x * xi1**2], method="LSODA", events=hit,
                    rtol=rtol, atol=atol * max(1.0, N * L), dense_output=True)
    if sol.status < 0:
        return Trajectory(root, m0, np.r_[0.0, sol.t], np.r_[m0, sol.y[0]], "failed")
    xi_end = float(sol.t[-1])
    grid = np.linspace(xi1, xi_end, n_out)
    m = sol.sol(grid)[0]
    end = "D=0" if sol.status == 1 else "wall"
    return Trajectory(root, m0, np.r_[0.0, grid], np.r_[m0, m], end)


def phase_plane(eps, L, A, N, *, n_xi=301, n_m=401, m_range=None) -> PhasePlane:
    """Data of the phase plane of eq:a1 and eq:a2 (figure 12) at ``(eps, L, A, N)``.

    Parameters
    ----------
    eps, L, A, N : float
        Parameters (``K`` plays no part in stage 1).
    n_xi, n_m : int
        Grid size for the sign regions.
    m_range : (float, float), optional
        Ordinate range of the grid, ``m/nu``; default a little beyond ``+-N L`` and the curves.

    Returns
    -------
    PhasePlane
        Grid fields, analytic curves and the four trajectories (E+ and E-, each from ``-NL`` and
        ``+NL``).
    """
    eps, L, _, A, N = check_point(eps, L, 0.0, A, N)
    if A == -1.0:
        raise ParameterError("phase plane: A = -1 has the closed form m = -N L (Appendix A); "
                             "D does not depend on xi there")
    xi = np.linspace(0.0, 1.0, n_xi)
    dz = d_zero_curve(xi, L, A, N)
    if m_range is None:
        top = 1.15 * max(N * L, float(np.nanmax(dz)) if np.any(np.isfinite(dz)) else N * L)
        m_range = (-top, top)
    m = np.linspace(m_range[0], m_range[1], n_m)
    XI, M = np.meshgrid(xi, m)
    D = yield_D(XI, M, L, A, N)
    root = np.sqrt(np.where(D >= 0.0, D, np.nan))
    Ep = (A + 1.0) * XI + root
    Em = (A + 1.0) * XI - root
    region = np.full(D.shape, REGION_D_NEGATIVE, dtype=np.int8)
    inside = D >= 0.0
    region[inside & (Ep >= 0.0) & (Em < 0.0)] = REGION_EP_POS_EM_NEG
    region[inside & (Em >= 0.0)] = REGION_EM_POS
    region[inside & (Ep < 0.0)] = REGION_EP_NEG
    trajectories = [
        phase_trajectory(eps, L, A, N, root=r, start=s) for r in ("+", "-") for s in (-1, 1)
    ]
    return PhasePlane(eps, L, A, N, xi, m, D, Ep, Em, region, dz, nullcline_curve(xi, L, N),
                      trajectories)
