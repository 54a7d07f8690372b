"""Where the model has a solution: phase-plane data (figure 12) and the traced edge eta_max(A, N).

Two questions, both in the scaled variables of :mod:`cosserat_channel.physics.model` (stresses over nu):

* **Phase plane** (Appendix A, figure 12). The angular-momentum balance with either root of eq:56,

      eps dm/dxi = (A+1) xi + sqrt(D) = E+        (eq:a1)
      eps dm/dxi = (A+1) xi - sqrt(D) = E-        (eq:a2)
      D = (A^2-1) xi^2 + 2(A+1)(N^2 - m^2/L^2)    (eq:a3)

  from ``m(0) = +-N L`` (eq:16). :func:`phase_plane` returns the curves ``D = 0``
  (``m = +-L sqrt(N^2 + (A-1) xi^2/2)``), the nullcline ``xi^2 + m^2/L^2 = N^2`` (there
  ``sqrt(D) = |A+1| xi``: ``E- = 0`` for A > -1, ``E+ = 0`` for A < -1; it is the outer solution
  eq:15), the sign regions of ``E+-`` on a grid, and the four trajectories, integrated with
  :func:`scipy.integrate.solve_ivp` until ``D = 0`` or the wall. This is a plotting aid, not the
  solver: :func:`cosserat_channel.solver.point.solve_point` decides whether a point has a solution.

* **Edge of solvability.** By the similarity of model.md, whether a point has a solution depends on
  ``(eta = eps L, A, N)`` only. :func:`trace_edge` finds ``eta_max(A, N)``, the largest ``eta`` in
  the searched range with status ``ok``, by sampling a coarse grid in ``eta`` and bisecting every
  sampled change of feasibility; where the edge is *tangential* (the path runs into the node of
  the yield condition at the wall, :func:`node_edge_eta`) the status is noise within ~1e-6 of the
  edge, and the edge is the node's closed-form ``eta`` once ``D(1)`` sampled below it
  (:func:`wall_D`, :func:`probe_edge`) confirms it. Where the edge is transversal but ``D(1)`` rises
  so slowly that the status is noise over more than ``SMOOTH_BAND`` (next to the node/focus
  switch), the edge is the zero of a smooth ``D(1)`` (:func:`smooth_wall_D`,
  :func:`smooth_edge`). :func:`trace_boundary` does that on a grid of ``(A, N)`` and returns an
  :class:`xarray.Dataset`.

Pure numpy/scipy/xarray (no matplotlib: figures live in :mod:`cosserat_channel.plot.regimes`, which
reads the codes of this data from :mod:`cosserat_channel.regime_codes` and never solves).
:func:`bisect_edge` is the one bisection of a solvability edge in the package. The module is
about 800 lines because the phase plane and the edge share the model's regime logic and the
Dataset layout of :func:`trace_boundary`, and the edge needs its probes of ``D(1)``; splitting it
into a ``regimes/`` package (phase plane, edge) is the next step it asks for.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from ._jit import JIT as _JIT

from .physics import analytic
from .integrate import dense
from .physics import model
from .integrate import rk45
from .solver import layout, stage1, stress_path
from .integrate import stepping
from .physics.analytic import axis_edge_eta  # noqa: F401 (its home is analytic.py; callers import it here)
from . import status as st
from .parameters import (
    PARAMETERS,
    ParameterError,
    check_eta_range,
    check_point,
    check_values,
)
# The codes of the data this module produces live in regime_codes (the figures read them from
# there without importing the solver); imported here under their old names, for callers.
from .regime_codes import (  # noqa: F401
    EDGE_BOUNDED,
    EDGE_KINDS,
    EDGE_NONE,
    EDGE_UNBOUNDED,
    ETA_SEARCH_MAX,
    ETA_SEARCH_MIN,
    REGION_D_NEGATIVE,
    REGION_EM_POS,
    REGION_EP_NEG,
    REGION_EP_POS_EM_NEG,
    REGION_LABELS,
)
from .solver.point import Workspace

ETA_COARSE = 48  # log-spaced samples of the coarse pass
ETA_XTOL = 1e-10  # relative width of the final bracket
# Tolerances of the solves inside the bisection. Near the edge the path meets D = 0 just before
# the wall, so where feasibility flips moves with the integration error: at the solver's default
# rtol = 1e-8 by up to ~2e-6 relative (A = -0.9, N = 1), at rtol = 1e-10 by ~1e-8 (compared with
# 1e-12). Tighter than 1e-10 the solver reports some paths just past the edge as
# integration_failed (it crawls into the sqrt(D) kink) and gets slow, so 1e-10 it is: the bracket
# is 1e-10 wide, the edge it brackets is the solver's at this tolerance, good to ~1e-8.
EDGE_RTOL = 1e-10
EDGE_ATOL = 1e-14
# Stage-1 step budget inside the bisection: ok points near the edge take a few thousand steps;
# a path crawling into the sqrt(D) kink just past the edge would spend the solver's default
# 200,000 before it is called integration_failed (not ok either way), which made tracing slow.
EDGE_MAX_STEPS = 20_000
# Tangential edges (trace_edge's Notes). The status bisection first stops at PROBE_XTOL; D(1) is
# then sampled at these relative distances on the ok side of the bracket, where it is 1e6-1e9
# times its noise at a tangential edge and the probes cost 6 stage-1 solves (a trace takes ~80).
PROBE_XTOL = 1e-7
PROBE_OFFSETS = np.geomspace(3e-5, 3e-4, 6)
# Noise of D(1) next to the edge, in units of stage 1's resolution of it (STAGE1_RTOL_FLOOR times
# |dD/d delta| delta at the wall). Measured: our stage 1 and scipy's DOP853 at rtol 1e-13 differ
# by up to ~1e-13 at A = 0, N = 2, about 10 resolutions; statuses flip within the band this gives
# (tests/test_regimes.py::test_noise_band_holds_the_flipping_statuses).
D_NOISE = 40.0
# The node's eta is taken as the edge when the status bisection lies within this many noise bands
# of it and the extrapolation of sqrt(D(1)) puts the zero there too.
NODE_AGREE = 4.0


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


# ---------------------------------------------------------------------------------------------
# Edge of solvability
# ---------------------------------------------------------------------------------------------
@njit(**_JIT)
def _wall_D_kernel(etas, A, N, rtol, atol, ax, T1, Q1, stats1, res, status, D1, delta1):
    # Stage 1 exactly as the status solve runs it (stage1.solve_stage1: same start, re-marches
    # and floor tolerance), then D(1) from the dense output's wall value, also where stage 1
    # reached the wall but called D(1) zero within its resolution (status eps_too_large_path with
    # xi_stop = 1). NaN where the path met D = 0 before the wall or stage 1 failed.
    buf = np.empty(1)
    for i in range(etas.size):
        code, _ = stage1.solve_stage1(etas[i], A, N, rtol, atol, ax, T1, Q1, stats1, res,
                                      layout.METHOD_AUTO)
        status[i] = code
        n1 = int(res[layout.R_N1])
        if n1 > 0 and (code == st.OK or res[layout.R_XI_STOP] == 1.0):
            delta1[i] = stress_path._delta_wall(T1, Q1, n1, buf)
            D1[i] = model.yield_D(1.0, delta1[i], A, N, ax)
        else:
            delta1[i] = math.nan
            D1[i] = math.nan


def wall_D(workspace, etas, A, N, rtol=EDGE_RTOL, atol=EDGE_ATOL):
    """Stage 1's status, ``D(1)`` (the yield function at the wall) and ``delta(1)`` at each ``eta``.

    Parameters
    ----------
    workspace : cosserat_channel.solver.point.Workspace
        Its stage-1 arrays are used; a stand-in that counts solves (``atlas._Counting``) passes
        its ``ws`` and counts the solves itself.
    etas : array_like
        Values of ``eta = eps L``.
    A, N : float
        The point of the ``(A, N)`` plane (``A > -1``).
    rtol, atol : float
        Tolerances handed to stage 1, which tightens them near the edge (down to
        ``stage1.STAGE1_RTOL_FLOOR``), as in a status solve.

    Returns
    -------
    status : ndarray of int8
        Stage 1's status (stage 2 is not run: next to the edge it may turn ok into not ok).
    D1, delta1 : ndarray
        ``D(1)`` and ``delta(1) = (m(1)/nu + N L)/L`` where stage 1 reached the wall, else NaN.
    """
    ws = getattr(workspace, "ws", workspace)
    count = getattr(workspace, "count", None)
    etas = np.ascontiguousarray(np.atleast_1d(np.asarray(etas, dtype=float)))
    if count is not None:
        count(etas.size)
    status = np.empty(etas.size, dtype=np.int8)
    D1 = np.empty(etas.size)
    delta1 = np.empty(etas.size)
    _wall_D_kernel(etas, float(A), float(N), float(rtol), float(atol), ws.ax, ws.T1, ws.Q1,
                   ws.stats1, ws.res, status, D1, delta1)
    return status, D1, delta1


# ---------------------------------------------------------------------------------------------
# A smooth D(1): D marched as a state of its own next to the wall (transversal edges near the
# node/focus switch; see trace_edge's Notes)
# ---------------------------------------------------------------------------------------------
# Where the march switches from w = delta/xi^2 (as in stage 1) to the state (delta, D).
SMOOTH_XI_SWITCH = 0.5
SMOOTH_RTOL = 1e-13
SMOOTH_ATOL = 1e-16  # on w and delta
SMOOTH_ATOL_D = 1e-24  # on D: D(1) is wanted to ~1e-18 where the edge is a near-double zero
SMOOTH_MAX_STEPS = 20_000
# The smooth root replaces the status bisection where the probe's noise band exceeds this
# (relative in eta): there the status is decided by the noise of stage 1's D(1).
SMOOTH_BAND = 3e-9
SMOOTH_XTOL = 1e-12  # relative width of the root's final bracket
SMOOTH_WIDEN = (1.0, 4.0, 16.0, 64.0)  # brackets tried, in noise bands either side


@njit(**_JIT)
def _w_rhs(xi, y, args, out):
    eta, A, N, ax = args
    out[0] = model.dw_dxi(xi, y[0], eta, A, N, ax)


@njit(**_JIT)
def _delta_D_rhs(xi, y, args, out):
    # (delta, D) along a stage-1 path: eta delta' = (A+1) xi - sqrt(D) and
    # D' = F - (D_delta / eta) sqrt(D), F = 2(A+1) xi [(A-1) + 2(A+1)(N - delta)/eta]
    # (node_edge_eta). D is carried, not recomputed from delta: next to the wall it is a tiny
    # difference of O(1) terms, and carried it keeps a relative error. sqrt(max(D, 0)) continues
    # the path past D = 0 (D' = F < 0 there), so D(1) changes sign at the edge, continuously.
    eta, A, N, ax = args
    a1 = A + 1.0
    s = math.sqrt(max(y[1], 0.0))
    out[0] = (a1 * xi - s) / eta
    out[1] = 2.0 * a1 * xi * ((A - 1.0) + 2.0 * a1 * (N - y[0]) / eta) - 4.0 * a1 * (N - y[0]) * s / eta


@njit(**_JIT)
def _smooth_wall_D_kernel(eta, A, N, rtol, ax, T, Qw, Q, stats):
    args = (eta, A, N, ax)
    xi1, w1 = stage1.stage1_start(ax, rtol)
    if xi1 < SMOOTH_XI_SWITCH:
        y1 = np.empty(1)
        y1[0] = w1
        atol1 = np.empty(1)
        atol1[0] = SMOOTH_ATOL
        code, n, _ = rk45.dopri5(_w_rhs, stepping.no_event, xi1, y1, SMOOTH_XI_SWITCH, args, rtol,
                                 atol1, 0.0, 0.0, T, Qw, stats)
        if code != stepping.SUCCESS:
            return math.nan
        dense.dense_eval_step(T, Qw, n - 1, SMOOTH_XI_SWITCH, y1)
        xi1, w1 = SMOOTH_XI_SWITCH, y1[0]
    y = np.empty(2)
    y[0] = xi1 * xi1 * w1
    y[1] = model.yield_D(xi1, y[0], A, N, ax)
    atol = np.empty(2)
    atol[0] = SMOOTH_ATOL
    atol[1] = SMOOTH_ATOL_D
    code, n, _ = rk45.dopri5(_delta_D_rhs, stepping.no_event, xi1, y, 1.0, args, rtol, atol, 0.0, 0.0,
                             T, Q, stats)
    if code != stepping.SUCCESS:
        return math.nan
    dense.dense_eval_step(T, Q, n - 1, 1.0, y)
    return y[1]


_SMOOTH_WORK = threading.local()  # work arrays per thread (the atlas traces in threads)


def smooth_wall_D(eta, A, N, rtol=SMOOTH_RTOL):
    """``D(1)`` of the stage-1 path, marched so that it is a smooth function of ``eta``.

    From the axis series (``stage1.stage1_start``) the path is marched in ``w = delta/xi^2`` to
    ``xi = SMOOTH_XI_SWITCH``, then in ``(delta, D)`` with ``D`` a state of its own
    (:func:`_delta_D_rhs`), to the wall, both by ``rk45.dopri5`` at ``rtol``. Stage 1 reads
    ``D(1)`` off ``delta(1)``, a difference of O(1) terms with a noise of ~1e-13 (its step
    sequence changes with ``eta``); here ``D`` keeps a relative error, and the error committed
    before the switch is damped by the time the path reaches the wall (the singular point there
    attracts the paths: measured, marches whose ``delta`` at the switch differs by ~1e-13 give the
    same ``D(1) ~ 1e-12`` to ~1e-18). Past the edge the path is continued through ``D = 0``
    (``D' = F < 0``), so ``D(1)`` changes sign at the edge, continuously.

    Returns ``D(1)``, or NaN where a march failed or no stage 1 applies (``model.classify``).
    """
    A = float(A)
    N = float(N)
    eta = float(eta)
    if A <= -1.0 or model.classify(eta, A, N) != st.OK:
        return math.nan
    w = _SMOOTH_WORK
    if not hasattr(w, "T"):
        w.T = np.empty(SMOOTH_MAX_STEPS + 1)
        w.Qw = np.empty((SMOOTH_MAX_STEPS, dense.N_DENSE, 1))
        w.Q = np.empty((SMOOTH_MAX_STEPS, dense.N_DENSE, 2))
        w.stats = np.zeros(stepping.N_STATS, dtype=np.int64)
    ax = np.empty(model.N_AX)
    model.axis_constants(eta, A, N, ax)
    return float(_smooth_wall_D_kernel(eta, A, N, float(rtol), ax, w.T, w.Qw, w.Q, w.stats))


def smooth_edge(A, N, lo, hi, band, *, count=None, xtol=SMOOTH_XTOL):
    """The zero of :func:`smooth_wall_D` in ``eta`` next to the status bracket ``[lo, hi]``.

    The bracket is widened by ``SMOOTH_WIDEN`` noise bands (``band``, relative) until
    ``smooth_wall_D`` is positive at its low end and negative at its high end, then the zero is
    found by Brent's method to ``xtol`` (relative). ``count(n)``, if given, is told of each march.
    Returns the zero, or NaN where no widening brackets one.
    """
    from scipy.optimize import brentq

    def g(eta):
        if count is not None:
            count(1)
        v = smooth_wall_D(eta, A, N)
        if not math.isfinite(v):
            raise FloatingPointError(f"smooth_wall_D failed at eta = {eta!r}")
        return v

    try:
        for k in SMOOTH_WIDEN:
            w = max(k * band, 10.0 * xtol)
            a, b = lo * (1.0 - w), hi * (1.0 + w)
            ga, gb = g(a), g(b)
            if ga > 0.0 and gb < 0.0:
                return float(brentq(g, a, b, xtol=xtol * a, rtol=4 * np.finfo(float).eps))
    except FloatingPointError:
        pass  # a march failed: the caller falls back to the status bisection
    return math.nan


def node_edge_eta(A, N):
    """``eta`` at which the node of the yield condition sits at the wall, and whether it is a node.

    Along a stage-1 path ``dD/dxi = F - (D_delta / eta) sqrt(D)`` with
    ``D = (A^2-1) xi^2 + 2(A+1)(2 N delta - delta^2)`` and
    ``F = 2(A+1) xi [(A-1) + 2(A+1)(N - delta)/eta]``: a path can reach ``D = 0`` only where
    ``F <= 0``, and the point of ``D = 0`` where ``F = 0`` (``N - delta = (1-A) eta / (2(A+1))``)
    is a singular point of ``(xi, sqrt(D))``. Linearised there (``ds/dtau = 2z``,
    ``dz/dtau = -Phi s - gamma z`` with ``gamma = 2(1-A)``, ``Phi = 4(A+1)^3 xi^2 / eta^2``) it is
    a stable node when ``gamma^2 > 8 Phi`` and a focus otherwise. At a node the paths that come
    close to ``D = 0`` run into it with ``sqrt(D)`` falling linearly: beyond the node ``F < 0``
    and ``D`` turns negative. So where the node is reached, the edge is the ``eta`` that puts it
    at the wall: ``D(1) = 0`` and ``F(1) = 0`` give

        eta_node = 2 (A+1) sqrt(N^2 - (1-A)/2) / (1-A)

    and the node condition at the wall reads ``N^2 > (5 + 3A)/2``
    (:func:`~cosserat_channel.physics.analytic.node_focus_switch_N`).
    Whether the path does reach the node is for the data to say (:func:`trace_edge` checks it); at
    a focus the path meets ``D = 0`` past the singular point, transversally, and
    ``eta_max > eta_node``.

    Parameters
    ----------
    A, N : float

    Returns
    -------
    eta : float
        ``eta_node``; NaN unless ``-1 < A < 1`` and ``N^2 > (1-A)/2`` (``A`` above the wall line).
    node : bool
        The singular point at the wall is a node (``N^2 > (5 + 3A)/2``).
    ratio : float
        ``lambda_fast / lambda_slow`` of the node (NaN at a focus): ``sqrt(D(1))`` is linear in
        ``eta_node - eta`` up to a term in its power ``ratio``, so a polynomial extrapolation of
        it is good where the ratio is well above 2 and biased as it approaches 1.
    """
    A = float(A)
    N = float(N)
    arg = N * N - 0.5 * (1.0 - A)
    if not (-1.0 < A < 1.0 and arg > 0.0):
        return math.nan, False, math.nan
    eta = 2.0 * (A + 1.0) * math.sqrt(arg) / (1.0 - A)
    if not N > analytic.node_focus_switch_N(A):
        return eta, False, math.nan
    gamma = 2.0 * (1.0 - A)
    root = math.sqrt(max(gamma * gamma - 32.0 * (A + 1.0) ** 3 / (eta * eta), 0.0))
    return eta, True, (gamma + root) / (gamma - root)


@dataclass
class Probe:
    """``D(1)`` on the ok side of a bracketed transition (:func:`probe_edge`).

    Attributes
    ----------
    root2, root3 : float
        ``eta`` where degree-2 and degree-3 polynomial fits of ``sqrt(D(1))`` extrapolate to zero
        (NaN where a fit has no real root nearby).
    exponent : float
        Local power of ``D(1)`` in the distance to ``root3`` (to the bracket where that is NaN):
        2 at a tangential edge, towards 1 at a transversal one.
    band : float
        Relative distance from the edge within which ``D(1)``, continued by that power law, is
        below its noise (``D_NOISE`` resolutions): the statuses there are not reliable.
    """

    root2: float
    root3: float
    exponent: float
    band: float


def _root_near_zero(coef):
    r = np.roots(coef)
    r = r[np.abs(r.imag) <= 1e-9 * np.maximum(1.0, np.abs(r))].real
    return float(r[np.argmin(np.abs(r))]) if r.size else math.nan


def probe_edge(workspace, t_ok, side, A, N, rtol=EDGE_RTOL, atol=EDGE_ATOL):
    """Sample ``D(1)`` at ``t_ok (1 + side * PROBE_OFFSETS)`` and extrapolate it to the edge.

    Parameters
    ----------
    workspace : Workspace or a stand-in with ``ws``
    t_ok : float
        The ok end of a bracketed transition.
    side : {-1, 1}
        -1 where ok lies below the transition (an upper edge), +1 above it.
    A, N, rtol, atol : float

    Returns
    -------
    Probe or None
        None where a probe is not ok or has ``D(1) <= 0`` (the transition is not one of ``D(1)``
        reaching zero at the wall, or another transition is within 3e-4).
    """
    eps = PROBE_OFFSETS
    etas = t_ok * (1.0 + side * eps)
    status, D1, delta1 = wall_D(workspace, etas, A, N, rtol, atol)
    if not (np.all(status == st.OK) and np.all(D1 > 0.0)):
        return None
    u = eps / eps[-1]
    s = np.sqrt(D1)
    # Roots in u (0 at t_ok, positive into the ok side): the edge is a little beyond t_ok.
    u2 = _root_near_zero(np.polyfit(u, s, 2))
    u3 = _root_near_zero(np.polyfit(u, s, 3))
    # The power is measured from the extrapolated zero where the two fits agree on it, else from
    # the bracket (within PROBE_XTOL plus the band of the edge, ~3 % of the nearest offset).
    agree = math.isfinite(u3) and math.isfinite(u2) and abs(u3 - u2) <= 0.05 * u[0]
    ur = u3 if agree and abs(u3) <= 0.5 * u[0] else 0.0
    exponent = math.log(D1[-1] / D1[0]) / math.log((u[-1] - ur) / (u[0] - ur))
    sens = 4.0 * (A + 1.0) * np.abs(N - delta1) * np.abs(delta1)
    noise = D_NOISE * stage1.STAGE1_RTOL_FLOOR * float(np.max(sens))
    dist0 = (u[0] - ur) * eps[-1]
    band = dist0 * (noise / D1[0]) ** (1.0 / exponent) if exponent > 0.0 else dist0
    to_eta = lambda v: t_ok * (1.0 + side * eps[-1] * v)  # noqa: E731
    return Probe(to_eta(u2), to_eta(u3), exponent, min(band, dist0))


@dataclass
class Edge:
    """The traced edge of solvability in ``eta = eps L`` at one ``(A, N)``.

    Attributes
    ----------
    eta_max : float
        Largest ``eta`` with status ok (bracketed to ``xtol`` relative), or at a tangential edge
        the node's ``eta`` (the zero of ``D(1)``; the status is noise within ``bands[-1]`` of it);
        for ``kind`` unbounded the upper end of the search range (a lower bound only); NaN for
        ``kind`` no_solution.
    kind : int
        ``EDGE_BOUNDED``, ``EDGE_UNBOUNDED`` or ``EDGE_NONE``.
    eta_min : float
        Smallest ``eta`` with status ok, bisected likewise; the lower end of the range when the
        smallest sample is already ok.
    status_above : int
        Status just above ``eta_max`` (bounded edges), else -1.
    transitions : ndarray
        Every ``eta`` where the coarse samples change feasibility, each bisected, or the node's
        ``eta`` where the edge is tangential. One entry (for a bounded edge with ok below) means
        feasibility is monotone on the samples.
    bands : ndarray
        Per transition, the relative distance from it within which the solver's status is not
        reliable (:attr:`Probe.band`; 0 where ``D(1)`` could not be probed).
    tangential : ndarray of bool
        Per transition, whether it is the node's ``eta`` (a tangential edge, :func:`trace_edge`).
    smooth : ndarray of bool
        Per transition, whether it is the zero of :func:`smooth_wall_D` (a transversal edge where
        the status is noise over more than ``SMOOTH_BAND``, :func:`trace_edge`).
    """

    A: float
    N: float
    eta_max: float
    kind: int
    eta_min: float
    status_above: int
    transitions: np.ndarray
    bands: np.ndarray = None
    tangential: np.ndarray = None
    smooth: np.ndarray = None

    def __post_init__(self):
        if self.bands is None:
            self.bands = np.zeros(self.transitions.size)
        if self.tangential is None:
            self.tangential = np.zeros(self.transitions.size, dtype=bool)
        if self.smooth is None:
            self.smooth = np.zeros(self.transitions.size, dtype=bool)

    @property
    def monotone(self) -> bool:
        """Feasibility changes at most once over the sampled range."""
        return self.transitions.size <= 1


def bisect_edge(feasible, lo, hi, xtol, *, feasible_lo=True):
    """Narrow a bracket of a change of feasibility in ``eta`` by bisection in ``log eta``.

    The one bisection of the solvability edge: :func:`trace_edge`, the stability report's
    ``feasible_eta_max`` and the edge stratum of the work-precision validation set all call it,
    each with its own feasibility predicate. The validation set's points depend on where this
    stops (``measure/validation.py``): a change here that moves an edge by more than the rounding
    there needs a bump of its ``GENERATOR_VERSION``.

    Parameters
    ----------
    feasible : callable
        ``feasible(eta) -> bool``.
    lo, hi : float
        The bracket, ``0 < lo < hi``: ``feasible(lo) == feasible_lo`` and ``feasible(hi)`` is the
        opposite (the caller has evaluated both ends; they are not evaluated again).
    xtol : float
        Relative width at which to stop: ``hi / lo - 1 <= xtol``.
    feasible_lo : bool, optional
        Feasibility at ``lo``: True for an upper edge (feasible below), False for a lower edge.

    Returns
    -------
    lo, hi : float
        The narrowed bracket, with the feasibility of the input ends.

    Notes
    -----
    The midpoint is geometric: the bracket can span decades of ``eta`` (1e-3 to 50), and a
    geometric midpoint halves ``log(hi/lo)``, so the number of predicate calls is
    ``log2(log(hi/lo) / xtol)`` whatever the span. It stops early should round-off leave no
    float strictly inside the bracket.
    """
    while hi - lo > xtol * lo:
        mid = math.sqrt(lo * hi)
        if not lo < mid < hi:
            break
        if feasible(mid) == feasible_lo:
            lo = mid
        else:
            hi = mid
    return lo, hi


def trace_edge(A, N, *, eta_range=(ETA_SEARCH_MIN, ETA_SEARCH_MAX), n_coarse=ETA_COARSE,
               xtol=ETA_XTOL, rtol=EDGE_RTOL, atol=EDGE_ATOL, workspace=None,
               tangential=True) -> Edge:
    """``eta_max(A, N)``: the largest ``eta = eps L`` in ``eta_range`` that has a solution.

    Feasibility is status ok of :func:`cosserat_channel.solver.point.Workspace.status` (the status of
    ``solve_point`` by the cheapest solve that decides it: stage 2 only next to the path edge);
    the regimes of Appendix A with no solution for any ``eta`` are decided by
    :func:`model.classify` alone.

    Assumption, and how it is checked: the feasible set is a union of intervals no shorter than
    the spacing of ``n_coarse`` log-spaced samples. Every change of feasibility between adjacent
    samples is bisected to ``xtol`` (relative), so ``transitions`` lists all edges that the samples
    see; ``eta_max`` is the last ok side. The feasible set is *not* assumed to be one interval
    starting at 0: for ``A > 1`` and ``N < 1`` small ``eta`` fails along the path and only large
    ``eta`` is solvable (``eta_min`` reports that lower edge). For ``-1 < A < 1`` the axis
    condition bounds the range from above: samples stop at ``2(A+1)N/(1-A)``.

    Parameters
    ----------
    A, N : float
        The point of the ``(A, N)`` plane.
    eta_range : (float, float)
        The searched range of ``eta``.
    n_coarse : int
        Log-spaced samples of the coarse pass.
    xtol : float
        Relative width of the final bracket of a status bisection.
    rtol, atol : float
        Tolerances of the status solves.
    workspace : Workspace, optional
        Work arrays to reuse (or a stand-in that counts the solves).
    tangential : bool
        Whether to probe ``D(1)`` and take the node's ``eta`` at tangential edges (False: every
        transition is the status bisection's, as before the probes existed).

    Returns
    -------
    Edge

    Notes
    -----
    **Tangential edges.** Where the stress path runs into the node of the yield condition at the
    wall (:func:`node_edge_eta`), ``D(1)`` vanishes like ``c (eta_node - eta)^2`` (c ~ 0.1) and
    the status just below the edge is decided by the noise of ``D(1)`` (~1e-13, stage 1 at its
    floor tolerance): statuses flip within a few 1e-7 (relative) of the edge and a bisection lands
    anywhere there. Each transition is therefore bisected to ``PROBE_XTOL`` first and
    ``D(1)`` sampled on its ok side at ``PROBE_OFFSETS`` (:func:`probe_edge`), where it is far
    above its noise and ``sqrt(D(1))`` is smooth. The transition is the node's ``eta`` when (a) the
    singular point at the wall is a node, (b) the bisected bracket lies within ``NODE_AGREE``
    noise bands of it and (c) the degree-3 extrapolation of ``sqrt(D(1))`` reaches zero there
    within ``NODE_AGREE`` times the larger of its spread (degree 2 against 3) and the band: the
    data say the path reaches the node, the closed form says where. Every other transition is
    bisected on to ``xtol``, except where the probe's band exceeds ``SMOOTH_BAND`` (an upper
    edge): there the transition is the zero of :func:`smooth_wall_D` found by
    :func:`smooth_edge` (``smooth`` flags it).

    **Transversal edges next to the node/focus switch.** On the focus side of
    ``N^2 = (5 + 3A)/2`` the path meets ``D = 0`` transversally, but close to the singular point:
    ``D(1)`` rises with a slope ``~F(1)`` that vanishes at the switch, and stage 1's ``D(1)``,
    read off ``delta(1)`` with a noise of ~1e-13, makes the status noise over up to ~1e-6 (at
    ``A = -0.265``, ``N = 1.415`` the bisected edge was 1e-8 above the model's and the status not
    monotone within 1e-7). :func:`smooth_wall_D` carries ``D`` itself next to the wall, where the
    error of the march before it is damped: its ``D(1)`` is smooth to ~1e-18, and Brent's method
    puts the zero to ``SMOOTH_XTOL``. Its conditioning degrades only at the switch itself, where
    the zero becomes double (then ~``sqrt(1e-18 / c)`` ~ 1e-9). Either way ``bands`` says how
    close to the transition the statuses stop being reliable;
    :func:`cosserat_channel.atlas.classify` leaves points that close undecided.
    """
    A = PARAMETERS["A"].check(A)
    N = PARAMETERS["N"].check(N)
    lo_e, hi_e = check_eta_range(eta_range)
    if n_coarse < 2:
        raise ParameterError(f"n_coarse must be >= 2; got {n_coarse!r}")
    ws = workspace or Workspace(max_steps_stage1=EDGE_MAX_STEPS)
    empty = np.empty(0)

    def feasible_at(eta):
        code = model.classify(eta, A, N)
        if code == st.OK and A != -1.0:
            code = ws.status(eta, A, N, rtol, atol)
        return code == st.OK, int(code)

    code = model.classify(lo_e, A, N)
    if code in (st.WALL_INADMISSIBLE, st.AXIS_SPIN_UNBOUNDED):
        return Edge(A, N, math.nan, EDGE_NONE, math.nan, -1, empty)
    if A == -1.0:
        return Edge(A, N, hi_e, EDGE_UNBOUNDED, lo_e, -1, empty)
    top = hi_e
    edge = float(axis_edge_eta(A, N))
    if edge <= lo_e:
        return Edge(A, N, math.nan, EDGE_NONE, math.nan, -1, empty)
    if edge < top:
        top = edge  # the axis edge itself is infeasible (classify: margin <= 0)
    etas = np.geomspace(lo_e, top, n_coarse)
    flags = [feasible_at(e) for e in etas]
    if top == edge:
        # The axis edge belongs to the infeasible side (model.classify); round-off in the margin
        # must not make the sample there look ok.
        flags[-1] = (False, st.EPS_TOO_LARGE_AXIS)
    ok = np.array([f[0] for f in flags])
    if not ok.any():
        return Edge(A, N, math.nan, EDGE_NONE, math.nan, -1, empty)
    transitions, bands, tangent, smooth = [], [], [], []
    hi = math.nan
    for i in np.flatnonzero(ok[1:] != ok[:-1]):
        eta_t, band, is_node, lo, hi, is_smooth = _transition(
            feasible_at, ws, A, N, etas[i], etas[i + 1], bool(ok[i]), xtol, rtol, atol, tangential)
        transitions.append(eta_t)
        bands.append(band)
        tangent.append(is_node)
        smooth.append(is_smooth)
    transitions = np.array(transitions)
    bands = np.array(bands)
    tangent = np.array(tangent, dtype=bool)
    smooth = np.array(smooth, dtype=bool)
    eta_min = lo_e if ok[0] else float(transitions[0])
    last = int(np.flatnonzero(ok)[-1])
    if last == n_coarse - 1:
        return Edge(A, N, hi_e, EDGE_UNBOUNDED, eta_min, -1, transitions, bands, tangent, smooth)
    # The last change is ok -> not ok (ok is False at the last sample); hi is just above it. The
    # status is taken 1e-4 (relative) higher: right at the edge the path meets D = 0 a hair before
    # the wall and the solver may report integration_failed while it crawls into the sqrt kink.
    probe = min(hi * (1.0 + 1e-4), float(etas[last + 1]))
    above = feasible_at(probe)
    if above[0]:
        above = feasible_at(hi)
    return Edge(A, N, float(transitions[-1]), EDGE_BOUNDED, eta_min, above[1], transitions,
                bands, tangent, smooth)


def _transition(feasible_at, ws, A, N, a, b, ok_low, xtol, rtol, atol, tangential):
    """One change of feasibility between the samples ``a < b`` (``ok_low``: ok at ``a``).

    Returns ``(eta, band, tangential, lo, hi)``: the transition (the node's ``eta`` or the status
    bisection's ok end), its noise band, whether it is the node's, and the last bracket.
    See :func:`trace_edge`'s Notes.
    """
    def feasible(eta):
        return feasible_at(eta)[0]

    if not tangential:
        lo, hi = bisect_edge(feasible, a, b, xtol, feasible_lo=ok_low)
        return (lo if ok_low else hi), 0.0, False, lo, hi, False
    lo, hi = bisect_edge(feasible, a, b, max(xtol, PROBE_XTOL), feasible_lo=ok_low)
    t_ok = lo if ok_low else hi
    probe = probe_edge(ws, t_ok, -1 if ok_low else 1, A, N, rtol, atol)
    band = probe.band if probe is not None else 0.0
    if probe is not None and ok_low:
        node, is_node, _ = node_edge_eta(A, N)
        near = NODE_AGREE * band
        spread = abs(probe.root3 - probe.root2) / node if math.isfinite(probe.root2) else math.inf
        if (is_node and lo * (1.0 - near) <= node <= hi * (1.0 + near)
                and abs(probe.root3 / node - 1.0) <= NODE_AGREE * max(spread, band)):
            return node, band, True, lo, hi, False
        if band > SMOOTH_BAND:
            # Transversal, but the status is noise over more than the bracket asked for (next
            # to the node/focus switch D(1) rises slowly): the zero of the smooth D(1) instead.
            zero = smooth_edge(A, N, lo, hi, band, count=getattr(ws, "count", None))
            if math.isfinite(zero):
                return zero, band, False, lo, hi, True
    lo, hi = bisect_edge(feasible, lo, hi, xtol, feasible_lo=ok_low)
    return (lo if ok_low else hi), band, False, lo, hi, False


def trace_boundary(A, N, *, eta_range=(ETA_SEARCH_MIN, ETA_SEARCH_MAX), n_coarse=ETA_COARSE,
                   xtol=ETA_XTOL, rtol=EDGE_RTOL, atol=EDGE_ATOL, progress=None):
    """:func:`trace_edge` on the grid ``A x N``; returns an :class:`xarray.Dataset` on ``(A, N)``.

    Variables: ``eta_max``, ``eta_min``, ``edge_kind`` (int8 flag: bounded, unbounded_in_range,
    no_solution), ``status_above`` (int8 status code just above a bounded edge, otherwise -1, the
    flag ``no_edge``), ``n_transitions`` and the analytic ``axis_edge_eta``. ``progress(k, n)``, if given, is called
    after each of the ``n`` edges.
    """
    import xarray as xr

    from . import __version__

    A = np.atleast_1d(np.asarray(A, dtype=float))
    N = np.atleast_1d(np.asarray(N, dtype=float))
    if A.ndim != 1 or N.ndim != 1 or A.size == 0 or N.size == 0:
        raise ParameterError("A and N must be non-empty 1-D sequences")
    check_values("A", A)
    check_values("N", N)
    check_eta_range(eta_range)
    shape = (A.size, N.size)
    eta_max = np.full(shape, np.nan)
    eta_min = np.full(shape, np.nan)
    kind = np.empty(shape, dtype=np.int8)
    above = np.full(shape, -1, dtype=np.int8)
    n_tr = np.zeros(shape, dtype=np.int16)
    ws = Workspace(max_steps_stage1=EDGE_MAX_STEPS)
    for i, a in enumerate(A):
        for j, n in enumerate(N):
            e = trace_edge(a, n, eta_range=eta_range, n_coarse=n_coarse, xtol=xtol, rtol=rtol,
                           atol=atol, workspace=ws)
            eta_max[i, j], eta_min[i, j], kind[i, j] = e.eta_max, e.eta_min, e.kind
            above[i, j], n_tr[i, j] = e.status_above, e.transitions.size
            if progress is not None:
                progress(i * N.size + j + 1, A.size * N.size)
    flags = st.cf_flag_attrs()
    ds = xr.Dataset(
        {
            "eta_max": (("A", "N"), eta_max, {
                "long_name": "largest eps L with a solution", "units": "1"}),
            "eta_min": (("A", "N"), eta_min, {
                "long_name": "smallest eps L with a solution", "units": "1"}),
            "edge_kind": (("A", "N"), kind, {
                "long_name": "kind of the traced edge",
                "flag_values": np.arange(len(EDGE_KINDS), dtype=np.int8),
                "flag_meanings": " ".join(EDGE_KINDS)}),
            "status_above": (("A", "N"), above, {
                "long_name": "status just above eta_max (no_edge where no bounded edge)",
                "flag_values": np.r_[np.int8(-1), flags["flag_values"]].astype(np.int8),
                "flag_meanings": "no_edge " + flags["flag_meanings"]}),
            "n_transitions": (("A", "N"), n_tr, {
                "long_name": "changes of feasibility seen over the search range", "units": "1"}),
            "axis_edge_eta": (("A", "N"), axis_edge_eta(A[:, None], N[None, :]), {
                "long_name": "eps L on the axis condition (A-1) eps L + 2(A+1) N = 0",
                "units": "1"}),
        },
        coords={d: (d, v, {"long_name": PARAMETERS[d].long_name, "units": PARAMETERS[d].units})
                for d, v in (("A", A), ("N", N))},
        attrs={
            "title": "cosserat-channel boundary: edge of solvability in eta = eps L", "Conventions": st.CONVENTIONS,
            "eta_search_min": float(eta_range[0]), "eta_search_max": float(eta_range[1]),
            "n_coarse": int(n_coarse), "xtol_relative": float(xtol), "rtol": float(rtol),
            "atol": float(atol), "cosserat_channel_version": __version__,
        },
    )
    return ds
