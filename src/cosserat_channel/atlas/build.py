"""Building an atlas: the tracer (predictions and continued traces), the refinement of cells
(degree, splits, envelopes at the deepest level) over records, then :func:`.assemble._assemble`.
Imports the solver through :mod:`cosserat_channel.regimes`, when :func:`build_atlas` runs."""

from __future__ import annotations

import concurrent.futures
import math
import threading
from dataclasses import dataclass

import numpy as np

from ..physics import analytic
from .. import regime_codes as rc
from ..parameters import ETA_MAX, ETA_MIN, PARAMETERS, ParameterError
from .assemble import _assemble
from .chebyshev import _coefficients, _estimate, _vandermonde, lobatto
from .signatures import _cluster_columns, _envelope, _unify, _variants
from .settings import (
    ANSWERED_GRID,
    DEFAULT_A,
    DEFAULT_N,
    DEFAULT_TOL,
    DEGREE,
    MAX_DEGREE,
    MAX_DEPTH,
    MAX_DEPTH_LIMIT,
    NEAR_NODE,
    NEAR_SPREAD,
    RATE_GEOMETRIC,
    REFINE_GAIN,
    ROOT_CELL,
    TAU_OF_TOL,
    TOL_MAX,
    TOL_MIN,
    TRACE_WIDEN,
)


def _crosses_switch(a_lo, a_hi, n_lo, n_hi):
    """Whether the node/focus switch (:func:`analytic.node_focus_switch_N`) runs through the cell.

    The curve rises with ``A``, so its values at the cell's ends in ``A`` (clipped to where it
    exists) decide.
    """
    lo, hi = max(a_lo, -1.0), min(a_hi, 1.0)
    return bool(lo < hi and analytic.node_focus_switch_N(lo) < n_hi
                and analytic.node_focus_switch_N(hi) > n_lo)


class _Counting:
    """A :class:`solve.Workspace` stand-in for ``trace_edge`` that counts the solves: status
    solves and the stage-1 solves of ``regimes.wall_D`` (which calls :meth:`count`)."""

    def __init__(self, ws):
        self.ws = ws
        self.solves = 0

    def status(self, eta, A, N, rtol, atol):
        self.solves += 1
        return self.ws.status(eta, A, N, rtol, atol)

    def count(self, n):
        self.solves += n


def check_build_arguments(A_range, N_range, tol, degree, max_depth, eta_range,
                          max_degree=MAX_DEGREE):
    """Validate :func:`build_atlas`'s arguments; ParameterError naming the one that is wrong."""
    # Both ends inside a parameter's interval put the whole range inside it.
    a0, a1 = (PARAMETERS["A"].check(v, "A") for v in A_range)
    n0, n1 = (PARAMETERS["N"].check(v, "N") for v in N_range)
    if not a0 < a1:
        raise ParameterError(f"A range must be lo < hi; got {a0:g}:{a1:g}")
    if not n0 < n1:
        raise ParameterError(f"N range must be lo < hi; got {n0:g}:{n1:g}")
    if not TOL_MIN <= tol <= TOL_MAX:
        raise ParameterError(f"tol = {tol!r} is outside [{TOL_MIN:g}, {TOL_MAX:g}] (the edge "
                             "itself is known to ~1e-8 relative)")
    if not (isinstance(degree, (int, np.integer)) and 2 <= degree <= 32 and degree % 2 == 0):
        raise ParameterError(f"degree must be an even integer in [2, 32]; got {degree!r}")
    if not (isinstance(max_depth, (int, np.integer)) and 0 <= max_depth <= MAX_DEPTH_LIMIT):
        raise ParameterError(f"max_depth must be an integer in [0, {MAX_DEPTH_LIMIT}]; "
                             f"got {max_depth!r}")
    if not (isinstance(max_degree, (int, np.integer)) and degree <= max_degree <= 64):
        raise ParameterError(f"max_degree must be an integer in [degree, 64]; got {max_degree!r}")
    lo, hi = (float(v) for v in eta_range)
    if not (ETA_MIN * TRACE_WIDEN <= lo < hi <= ETA_MAX / TRACE_WIDEN):
        raise ParameterError(f"eta range must be lo < hi inside [{ETA_MIN * TRACE_WIDEN:g}, "
                             f"{ETA_MAX / TRACE_WIDEN:g}]; got {lo:g}:{hi:g}")
    return (a0, a1), (n0, n1), float(tol), int(degree), int(max_depth), (lo, hi)


