"""Building an atlas: a loop over a queue of cells that traces each (:func:`_trace_cell`, with
the :class:`~.tracer._Tracer` that holds the traces), fits its last grid (:class:`_Fit`) and
applies the refinement decision (:func:`_refine`, a pure function of the cell and its fit: a
leaf, an envelope leaf, a higher degree or four children), then :func:`.assemble._assemble`.
Imports the solver through :mod:`cosserat_channel.regimes`, when :func:`build_atlas` runs."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..physics import analytic
from .. import regime_codes as rc
from ..parameters import ETA_MAX, ETA_MIN, PARAMETERS, ParameterError
from .assemble import _assemble
from .chebyshev import _coefficients, _estimate, _vandermonde, lobatto
from .signatures import _cluster_columns, _envelope, _unify
from .tracer import _Tracer
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


@dataclass
class _Fit:
    """A grid's interpolant where :func:`_unify` aligns its nodes with transitions.

    ``predictor`` interpolates every transition; ``err``, ``tails``, ``rates`` and ``raw`` are
    :func:`_estimate`'s over the answered transitions but the clamped ones (``hard``, which only a
    cell that may not be split keeps, :func:`_cluster_columns`); ``logt`` the nodes' transitions
    ``(p + 1, q + 1, k)`` in ``log eta``; ``answered`` those :func:`_answered` holds to ``tol``.
    """

    predictor: _Predictor
    err: float
    tails: np.ndarray
    rates: np.ndarray
    raw: float
    hard: list
    logt: np.ndarray
    answered: list


def _grid_fit(traces, pa, pn, bounds, trace_range, log_range):
    """The signature set of a grid's ``traces`` (``(low, transitions)`` per node, A-major), one
    where :func:`_unify` aligns them and no transition it clamped reaches into the answered range;
    and wherever it aligns them with transitions, their :class:`_Fit` (else None)."""
    unified = _unify(traces, trace_range)
    if unified is None:
        return {(bool(low), t.size) for low, t in traces}, None
    low, logt, clamped = unified
    if not logt.shape[1]:
        return {(low, 0)}, None
    logt = logt.reshape(pa + 1, pn + 1, -1)  # (p, q, k)
    coef = _coefficients(np.moveaxis(logt, -1, 0), pa, pn)  # (k, p, q)
    answered = _answered(coef, log_range)
    hard = [k for k in answered if clamped[k]]
    err, tails, rates, raw = _estimate(coef[[k for k in answered if not clamped[k]]])
    errs = np.array([_estimate(c[None])[0] for c in coef])
    sig = {(bool(low), t.size) for low, t in traces} if hard else {(low, logt.shape[-1])}
    return sig, _Fit(_Predictor(bounds, coef, low, err, errs, clamped), err, tails, rates, raw,
                     hard, logt, answered)


def _nodes(lo, hi, p):
    """The ``p + 1`` Chebyshev-Lobatto nodes of ``[lo, hi]``; the ends are the bounds themselves,
    so neighbours share the traces on their common side."""
    x = lo + (hi - lo) * (lobatto(p) + 1.0) / 2.0
    x[0], x[-1] = lo, hi
    return x


def _envelope_leaf(tracer, cell, na, nn):
    """A cell whose nodes ``na x nn`` mix signatures at the deepest level, as a leaf
    (:func:`_envelope`)."""
    cache = tracer.cache
    traces = [(cache[(a, b)].low, cache[(a, b)].transitions) for a in na for b in nn]
    low, logt, errs = _envelope(traces, *tracer.trace_range)
    band = max([float(np.nanmax(cache[(a, b)].bands, initial=0.0)) for a in na for b in nn])
    return _Leaf(cell.level, cell.i, cell.j, int(low), logt.size, float(np.max(errs, initial=0.0)),
                 logt.reshape(-1, 1, 1), (0, 0), band, errs)


@dataclass(frozen=True)
class _Grid:
    """What the tracing of a cell ended on: the signature set and fit of its last grid, that
    grid's degrees and nodes."""

    sig: set
    fit: _Fit | None
    degree: tuple
    na: np.ndarray
    nn: np.ndarray


@dataclass(frozen=True)
class _Rules:
    """The build's arguments that the refinement decision reads."""

    tol: float
    max_depth: int
    max_degree: int
    degree: int
    uniform: bool


