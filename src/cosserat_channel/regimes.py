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
# Continuation (continue_edge): a transition predicted from a neighbour is corrected on a smooth
# scalar and verified by a sign bracket of it.
CORRECT_TAU = 1e-10  # default half-width (relative) of the bracket that verifies a corrected root
CORRECT_MAX_EVALS = 8  # marches one transition may take before the caller traces afresh
CORRECT_REACH = 2.0  # a root further than this from its prediction (in log eta) is not taken
NODE_VERIFY = 1e-5  # least relative distance of the checks either side of a node's eta
NODE_VERIFY_BANDS = 4.0  # ... in noise bands at least
BAND_CAP = 1e-5  # a noise band noise / slope is capped here (a near-double zero: see Notes)


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
def _smooth_wall_D_kernel(eta, A, N, rtol, ax, T, Qw, Q, stats, out):
    # out: (D(1), delta(1)); returns D(1) (NaN where a march failed)
    out[0] = math.nan
    out[1] = math.nan
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
    out[0] = y[1]
    out[1] = y[0]
    return y[1]


_SMOOTH_WORK = threading.local()  # work arrays per thread (the atlas traces in threads)


def smooth_wall_D(eta, A, N, rtol=SMOOTH_RTOL, out=None):
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
    ``out``, if given (a float array of 2), receives ``D(1)`` and ``delta(1)``.
    """
    A = float(A)
    N = float(N)
    eta = float(eta)
    if out is not None:
        out[:] = math.nan
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
    if out is None:
        out = np.empty(2)
    return float(_smooth_wall_D_kernel(eta, A, N, float(rtol), ax, w.T, w.Qw, w.Q, w.stats, out))


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
    slopes : ndarray
        Per transition, ``d D(1) / d log eta`` there where the corrector measured it (NaN
        elsewhere): what a neighbour's corrector takes as its first slope.
    continued : bool
        Whether the edge was corrected from a prediction (:func:`continue_edge`) rather than
        traced afresh.
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
    slopes: np.ndarray = None
    continued: bool = False

    def __post_init__(self):
        if self.bands is None:
            self.bands = np.zeros(self.transitions.size)
        if self.tangential is None:
            self.tangential = np.zeros(self.transitions.size, dtype=bool)
        if self.smooth is None:
            self.smooth = np.zeros(self.transitions.size, dtype=bool)
        if self.slopes is None:
            self.slopes = np.full(self.transitions.size, math.nan)

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
               tangential=True, prediction=None, tau=CORRECT_TAU) -> Edge:
    """``eta_max(A, N)``: the largest ``eta = eps L`` in ``eta_range`` that has a solution.

    With a ``prediction`` (``(low, guesses)``, as :func:`guesses_from` gives), the edge is
    first continued from it (:func:`continue_edge`, roots verified to ``tau``); the coarse
    samples and bisections below run only where that fails (``Edge.continued`` says which).

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
    prediction : (bool, list of Guess) or a list of them, optional
        A neighbour's signature and transitions to continue from (several: tried in order).
    tau : float
        Half-width (relative) of the bracket that verifies a continued transition.

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
    for low, guesses in ([] if prediction is None else
                         [prediction] if isinstance(prediction, tuple) else prediction):
        e = continue_edge(A, N, low, guesses, eta_range=(lo_e, hi_e), workspace=ws, tau=tau)
        if e is not None:
            return e
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
    slopes = _slopes(ws, A, N, transitions, tangent, [bool(ok[i]) for i in
                                                       np.flatnonzero(ok[1:] != ok[:-1])])
    eta_min = lo_e if ok[0] else float(transitions[0])
    last = int(np.flatnonzero(ok)[-1])
    if last == n_coarse - 1:
        return Edge(A, N, hi_e, EDGE_UNBOUNDED, eta_min, -1, transitions, bands, tangent, smooth,
                    slopes)
    # The last change is ok -> not ok (ok is False at the last sample); hi is just above it. The
    # status is taken 1e-4 (relative) higher: right at the edge the path meets D = 0 a hair before
    # the wall and the solver may report integration_failed while it crawls into the sqrt kink.
    probe = min(hi * (1.0 + 1e-4), float(etas[last + 1]))
    above = feasible_at(probe)
    if above[0]:
        above = feasible_at(hi)
    return Edge(A, N, float(transitions[-1]), EDGE_BOUNDED, eta_min, above[1], transitions,
                bands, tangent, smooth, slopes)


