"""The interpolant :class:`Atlas`: its quadtree of leaves (geometry) and the transitions it
gives anywhere in its box (evaluation). Imports numpy (xarray for :meth:`Atlas.boundary`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import regime_codes as rc
from ..physics import analytic
from .. import status as st
from .chebyshev import _vandermonde
from .settings import SAFETY


@dataclass
class Atlas:
    """An atlas: the quadtree's leaves with their interpolants, and the samples behind them.

    Attributes
    ----------
    box : tuple of float
        ``(A_min, A_max, N_min, N_max)``.
    roots : tuple of int
        Root cells along A and N.
    degree, max_depth : int
        Chebyshev degree a cell starts with; splits allowed below a root cell.
    tol : float
        Requested relative error of the transitions in ``eta``.
    eta_range : tuple of float
        The ``eta`` the atlas answers for; the traces searched ``TRACE_WIDEN`` times wider.
    leaf_level, leaf_i, leaf_j : ndarray of int
        Each leaf's depth and index along A and N at that depth.
    leaf_low : ndarray of int8
        Feasibility at the lowest traced ``eta`` (1 ok, 0 not).
    leaf_n : ndarray of int8
        Number of transitions; -1 for an unresolved leaf.
    leaf_error : ndarray of float
        Error estimate of the leaf's transitions in ``log eta`` (~relative in ``eta``).
    coef : ndarray
        ``(leaf, transition, P+1, Q+1)`` Chebyshev coefficients of ``log eta`` (A, N), ``P`` and
        ``Q`` the largest degrees of any leaf; zero beyond a leaf's own degrees, NaN beyond
        ``leaf_n``.
    leaf_degree : ndarray of int
        ``(leaf, 2)``: each leaf's Chebyshev degree along A and N.
    leaf_transition_error : ndarray of float
        ``(leaf, transition)``: the error of each transition (an envelope leaf's clusters have
        their own widths; elsewhere the leaf's estimate); NaN beyond ``leaf_n``.
    leaf_band : ndarray of float
        The largest noise band (``regimes.Edge.bands``, relative) of the traces at the leaf's
        nodes: how close to a transition the solver's own status stops being reliable.
    samples : dict of ndarray
        ``A``, ``N``, ``low``, ``n``, ``transitions`` and ``bands`` of every trace the build made.
    attrs : dict
        Provenance (tolerances of the traces, counts of traces and solves, version).
    """

    box: tuple
    roots: tuple
    degree: int
    max_depth: int
    tol: float
    eta_range: tuple
    leaf_level: np.ndarray
    leaf_i: np.ndarray
    leaf_j: np.ndarray
    leaf_low: np.ndarray
    leaf_n: np.ndarray
    leaf_error: np.ndarray
    coef: np.ndarray
    samples: dict
    attrs: dict
    leaf_degree: np.ndarray = None
    leaf_band: np.ndarray = None
    leaf_transition_error: np.ndarray = None

    def __post_init__(self):
        if self.leaf_degree is None:
            self.leaf_degree = np.full((self.leaf_n.size, 2), self.degree, dtype=np.int64)
        if self.leaf_band is None:
            self.leaf_band = np.zeros(self.leaf_n.size)
        if self.leaf_transition_error is None:
            k = np.arange(self.coef.shape[1])
            self.leaf_transition_error = np.where(k < self.leaf_n[:, None],
                                                  self.leaf_error[:, None], np.nan)
        if "bands" not in self.samples:
            self.samples["bands"] = np.zeros_like(self.samples["transitions"])

    # -- geometry --------------------------------------------------------------------------
    def _fine(self):
        return self.roots[0] << self.max_depth, self.roots[1] << self.max_depth

    def leaf_bounds(self):
        """``(A_lo, A_hi, N_lo, N_hi)`` arrays of the leaves."""
        a0, a1, n0, n1 = self.box
        ma, mn = self._fine()
        s = np.left_shift(1, self.max_depth - self.leaf_level)
        return (a0 + (a1 - a0) * (self.leaf_i * s) / ma, a0 + (a1 - a0) * ((self.leaf_i + 1) * s) / ma,
                n0 + (n1 - n0) * (self.leaf_j * s) / mn, n0 + (n1 - n0) * ((self.leaf_j + 1) * s) / mn)

    def _raster(self):
        if getattr(self, "_raster_cache", None) is None:
            ma, mn = self._fine()
            r = np.full((ma, mn), -1, dtype=np.int32)
            s = np.left_shift(1, self.max_depth - self.leaf_level)
            for k, (i, j, w) in enumerate(zip(self.leaf_i * s, self.leaf_j * s, s)):
                r[i:i + w, j:j + w] = k
            self._raster_cache = r
        return self._raster_cache

    def leaf_of(self, A, N):
        """Index of the leaf holding each ``(A, N)``; -1 outside the box."""
        a0, a1, n0, n1 = self.box
        ma, mn = self._fine()
        A = np.asarray(A, dtype=float)
        N = np.asarray(N, dtype=float)
        inside = (A >= a0) & (A <= a1) & (N >= n0) & (N <= n1)
        with np.errstate(invalid="ignore"):
            ia = np.clip(np.floor((A - a0) / (a1 - a0) * ma), 0, ma - 1)
            jn = np.clip(np.floor((N - n0) / (n1 - n0) * mn), 0, mn - 1)
        ia = np.where(inside, ia, 0).astype(np.intp)
        jn = np.where(inside, jn, 0).astype(np.intp)
        return np.where(inside, self._raster()[ia, jn], -1)

    # -- interpolation ---------------------------------------------------------------------
    def undecided_band(self, leaf):
        """Per point and transition of :meth:`transitions` (``leaf`` is its first output), the
        relative distance from the transition within which :func:`classify` decides nothing:
        ``SAFETY * max(tol, the transition's error, the leaf's noise band)``."""
        known = leaf >= 0
        k = np.maximum(leaf, 0)
        noise = np.where(known, self.leaf_band[k], 0.0)
        terr = np.where(known[..., None], self.leaf_transition_error[k], np.nan)
        return SAFETY * np.fmax(self.tol, np.fmax(terr, noise[..., None]))

    def transitions(self, A, N):
        """Interpolated transitions at ``(A, N)``.

        Returns
        -------
        leaf : ndarray of int
            The leaf (-1 outside the box).
        low : ndarray of int8
            Feasibility at the low end (-1 where unknown: outside, or an unresolved leaf).
        eta : ndarray
            ``A.shape + (n_max,)`` transitions in ``eta``, ascending, NaN-padded. Where a
            transition leaves the traced range across a leaf, the leaf keeps it clamped at that
            range's end: outside ``eta_range``, which is all the atlas answers for.
        error : ndarray
            The leaf's error estimate (NaN where unknown).
        """
        A, N = np.broadcast_arrays(np.asarray(A, dtype=float), np.asarray(N, dtype=float))
        shape = A.shape  # worked on flat copies: scalars too (0-d arrays take no masked assignment)
        A, N = A.ravel(), N.ravel()
        leaf = self.leaf_of(A, N)
        kmax = self.coef.shape[1]
        eta = np.full(A.shape + (kmax,), np.nan)
        low = np.full(A.shape, -1, dtype=np.int8)
        err = np.full(A.shape, np.nan)
        known = leaf >= 0
        known[known] = self.leaf_n[leaf[known]] >= 0
        if known.any() and kmax:
            # Leaf by leaf, each at its own degrees: gathering every point's coefficients would
            # take points x (P+1)(Q+1) floats (a 400 x 400 map at degree 32: over 1 GB).
            idx = np.flatnonzero(known)
            lf = leaf[idx]
            order = np.argsort(lf, kind="stable")
            idx, lf = idx[order], lf[order]
            starts = np.flatnonzero(np.r_[True, lf[1:] != lf[:-1]])
            bounds = self.leaf_bounds()
            logt = np.empty((idx.size, kmax))
            for s0, s1 in zip(starts, np.r_[starts[1:], idx.size]):
                k = lf[s0]
                pts = idx[s0:s1]
                pa, pn = self.leaf_degree[k]
                alo, ahi, nlo, nhi = (b[k] for b in bounds)
                ta = _vandermonde(2.0 * (A[pts] - alo) / (ahi - alo) - 1.0, pa)
                tn = _vandermonde(2.0 * (N[pts] - nlo) / (nhi - nlo) - 1.0, pn)
                logt[s0:s1] = np.einsum("pi,kij,pj->pk", ta, self.coef[k, :, :pa + 1, :pn + 1], tn)
            eta[idx] = np.exp(logt)
        low[known] = self.leaf_low[leaf[known]]
        err[known] = self.leaf_error[leaf[known]]
        return leaf.reshape(shape), low.reshape(shape), eta.reshape(shape + (kmax,)), err.reshape(shape)

    def boundary(self, A, N):
        """The atlas on the grid ``A x N`` as a :func:`regimes.trace_boundary`-style Dataset.

        ``eta_max``, ``eta_min``, ``edge_kind``, ``n_transitions`` and ``axis_edge_eta`` mean what
        they mean there, over the atlas's ``eta_range``, so :func:`plot.regimes.regime_map` and
        :func:`plot.regimes.boundary_figure` draw it unchanged. Where the atlas does not know (an
        unresolved leaf, outside the box) ``eta_max`` and ``eta_min`` are NaN, ``n_transitions``
        is -1 and ``resolved`` is False; ``status_above`` is -1 (the atlas keeps feasibility, not
        the status beyond an edge). ``eta_error`` is the error the atlas states for the
        transitions in range at each point (at least ``tol``; above it in a cell that could not
        reach it, whose interpolant is an envelope of its nodes).
        """
        from ..regimes.boundary import boundary_dataset

        A = np.atleast_1d(np.asarray(A, dtype=float))
        N = np.atleast_1d(np.asarray(N, dtype=float))
        AA, NN = np.meshgrid(A, N, indexing="ij")
        leaf, low, eta, _ = self.transitions(AA, NN)
        terr = np.where((leaf >= 0)[..., None],
                        self.leaf_transition_error[np.maximum(leaf, 0)], np.nan)
        lo, hi = self.eta_range
        # Feasibility at lo: that at the low end of the traces, flipped by each transition below lo
        # (the traces search a wider range than the atlas answers for).
        ok_lo = (low == 1) ^ (np.sum(eta <= lo, axis=-1) % 2 == 1)
        inside = np.where((eta > lo) & (eta < hi), eta, np.nan)
        with np.errstate(invalid="ignore"):
            reached = np.max(np.where(np.isfinite(inside), np.fmax(terr, self.tol), 0.0),
                             axis=-1, initial=0.0)
        n_in = np.sum(np.isfinite(inside), axis=-1)
        ok_hi = ok_lo ^ (n_in % 2 == 1)
        if inside.shape[-1]:
            first = np.nanmin(np.where(n_in[..., None] > 0, inside, np.inf), axis=-1)
            last = np.nanmax(np.where(n_in[..., None] > 0, inside, -np.inf), axis=-1)
        else:
            first = last = np.full(AA.shape, np.nan)
        kind = np.where(ok_hi, rc.EDGE_UNBOUNDED,
                        np.where(ok_lo | (n_in > 0), rc.EDGE_BOUNDED, rc.EDGE_NONE)).astype(np.int8)
        eta_max = np.where(ok_hi, hi, np.where(kind == rc.EDGE_BOUNDED, last, np.nan))
        eta_min = np.where(ok_lo, lo, np.where(kind == rc.EDGE_NONE, np.nan, first))
        known = low >= 0
        # The regimes of Appendix A with no solution at any eta are known everywhere, atlas or not.
        code = analytic.classify_points(np.full(AA.shape, lo), AA, NN)
        none = np.isin(code, (st.WALL_INADMISSIBLE, st.AXIS_SPIN_UNBOUNDED))
        kind[none] = rc.EDGE_NONE
        n_in = np.where(none, 0, n_in)
        known |= none
        eta_max[~known | none] = np.nan
        eta_min[~known | none] = np.nan
        kind[~known] = rc.EDGE_NONE
        return boundary_dataset(
            A, N, eta_max=eta_max, eta_min=eta_min, edge_kind=kind,
            status_above=np.full(AA.shape, -1, dtype=np.int8),
            n_transitions=np.where(known, n_in, -1), resolved=known,
            eta_error=np.where(known & ~none & (n_in > 0), reached, np.nan),
            title="cosserat-channel boundary drawn from a solvability atlas",
            attrs={"eta_search_min": float(lo), "eta_search_max": float(hi),
                   "atlas_tol": float(self.tol)})

    def covers(self, A_range, N_range):
        """Whether the box holds ``[A_range] x [N_range]``."""
        a0, a1, n0, n1 = self.box
        return a0 <= min(A_range) and max(A_range) <= a1 and n0 <= min(N_range) and max(N_range) <= n1