def _mixed(sig, fit, can_split):
    """Whether a grid's nodes must be split apart: they mix signatures, and the cell may be split
    or they do not align (a deepest cell goes on where only transitions clamped at the traced
    range's ends differ: the others still reach ``tol``)."""
    return len(sig) > 1 and (can_split or fit is None)


def _trace_cell(tracer, cell, bounds, rules):
    """Trace a cell's grids (:func:`_levels` for a fresh cell, its own degree for a refined one),
    each predicted by the best interpolant so far, until one mixes signatures or the last is
    traced; returns the :class:`_Grid` it ended on."""
    a_lo, a_hi, n_lo, n_hi = bounds
    can_split = cell.level < rules.max_depth
    log_range = tracer.log_range
    predictor = cell.predictor
    refined = math.isfinite(cell.before)
    for p, q in ([(cell.pa, cell.pn)] if refined else _levels(cell.pa, cell.pn)):
        na, nn = _nodes(a_lo, a_hi, p), _nodes(n_lo, n_hi, q)
        traces = tracer.trace_grid(na, nn, predictor)
        sig, fit = _grid_fit(traces, p, q, bounds, tracer.trace_range, log_range)
        if _mixed(sig, fit, can_split) or (rules.uniform and can_split):
            break  # mixed (or the uniform baseline): split before tracing finer grids
        if len(sig) > 1 and set(fit.answered) <= set(fit.hard):
            break  # only clamped transitions are answered: finer grids would not help
        if fit is not None and (predictor is None or fit.predictor.err < predictor.err):
            predictor = fit.predictor
    return _Grid(sig, fit, (p, q), na, nn)


@dataclass(frozen=True)
class _Refinement:
    """What becomes of a cell (:func:`_refine`): a leaf (its noise band still to be filled in),
    an envelope leaf, or cells to trace next (its own at a higher degree, first in the queue, or
    its four children, last)."""

    leaf: _Leaf | None = None
    envelope: bool = False
    grown: _Cell | None = None
    children: tuple = ()