SLOPE_STEP = 1e-4  # relative distance of the one march that measures a traced transition's slope


def _slopes(ws, A, N, transitions, tangential, ok_below):
    """``d D(1) / d log eta`` at each transversal transition, from one :func:`wall_scalar` march
    ``SLOPE_STEP`` (relative) into its ok side: what a neighbour's corrector starts from."""
    out = np.full(transitions.size, math.nan)
    for k, (t, tang, below) in enumerate(zip(transitions, tangential, ok_below)):
        if tang:
            continue
        _, G, _ = wall_scalar(ws, [t * (1.0 - SLOPE_STEP if below else 1.0 + SLOPE_STEP)], A, N)
        if math.isfinite(G[0]) and G[0] > 0.0:
            out[k] = -G[0] / SLOPE_STEP if below else G[0] / SLOPE_STEP
    return out


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


# ---------------------------------------------------------------------------------------------
# Continuation: transitions predicted from their neighbours, corrected on a smooth scalar
# ---------------------------------------------------------------------------------------------


@njit(**_JIT)
def _wall_scalar_kernel(etas, A, N, ax, T1, Q1, stats1, res, status, G, sens):
    # Stage 1 at its floor tolerance (one march: it never re-marches there), then a signed
    # distance from the edge in D: D(1) where the path reached the wall; F(xi_s) (1 - xi_s) where
    # it met D = 0 at xi_s < 1 (there D' = F, so this continues D(1) through zero to first order);
    # NaN where stage 1 says neither. sens: |dD/d delta| delta, what stage 1's error does to D.
    buf = np.empty(1)
    work = np.zeros(stress_path.N_W)
    rtol = stage1.STAGE1_RTOL_FLOOR
    atol = EDGE_ATOL * rtol / EDGE_RTOL
    for i in range(etas.size):
        eta = etas[i]
        code, _ = stage1.solve_stage1(eta, A, N, rtol, atol, ax, T1, Q1, stats1, res,
                                      layout.METHOD_AUTO)
        status[i] = code
        n1 = int(res[layout.R_N1])
        xs = res[layout.R_XI_STOP]
        G[i] = math.nan
        sens[i] = math.nan
        if n1 > 0 and (code == st.OK or xs == 1.0):
            d = stress_path._delta_wall(T1, Q1, n1, buf)
            G[i] = model.yield_D(1.0, d, A, N, ax)
            sens[i] = stage1._wall_D_sensitivity(A, N, d)
        elif code == st.EPS_TOO_LARGE_PATH and n1 > 0 and xs < 1.0:
            work[0] = 0.0
            d = stress_path._delta_at(xs, res[layout.R_XI1], ax, T1, Q1, n1, buf, work)
            a1 = A + 1.0
            F = 2.0 * a1 * xs * ((A - 1.0) + 2.0 * a1 * (N - d) / eta)
            G[i] = min(F, 0.0) * (1.0 - xs)
            sens[i] = stage1._wall_D_sensitivity(A, N, d)


