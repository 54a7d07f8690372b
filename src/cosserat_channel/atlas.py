"""The solvability atlas: every change of feasibility in ``eta = eps L`` over a box of ``(A, N)``.

By the similarity of model.md a point's status depends on ``(eta, A, N)`` only. At each ``(A, N)``
:func:`cosserat_channel.regimes.trace_edge` finds the ``eta`` where feasibility changes (the
*transitions*: ``eta_max``, and ``eta_min`` where small ``eta`` fails too) and whether the lowest
searched ``eta`` is feasible. Together, the *signature* ``(feasible_low, n_transitions)`` and the
transitions say the status of every ``eta`` at that ``(A, N)``.

The atlas interpolates them. The box is cut into a quadtree of cells; on each cell the transitions
are sampled on a tensor grid of Chebyshev-Lobatto nodes (``degree + 1`` per side to start with)
and interpolated in ``log eta`` by the tensor Chebyshev polynomial through them. A cell is split
into four when its nodes do not all have the same signature (a transition enters or leaves the
searched range, an ``eta_min`` appears, the wall line crosses it). Where they do, the error
estimate of the interpolant (:func:`_estimate`: the Chebyshev tail of each direction, extrapolated
where the coefficients decay geometrically) decides: below ``tol`` the cell is a leaf; above it the
degree is doubled along a direction whose coefficients still decay (the nodes are nested: every
trace is kept), else the cell is split. A cell that the node/focus switch crosses
(:func:`~cosserat_channel.physics.analytic.node_focus_switch_N`, known in closed form) is split rather
than raised in degree while it can be: the edge is not analytic across that curve, so a higher
degree buys little there; and a refinement that does not cut the tail (the raw
two-degree sum) by :data:`REFINE_GAIN` ends it (the traces are then noisier than ``tol``: the solver's edge is not
smooth at that level). Splits go down to ``max_depth``. A cell still mixed there is *unresolved*
(every point in it is undecided); a leaf whose estimate is still above ``tol`` keeps its own
estimate, which :func:`classify` uses in place of ``tol``.

Why not python-adaptive's ``Learner2D``: it interpolates piecewise-linearly on a triangulation, so
its error falls like ``h^2``; the edge is analytic, and the Chebyshev cells reach 1e-8 with a few
hundred traces where the edge is smooth (289 on A in [-0.5, 0.5], N in [1, 1.25]), while a linear
interpolant needs millions (measured in ``benchmarks/bench_atlas.py``
and ``docs/performance.md``). It also learns one scalar, while a point here has zero to two
transitions and the number changes across the plane.

Numerics. The transitions are those of :func:`~cosserat_channel.regimes.trace_edge`: bisected
by :func:`~cosserat_channel.regimes.bisect_edge` to ``regimes.ETA_XTOL`` (1e-10 relative) with
the solver at ``regimes.EDGE_RTOL``, except at tangential edges, where the stress path runs into
the node of the yield condition at the wall and ``D(1) ~ c (eta_max - eta)^2``: there the status
is decided by the noise of ``D(1)`` within ~1e-6 of the edge, and the transition is the node's
closed-form ``eta`` once ``D(1)`` sampled well below the edge confirms it
(``regimes.node_edge_eta``; scipy's DOP853 puts the zero of ``D(1)`` within 5e-9 of it). Where
the edge is known is thus about 1e-8 relative (how far it moves with the solver's tolerance), so
``tol`` is at least :data:`TOL_MIN`. Every trace also states its *noise band*, how close to the
transition the solver's status stops being reliable (~1e-6 at tangential edges, up to ~1e-6 at
transversal ones next to the node/focus switch ``N^2 = (5 + 3A)/2`` where ``D(1)`` rises slowly,
1e-9 to 1e-7 elsewhere); a leaf keeps the largest of its nodes' bands and :func:`classify` leaves
points within it undecided. On the focus side of that switch, over about 0.15 in N, the status
bisection's edge is itself noise at up to ~1e-7 (a near-double zero of stage 1's ``D(1)``, whose
noise is ~1e-13): where a trace's band exceeds ``regimes.SMOOTH_BAND`` the transition is instead
the zero of ``regimes.smooth_wall_D``, ``D(1)`` marched as a state of its own next to the wall
(smooth in ``eta``, noise ~1e-18; an independent scipy march puts the model's edge within 1e-9
of it), so the atlas interpolates a smooth function there too. The traces search twice the
claimed range of ``eta`` each way, so that a transition just outside the claimed range keeps the
signature of the cells next to it and is interpolated, not lost.

Reading an atlas (:func:`load_atlas`, :func:`classify`, :meth:`Atlas.boundary`) imports numpy
and xarray only: building one (:func:`build_atlas`) imports the solver.
"""

from __future__ import annotations

import concurrent.futures
import math
import threading
from dataclasses import dataclass

import numpy as np

from .physics import analytic
from . import regime_codes as rc
from . import status as st
from .parameters import ETA_MAX, ETA_MIN, PARAMETERS, ParameterError, check_values

