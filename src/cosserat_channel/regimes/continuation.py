"""Transitions predicted from a neighbour, corrected on a smooth scalar and verified by a sign
bracket of it (:func:`continue_edge`): what the atlas and the boundary spend per edge point.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..physics import model
from ..solver import stage1
from .. import status as st
from ..physics.analytic import axis_edge_eta
from ..regime_codes import (
    EDGE_BOUNDED,
    EDGE_NONE,
    EDGE_UNBOUNDED,
    ETA_SEARCH_MAX,
    ETA_SEARCH_MIN,
)
from ..solver.point import Workspace
from .edge import Edge
from .wall import D_NOISE, EDGE_MAX_STEPS, SMOOTH_BAND, node_edge_eta, smooth_wall_D, wall_scalar

# Continuation (continue_edge): a transition predicted from a neighbour is corrected on a smooth
# scalar and verified by a sign bracket of it.
CORRECT_TAU = 1e-10  # default half-width (relative) of the bracket that verifies a corrected root
# Marches one transition may take before the caller traces afresh (~100 solves). From an
# interpolant 10-40 % off in eta the search gains a factor 20-50 a march in its last steps
# and closes its bracket in 9-10 marches: 8 sent 2 % of predicted traces to a fresh trace.
CORRECT_MAX_EVALS = 12
CORRECT_REACH = 2.0  # a root further than this from its prediction (in log eta) is not taken
NODE_VERIFY = 1e-5  # least relative distance of the checks either side of a node's eta
NODE_VERIFY_BANDS = 4.0  # ... in noise bands at least
BAND_CAP = 1e-5  # a noise band noise / slope is capped here (a near-double zero: see Notes)


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
        or a check disagrees) or leaves no transition and no solution at either end (the ends
        cannot rule out a window of solutions between them): the caller traces afresh
        (:func:`trace_edge`).
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
        # No solution at either end says nothing of a window of solutions between them: only
        # a fresh trace, which samples the whole range, may conclude there is none.
        return None
    eta_min = lo_e if ok_lo else float(transitions[0])
    if ok_hi:
        return Edge(A, N, hi_e, EDGE_UNBOUNDED, eta_min, -1, transitions, **extra)
    return Edge(A, N, float(transitions[-1]), EDGE_BOUNDED, eta_min, found[-1][0].code_bad,
                transitions, **extra)


def guesses_from(edge, spread=1e-2):
    """:class:`Guess` es for :func:`continue_edge` at a neighbour of a traced ``edge``: its
    transitions, sides, slopes, kinds and bands, each with relative uncertainty ``spread``."""
    low = edge.feasible_low
    out = []
    side = 1 if not low else -1
    for k, t in enumerate(edge.transitions):
        out.append(Guess(float(t), side, spread, float(edge.slopes[k]), bool(edge.tangential[k]),
                         bool(edge.smooth[k]), float(edge.bands[k])))
        side = -side
    return bool(low), out