def wall_scalar(workspace, etas, A, N):
    """Stage 1's status and a signed, smooth distance from the edge at each ``eta``.

    One stage-1 march at its floor tolerance per ``eta`` (``stage1.STAGE1_RTOL_FLOOR``). The
    scalar is ``D(1)`` where the path reaches the wall, and ``F(xi_s) (1 - xi_s) <= 0`` where it
    meets ``D = 0`` at ``xi_s < 1`` (``F`` as in :func:`node_edge_eta`: ``D' = F`` where
    ``D = 0``), so it continues ``D(1)`` through its zero at a transversal edge with the same
    slope; NaN where stage 1 says neither (it failed, or the axis condition decides).

    Parameters
    ----------
    workspace : Workspace or a counting stand-in with ``ws`` and ``count``
    etas : array_like
    A, N : float

    Returns
    -------
    status : ndarray of int8
        Stage 1's status.
    G : ndarray
        The scalar.
    sens : ndarray
        ``|dD/d delta| delta`` there: stage 1's noise in ``G`` is ``D_NOISE * STAGE1_RTOL_FLOOR``
        times it.
    """
    ws = getattr(workspace, "ws", workspace)
    count = getattr(workspace, "count", None)
    etas = np.ascontiguousarray(np.atleast_1d(np.asarray(etas, dtype=float)))
    if count is not None:
        count(etas.size)
    status = np.empty(etas.size, dtype=np.int8)
    G = np.empty(etas.size)
    sens = np.empty(etas.size)
    _wall_scalar_kernel(etas, float(A), float(N), ws.ax, ws.T1, ws.Q1, ws.stats1, ws.res, status,
                        G, sens)
    return status, G, sens


@dataclass
class Guess:
    """A predicted transition for :func:`continue_edge`.

    Attributes
    ----------
    eta : float
        Where it is predicted.
    side : int
        -1 where ``eta`` below it has a solution (an upper edge), +1 where ``eta`` above it has.
    spread : float
        Relative uncertainty of the prediction (how far a search widens when no slope is known).
    slope : float
        Predicted ``d D(1) / d log eta`` at it (NaN: unknown).
    tangential, smooth : bool
        How the neighbour's transition was found (the node's eta; the smooth D(1)).
    band : float
        The neighbour's noise band.
    """

    eta: float
    side: int
    spread: float = 1e-2
    slope: float = math.nan
    tangential: bool = False
    smooth: bool = False
    band: float = 0.0


@dataclass
class Corrected:
    """A transition found by :func:`correct_transition`: where, how, and what it cost.

    ``outside`` is -1 (+1) where the transition has left the searched range through its low
    (high) end: ``eta`` is then that end. ``code_bad`` is the status on its side without a
    solution.
    """

    eta: float
    band: float = 0.0
    tangential: bool = False
    smooth: bool = False
    slope: float = math.nan
    code_bad: int = -1
    outside: int = 0


def _quadratic_root(points):
    """The root next to the first of three ``(u, h, ...)`` points of the parabola through them
    (Muller's step: where ``h`` is near a double zero, as next to the node/focus switch, the
    secant only halves the error each step); NaN where it has no real root."""
    (u1, h1, *_), (u2, h2, *_), (u3, h3, *_) = points
    if u1 == u2 or u1 == u3 or u2 == u3:
        return math.nan
    d12 = (h2 - h1) / (u2 - u1)
    d13 = (h3 - h1) / (u3 - u1)
    c = (d13 - d12) / (u3 - u2)
    b = d12 + c * (u1 - u2)  # h = h1 + b (u - u1) + c (u - u1)^2
    disc = b * b - 4.0 * c * h1
    if disc < 0.0:
        return math.nan
    q = b + math.copysign(math.sqrt(disc), b)
    return u1 - 2.0 * h1 / q if q != 0.0 else math.nan


