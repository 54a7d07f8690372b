"""The :class:`.Atlas` of a build's leaves and traces, with its provenance."""

from __future__ import annotations

import numpy as np

from .interpolant import Atlas


def _assemble(leaves, cache, *, box, roots, degree, max_depth, tol, eta_range, trace_range,
              uniform, max_degree, solves, tally, tau, version):
    """The :class:`Atlas` of the leaves and every trace made."""
    from .. import regimes

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
