"""Deciding points from an atlas (:func:`classify`), Appendix A's regimes exactly
(:func:`~cosserat_channel.physics.analytic.classify_points`). Imports numpy (xarray to read a
file), never numba."""

from __future__ import annotations

import numpy as np

from .. import status as st
from ..physics import analytic
from ..parameters import ETA_MAX, ETA_MIN, ParameterError, check_values
from .interpolant import Atlas
from .settings import UNDECIDED
from .store import default_atlas, load_atlas


def classify(eps, L, K, A, N, atlas=None):
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
    atlas : Atlas or path-like, optional
        An atlas, or the file of one. Default: the cached atlas (``atlas --cache``) where it
        covers the points' ``(A, N)``, else the whole-plane atlas that comes with the package
        (:func:`~cosserat_channel.atlas.store.default_atlas`).

    Returns
    -------
    ndarray of int8
        Status codes (:class:`status.Status`) or :data:`UNDECIDED`, of the broadcast shape.

    Notes
    -----
    The transitions are the solver's at ``regimes.EDGE_RTOL``. A solve at a looser tolerance moves
    the edge by up to ~2e-6 relative (:data:`cosserat_channel.regimes.wall.EDGE_RTOL`): such a
    solve may disagree with a decided point that close to an edge.
    """
    eps, L, K, A, N = np.broadcast_arrays(
        *(check_values(d, v) for d, v in zip(("eps", "L", "K", "A", "N"), (eps, L, K, A, N))))
    atlas = _atlas_for(A, N, atlas)
    eta = _eta(eps, L)
    out = analytic.classify_points(eta, A, N)
    need = (out == st.OK) & (A != -1.0)
    if need.any():
        out[need] = _decide(atlas, eta[need], *atlas.transitions(A[need], N[need]))
    return out


class Plane:
    """:func:`classify` at fixed points ``(A, N)`` for any ``eps L``: the atlas's transitions
    there are looked up once, so that each ``eps L`` costs a comparison (a map of the ``(A, N)``
    plane redrawn as ``eps`` or ``L`` moves). ``Plane(A, N)(eps, L)`` equals
    ``classify(eps, L, 0, A, N)``.

    Parameters
    ----------
    A, N : array_like
        The points (broadcast), validated as :func:`classify` does.
    atlas : Atlas or path-like, optional
        As for :func:`classify`.
    """

    def __init__(self, A, N, atlas=None):
        A, N = np.broadcast_arrays(check_values("A", A), check_values("N", N))
        self.atlas = _atlas_for(A, N, atlas)
        self.A, self.N = A, N
        self._fixed = A != -1.0
        self._looked = self.atlas.transitions(A[self._fixed], N[self._fixed])

    def __call__(self, eps, L):
        """The status codes (or :data:`UNDECIDED`) of the points at ``(eps, L)`` (numbers)."""
        eps, L = check_values("eps", eps), check_values("L", L)
        if eps.ndim or L.ndim:
            raise ParameterError("Plane: eps and L must be numbers (one eps L per call)")
        eta = np.broadcast_to(_eta(eps, L), self.A.shape)
        out = analytic.classify_points(eta, self.A, self.N)
        need = (out == st.OK) & self._fixed
        if need.any():
            sub = need[self._fixed]
            out[need] = _decide(self.atlas, eta[need], *(x[sub] for x in self._looked))
        return out


def _atlas_for(A, N, atlas):
    """The atlas to decide ``(A, N)`` with: ``atlas`` (an Atlas or a file), else the default."""
    if atlas is None:
        span = ((float(A.min()), float(A.max())), (float(N.min()), float(N.max()))) if A.size \
            else (None, None)
        atlas = default_atlas(*span)[0] or default_atlas()[0]
        if atlas is None:
            raise ParameterError("classify: no atlas given, and neither a cached atlas "
                                 "('atlas --cache') nor the shipped one is there")
    elif not isinstance(atlas, Atlas):
        atlas = load_atlas(atlas)
    return atlas


def _eta(eps, L):
    """``eps * L``; ParameterError naming the first point outside the solver's range."""
    eta = eps * L
    bad = ~((eta >= ETA_MIN) & (eta <= ETA_MAX))
    if bad.any():
        from ..parameters import check_eta

        k = np.flatnonzero(np.ravel(bad))[0]
        check_eta(float(np.ravel(eps)[k]), float(np.ravel(L)[k]))
    return eta


def _decide(atlas, e, leaf, low, t, err):
    """The codes at ``eta = e`` from the atlas's :meth:`~Atlas.transitions` there."""
    lo, hi = atlas.eta_range
    known = (low >= 0) & (e >= lo) & (e <= hi)
    band = atlas.undecided_band(leaf)
    with np.errstate(invalid="ignore"):
        dist = np.abs(np.log(e)[:, None] - np.log(t))
        near = np.any(dist <= band, axis=-1)
        flips = np.sum(t < e[:, None], axis=-1)
    feasible = (low == 1) ^ (flips % 2 == 1)
    code = np.where(feasible, st.OK, st.EPS_TOO_LARGE_PATH).astype(np.int8)
    return np.where(known & ~near, code, UNDECIDED)