def _power_root(points, sb):
    """Where ``h = c (r - u)^p`` through three points on the ok side (nearest the root first)
    vanishes: next to the node/focus switch the smooth ``D(1)`` vanishes like a power between 1
    and 2 (measured ~1.5), where a secant or a parabola gains only a factor of a few per march.
    NaN where the points do not fall towards the root or no such ``r`` lies within 100 spacings."""
    (u3, h3, *_), (u2, h2, *_), (u1, h1, *_) = points
    if not (h1 > h2 > h3 > 0.0 and sb * (u2 - u1) > 0.0 and sb * (u3 - u2) > 0.0):
        return math.nan
    a, b = math.log(h1 / h2), math.log(h2 / h3)
    g32, g21 = abs(u3 - u2), abs(u2 - u1)

    def f(t):  # t: distance of the root beyond u3
        return a * math.log((t + g32) / t) - b * math.log((t + g32 + g21) / (t + g32))

    lo, hi = 1e-6 * g32, 100.0 * g32
    if not (f(lo) > 0.0 > f(hi)):
        return math.nan
    for _ in range(60):
        mid = math.sqrt(lo * hi)
        if f(mid) > 0.0:
            lo = mid
        else:
            hi = mid
    return u3 + sb * math.sqrt(lo * hi)


def _root_search(h, u0, spread, sb, slope, tau, u_lo, u_hi, max_evals):
    """The zero of ``h`` in ``u = log eta`` next to ``u0``, verified by a bracket ``2 tau`` wide.

    ``h(u) -> (value, ok, code)``: ``ok`` on the side with a solution, where ``value > 0``;
    ``value`` is NaN where only the side is known, ``ok`` None where not even that. ``sb`` is
    the direction (+-1 in ``u``) from the ok side to the other. The ok side is where ``h`` is
    analytic (beyond the edge :func:`wall_scalar` continues it to first order only), so the
    estimates come from there: a secant through the two ok points next to the root, else the
    slope between the bracket's ends, else the predicted ``slope``, else a widening by
    ``spread``. The next point is taken ``tau / 2`` short of the estimate, on the ok side; once
    the ok point nearest the root is within ``tau`` of the estimate, a point ``2 tau`` beyond it
    closes the bracket. A good prediction so costs three marches. Returns ``(root, slope,
    code_bad, outside, evals)`` (``outside`` -1 or +1 where the transition lies beyond the low
    or high end of ``[u_lo, u_hi]``) or None where ``max_evals`` marches did not close the
    bracket, a point had no side, or the root ran further than ``CORRECT_REACH`` from ``u0``.
    """
    pts = []

    def ev(u):
        value, ok, code = h(u)
        if ok is None:
            return False
        pts.append((u, value, bool(ok), code))
        return True

    def secant(p, q):
        if not (math.isfinite(p[1]) and math.isfinite(q[1])) or p[1] == q[1] or p[0] == q[0]:
            return math.nan
        return (q[1] - p[1]) / (q[0] - p[0])

    widen = max(spread, 4.0 * tau)
    if not ev(u0):
        return None
    while True:
        oks = sorted((p for p in pts if p[2]), key=lambda p: -sb * p[0])
        bads = sorted((p for p in pts if not p[2]), key=lambda p: sb * p[0])
        o = oks[0] if oks else None
        b = bads[0] if bads else None
        if o is not None and b is not None:
            gap = sb * (b[0] - o[0])
            if gap <= 0.0:
                return None  # a solution beyond a point without one: not one transition here
            if gap <= 2.0 * tau * (1.0 + 1e-6) + 4e-16 * abs(o[0]):
                break
        # An end of the range on the side of a root not yet bracketed: it has left the range.
        end = u_hi if sb > 0 else u_lo
        if o is not None and b is None and o[0] == end:
            return end, math.nan, -1, (1 if sb > 0 else -1), len(pts)
        end = u_lo if sb > 0 else u_hi
        if b is not None and o is None and b[0] == end:
            return end, math.nan, -1, (-1 if sb > 0 else 1), len(pts)
        if len(pts) >= max_evals:
            return None
        # A secant through the two points of smallest |h| (both sides: beyond the edge h is
        # continued to first order), else the predicted slope, else a widening by spread.
        fin = sorted((q for q in pts if math.isfinite(q[1])), key=lambda q: abs(q[1]))
        oks_fin = [q for q in oks if math.isfinite(q[1])]
        s = secant(fin[0], fin[1]) if len(fin) >= 2 else math.nan
        if not (s * sb < 0.0):
            s = slope
        p = fin[0] if fin else None
        candidates = [_power_root(oks_fin[:3], sb) if len(oks_fin) >= 3 else math.nan,
                      _quadratic_root(fin[:3]) if len(fin) >= 3 else math.nan,
                      p[0] - p[1] / s if p is not None and s * sb < 0.0 else math.nan]
        if o is not None and b is not None:
            if math.isfinite(b[1]) and o[1] > 0.0 and b[1] < 0.0:
                candidates.append(o[0] + (b[0] - o[0]) * o[1] / (o[1] - b[1]))
            candidates.append(0.5 * (o[0] + b[0]))
            r = next(c for c in candidates if math.isfinite(c)
                     and sb * (c - o[0]) > 0.0 and sb * (b[0] - c) > 0.0)
        else:
            r = next((c for c in candidates if math.isfinite(c)
                      and (o is None or sb * (c - o[0]) > 0.0)
                      and (b is None or sb * (b[0] - c) > 0.0)), math.nan)
            if not math.isfinite(r):
                r = o[0] + sb * widen if o is not None else b[0] - sb * widen
                widen *= 4.0
        if o is not None and sb * (r - o[0]) <= tau:
            nxt = o[0] + sb * 2.0 * tau  # the ok point is within tau of the root: close
        elif b is not None and sb * (b[0] - r) <= tau:
            nxt = b[0] - sb * 2.0 * tau  # likewise from beyond the edge
        else:
            nxt = r - sb * 0.5 * tau  # just short of the estimate: on the analytic side
        if o is not None and b is not None and not (
                sb * (nxt - o[0]) > 0.0 and sb * (b[0] - nxt) > 0.0):
            nxt = 0.5 * (o[0] + b[0])
        if abs(nxt - u0) > CORRECT_REACH:
            return None
        if nxt < u_lo or nxt > u_hi:
            end = u_lo if nxt < u_lo else u_hi
            if any(q[0] == end for q in pts):
                return None
            nxt = end
        if not ev(nxt):
            return None
    # The root: linear between the bracket's ends where both have a value, else from the ok end
    # along the best slope known.
    s = secant(o, b)
    if not (s * sb < 0.0) and len(oks) >= 2:
        s = secant(oks[0], oks[1])
    if math.isfinite(b[1]) and o[1] > 0.0 and b[1] < 0.0:
        root = o[0] + (b[0] - o[0]) * o[1] / (o[1] - b[1])
    elif s * sb < 0.0 and math.isfinite(o[1]):
        root = min(max(o[0] - o[1] / s, min(o[0], b[0])), max(o[0], b[0]))
    else:
        root = 0.5 * (o[0] + b[0])
    return root, s, b[3], 0, len(pts)


