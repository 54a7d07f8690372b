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
    if atlas is None:
        span = ((float(A.min()), float(A.max())), (float(N.min()), float(N.max()))) if A.size \
            else (None, None)
        atlas = default_atlas(*span)[0] or default_atlas()[0]
        if atlas is None:
            raise ParameterError("classify: no atlas given, and neither a cached atlas "
                                 "('atlas --cache') nor the shipped one is there")
    elif not isinstance(atlas, Atlas):
        atlas = load_atlas(atlas)
    eta = eps * L
    bad = ~((eta >= ETA_MIN) & (eta <= ETA_MAX))
    if bad.any():
        from ..parameters import check_eta

        k = np.flatnonzero(bad.ravel())[0]
        check_eta(float(eps.ravel()[k]), float(L.ravel()[k]))
    out = analytic.classify_points(eta, A, N)
    need = (out == st.OK) & (A != -1.0)
    if not need.any():
        return out
    e, a, n = eta[need], A[need], N[need]
    leaf, low, t, err = atlas.transitions(a, n)
    lo, hi = atlas.eta_range
    known = (low >= 0) & (e >= lo) & (e <= hi)
    band = atlas.undecided_band(leaf)
    with np.errstate(invalid="ignore"):
        dist = np.abs(np.log(e)[:, None] - np.log(t))
        near = np.any(dist <= band, axis=-1)
        flips = np.sum(t < e[:, None], axis=-1)
    feasible = (low == 1) ^ (flips % 2 == 1)
    code = np.where(feasible, st.OK, st.EPS_TOO_LARGE_PATH).astype(np.int8)
    out[need] = np.where(known & ~near, code, UNDECIDED)
    return out
