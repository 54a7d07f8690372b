"""The edge of solvability at one ``(A, N)`` (:func:`trace_edge`: continued from a prediction,
else coarse samples and bisections) and on a grid (:func:`trace_boundary`).
"""

from __future__ import annotations

import math

import numpy as np

from ..physics import model
from .. import status as st
from ..physics.analytic import axis_edge_eta
from ..parameters import PARAMETERS, ParameterError, check_eta_range, check_values
from ..regime_codes import (
    EDGE_BOUNDED,
    EDGE_NONE,
    EDGE_UNBOUNDED,
    ETA_COARSE,
    ETA_SEARCH_MAX,
    ETA_SEARCH_MIN,
)
from ..solver.point import Workspace
from .boundary import boundary_dataset
from .continuation import CORRECT_TAU, continue_edge, guesses_from
from .edge import Edge, bisect_edge
from .wall import (
    EDGE_ATOL,
    EDGE_MAX_STEPS,
    EDGE_RTOL,
    PROBE_XTOL,
    SMOOTH_BAND,
    node_edge_eta,
    probe_edge,
    smooth_edge,
    wall_scalar,
)

ETA_XTOL = 1e-10  # relative width of the final bracket
# The node's eta is taken as the edge when the status bisection lies within this many noise bands
# of it and the extrapolation of sqrt(D(1)) puts the zero there too.
NODE_AGREE = 4.0


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


BOUNDARY_NEAR = 0.05  # trace_boundary continues from a grid neighbour this close in A and N
BOUNDARY_SPREAD = 0.05  # ... with this relative uncertainty


def trace_boundary(A, N, *, eta_range=(ETA_SEARCH_MIN, ETA_SEARCH_MAX), n_coarse=ETA_COARSE,
                   xtol=ETA_XTOL, rtol=EDGE_RTOL, atol=EDGE_ATOL, progress=None):
    """:func:`trace_edge` on the grid ``A x N``; returns an :class:`xarray.Dataset` on ``(A, N)``.

    Variables: ``eta_max``, ``eta_min``, ``edge_kind`` (int8 flag: bounded, unbounded_in_range,
    no_solution), ``status_above`` (int8 status code just above a bounded edge, otherwise -1, the
    flag ``no_edge``), ``n_transitions`` and the analytic ``axis_edge_eta``.
    ``progress(done, total, text)`` (the package's progress protocol), if given, is called after
    each edge.

    Each edge is continued (:func:`continue_edge`, verified to ``xtol``) from the edges traced
    before it at the grid's neighbours within ``BOUNDARY_NEAR`` in A and N (the previous ``N``,
    the previous ``A``), and traced afresh where there is none or the continuation fails.
    """
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
    traced = {}
    for i, a in enumerate(A):
        for j, n in enumerate(N):
            near = [traced[k] for k in ((i, j - 1), (i - 1, j)) if k in traced
                    and max(abs(traced[k].A - a), abs(traced[k].N - n)) <= BOUNDARY_NEAR]
            prediction = [guesses_from(p, BOUNDARY_SPREAD) for p in near] or None
            e = trace_edge(a, n, eta_range=eta_range, n_coarse=n_coarse, xtol=xtol, rtol=rtol,
                           atol=atol, workspace=ws, prediction=prediction, tau=xtol)
            traced[(i, j)] = e
            eta_max[i, j], eta_min[i, j], kind[i, j] = e.eta_max, e.eta_min, e.kind
            above[i, j], n_tr[i, j] = e.status_above, e.transitions.size
            if progress is not None:
                progress(i * N.size + j + 1, A.size * N.size, "edges traced")
    return boundary_dataset(
        A, N, eta_max=eta_max, eta_min=eta_min, edge_kind=kind, status_above=above,
        n_transitions=n_tr, title="cosserat-channel boundary: edge of solvability in eta = eps L",
        attrs={"eta_search_min": float(eta_range[0]), "eta_search_max": float(eta_range[1]),
               "n_coarse": int(n_coarse), "xtol_relative": float(xtol), "rtol": float(rtol),
               "atol": float(atol)})