def correct_transition(workspace, A, N, guess, *, tau=CORRECT_TAU, eta_range=None,
                       max_evals=CORRECT_MAX_EVALS):
    """Correct one predicted transition at ``(A, N)``; None where the prediction does not hold.

    In order: where the singular point at the wall is a node, an upper edge is the node's
    closed-form ``eta`` (:func:`node_edge_eta`) once stage 1 has a solution at
    ``eta_node (1 - v)`` and none at ``eta_node (1 + v)``, ``v`` at least ``NODE_VERIFY_BANDS``
    noise bands (two marches). Otherwise the transition is the zero of :func:`wall_scalar`
    (``D(1)``, continued through zero) found by :func:`_root_search` from the guess and verified
    by a sign bracket ``2 tau`` wide (typically three marches); where stage 1's noise in
    ``D(1)`` over the slope there (the noise band) exceeds ``SMOOTH_BAND``, it is the zero of
    :func:`smooth_wall_D` instead, found and verified alike. A root never counts unless a point
    with a solution and one without lie within ``2 tau`` of each other around it.

    Parameters
    ----------
    workspace : Workspace or a counting stand-in (``ws``, ``count``)
    A, N : float
    guess : Guess
    tau : float
        Half-width of the verifying bracket, relative in ``eta``.
    eta_range : (float, float), optional
        Where to search; a transition found beyond an end is reported as ``outside``.
    max_evals : int
        Marches allowed to the transversal search (each of the two kinds).

    Returns
    -------
    Corrected or None
    """
    count = getattr(workspace, "count", None)
    side = int(guess.side)
    sb = -side
    u_lo, u_hi = ((-math.inf, math.inf) if eta_range is None
                  else (math.log(eta_range[0]), math.log(eta_range[1])))
    node, is_node, _ = node_edge_eta(A, N)
    if side == -1 and is_node and math.isfinite(node) and u_lo < math.log(node) < u_hi:
        v = max(NODE_VERIFY, NODE_VERIFY_BANDS * guess.band)
        for _ in range(2):
            code, G, sens = wall_scalar(workspace, [node * (1.0 - v), node * (1.0 + v)], A, N)
            if not (code[0] == st.OK and G[0] > 0.0 and code[1] != st.OK):
                break
            band = v * math.sqrt(D_NOISE * stage1.STAGE1_RTOL_FLOOR * sens[0] / G[0])
            if NODE_VERIFY_BANDS * band <= v:
                return Corrected(node, band, True, False, math.nan, int(code[1]))
            v = 2.0 * NODE_VERIFY_BANDS * band
    noise = [math.nan]

    def h_stage1(u):
        code, G, sens = wall_scalar(workspace, [math.exp(u)], A, N)
        noise[0] = D_NOISE * stage1.STAGE1_RTOL_FLOOR * sens[0] if math.isfinite(sens[0]) \
            else noise[0]
        if math.isfinite(G[0]):
            return G[0], bool(G[0] > 0.0), int(code[0])
        return math.nan, (None if code[0] == st.OK else False), int(code[0])

    out = np.empty(2)

    def h_smooth(u):
        if count is not None:
            count(1)
        G = smooth_wall_D(math.exp(u), A, N, out=out)
        if not math.isfinite(G):
            return math.nan, None, -1
        noise[0] = D_NOISE * stage1.STAGE1_RTOL_FLOOR * stage1._wall_D_sensitivity(A, N, out[1])
        return G, bool(G > 0.0), st.EPS_TOO_LARGE_PATH

    u0 = math.log(guess.eta)
    spread = max(float(guess.spread), tau)
    slope = float(guess.slope)
    use_smooth = bool(guess.smooth) and side == -1
    for smooth in ((True,) if use_smooth else (False, True)):
        found = _root_search(h_smooth if smooth else h_stage1, u0, spread, sb, slope, tau, u_lo,
                             u_hi, max_evals)
        if found is None:
            if smooth or side != -1:
                return None
            continue  # next to the node/focus switch stage 1's D(1) may be too noisy to bracket
        root, s, code_bad, outside, _ = found
        if outside:
            return Corrected(math.exp(root), outside=outside)
        band = min(noise[0] / abs(s), BAND_CAP) if math.isfinite(s) and s != 0.0 else BAND_CAP
        if smooth or band <= SMOOTH_BAND or side != -1:
            return Corrected(math.exp(root), band, False, smooth, s, code_bad)
        u0, spread, slope = root, max(4.0 * band, tau), s
    return None


