"""Where the model has a solution: phase-plane data (figure 12) and the traced edge eta_max(A, N).

Two questions, both in the scaled variables of :mod:`cosserat_channel.model` (stresses over nu):

* **Phase plane** (Appendix A, figure 12). The angular-momentum balance with either root of eq:56,

      eps dm/dxi = (A+1) xi + sqrt(D) = E+        (eq:a1)
      eps dm/dxi = (A+1) xi - sqrt(D) = E-        (eq:a2)
      D = (A^2-1) xi^2 + 2(A+1)(N^2 - m^2/L^2)    (eq:a3)

  from ``m(0) = +-N L`` (eq:16). :func:`phase_plane` returns the curves ``D = 0``
  (``m = +-L sqrt(N^2 + (A-1) xi^2/2)``), the nullcline ``xi^2 + m^2/L^2 = N^2`` (there
  ``sqrt(D) = |A+1| xi``: ``E- = 0`` for A > -1, ``E+ = 0`` for A < -1; it is the outer solution
  eq:15), the sign regions of ``E+-`` on a grid, and the four trajectories, integrated with
  :func:`scipy.integrate.solve_ivp` until ``D = 0`` or the wall. This is a plotting aid, not the
  solver: :func:`cosserat_channel.solve.solve_point` decides whether a point has a solution.

* **Edge of solvability.** By the similarity of model.md, whether a point has a solution depends on
  ``(eta = eps L, A, N)`` only. :func:`trace_edge` finds ``eta_max(A, N)``, the largest ``eta`` in
  the searched range with status ``ok``, by sampling a coarse grid in ``eta`` and bisecting every
  sampled change of feasibility; :func:`trace_boundary` does that on a grid of ``(A, N)`` and returns
  an :class:`xarray.Dataset`.

Pure numpy/scipy/xarray (no matplotlib: figures live in :mod:`cosserat_channel.plot.regimes`, which
reads the codes of this data from :mod:`cosserat_channel.regime_codes` and never solves).
:func:`bisect_edge` is the one bisection of a solvability edge in the package. The module is
just over 500 lines because the phase plane and the edge share the model's regime logic and the
Dataset layout of :func:`trace_boundary`; a solvability atlas would make it a ``regimes/`` package.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from . import model
from .analytic import axis_edge_eta  # noqa: F401 (its home is analytic.py; callers import it here)
from . import status as st
from .parameters import PARAMETERS, ParameterError, check_point
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
from .solve import Workspace

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
@dataclass
class Edge:
    """The traced edge of solvability in ``eta = eps L`` at one ``(A, N)``.

    Attributes
    ----------
    eta_max : float
        Largest ``eta`` with status ok (bracketed to ``xtol`` relative); for ``kind`` unbounded the
        upper end of the search range (a lower bound only); NaN for ``kind`` no_solution.
    kind : int
        ``EDGE_BOUNDED``, ``EDGE_UNBOUNDED`` or ``EDGE_NONE``.
    eta_min : float
        Smallest ``eta`` with status ok, bisected likewise; the lower end of the range when the
        smallest sample is already ok.
    status_above : int
        Status just above ``eta_max`` (bounded edges), else -1.
    transitions : ndarray
        Every ``eta`` where the coarse samples change feasibility, each bisected. One entry (for a
        bounded edge with ok below) means feasibility is monotone on the samples.
    """

    A: float
    N: float
    eta_max: float
    kind: int
    eta_min: float
    status_above: int
    transitions: np.ndarray

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
               xtol=ETA_XTOL, rtol=EDGE_RTOL, atol=EDGE_ATOL, workspace=None) -> Edge:
    """``eta_max(A, N)``: the largest ``eta = eps L`` in ``eta_range`` that has a solution.

    Feasibility is status ok of :func:`cosserat_channel.solve.Workspace.status` (the status of
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

    Returns
    -------
    Edge
    """
    A = float(A)
    N = float(N)
    if not (math.isfinite(A) and math.isfinite(N) and N > 0.0):
        raise ParameterError(f"A must be finite and N > 0; got A = {A!r}, N = {N!r}")
    lo_e, hi_e = (float(v) for v in eta_range)
    if not (0.0 < lo_e < hi_e < math.inf):
        raise ParameterError(f"eta_range must be 0 < lo < hi < inf; got {eta_range!r}")
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
    transitions = []
    hi = math.nan
    for i in np.flatnonzero(ok[1:] != ok[:-1]):
        lo, hi = bisect_edge(lambda eta: feasible_at(eta)[0], etas[i], etas[i + 1], xtol,
                             feasible_lo=bool(ok[i]))
        transitions.append(lo if ok[i] else hi)
    transitions = np.array(transitions)
    eta_min = lo_e if ok[0] else float(transitions[0])
    last = int(np.flatnonzero(ok)[-1])
    if last == n_coarse - 1:
        return Edge(A, N, hi_e, EDGE_UNBOUNDED, eta_min, -1, transitions)
    # The last change is ok -> not ok (ok is False at the last sample); hi is just above it. The
    # status is taken 1e-4 (relative) higher: right at the edge the path meets D = 0 a hair before
    # the wall and the solver may report integration_failed while it crawls into the sqrt kink.
    probe = min(hi * (1.0 + 1e-4), float(etas[last + 1]))
    above = feasible_at(probe)
    if above[0]:
        above = feasible_at(hi)
    return Edge(A, N, float(transitions[-1]), EDGE_BOUNDED, eta_min, above[1], transitions)


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
            "title": "cosserat-channel boundary: edge of solvability in eta = eps L",
            "eta_search_min": float(eta_range[0]), "eta_search_max": float(eta_range[1]),
            "n_coarse": int(n_coarse), "xtol_relative": float(xtol), "rtol": float(rtol),
            "atol": float(atol), "cosserat_channel_version": __version__,
        },
    )
    return ds