def _refine(cell, grid, crosses, rules):
    """The refinement decision for a traced ``cell``, a pure function of the cell, the
    :class:`_Grid` its tracing ended on and whether the node/focus switch crosses it.

    Mixed nodes split the cell (an envelope leaf at ``max_depth``). Otherwise the cell's estimate
    decides: within ``tol``, stalled (a refinement that did not cut the raw tail by
    :data:`REFINE_GAIN`) or with nothing left to try, a leaf; else grown in degree along each
    direction whose coefficients still decay geometrically, else split.
    """
    sig, fit = grid.sig, grid.fit
    p, q = grid.degree
    pa, pn = cell.pa, cell.pn
    can_split = cell.level < rules.max_depth
    children = [_Cell(cell.level + 1, 2 * cell.i + di, 2 * cell.j + dj, rules.degree, rules.degree)
                for di in (0, 1) for dj in (0, 1)]
    if _mixed(sig, fit, can_split) or (rules.uniform and can_split):
        if not can_split:
            return _Refinement(envelope=True)
        own = fit.predictor if fit is not None else (cell.predictor if len(sig) == 1 else None)
        for c in children:
            c.predictor = own
        return _Refinement(children=tuple(children))
    low, n_tr = (fit.predictor.low, fit.predictor.coef.shape[0]) if fit else next(iter(sig))
    coef, err, raw = np.empty((0, pa + 1, pn + 1)), 0.0, 0.0
    tails, rates = np.zeros(2), np.zeros(2)
    errs, hard = None, []
    if n_tr:
        coef, errs = fit.predictor.coef, fit.predictor.errs
        err, tails, rates, raw, hard = fit.err, fit.tails, fit.rates, fit.raw, fit.hard
    # Across the node/focus switch the edge is not analytic: a higher degree buys little there
    # (the tail of a degree-8 cell fell 2-4x at degree 16, against 130-1000x beside it), so such
    # a cell is split while it can be.
    grow = [not rules.uniform and t > rules.tol / 2 and r < RATE_GEOMETRIC
            and 2 * d <= rules.max_degree and not (can_split and crosses)
            for t, r, d in zip(tails, rates, (pa, pn))]
    # Stalled: a higher degree did not pay, or a child that will not raise its degree (its
    # coefficients do not decay) is no better than its parent was. Compared on the raw two-degree
    # sums: the estimates' factors change with the degree and the decay. A split cuts a degree-p
    # tail by about 2^(p+1) where the edge is smooth: at low degrees ask for less than
    # REFINE_GAIN.
    gain = min(REFINE_GAIN, 2.0 ** (min(pa, pn) - 1))
    stalled = raw > cell.before / gain or (raw > cell.parent / gain and not any(grow))
    own = fit.predictor if fit is not None else None
    done = err <= rules.tol or stalled
    if not can_split and n_tr and (done or not any(grow)):
        # The deepest cells: a transition clamped by _unify that reaches into the answered range,
        # or one whose nodes' envelope states less than its estimate, is kept as that envelope
        # (_cluster_columns).
        clustered = _cluster_columns(coef, errs, fit.logt, hard)
        if clustered is None and hard:
            return _Refinement(envelope=True)
        if clustered is not None:
            coef, errs = clustered
            err = float(np.max(errs[fit.answered], initial=0.0)) or err
        return _Refinement(leaf=_Leaf(cell.level, cell.i, cell.j, int(low), n_tr, err, coef,
                                      (p, q), 0.0, errs))
    if done or not (any(grow) or can_split):
        return _Refinement(leaf=_Leaf(cell.level, cell.i, cell.j, int(low), n_tr, err, coef,
                                      (pa, pn), 0.0, errs))
    if any(grow):
        return _Refinement(grown=_Cell(cell.level, cell.i, cell.j, pa * (1 + grow[0]),
                                       pn * (1 + grow[1]), raw, cell.parent, own))
    for c in children:
        c.parent, c.predictor = raw, own
    return _Refinement(children=tuple(children))


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
    from .. import __version__

    A_range, N_range, tol, degree, max_depth, eta_range = check_build_arguments(
        A_range, N_range, tol, degree, max_depth, eta_range, max_degree)
    if roots is None:
        roots = (max(1, math.ceil((A_range[1] - A_range[0]) / ROOT_CELL)),
                 max(1, math.ceil((N_range[1] - N_range[0]) / ROOT_CELL)))
    roots = (int(roots[0]), int(roots[1]))
    if not (isinstance(workers, (int, np.integer)) and workers >= 1):
        raise ParameterError(f"workers must be a positive integer; got {workers!r}")
    tau = TAU_OF_TOL * tol
    # Traced nodes are indexed by bucket of a root cell's eighth, at least NEAR_NODE.
    bucket = (max((A_range[1] - A_range[0]) / (8 * roots[0]), NEAR_NODE),
              max((N_range[1] - N_range[0]) / (8 * roots[1]), NEAR_NODE))
    tracer = _Tracer(eta_range, tau, bucket, traces, workers)
    rules = _Rules(tol, max_depth, max_degree, degree, uniform)
    ma, mn = roots[0] << max_depth, roots[1] << max_depth

    def coord(lo, hi, k, m):
        return lo + (hi - lo) * k / m

    leaves = []
    queue = [_Cell(0, i, j, degree, degree) for i in range(roots[0]) for j in range(roots[1])]
    try:
        while queue:
            cell = queue.pop(0)
            s = 1 << (max_depth - cell.level)
            a_lo, a_hi = coord(*A_range, cell.i * s, ma), coord(*A_range, (cell.i + 1) * s, ma)
            n_lo, n_hi = coord(*N_range, cell.j * s, mn), coord(*N_range, (cell.j + 1) * s, mn)
            grid = _trace_cell(tracer, cell, (a_lo, a_hi, n_lo, n_hi), rules)
            step = _refine(cell, grid, _crosses_switch(a_lo, a_hi, n_lo, n_hi), rules)
            if step.envelope:
                leaves.append(_envelope_leaf(tracer, cell, grid.na, grid.nn))
            elif step.leaf is not None:
                if step.leaf.n:
                    step.leaf.band = tracer.band(grid.na, grid.nn)
                leaves.append(step.leaf)
            elif step.grown is not None:
                queue.insert(0, step.grown)
            else:
                queue.extend(step.children)
            if progress is not None:
                progress(len(leaves), len(leaves) + len(queue),
                         f"cells done, {len(tracer.cache)} edges traced")
    finally:
        tracer.close()
    box = (A_range[0], A_range[1], N_range[0], N_range[1])
    return _assemble(leaves, tracer.cache, box=box, roots=roots, degree=degree,
                     max_depth=max_depth, tol=tol, eta_range=eta_range, trace_range=tracer.trace_range,
                     uniform=uniform, max_degree=max_degree,
                     solves=sum(tr.solves for tr in tracer.cache.values()), tally=tracer.tally,
                     tau=tau, version=__version__)