UNDECIDED = -1  # classify's code for a point the atlas cannot decide: a solve decides it
TOL_MIN = 1e-8  # how well the edge itself is known (regimes.EDGE_RTOL), relative in eta
TOL_MAX = 1e-1
DEGREE = 8  # Chebyshev degree per cell and direction to start with: 81 nodes
MAX_DEGREE = 32  # a cell's degree per direction grows (doubling: nested nodes) up to this
RATE_GEOMETRIC = 0.5  # coefficient decay per degree below which a tail is extrapolated
TAIL_SAFETY = 2.0  # factor on the extrapolated tail
REFINE_GAIN = 4.0  # a refinement that does not cut the estimate by this much stops (noise)
ROUNDOFF = 1e-13  # floor of an estimate: round-off of the interpolant of log eta
# Factor on the two-degree sum where the coefficients do not decay, per unit of the cell's
# largest degree. One trace off by d (a node landed low in a ragged stretch of the solver's
# edge) puts only ~3d/p into that sum at degree p (measured at p = 16: 0.16 d for a node on a
# side, 0.28 d inside), while the interpolant is off by d next to that node: p times the sum
# leaves a margin of about 2.5.
PLATEAU_SAFETY = 1.0
MAX_DEPTH = 6  # splits of a root cell; the raster of leaves is (roots * 2^depth)^2
MAX_DEPTH_LIMIT = 8
SAFETY = 2.0  # undecided band: SAFETY * max(tol, the cell's error estimate), relative in eta
TRACE_WIDEN = 2.0  # traces search [lo / TRACE_WIDEN, hi * TRACE_WIDEN] (see the module notes)
TAU_OF_TOL = 0.125  # continued transitions are verified by a bracket this many tol either side
NEAR_NODE = 0.03  # a node with no interpolant over it continues from a traced one this close (A, N)
NEAR_SPREAD = 0.05  # ... with this relative uncertainty
DEFAULT_A = (-1.0, 5.0)
DEFAULT_N = (0.3, 3.0)
ROOT_CELL = 1.0  # the root cells are about this wide in A and N
FORMAT = "cosserat-channel atlas 4"  # 4: an error per transition (leaf_transition_error)
# 3: noise bands of the traces (sample_bands, leaf_band)
# 1: every leaf of the atlas's degree; 2: leaves of their own degrees (leaf_degree). Both are read
# with zero bands: their traces bisected the status at tangential edges (see the module notes).
FORMATS = ("cosserat-channel atlas 1", "cosserat-channel atlas 2", "cosserat-channel atlas 3",
           FORMAT)


def cache_path():
    """Where ``atlas --cache`` writes and ``plot --regime`` looks: ``atlas.nc`` in the package's
    cache directory (:func:`cosserat_channel.cache_dir`)."""
    from . import cache_dir

    return str(cache_dir() / "atlas.nc")