@dataclass
class _Trace:
    """One traced ``(A, N)``: feasibility at the lowest traced ``eta``, the transitions, their
    noise bands, the :class:`regimes.Edge` behind them (its kinds and slopes seed the
    neighbours' predictions) and the solves it took."""

    low: bool
    transitions: np.ndarray
    bands: np.ndarray
    edge: object = None
    solves: int = 0  # the solves it took (the atlas's n_solves sums them)

    @property
    def signature(self):
        return (self.low, self.transitions.size)


@dataclass
class _Predictor:
    """The interpolant of ``log eta`` over a cell: predicts the transitions anywhere inside it."""

    bounds: tuple
    coef: np.ndarray  # (transition, p + 1, q + 1)
    low: bool
    err: float  # the estimate of the transitions it answers for (:func:`_answered`)
    errs: np.ndarray  # each transition's own estimate
    clamped: np.ndarray  # each transition: clamped at the low (1) or high (2) end somewhere

    def __call__(self, a, n):
        a_lo, a_hi, n_lo, n_hi = self.bounds
        ta = _vandermonde(np.array(2.0 * (a - a_lo) / (a_hi - a_lo) - 1.0), self.coef.shape[1] - 1)
        tn = _vandermonde(np.array(2.0 * (n - n_lo) / (n_hi - n_lo) - 1.0), self.coef.shape[2] - 1)
        return np.einsum("i,kij,j->k", ta, self.coef, tn)


@dataclass
class _Cell:
    """A cell waiting in the build's queue."""

    level: int
    i: int
    j: int
    pa: int  # degree along A
    pn: int  # degree along N
    before: float = math.inf  # its raw tail at its previous degree
    parent: float = math.inf  # its parent's raw tail
    predictor: _Predictor = None  # its own interpolant at the previous degree, or its parent's


@dataclass
class _Leaf:
    """A finished cell: its signature, interpolant, error estimate, degrees and noise band."""

    level: int
    i: int
    j: int
    low: int
    n: int  # transitions; -1: unresolved
    err: float
    coef: np.ndarray
    degree: tuple
    band: float = 0.0
    errors: np.ndarray = None  # per transition: its own estimate, or its envelope cluster's width


def _levels(pa, pn):
    """The nested node grids of a fresh cell, coarsest first: ``(2, 2)``, then doublings up to
    ``(pa, pn)``; each is traced with predictions from the one before, and a grid that already
    mixes signatures ends the cell's tracing."""
    out = [(pa, pn)]
    p, q = pa, pn
    while p % 2 == 0 and q % 2 == 0 and min(p, q) > 2:
        p, q = p // 2, q // 2
        out.append((p, q))
    if out[-1] != (2, 2) and pa % 2 == 0 and pn % 2 == 0:
        out.append((2, 2))
    return out[::-1]


def _answered(coef, log_range):
    """The transitions of a cell that its error estimate must hold to ``tol``: all but those
    whose interpolant stays outside the ``eta`` the atlas answers for, on an
    ``ANSWERED_GRID`` square grid, by at least twice their own error estimate (then the true
    transition stays outside too, and no answered point depends on where it is)."""
    x = np.linspace(-1.0, 1.0, ANSWERED_GRID)
    keep = []
    for k, c in enumerate(coef):
        t = _vandermonde(x, c.shape[0] - 1) @ c @ _vandermonde(x, c.shape[1] - 1).T
        out = float(np.min(np.maximum(log_range[0] - t, t - log_range[1])))
        if not (out > 0.0 and 2.0 * _estimate(c[None])[0] <= out):
            keep.append(k)
    return keep


