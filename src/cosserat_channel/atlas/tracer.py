"""The tracer of an atlas build: each ``(A, N)`` node traced once (continued from a prediction,
in threads), kept in the order met and indexed by place, with the solves it took.

:class:`_Tracer` holds a build's traces; :class:`_Index` finds the traced nodes nearest a point
(their kinds and slopes seed a neighbour's prediction); :class:`_Trace` is one node's record.
Imports the solver through :mod:`cosserat_channel.regimes` when a tracer is made.
"""

from __future__ import annotations

import concurrent.futures
import math
import threading
from dataclasses import dataclass

import numpy as np

from .. import regime_codes as rc
from .settings import NEAR_NODE, NEAR_SPREAD, TRACE_WIDEN
from .signatures import _variants


class _Counting:
    """A :class:`~cosserat_channel.solver.point.Workspace` stand-in for ``trace_edge`` that counts the solves: status
    solves and the stage-1 solves of ``regimes.wall_D`` (which calls :meth:`count`)."""

    def __init__(self, ws):
        self.ws = ws
        self.solves = 0

    def status(self, eta, A, N, rtol, atol):
        self.solves += 1
        return self.ws.status(eta, A, N, rtol, atol)

    def count(self, n):
        self.solves += n


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


class _Tracer:
    """The traces of one build: made (in threads), predicted, kept in the order met, indexed.

    Parameters
    ----------
    eta_range : (float, float)
        The ``eta`` the atlas answers for; the traces search ``TRACE_WIDEN`` times wider.
    tau : float
        Width of the continuation's verifying bracket (``TAU_OF_TOL * tol``).
    bucket : (float, float)
        Bucket size of the index of traced nodes (:class:`_Index`).
    known : dict or None
        An earlier build's traces by ``(A, N)``, taken instead of tracing; each trace made is
        added to it.
    workers : int
        Threads that trace a grid's nodes at once.
    """

    def __init__(self, eta_range, tau, bucket, known, workers):
        from .. import regimes
        from ..solver.point import Workspace

        self.trace_range = (eta_range[0] / TRACE_WIDEN, eta_range[1] * TRACE_WIDEN)
        self.log_range = (math.log(eta_range[0]), math.log(eta_range[1]))
        self.log_trace = (math.log(self.trace_range[0]), math.log(self.trace_range[1]))
        self.tau = tau
        self._regimes, self._workspace = regimes, Workspace
        self.cache = {}  # this build's traces, in the order they are met
        self.known = {} if known is None else known
        # Traced nodes by bucket: the nearest neighbours of a node, for the kinds and slopes of
        # its transitions and where no interpolant covers it.
        self.index = _Index(bucket)
        self.tally = {"predicted": 0, "fallback": 0}
        self._local = threading.local()
        self._pool = concurrent.futures.ThreadPoolExecutor(workers) if workers > 1 else None

    def close(self):
        if self._pool is not None:
            self._pool.shutdown(cancel_futures=True)

    def _trace(self, job):
        key, prediction = job
        regimes, local = self._regimes, self._local
        if not hasattr(local, "ws"):  # a Workspace per thread: its arrays are the solver's
            local.ws = _Counting(self._workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS))
        before = local.ws.solves
        e = regimes.trace_edge(key[0], key[1], eta_range=self.trace_range, workspace=local.ws,
                               prediction=prediction, tau=self.tau)
        low = e.kind != rc.EDGE_NONE and e.eta_min == self.trace_range[0]
        return _Trace(bool(low), np.asarray(e.transitions, dtype=float),
                      np.asarray(e.bands, dtype=float), e, local.ws.solves - before)

    def _prediction(self, key, predictor):
        # The interpolant's transitions (with the kinds and slopes of the nearest node of its
        # signature), then each other signature traced nearby: tried in that order; the node
        # whose kinds and slopes were taken too where the interpolant is no better than it (its
        # spread at NEAR_SPREAD: the interpolant of a coarse grid or across a crossing).
        regimes = self._regimes
        out = []
        found = [tr for tr in self.index.nearest(key) if tr.edge is not None]
        near = [tr for tr in found if max(abs(tr.edge.A - key[0]),
                                          abs(tr.edge.N - key[1])) <= NEAR_NODE]
        if predictor is not None:
            lt = predictor(*key)
            spread = np.minimum(np.maximum(10.0 * predictor.errs, 1e3 * self.tau), NEAR_SPREAD)
            for keep, flip in _variants(lt, spread, predictor.clamped, self.log_trace):
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

    def trace_grid(self, na, nn, predictor):
        """Trace the nodes ``na x nn`` not traced yet, in the order one thread would, with
        predictions made before any of them is traced; a node the earlier build's traces hold is
        taken from them. Returns the grid's ``(low, transitions)``, A-major."""
        missing = list(dict.fromkeys(k for k in ((a, n) for a in na for n in nn)
                                     if k not in self.cache))
        jobs = [(k, self._prediction(k, predictor)) for k in missing]
        todo = [job for job in jobs if job[0] not in self.known]
        pool = self._pool
        results = iter(map(self._trace, todo) if pool is None else pool.map(self._trace, todo))
        for k, pred in jobs:
            if k in self.known:
                tr = self.known[k]
            else:
                tr = self.known[k] = next(results)
            self.cache[k] = tr
            self.index.add(k, tr)
            if pred is not None:
                self.tally["predicted"] += 1
                self.tally["fallback"] += not tr.edge.continued
        return [(self.cache[(a, b)].low, self.cache[(a, b)].transitions) for a in na for b in nn]

    def band(self, na, nn):
        """The largest noise band of the grid's traces."""
        return max(float(np.max(self.cache[(a, b)].bands, initial=0.0)) for a in na for b in nn)