# ---------------------------------------------------------------------------------------------
# Chebyshev cells
# ---------------------------------------------------------------------------------------------
def lobatto(degree):
    """Chebyshev-Lobatto nodes on [-1, 1], ascending, ends exact."""
    x = -np.cos(np.pi * np.arange(degree + 1) / degree)
    x[0], x[-1] = -1.0, 1.0
    if degree % 2 == 0:
        x[degree // 2] = 0.0
    return x


def _vandermonde(x, degree):
    """``T_k(x)`` for k = 0..degree, shape ``x.shape + (degree + 1,)``."""
    t = np.arccos(np.clip(x, -1.0, 1.0))
    return np.cos(t[..., None] * np.arange(degree + 1))


def _coefficients(values, degree_A, degree_N):
    """Tensor Chebyshev coefficients of node values ``(..., degree_A+1, degree_N+1)``."""
    ta = np.linalg.inv(_vandermonde(lobatto(degree_A), degree_A))
    tn = np.linalg.inv(_vandermonde(lobatto(degree_N), degree_N))
    return ta @ values @ tn.T


def _tail(coef):
    """The old estimate, kept as a reference: the coefficients of the two highest degrees."""
    p, q = coef.shape[-2] - 1, coef.shape[-1] - 1
    mask = np.zeros(coef.shape[-2:], dtype=bool)
    mask[p - 1:, :] = True
    mask[:, q - 1:] = True
    return np.abs(coef[..., mask]).sum(axis=-1)


def _direction_tail(S, plateau):
    """Tail of one direction from ``S[k]``, the summed magnitudes of the degree-k coefficients.

    Returns ``(tail, rate)``. Where the last six degrees decay geometrically (``rate`` per degree
    below :data:`RATE_GEOMETRIC`, the slower of two pairs of pairs of degrees, which an even or odd
    function would otherwise fool), the omitted coefficients sum to about ``S[p] rate / (1 -
    rate)``, or ``S[p-1] rate^2 / (1 - rate)`` where ``S[p]`` is small by parity (the larger is
    taken), and the interpolant's error (aliasing included) to twice that; the estimate is
    :data:`TAIL_SAFETY` times more, and never above the two-degree sum. Elsewhere (slow decay, or a
    plateau of noise in the traces) it is ``plateau`` times the two-degree sum
    ``S[p-1] + S[p]``.
    """
    p = S.size - 1
    last = S[p] + S[p - 1]
    if p < 3:
        return plateau * last, 1.0
    tiny = 1e-300
    rate = min(1.0, math.sqrt((last + tiny) / (S[p - 2] + S[p - 3] + tiny)))
    if p < 5:  # one pair of pairs: enough to ask for a higher degree, not to extrapolate
        return plateau * last, rate
    rate = max(rate, min(1.0, math.sqrt((S[p - 2] + S[p - 3] + tiny) / (S[p - 4] + S[p - 5] + tiny))))
    if rate >= RATE_GEOMETRIC:
        return plateau * last, rate
    fitted = TAIL_SAFETY * 2.0 * max(S[p], S[p - 1] * rate) * rate / (1.0 - rate)
    return min(fitted, last), rate


def _estimate(coef):
    """Error estimate of a cell's interpolants ``coef`` ``(k, p+1, q+1)`` in ``log eta``.

    Returns ``(error, tails, rates, raw)``: the largest over the transitions of the sum of the
    two directions' tails (:func:`_direction_tail`); per direction (A, N) the largest tail and
    rate; and the largest two-degree sum of both directions without any factor (what the
    refinement compares before and after, like with like).
    """
    tails = np.zeros(2)
    rates = np.zeros(2)
    err = 0.0
    raw = 0.0
    plateau = PLATEAU_SAFETY * (max(coef.shape[-2:]) - 1)
    for c in np.abs(coef):
        sa, sn = c.sum(axis=1), c.sum(axis=0)
        ta, ra = _direction_tail(sa, plateau)
        tn, rn = _direction_tail(sn, plateau)
        raw = max(raw, sa[-1] + sa[-2] + sn[-1] + sn[-2])
        err = max(err, ta + tn)
        tails = np.maximum(tails, (ta, tn))
        rates = np.maximum(rates, (ra, rn))
    return max(err, ROUNDOFF), tails, rates, raw


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
    def transitions(self, A, N):
        """Interpolated transitions at ``(A, N)``.

        Returns
        -------
        leaf : ndarray of int
            The leaf (-1 outside the box).
        low : ndarray of int8
            Feasibility at the low end (-1 where unknown: outside, or an unresolved leaf).
        eta : ndarray
            ``A.shape + (n_max,)`` transitions in ``eta``, ascending, NaN-padded.
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
        the status beyond an edge).
        """
        import xarray as xr

        from . import __version__

        A = np.atleast_1d(np.asarray(A, dtype=float))
        N = np.atleast_1d(np.asarray(N, dtype=float))
        AA, NN = np.meshgrid(A, N, indexing="ij")
        _, low, eta, _ = self.transitions(AA, NN)
        lo, hi = self.eta_range
        # Feasibility at lo: that at the low end of the traces, flipped by each transition below lo
        # (the traces search a wider range than the atlas answers for).
        ok_lo = (low == 1) ^ (np.sum(eta <= lo, axis=-1) % 2 == 1)
        inside = np.where((eta > lo) & (eta < hi), eta, np.nan)
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
        code = classify_analytic(np.full(AA.shape, lo), AA, NN)
        none = np.isin(code, (st.WALL_INADMISSIBLE, st.AXIS_SPIN_UNBOUNDED))
        kind[none] = rc.EDGE_NONE
        n_in = np.where(none, 0, n_in)
        known |= none
        eta_max[~known | none] = np.nan
        eta_min[~known | none] = np.nan
        kind[~known] = rc.EDGE_NONE
        return xr.Dataset(
            {
                "eta_max": (("A", "N"), eta_max, {"long_name": "largest eps L with a solution",
                                                  "units": "1"}),
                "eta_min": (("A", "N"), eta_min, {"long_name": "smallest eps L with a solution",
                                                  "units": "1"}),
                "edge_kind": (("A", "N"), kind, {
                    "long_name": "kind of the edge (no_solution also where resolved is False)",
                    "flag_values": np.arange(len(rc.EDGE_KINDS), dtype=np.int8),
                    "flag_meanings": " ".join(rc.EDGE_KINDS)}),
                "status_above": (("A", "N"), np.full(AA.shape, -1, dtype=np.int8)),
                "n_transitions": (("A", "N"), np.where(known, n_in, -1).astype(np.int16), {
                    "long_name": "changes of feasibility in the atlas's eta range (-1: unknown)"}),
                "resolved": (("A", "N"), known, {"long_name": "the atlas decides this (A, N)"}),
                "axis_edge_eta": (("A", "N"), analytic.axis_edge_eta(AA, NN), {
                    "long_name": "eps L on the axis condition (A-1) eps L + 2(A+1) N = 0",
                    "units": "1"}),
            },
            coords={d: (d, v, {"long_name": PARAMETERS[d].long_name, "units": "1"})
                    for d, v in (("A", A), ("N", N))},
            attrs={"title": "cosserat-channel boundary drawn from a solvability atlas", "Conventions": st.CONVENTIONS,
                   "eta_search_min": float(lo), "eta_search_max": float(hi),
                   "atlas_tol": float(self.tol), "cosserat_channel_version": __version__},
        )

    def covers(self, A_range, N_range):
        """Whether the box holds ``[A_range] x [N_range]``."""
        a0, a1, n0, n1 = self.box
        return a0 <= min(A_range) and max(A_range) <= a1 and n0 <= min(N_range) and max(N_range) <= n1

    # -- files -----------------------------------------------------------------------------
    def to_dataset(self):
        """The atlas as an :class:`xarray.Dataset` (what :func:`save_atlas` writes)."""
        import xarray as xr

        s = self.samples
        return xr.Dataset(
            {
                "sample_A": ("sample", s["A"], {"long_name": "A of a trace"}),
                "sample_N": ("sample", s["N"], {"long_name": "N of a trace"}),
                "sample_low": ("sample", s["low"].astype(np.int8), {
                    "long_name": "1 if the lowest traced eta has a solution"}),
                "sample_n": ("sample", s["n"].astype(np.int8), {
                    "long_name": "changes of feasibility found in the traced eta range"}),
                "sample_transitions": (("sample", "transition"), s["transitions"], {
                    "long_name": "eta where feasibility changes, ascending (NaN-padded)"}),
                "sample_bands": (("sample", "transition"), s["bands"], {
                    "long_name": "relative distance from the transition within which the "
                                 "solver's status is not reliable (NaN-padded)"}),
                "leaf_level": ("leaf", self.leaf_level.astype(np.int8)),
                "leaf_i": ("leaf", self.leaf_i.astype(np.int32)),
                "leaf_j": ("leaf", self.leaf_j.astype(np.int32)),
                "leaf_low": ("leaf", self.leaf_low.astype(np.int8)),
                "leaf_n": ("leaf", self.leaf_n.astype(np.int8), {
                    "long_name": "transitions in the leaf; -1: unresolved (undecided)"}),
                "leaf_error": ("leaf", self.leaf_error, {
                    "long_name": "error estimate of the leaf's log eta interpolant"}),
                "leaf_coefficients": (("leaf", "transition", "cheb_A", "cheb_N"), self.coef, {
                    "long_name": "tensor Chebyshev coefficients of log eta on the leaf"}),
                "leaf_degree": (("leaf", "direction"), self.leaf_degree.astype(np.int8), {
                    "long_name": "Chebyshev degree of the leaf along A and N"}),
                "leaf_transition_error": (("leaf", "transition"), self.leaf_transition_error, {
                    "long_name": "error estimate of each transition of the leaf"}),
                "leaf_band": ("leaf", self.leaf_band, {
                    "long_name": "largest noise band of the traces at the leaf's nodes"}),
            },
            attrs={"title": "cosserat-channel solvability atlas", "format": FORMAT, "Conventions": st.CONVENTIONS,
                   "A_min": self.box[0], "A_max": self.box[1], "N_min": self.box[2],
                   "N_max": self.box[3], "roots_A": self.roots[0], "roots_N": self.roots[1],
                   "degree": self.degree, "max_depth": self.max_depth, "tol": self.tol,
                   "eta_min": self.eta_range[0], "eta_max": self.eta_range[1], **self.attrs},
        )

    @classmethod
    def from_dataset(cls, ds):
        """The inverse of :meth:`to_dataset`; ParameterError if ``ds`` is not an atlas."""
        if ds.attrs.get("format") not in FORMATS:
            raise ParameterError(f"not a solvability atlas (format {ds.attrs.get('format')!r}, "
                                 f"expected {FORMAT!r})")
        a = dict(ds.attrs)
        keys = ("title", "format", "A_min", "A_max", "N_min", "N_max", "roots_A", "roots_N",
                "degree", "max_depth", "tol", "eta_min", "eta_max")
        v = {k: np.asarray(ds[k].values) for k in ds.data_vars}
        return cls(
            box=(float(a["A_min"]), float(a["A_max"]), float(a["N_min"]), float(a["N_max"])),
            roots=(int(a["roots_A"]), int(a["roots_N"])), degree=int(a["degree"]),
            max_depth=int(a["max_depth"]), tol=float(a["tol"]),
            eta_range=(float(a["eta_min"]), float(a["eta_max"])),
            leaf_level=v["leaf_level"].astype(np.int64), leaf_i=v["leaf_i"].astype(np.int64),
            leaf_j=v["leaf_j"].astype(np.int64), leaf_low=v["leaf_low"].astype(np.int8),
            leaf_n=v["leaf_n"].astype(np.int8), leaf_error=v["leaf_error"].astype(float),
            coef=v["leaf_coefficients"].astype(float),
            samples={"A": v["sample_A"], "N": v["sample_N"], "low": v["sample_low"],
                     "n": v["sample_n"], "transitions": v["sample_transitions"],
                     **({"bands": v["sample_bands"]} if "sample_bands" in v else {})},
            attrs={k: val for k, val in a.items() if k not in keys},
            leaf_degree=v["leaf_degree"].astype(np.int64) if "leaf_degree" in v else None,
            leaf_band=v["leaf_band"].astype(float) if "leaf_band" in v else None,
            leaf_transition_error=(v["leaf_transition_error"].astype(float)
                                   if "leaf_transition_error" in v else None),
        )


def save_atlas(atlas, path):
    """Write ``atlas`` to ``path`` (NetCDF, checksummed) through :func:`files.netcdf_output`."""
    from .files import netcdf_output

    ds = atlas.to_dataset()
    enc = {v: {"fletcher32": True} for v in ds.variables
           if ds[v].ndim > 0 and ds[v].dtype.kind in "fiub"}
    netcdf_output(path, lambda tmp: ds.to_netcdf(tmp, encoding=enc))


def load_atlas(path):
    """Read an atlas written by :func:`save_atlas`; ParameterError (one line) if it is not one."""
    import xarray as xr

    try:
        ds = xr.load_dataset(path)
    except (OSError, ValueError, RuntimeError) as exc:
        raise ParameterError(f"cannot read atlas {str(path)!r}: {' '.join(str(exc).split())}") \
            from None
    try:
        return Atlas.from_dataset(ds)
    except (KeyError, ParameterError) as exc:
        raise ParameterError(f"{str(path)!r} is not a solvability atlas ({exc})") from None


# ---------------------------------------------------------------------------------------------
# Classification
# ---------------------------------------------------------------------------------------------
def classify_analytic(eta, A, N):
    """:func:`analytic.classify_margin` on arrays: the status Appendix A decides, else ``OK``."""
    eta, A, N = np.broadcast_arrays(*(np.asarray(x, dtype=float) for x in (eta, A, N)))
    if eta.size == 0:
        return np.zeros(eta.shape, dtype=np.int8)
    return analytic.classify_margins(analytic.axis_margin(eta, A, N), A, N)


def classify(eps, L, K, A, N, atlas):
    """The status of every point ``(eps, L, K, A, N)`` (broadcast) from the atlas, without solving.

    Appendix A's regimes (the wall line, ``A < -1``, ``A = -1``, the axis condition) are decided
    exactly, by :mod:`cosserat_channel.physics.analytic`. Every other point is decided from the atlas's
    transitions: ``ok`` or ``eps_too_large_path`` (the status of the solver beyond a traced edge).
    A point is :data:`UNDECIDED` (-1) when it lies within ``SAFETY * max(tol, error estimate,
    noise band)`` (relative) of an interpolated transition, in an unresolved leaf, outside the
    atlas's box or outside its ``eta_range``: a solve decides those. The noise band
    (:attr:`Atlas.leaf_band`) is where the solver's own status is decided by the noise of
    ``D(1)``: up to a few 1e-6 at tangential edges, where the transition is the node's ``eta``
    (``regimes.trace_edge``) and a solve that close may come out either way.

    Parameters
    ----------
    eps, L, K, A, N : array_like
        Points; validated as :func:`parameters.check_point` does (``K`` does not enter).
    atlas : Atlas or path-like
        An atlas, or the file of one.

    Returns
    -------
    ndarray of int8
        Status codes (:class:`status.Status`) or :data:`UNDECIDED`, of the broadcast shape.

    Notes
    -----
    The transitions are the solver's at ``regimes.EDGE_RTOL``. A solve at a looser tolerance moves
    the edge by up to ~2e-6 relative (regimes.py): such a solve may disagree with a decided
    point that close to an edge.
    """
    if not isinstance(atlas, Atlas):
        atlas = load_atlas(atlas)
    eps, L, K, A, N = np.broadcast_arrays(
        *(check_values(d, v) for d, v in zip(("eps", "L", "K", "A", "N"), (eps, L, K, A, N))))
    eta = eps * L
    bad = ~((eta >= ETA_MIN) & (eta <= ETA_MAX))
    if bad.any():
        from .parameters import check_eta

        k = np.flatnonzero(bad.ravel())[0]
        check_eta(float(eps.ravel()[k]), float(L.ravel()[k]))
    out = classify_analytic(eta, A, N)
    need = (out == st.OK) & (A != -1.0)
    if not need.any():
        return out
    e, a, n = eta[need], A[need], N[need]
    leaf, low, t, err = atlas.transitions(a, n)
    lo, hi = atlas.eta_range
    known = (low >= 0) & (e >= lo) & (e <= hi)
    noise = np.where(leaf >= 0, atlas.leaf_band[np.maximum(leaf, 0)], 0.0)
    terr = np.where((leaf >= 0)[:, None], atlas.leaf_transition_error[np.maximum(leaf, 0)], np.nan)
    band = SAFETY * np.fmax(atlas.tol, np.fmax(terr, noise[:, None]))
    with np.errstate(invalid="ignore"):
        dist = np.abs(np.log(e)[:, None] - np.log(t))
        near = np.any(dist <= band, axis=-1)
        flips = np.sum(t < e[:, None], axis=-1)
    feasible = (low == 1) ^ (flips % 2 == 1)
    code = np.where(feasible, st.OK, st.EPS_TOO_LARGE_PATH).astype(np.int8)
    out[need] = np.where(known & ~near, code, UNDECIDED)
    return out


# ---------------------------------------------------------------------------------------------
# Building (imports the solver)
# ---------------------------------------------------------------------------------------------
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
    noise bands, and the :class:`regimes.Edge` behind them (its kinds and slopes seed the
    neighbours' predictions)."""

    low: bool
    transitions: np.ndarray
    bands: np.ndarray
    edge: object = None

    @property
    def signature(self):
        return (self.low, self.transitions.size)


@dataclass
class _Predictor:
    """The interpolant of ``log eta`` over a cell: predicts the transitions anywhere inside it."""

    bounds: tuple
    coef: np.ndarray  # (transition, p + 1, q + 1)
    low: bool
    err: float

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
    errors: np.ndarray = None  # per transition (an envelope's clusters); else err for each


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


def _envelope(traces, lo, hi):
    """A mixed cell that may not be split again, as a leaf with its reached error.

    ``traces``: its nodes' ``(low, transitions)``. Every gap between the nodes' transitions
    (in ``log eta``) where the nodes agree on feasibility is decided; runs of gaps where they do
    not, with the transitions around them, form clusters, each widened by half its width for
    what lies between the nodes (at least ``TOL_MIN``). A cluster across which feasibility
    changes becomes one transition at its centre, one across which it does not two; the error
    of each is its cluster's half-width (over ``SAFETY``, which :func:`classify` applies).
    Returns ``(low, log_transitions, errors)``, an error per transition.
    """
    logs = np.unique(np.concatenate([np.log(t) for _, t in traces] + [np.empty(0)]))
    edges = np.r_[math.log(lo), logs, math.log(hi)]
    mids = 0.5 * (edges[:-1] + edges[1:])
    agree = []
    for x in mids:
        s = {bool(low) ^ (int(np.sum(np.log(t) < x)) % 2 == 1) for low, t in traces}
        agree.append(s.pop() if len(s) == 1 else None)
    decided = [k for k, a in enumerate(agree) if a is not None]
    if not decided:
        half = 0.75 * (edges[-1] - edges[0])
        return False, np.full(2, 0.5 * (edges[0] + edges[-1])), np.full(2, half / SAFETY)
    clusters = []  # (log start, log end, feasible below, feasible above; None: the range's end)
    first, last = decided[0], decided[-1]
    if first > 0:
        clusters.append((edges[0], edges[first], None, agree[first]))
    for k1, k2 in zip(decided, decided[1:]):
        if agree[k1] != agree[k2] or k2 > k1 + 1:
            clusters.append((edges[k1 + 1], edges[k2], agree[k1], agree[k2]))
    if last < len(agree) - 1:
        clusters.append((edges[last + 1], edges[-1], agree[last], None))
    low = agree[0] if first == 0 else not agree[first]
    centres, errs = [], []
    for c0, c1, below, above in clusters:
        flips = below is None or above is None or below != above
        centres.extend([0.5 * (c0 + c1)] * (1 if flips else 2))
        errs.extend([max(0.75 * (c1 - c0), TOL_MIN) / SAFETY] * (1 if flips else 2))
    return bool(low), np.array(centres), np.array(errs)


ANSWERED_GRID = 17  # points per direction where a transition's distance from the range is read


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


def _nearest(index, cell_size, key):
    """The traced nodes nearest ``key`` within the index's neighbouring buckets, one per
    signature, nearest first."""
    a, n = key
    ia, jn = int(math.floor(a / cell_size[0])), int(math.floor(n / cell_size[1]))
    best = {}
    for da in (-1, 0, 1):
        for dn in (-1, 0, 1):
            for k, tr in index.get((ia + da, jn + dn), ()):
                d = ((k[0] - a) / cell_size[0]) ** 2 + ((k[1] - n) / cell_size[1]) ** 2
                if tr.signature not in best or d < best[tr.signature][0]:
                    best[tr.signature] = (d, tr)
    return [tr for _, tr in sorted(best.values(), key=lambda v: v[0])]


def build_atlas(A_range=DEFAULT_A, N_range=DEFAULT_N, *, tol=1e-8, degree=DEGREE,
                max_depth=MAX_DEPTH, max_degree=MAX_DEGREE, roots=None,
                eta_range=(rc.ETA_SEARCH_MIN, rc.ETA_SEARCH_MAX), uniform=False, progress=None,
                workers=1):
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
        ``progress(leaves, cells_queued, traces)`` after each cell.
    workers : int
        Threads that trace a grid's nodes at once (the kernels release the GIL); the atlas is
        the same whatever their number (each trace depends on its ``(A, N)`` and on predictions
        made before the grid is traced, and the traces are kept in the order of one thread).

    Returns
    -------
    Atlas
    """
    from . import __version__, regimes
    from .solver.point import Workspace

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
    local, counters = threading.local(), []
    cache = {}
    # Traced nodes by bucket (a root cell's eighth): the nearest neighbour of a node with no
    # interpolant over it.
    bucket = ((A_range[1] - A_range[0]) / (8 * roots[0]), (N_range[1] - N_range[0]) / (8 * roots[1]))
    index = {}
    tally = {"predicted": 0, "fallback": 0}

    def traced(job):
        key, prediction = job
        if not hasattr(local, "ws"):  # a Workspace per thread: its arrays are the solver's
            local.ws = _Counting(Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS))
            counters.append(local.ws)
        e = regimes.trace_edge(key[0], key[1], eta_range=trace_range, workspace=local.ws,
                               prediction=prediction, tau=tau)
        low = e.kind != rc.EDGE_NONE and e.eta_min == trace_range[0]
        return _Trace(bool(low), np.asarray(e.transitions, dtype=float),
                      np.asarray(e.bands, dtype=float), e)

    def prediction_for(key, predictor):
        # The interpolant's transitions (with the kinds and slopes of the nearest node of its
        # signature), then each other signature traced nearby: tried in that order.
        out = []
        near = [tr for tr in _nearest(index, bucket, key) if tr.edge is not None and max(
            abs(tr.edge.A - key[0]), abs(tr.edge.N - key[1])) <= NEAR_NODE]
        if predictor is not None:
            sig = (predictor.low, predictor.coef.shape[0])
            src = next((tr for tr in near if tr.signature == sig), None)
            if src is not None:
                low, guesses = regimes.guesses_from(src.edge)
                spread = min(max(10.0 * predictor.err, 1e3 * tau), NEAR_SPREAD)
                for g, lt in zip(guesses, predictor(*key)):
                    g.eta, g.spread = float(np.exp(lt)), spread
                out.append((low, guesses))
                near = [tr for tr in near if tr is not src]
        out += [regimes.guesses_from(tr.edge, NEAR_SPREAD) for tr in near]
        return out or None

    pool = concurrent.futures.ThreadPoolExecutor(workers) if workers > 1 else None

    def prefetch(na, nn, predictor):
        # The nodes not traced yet, in the order one thread would trace them, with predictions
        # made before any of them is traced.
        missing = list(dict.fromkeys(k for k in ((a, n) for a in na for n in nn)
                                     if k not in cache))
        jobs = [(k, prediction_for(k, predictor)) for k in missing]
        results = map(traced, jobs) if pool is None else pool.map(traced, jobs)
        for (k, pred), tr in zip(jobs, results):
            cache[k] = tr
            index.setdefault((int(math.floor(k[0] / bucket[0])),
                              int(math.floor(k[1] / bucket[1]))), []).append((k, tr))
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
        """The signature set of a grid; where it is one with transitions, its interpolant."""
        sig = {cache[(a, b)].signature for a in na for b in nn}
        if len(sig) != 1:
            return sig, None, None
        low, n_tr = next(iter(sig))
        if not n_tr:
            return sig, None, None
        logt = np.log([[cache[(a, b)].transitions for b in nn] for a in na])  # (p, q, k)
        coef = _coefficients(np.moveaxis(logt, -1, 0), pa, pn)  # (k, p, q)
        est = _estimate(coef[_answered(coef, log_range)])
        return sig, coef, (_Predictor(bounds, coef, low, _estimate(coef)[0]), est)

    log_range = (math.log(eta_range[0]), math.log(eta_range[1]))

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
                if len(sig) > 1 or (uniform and can_split):
                    break  # mixed (or the uniform baseline): split before tracing finer grids
                if fit is not None and (predictor is None or fit[0].err < predictor.err):
                    predictor = fit[0]
            children = [_Cell(level + 1, 2 * i + di, 2 * j + dj, degree, degree)
                        for di in (0, 1) for dj in (0, 1)]
            if len(sig) > 1 or (uniform and can_split):
                if can_split:
                    own = fit[0] if fit is not None else (
                        cell.predictor if len(sig) == 1 else None)
                    for c in children:
                        c.predictor = own
                    queue.extend(children)
                else:
                    lo_t, hi_t = trace_range
                    traces = [(cache[(a, b)].low, cache[(a, b)].transitions)
                              for a in na for b in nn]
                    low, logt, errs = _envelope(traces, lo_t, hi_t)
                    coef = logt.reshape(-1, 1, 1)
                    band = max([float(np.nanmax(cache[(a, b)].bands, initial=0.0))
                                for a in na for b in nn])
                    leaves.append(_Leaf(level, i, j, int(low), logt.size,
                                        float(np.max(errs, initial=0.0)), coef, (0, 0), band,
                                        errs))
            else:
                low, n_tr = next(iter(sig))
                coef, err, raw = np.empty((0, pa + 1, pn + 1)), 0.0, 0.0
                tails, rates = np.zeros(2), np.zeros(2)
                band = 0.0
                if n_tr:
                    _, err_tails_rates_raw = fit
                    coef = fit[0].coef
                    err, tails, rates, raw = err_tails_rates_raw
                    band = max(float(cache[(a, b)].bands.max()) for a in na for b in nn)
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
                if err <= tol or stalled:
                    leaves.append(_Leaf(level, i, j, int(low), n_tr, err, coef, (pa, pn), band))
                elif any(grow):
                    queue.insert(0, _Cell(level, i, j, pa * (1 + grow[0]), pn * (1 + grow[1]),
                                          raw, cell.parent, own))
                elif can_split:
                    for c in children:
                        c.parent, c.predictor = raw, own
                    queue.extend(children)
                else:
                    leaves.append(_Leaf(level, i, j, int(low), n_tr, err, coef, (pa, pn), band))
            if progress is not None:
                progress(len(leaves), len(queue), len(cache))
    finally:
        if pool is not None:
            pool.shutdown(cancel_futures=True)
    return _assemble(leaves, cache, box=box, roots=roots, degree=degree, max_depth=max_depth,
                     tol=tol, eta_range=eta_range, trace_range=trace_range, uniform=uniform,
                     max_degree=max_degree, solves=sum(c.solves for c in counters), tally=tally,
                     tau=tau, version=__version__)


def _assemble(leaves, cache, *, box, roots, degree, max_depth, tol, eta_range, trace_range,
              uniform, max_degree, solves, tally, tau, version):
    """The :class:`Atlas` of the leaves and every trace made."""
    from . import regimes

    kmax = max([lf.n for lf in leaves] + [0])
    P = max([lf.degree[0] for lf in leaves] + [degree])
    Q = max([lf.degree[1] for lf in leaves] + [degree])
    coef = np.full((len(leaves), kmax, P + 1, Q + 1), np.nan)
    terr = np.full((len(leaves), kmax), np.nan)
    for k, lf in enumerate(leaves):
        terr[k, :lf.n] = lf.errors if lf.errors is not None else lf.err
        c = lf.coef
        coef[k, :c.shape[0]] = 0.0
        coef[k, :c.shape[0], :c.shape[1], :c.shape[2]] = c
    keys = list(cache)
    smax = max([cache[k].transitions.size for k in keys] + [0])
    transitions = np.full((len(keys), smax), np.nan)
    bands = np.full((len(keys), smax), np.nan)
    for k, key in enumerate(keys):
        transitions[k, :cache[key].transitions.size] = cache[key].transitions
        bands[k, :cache[key].bands.size] = cache[key].bands
    n_points = sum(max(cache[k].transitions.size, 1) for k in keys)
    return Atlas(
        box=box, roots=roots, degree=degree, max_depth=max_depth, tol=tol, eta_range=eta_range,
        leaf_level=np.array([lf.level for lf in leaves], dtype=np.int64),
        leaf_i=np.array([lf.i for lf in leaves], dtype=np.int64),
        leaf_j=np.array([lf.j for lf in leaves], dtype=np.int64),
        leaf_low=np.array([lf.low for lf in leaves], dtype=np.int8),
        leaf_n=np.array([lf.n for lf in leaves], dtype=np.int8),
        leaf_error=np.array([lf.err for lf in leaves], dtype=float),
        coef=coef,
        samples={"A": np.array([k[0] for k in keys]), "N": np.array([k[1] for k in keys]),
                 "low": np.array([cache[k].low for k in keys], dtype=np.int8),
                 "n": np.array([cache[k].transitions.size for k in keys], dtype=np.int8),
                 "transitions": transitions, "bands": bands},
        attrs={"n_traces": len(cache), "n_solves": solves,
               "n_edge_points": n_points,
               "solves_per_edge_point": solves / max(n_points, 1),
               "n_predicted": tally["predicted"], "n_fallback": tally["fallback"],
               "continuation_tau": tau,
               "uniform": int(uniform),
               "max_degree": int(max_degree),
               "trace_eta_min": trace_range[0], "trace_eta_max": trace_range[1],
               "edge_rtol": regimes.EDGE_RTOL, "edge_atol": regimes.EDGE_ATOL,
               "edge_xtol": regimes.ETA_XTOL, "n_coarse": regimes.ETA_COARSE,
               "probe_xtol": regimes.PROBE_XTOL, "d_noise": regimes.D_NOISE,
               "smooth_band": regimes.SMOOTH_BAND, "smooth_xtol": regimes.SMOOTH_XTOL,
               "cosserat_channel_version": version},
        leaf_degree=np.array([lf.degree for lf in leaves], dtype=np.int64).reshape(-1, 2),
        leaf_band=np.array([lf.band for lf in leaves], dtype=float),
        leaf_transition_error=terr,
    )