class _Index:
    """Traced nodes by bucket of ``cell_size``: the nearest of each signature to a point.

    A bucket keeps its nodes' coordinates and signatures in arrays, so a query costs a few
    vectorised passes over the nine buckets around the point, however many nodes they hold (a
    deep cell traces hundreds).
    """

    def __init__(self, cell_size):
        self.cell_size = cell_size
        self.buckets = {}  # (ia, jn) -> [coordinates (capacity, 2), codes (capacity,), traces]

    def _bucket(self, a, n):
        return int(math.floor(a / self.cell_size[0])), int(math.floor(n / self.cell_size[1]))

    def add(self, key, tr):
        b = self.buckets.setdefault(self._bucket(*key), [np.empty((16, 2)), np.empty(16, int), []])
        m = len(b[2])
        if m == b[1].size:
            b[0] = np.concatenate([b[0], np.empty_like(b[0])])
            b[1] = np.concatenate([b[1], np.empty_like(b[1])])
        b[0][m] = key
        b[1][m] = 2 * tr.transitions.size + int(tr.low)  # one code per signature
        b[2].append(tr)

    def nearest(self, key):
        """The traced nodes nearest ``key`` within the neighbouring buckets, one per signature,
        nearest first (the first met of equally near ones)."""
        a, n = key
        ia, jn = self._bucket(a, n)
        best = {}
        for da in (-1, 0, 1):
            for dn in (-1, 0, 1):
                b = self.buckets.get((ia + da, jn + dn))
                if b is None:
                    continue
                m = len(b[2])
                xy, codes = b[0][:m], b[1][:m]
                d = ((xy[:, 0] - a) / self.cell_size[0]) ** 2 + \
                    ((xy[:, 1] - n) / self.cell_size[1]) ** 2
                found, first = np.unique(codes, return_index=True)
                for c in found[np.argsort(first)]:
                    sel = np.flatnonzero(codes == c)
                    k = sel[np.argmin(d[sel])]
                    if c not in best or d[k] < best[c][0]:
                        best[c] = (d[k], b[2][k])
        return [tr for _, tr in sorted(best.values(), key=lambda v: v[0])]


