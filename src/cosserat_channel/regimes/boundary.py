"""The boundary Dataset: the edge of solvability on a grid of ``(A, N)``, one layout whoever
fills it (:func:`cosserat_channel.regimes.trace_boundary` by tracing,
:meth:`cosserat_channel.atlas.Atlas.boundary` from an atlas). Imports numpy and xarray only."""

from __future__ import annotations

import numpy as np

from .. import status as st
from ..physics.analytic import axis_edge_eta
from ..parameters import PARAMETERS
from ..regime_codes import EDGE_KINDS


def boundary_dataset(A, N, *, eta_max, eta_min, edge_kind, status_above, n_transitions, title,
                     attrs, resolved=None, eta_error=None):
    """The Dataset on ``(A, N)`` of an edge of solvability.

    Parameters
    ----------
    A, N : 1-D array_like
        The grid.
    eta_max, eta_min : ndarray, shape (A.size, N.size)
        Largest and smallest ``eps L`` with a solution (NaN where none, or unknown).
    edge_kind : ndarray of int8
        ``regime_codes.EDGE_*``.
    status_above : ndarray of int8
        Status just above a bounded ``eta_max``; -1 (``no_edge``) elsewhere or where not known.
    n_transitions : ndarray of int
        Changes of feasibility over the searched range; -1 where not known.
    title : str
    attrs : dict
        Provenance (searched range, tolerances, ...); the package's version is added.
    resolved : ndarray of bool, optional
        Where the source decides (an atlas); left out for traced data, which decides everywhere.
    eta_error : ndarray, optional
        The source's stated error of the transitions at each point, relative in ``eta`` (an
        atlas: the largest of its leaf's transitions in range); left out for traced data.

    Returns
    -------
    xarray.Dataset
        ``eta_max``, ``eta_min``, ``edge_kind``, ``status_above``, ``n_transitions``,
        ``axis_edge_eta`` (the analytic axis condition) and, if given, ``resolved`` and
        ``eta_error``.
    """
    import xarray as xr

    from .. import __version__

    A = np.asarray(A, dtype=float)
    N = np.asarray(N, dtype=float)
    flags = st.cf_flag_attrs()
    data = {
        "eta_max": (("A", "N"), eta_max, {
            "long_name": "largest eps L with a solution", "units": "1"}),
        "eta_min": (("A", "N"), eta_min, {
            "long_name": "smallest eps L with a solution", "units": "1"}),
        "edge_kind": (("A", "N"), np.asarray(edge_kind, dtype=np.int8), {
            "long_name": "kind of the traced edge",
            "flag_values": np.arange(len(EDGE_KINDS), dtype=np.int8),
            "flag_meanings": " ".join(EDGE_KINDS)}),
        "status_above": (("A", "N"), np.asarray(status_above, dtype=np.int8), {
            "long_name": "status just above eta_max (no_edge where no bounded edge)",
            "flag_values": np.r_[np.int8(-1), flags["flag_values"]].astype(np.int8),
            "flag_meanings": "no_edge " + flags["flag_meanings"]}),
        "n_transitions": (("A", "N"), np.asarray(n_transitions, dtype=np.int16), {
            "long_name": "changes of feasibility seen over the search range (-1: unknown)",
            "units": "1"}),
        "axis_edge_eta": (("A", "N"), axis_edge_eta(A[:, None], N[None, :]), {
            "long_name": "eps L on the axis condition (A-1) eps L + 2(A+1) N = 0",
            "units": "1"}),
    }
    if resolved is not None:
        data["resolved"] = (("A", "N"), np.asarray(resolved, dtype=bool), {
            "long_name": "the source decides this (A, N)"})
    if eta_error is not None:
        data["eta_error"] = (("A", "N"), np.asarray(eta_error, dtype=float), {
            "long_name": "stated error of eta_max and eta_min, relative", "units": "1"})
    return xr.Dataset(
        data,
        coords={d: (d, v, {"long_name": PARAMETERS[d].long_name, "units": PARAMETERS[d].units})
                for d, v in (("A", A), ("N", N))},
        attrs={"title": title, "Conventions": st.CONVENTIONS, **attrs, "cosserat_channel_version": __version__},
    )