def continue_edge(A, N, low, guesses, *, eta_range=(ETA_SEARCH_MIN, ETA_SEARCH_MAX),
                  workspace=None, tau=CORRECT_TAU, max_evals=CORRECT_MAX_EVALS):
    """The edge at ``(A, N)`` from a prediction: its transitions corrected, its signature checked.

    The prediction is a neighbour's: ``low`` (a solution at the low end of ``eta_range``) and
    one :class:`Guess` per transition, ascending. Each is corrected by
    :func:`correct_transition`; a transition found beyond an end of the range has left it and
    is dropped. The signature is then checked: the status at the low end of the range (one
    march) and at its high end (one march, none where the axis condition ends the range: its
    edge is infeasible in closed form) must be what the transitions imply. The regimes
    Appendix A decides for every ``eta`` cost nothing, as in :func:`trace_edge`.

    Returns
    -------
    Edge or None
        None where the prediction does not hold (a corrector failed, the sides do not alternate,
        or a check disagrees): the caller traces afresh (:func:`trace_edge`).
    """
    A = float(A)
    N = float(N)
    lo_e, hi_e = (float(v) for v in eta_range)
    ws = workspace or Workspace(max_steps_stage1=EDGE_MAX_STEPS)
    empty = np.empty(0)
    code = model.classify(lo_e, A, N)
    if code in (st.WALL_INADMISSIBLE, st.AXIS_SPIN_UNBOUNDED):
        return Edge(A, N, math.nan, EDGE_NONE, math.nan, -1, empty, continued=True)
    if A == -1.0:
        return Edge(A, N, hi_e, EDGE_UNBOUNDED, lo_e, -1, empty, continued=True)
    axis = float(axis_edge_eta(A, N))
    if axis <= lo_e:
        return Edge(A, N, math.nan, EDGE_NONE, math.nan, -1, empty, continued=True)
    top = min(hi_e, axis)
    found = []
    for g in sorted(guesses, key=lambda g: g.eta):
        c = correct_transition(ws, A, N, g, tau=tau, eta_range=(lo_e, top), max_evals=max_evals)
        if c is None:
            return None
        if not c.outside:
            found.append((c, g.side))
    etas = [c.eta for c, _ in found]
    sides = [s for _, s in found]
    if any(b <= a * (1.0 + 4.0 * tau) for a, b in zip(etas, etas[1:])):
        return None
    if any(s == t for s, t in zip(sides, sides[1:])):
        return None
    # The signature: feasibility at the ends of the range is what the transitions say.
    ok_lo = (sides[0] == -1) if sides else bool(low)
    ok_hi = (sides[-1] == 1) if sides else bool(low)
    checks = [(lo_e, ok_lo)]
    if top == hi_e:
        checks.append((hi_e, ok_hi))
    elif ok_hi:
        return None  # the axis edge itself has no solution
    code, G, _ = wall_scalar(ws, [e for e, _ in checks], A, N)
    for (_, want), c_, g_ in zip(checks, code, G):
        ok = bool(g_ > 0.0) if math.isfinite(g_) else c_ == st.OK
        if ok != want:
            return None
    transitions = np.array(etas)
    bands = np.array([c.band for c, _ in found])
    tangent = np.array([c.tangential for c, _ in found], dtype=bool)
    smooth = np.array([c.smooth for c, _ in found], dtype=bool)
    slopes = np.array([c.slope for c, _ in found])
    extra = dict(bands=bands, tangential=tangent, smooth=smooth, slopes=slopes, continued=True)
    if not ok_lo and not sides:
        return Edge(A, N, math.nan, EDGE_NONE, math.nan, -1, empty, continued=True)
    eta_min = lo_e if ok_lo else float(transitions[0])
    if ok_hi:
        return Edge(A, N, hi_e, EDGE_UNBOUNDED, eta_min, -1, transitions, **extra)
    return Edge(A, N, float(transitions[-1]), EDGE_BOUNDED, eta_min, found[-1][0].code_bad,
                transitions, **extra)


def guesses_from(edge, spread=1e-2):
    """:class:`Guess` es for :func:`continue_edge` at a neighbour of a traced ``edge``: its
    transitions, sides, slopes, kinds and bands, each with relative uncertainty ``spread``."""
    low = edge.kind != EDGE_NONE and not (edge.transitions.size
                                          and edge.eta_min == edge.transitions[0])
    out = []
    side = 1 if not low else -1
    for k, t in enumerate(edge.transitions):
        out.append(Guess(float(t), side, spread, float(edge.slopes[k]), bool(edge.tangential[k]),
                         bool(edge.smooth[k]), float(edge.bands[k])))
        side = -side
    return bool(low), out


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