def build_atlas(A_range=DEFAULT_A, N_range=DEFAULT_N, *, tol=DEFAULT_TOL, degree=DEGREE,
                max_depth=MAX_DEPTH, max_degree=MAX_DEGREE, roots=None,
                eta_range=(rc.ETA_SEARCH_MIN, rc.ETA_SEARCH_MAX), uniform=False, progress=None,
                workers=1, traces=None):
    """Sample every transition of feasibility in ``eta`` over ``A_range x N_range`` adaptively.

    A cell whose nodes share one signature gets its interpolants and their error estimate
    (:func:`_estimate`). Above ``tol`` it is refined:

    * in degree (p), along each direction whose tail is above ``tol / 2`` and decays
      geometrically, by doubling the degree there (the Chebyshev-Lobatto nodes of degree ``2p``
      hold those of degree ``p``: every trace made is kept), up to ``max_degree``;
    * else split into four (h), the children starting again at ``degree``;
    * and not at all once a refinement has not cut the raw tail by :data:`REFINE_GAIN`: the
      traces are then noisier than ``tol`` there (the solver's edge is not smooth at that level),
      and the leaf keeps its estimate, which :func:`classify` uses in place of ``tol``.

    A cell that still mixes signatures at ``max_depth`` becomes an *envelope* leaf
    (:func:`_envelope`): where its nodes agree it decides, elsewhere it states the width of the
    band it leaves undecided as its error. No leaf is left without an answer.

    Traces are continued, not made afresh: a fresh cell traces its nodes grid by grid
    (:func:`_levels`), each grid predicted by the interpolant of the grid before (or by the
    parent's interpolant, whichever estimates itself better), a refined cell by its interpolant
    at the previous degree, and a node with no interpolant over it by its nearest traced
    neighbour (within :data:`NEAR_NODE`). :func:`regimes.trace_edge` corrects each predicted
    transition on the smooth ``D(1)`` and verifies it by a sign bracket ``TAU_OF_TOL * tol``
    wide either side (:func:`regimes.continue_edge`); where that fails it traces afresh.

    Parameters
    ----------
    A_range, N_range : (float, float)
        The box of ``(A, N)``.
    tol : float
        Target relative error of the transitions in ``eta``, in ``[TOL_MIN, TOL_MAX]``.
    degree : int
        Chebyshev degree per direction a cell starts with (even: its ``(2, 2)`` sub-grid is
        traced first).
    max_depth : int
        Splits allowed below a root cell.
    max_degree : int
        Largest degree per direction (``degree`` times a power of 2 at most this; ``degree`` for
        h-refinement only).
    roots : (int, int), optional
        Root cells along A and N; default about :data:`ROOT_CELL` wide.
    eta_range : (float, float)
        The ``eta`` the atlas answers for; traces search ``TRACE_WIDEN`` times wider each way.
    uniform : bool
        Split every cell to ``max_depth`` whatever its error, at ``degree`` (the benchmark's
        non-adaptive baseline).
    progress : callable, optional
        ``progress(done, total, text)`` (the package's progress protocol) after each cell: the
        cells done against those done and queued (the queue grows as cells split), and the
        edges traced.
    workers : int
        Threads that trace a grid's nodes at once (the kernels release the GIL); the atlas is
        the same whatever their number (each trace depends on its ``(A, N)`` and on predictions
        made before the grid is traced, and the traces are kept in the order of one thread).
    traces : dict, optional
        The traces of an earlier build with the same arguments (an interrupted one), by
        ``(A, N)``: each is taken instead of traced again, and each trace made is added, as soon
        as it is made, so that the caller still holds them when the build is interrupted. The
        build replays the earlier one (predictions from the same traces in the same order), so
        the atlas is the one an uninterrupted build gives, and its ``n_solves`` counts the
        earlier solves too.

    Returns
    -------
    Atlas
    """
    from .. import __version__, regimes
    from ..solver.point import Workspace

    A_range, N_range, tol, degree, max_depth, eta_range = check_build_arguments(
        A_range, N_range, tol, degree, max_depth, eta_range, max_degree)
    if roots is None:
        roots = (max(1, math.ceil((A_range[1] - A_range[0]) / ROOT_CELL)),
                 max(1, math.ceil((N_range[1] - N_range[0]) / ROOT_CELL)))
    roots = (int(roots[0]), int(roots[1]))
    if not (isinstance(workers, (int, np.integer)) and workers >= 1):
        raise ParameterError(f"workers must be a positive integer; got {workers!r}")
    trace_range = (eta_range[0] / TRACE_WIDEN, eta_range[1] * TRACE_WIDEN)
    tau = TAU_OF_TOL * tol
    local = threading.local()
    cache = {}  # this build's traces, in the order they are met
    known = {} if traces is None else traces
    # Traced nodes by bucket (a root cell's eighth, at least NEAR_NODE): the nearest neighbours
    # of a node, for the kinds and slopes of its transitions and where no interpolant covers it.
    bucket = (max((A_range[1] - A_range[0]) / (8 * roots[0]), NEAR_NODE),
              max((N_range[1] - N_range[0]) / (8 * roots[1]), NEAR_NODE))
    index = _Index(bucket)
    tally = {"predicted": 0, "fallback": 0}

    def traced(job):
        key, prediction = job
        if not hasattr(local, "ws"):  # a Workspace per thread: its arrays are the solver's
            local.ws = _Counting(Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS))
        before = local.ws.solves
        e = regimes.trace_edge(key[0], key[1], eta_range=trace_range, workspace=local.ws,
                               prediction=prediction, tau=tau)
        low = e.kind != rc.EDGE_NONE and e.eta_min == trace_range[0]
        return _Trace(bool(low), np.asarray(e.transitions, dtype=float),
                      np.asarray(e.bands, dtype=float), e, local.ws.solves - before)

    def prediction_for(key, predictor):
        # The interpolant's transitions (with the kinds and slopes of the nearest node of its
        # signature), then each other signature traced nearby: tried in that order; the node
        # whose kinds and slopes were taken too where the interpolant is no better than it (its
        # spread at NEAR_SPREAD: the interpolant of a coarse grid or across a crossing).
        out = []
        found = [tr for tr in index.nearest(key) if tr.edge is not None]
        near = [tr for tr in found if max(abs(tr.edge.A - key[0]),
                                          abs(tr.edge.N - key[1])) <= NEAR_NODE]
        if predictor is not None:
            lt = predictor(*key)
            spread = np.minimum(np.maximum(10.0 * predictor.errs, 1e3 * tau), NEAR_SPREAD)
            for keep, flip in _variants(lt, spread, predictor.clamped, log_trace):
                sig = (predictor.low ^ flip, int(keep.sum()))
                src = next((tr for tr in found if tr.signature == sig), None)
                if src is not None:
                    low, guesses = regimes.guesses_from(src.edge)
                    for g, x, sp in zip(guesses, lt[keep], spread[keep]):
                        g.eta, g.spread = float(np.exp(x)), float(sp)
                    out.append((low, guesses))
                    if (spread[keep] < NEAR_SPREAD).all():
                        near = [tr for tr in near if tr is not src]
        out += [regimes.guesses_from(tr.edge, NEAR_SPREAD) for tr in near]
        return out or None

    pool = concurrent.futures.ThreadPoolExecutor(workers) if workers > 1 else None

    def prefetch(na, nn, predictor):
        # The nodes not traced yet, in the order one thread would trace them, with predictions
        # made before any of them is traced; a node the caller's traces hold is taken from them.
        missing = list(dict.fromkeys(k for k in ((a, n) for a in na for n in nn)
                                     if k not in cache))
        jobs = [(k, prediction_for(k, predictor)) for k in missing]
        todo = [job for job in jobs if job[0] not in known]
        results = iter(map(traced, todo) if pool is None else pool.map(traced, todo))
        for k, pred in jobs:
            if k in known:
                tr = known[k]
            else:
                tr = known[k] = next(results)
            cache[k] = tr
            index.add(k, tr)
            if pred is not None:
                tally["predicted"] += 1
                tally["fallback"] += not tr.edge.continued
    ma, mn = roots[0] << max_depth, roots[1] << max_depth
    box = (A_range[0], A_range[1], N_range[0], N_range[1])

    def coord(lo, hi, k, m):
        return lo + (hi - lo) * k / m

    def nodes(lo, hi, p):
        # The ends are the bounds themselves, so neighbours share the traces on their common side.
        x = lo + (hi - lo) * (lobatto(p) + 1.0) / 2.0
        x[0], x[-1] = lo, hi
        return x

    def grid_fit(na, nn, pa, pn, bounds):
        """The signature set of a grid, one where :func:`_unify` aligns its nodes and no
        transition it clamped reaches into the answered range; and wherever it aligns them with
        transitions, their interpolant ``(predictor, estimate, hard, log_transitions,
        answered)``: the estimate over the answered transitions but the clamped ones (``hard``),
        which only a cell that may not be split keeps (:func:`_cluster_columns`)."""
        traces = [(cache[(a, b)].low, cache[(a, b)].transitions) for a in na for b in nn]
        unified = _unify(traces, trace_range)
        if unified is None:
            return {(bool(low), t.size) for low, t in traces}, None, None
        low, logt, clamped = unified
        if not logt.shape[1]:
            return {(low, 0)}, None, None
        logt = logt.reshape(pa + 1, pn + 1, -1)  # (p, q, k)
        coef = _coefficients(np.moveaxis(logt, -1, 0), pa, pn)  # (k, p, q)
        answered = _answered(coef, log_range)
        hard = [k for k in answered if clamped[k]]
        est = _estimate(coef[[k for k in answered if not clamped[k]]])
        errs = np.array([_estimate(c[None])[0] for c in coef])
        sig = {(bool(low), t.size) for low, t in traces} if hard else {(low, logt.shape[-1])}
        return sig, coef, (_Predictor(bounds, coef, low, est[0], errs, clamped), est, hard, logt,
                           answered)

    log_range = (math.log(eta_range[0]), math.log(eta_range[1]))
    log_trace = (math.log(trace_range[0]), math.log(trace_range[1]))

    def envelope_leaf(level, i, j, na, nn):
        traces = [(cache[(a, b)].low, cache[(a, b)].transitions) for a in na for b in nn]
        low, logt, errs = _envelope(traces, *trace_range)
        band = max([float(np.nanmax(cache[(a, b)].bands, initial=0.0)) for a in na for b in nn])
        return _Leaf(level, i, j, int(low), logt.size, float(np.max(errs, initial=0.0)),
                     logt.reshape(-1, 1, 1), (0, 0), band, errs)

    leaves = []
    queue = [_Cell(0, i, j, degree, degree) for i in range(roots[0]) for j in range(roots[1])]
    try:
        while queue:
            cell = queue.pop(0)
            level, i, j, pa, pn = cell.level, cell.i, cell.j, cell.pa, cell.pn
            s = 1 << (max_depth - level)
            a_lo, a_hi = coord(*A_range, i * s, ma), coord(*A_range, (i + 1) * s, ma)
            n_lo, n_hi = coord(*N_range, j * s, mn), coord(*N_range, (j + 1) * s, mn)
            bounds = (a_lo, a_hi, n_lo, n_hi)
            can_split = level < max_depth
            refined = math.isfinite(cell.before)
            predictor = cell.predictor
            sig, fit = set(), None
            for p, q in ([(pa, pn)] if refined else _levels(pa, pn)):
                na, nn = nodes(a_lo, a_hi, p), nodes(n_lo, n_hi, q)
                prefetch(na, nn, predictor)
                sig, coef, fit = grid_fit(na, nn, p, q, bounds)
                # A cell that may not be split goes on where only transitions clamped at the
                # traced range's ends differ: the others still reach tol.
                mixed = len(sig) > 1 and (can_split or fit is None)
                if mixed or (uniform and can_split):
                    break  # mixed (or the uniform baseline): split before tracing finer grids
                if len(sig) > 1 and set(fit[4]) <= set(fit[2]):
                    break  # only clamped transitions are answered: finer grids would not help
                if fit is not None and (predictor is None or fit[0].err < predictor.err):
                    predictor = fit[0]
            children = [_Cell(level + 1, 2 * i + di, 2 * j + dj, degree, degree)
                        for di in (0, 1) for dj in (0, 1)]
            if mixed or (uniform and can_split):
                if can_split:
                    own = fit[0] if fit is not None else (
                        cell.predictor if len(sig) == 1 else None)
                    for c in children:
                        c.predictor = own
                    queue.extend(children)
                else:
                    leaves.append(envelope_leaf(level, i, j, na, nn))
            else:
                low, n_tr = (fit[0].low, fit[0].coef.shape[0]) if fit else next(iter(sig))
                coef, err, raw = np.empty((0, pa + 1, pn + 1)), 0.0, 0.0
                tails, rates = np.zeros(2), np.zeros(2)
                band, errs, hard = 0.0, None, []
                if n_tr:
                    _, err_tails_rates_raw, hard, logt, answered = fit
                    coef, errs = fit[0].coef, fit[0].errs
                    err, tails, rates, raw = err_tails_rates_raw
                    band = max(float(np.max(cache[(a, b)].bands, initial=0.0))
                               for a in na for b in nn)
                # Across the node/focus switch the edge is not analytic: a higher degree buys little
                # there (the tail of a degree-8 cell fell 2-4x at degree 16, against 130-1000x beside
                # it), so such a cell is split while it can be.
                grow = [not uniform and t > tol / 2 and r < RATE_GEOMETRIC and 2 * p <= max_degree
                        and not (can_split and _crosses_switch(a_lo, a_hi, n_lo, n_hi))
                        for t, r, p in zip(tails, rates, (pa, pn))]
                # Stalled: a higher degree did not pay, or a child that will not raise its degree
                # (its coefficients do not decay) is no better than its parent was. Compared on the
                # raw two-degree sums: the estimates' factors change with the degree and the decay.
                # A split cuts a degree-p tail by about 2^(p+1) where the edge is smooth: at low
                # degrees ask for less than REFINE_GAIN.
                gain = min(REFINE_GAIN, 2.0 ** (min(pa, pn) - 1))
                stalled = raw > cell.before / gain or (raw > cell.parent / gain and not any(grow))
                own = fit[0] if fit is not None else None
                if not can_split and n_tr and (err <= tol or stalled or not any(grow)):
                    # The deepest cells: a transition clamped by _unify that reaches into the
                    # answered range, or one whose nodes' envelope states less than its
                    # estimate, is kept as that envelope (_cluster_columns).
                    clustered = _cluster_columns(coef, errs, logt, hard)
                    if clustered is None and hard:
                        leaves.append(envelope_leaf(level, i, j, na, nn))
                    else:
                        if clustered is not None:
                            coef, errs = clustered
                            err = float(np.max(errs[answered], initial=0.0)) or err
                        leaves.append(_Leaf(level, i, j, int(low), n_tr, err, coef, (p, q),
                                            band, errs))
                elif err <= tol or stalled or not (any(grow) or can_split):
                    leaves.append(_Leaf(level, i, j, int(low), n_tr, err, coef, (pa, pn), band,
                                        errs))
                elif any(grow):
                    queue.insert(0, _Cell(level, i, j, pa * (1 + grow[0]), pn * (1 + grow[1]),
                                          raw, cell.parent, own))
                else:
                    for c in children:
                        c.parent, c.predictor = raw, own
                    queue.extend(children)
            if progress is not None:
                progress(len(leaves), len(leaves) + len(queue),
                         f"cells done, {len(cache)} edges traced")
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    return _assemble(leaves, cache, box=box, roots=roots, degree=degree, max_depth=max_depth,
                     tol=tol, eta_range=eta_range, trace_range=trace_range, uniform=uniform,
                     max_degree=max_degree, solves=sum(tr.solves for tr in cache.values()),
                     tally=tally,
                     tau=tau, version=__version__)
