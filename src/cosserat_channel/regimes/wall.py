"""Scalars at the wall that locate an edge of solvability: stage 1's ``D(1)`` (:func:`wall_D`),
a signed continuation of it through zero (:func:`wall_scalar`), ``D(1)`` marched as a state of
its own so that it is smooth in ``eta`` (:func:`smooth_wall_D`), the node's closed form at
tangential edges (:func:`node_edge_eta`) and the probes of ``D(1)`` next to a bracket
(:func:`probe_edge`).

The kernels behind them are :mod:`cosserat_channel.solver.wall`'s; here is what the scalars
mean and how an edge is read from them.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass

import numpy as np

from ..physics import analytic, model
from ..solver import stage1
from ..solver.wall import (smooth_arrays, smooth_wall_D_kernel, wall_D_kernel,
                           wall_scalar_kernel)
from .. import status as st

# Tolerances of the solves inside the bisection. Near the edge the path meets D = 0 just before
# the wall, so where feasibility flips moves with the integration error: at the solver's default
# rtol = 1e-8 by up to ~2e-6 relative (A = -0.9, N = 1), at rtol = 1e-10 by ~1e-8 (compared with
# 1e-12). Tighter than 1e-10 the solver reports some paths just past the edge as
# integration_failed (it crawls into the sqrt(D) kink) and gets slow, so 1e-10 it is: the bracket
# is 1e-10 wide, the edge it brackets is the solver's at this tolerance, good to ~1e-8.
EDGE_RTOL = 1e-10
EDGE_ATOL = 1e-14
# Stage-1 step budget inside the bisection: ok points near the edge take a few thousand steps;
# a path crawling into the sqrt(D) kink just past the edge would spend the solver's default
# 200,000 before it is called integration_failed (not ok either way), which made tracing slow.
EDGE_MAX_STEPS = 20_000
# Tangential edges (trace_edge's Notes). The status bisection first stops at PROBE_XTOL; D(1) is
# then sampled at these relative distances on the ok side of the bracket, where it is 1e6-1e9
# times its noise at a tangential edge and the probes cost 6 stage-1 solves (a trace takes ~80).
PROBE_XTOL = 1e-7
PROBE_OFFSETS = np.geomspace(3e-5, 3e-4, 6)
# Noise of D(1) next to the edge, in units of stage 1's resolution of it (STAGE1_RTOL_FLOOR times
# |dD/d delta| delta at the wall). Measured: our stage 1 and scipy's DOP853 at rtol 1e-13 differ
# by up to ~1e-13 at A = 0, N = 2, about 10 resolutions; statuses flip within the band this gives
# (tests/test_regimes.py::test_noise_band_holds_the_flipping_statuses).
D_NOISE = 40.0


def wall_D(workspace, etas, A, N, rtol=EDGE_RTOL, atol=EDGE_ATOL):
    """Stage 1's status, ``D(1)`` (the yield function at the wall) and ``delta(1)`` at each ``eta``.

    Parameters
    ----------
    workspace : cosserat_channel.solver.point.Workspace
        Its stage-1 arrays are used; a stand-in that counts solves (``atlas.tracer._Counting``) passes
        its ``ws`` and counts the solves itself.
    etas : array_like
        Values of ``eta = eps L``.
    A, N : float
        The point of the ``(A, N)`` plane (``A > -1``).
    rtol, atol : float
        Tolerances handed to stage 1, which tightens them near the edge (down to
        ``stage1.STAGE1_RTOL_FLOOR``), as in a status solve.

    Returns
    -------
    status : ndarray of int8
        Stage 1's status (stage 2 is not run: next to the edge it may turn ok into not ok).
    D1, delta1 : ndarray
        ``D(1)`` and ``delta(1) = (m(1)/nu + N L)/L`` where stage 1 reached the wall, else NaN.
    """
    ws, etas, status, D1, delta1 = _counted_slots(workspace, etas)
    wall_D_kernel(etas, float(A), float(N), float(rtol), float(atol), ws.ax, ws.T1, ws.Q1,
                  ws.stats1, ws.res, status, D1, delta1)
    return status, D1, delta1


# ---------------------------------------------------------------------------------------------
# A smooth D(1): D marched as a state of its own next to the wall (transversal edges near the
# node/focus switch; see trace_edge's Notes)
# ---------------------------------------------------------------------------------------------
SMOOTH_RTOL = 1e-13
SMOOTH_MAX_STEPS = 20_000
# The smooth root replaces the status bisection where the probe's noise band exceeds this
# (relative in eta): there the status is decided by the noise of stage 1's D(1).
SMOOTH_BAND = 3e-9
SMOOTH_XTOL = 1e-12  # relative width of the root's final bracket
SMOOTH_WIDEN = (1.0, 4.0, 16.0, 64.0)  # brackets tried, in noise bands either side


_SMOOTH_WORK = threading.local()  # work arrays per thread (the atlas traces in threads)


def smooth_wall_D(eta, A, N, rtol=SMOOTH_RTOL, out=None):
    """``D(1)`` of the stage-1 path, marched so that it is a smooth function of ``eta``.

    From the axis series (``stage1.stage1_start``) the path is marched in ``w = delta/xi^2`` to
    ``xi = solver.wall.SMOOTH_XI_SWITCH``, then in ``(delta, D)`` with ``D`` a state of its own
    (``solver.wall._delta_D_rhs``), to the wall, both by ``rk45.dopri5`` at ``rtol``. Stage 1 reads
    ``D(1)`` off ``delta(1)``, a difference of O(1) terms with a noise of ~1e-13 (its step
    sequence changes with ``eta``); here ``D`` keeps a relative error, and the error committed
    before the switch is damped by the time the path reaches the wall (the singular point there
    attracts the paths: measured, marches whose ``delta`` at the switch differs by ~1e-13 give the
    same ``D(1) ~ 1e-12`` to ~1e-18). Past the edge the path is continued through ``D = 0``
    (``D' = F < 0``), so ``D(1)`` changes sign at the edge, continuously.

    Returns ``D(1)``, or NaN where a march failed or no stage 1 applies (``model.classify``).
    ``out``, if given (a float array of 2), receives ``D(1)`` and ``delta(1)``.
    """
    A = float(A)
    N = float(N)
    eta = float(eta)
    if out is not None:
        out[:] = math.nan
    if A <= -1.0 or model.classify(eta, A, N) != st.OK:
        return math.nan
    w = _SMOOTH_WORK
    if not hasattr(w, "T"):
        w.T, w.Qw, w.Q, w.stats = smooth_arrays(SMOOTH_MAX_STEPS)
    ax = np.empty(model.N_AX)
    model.axis_constants(eta, A, N, ax)
    if out is None:
        out = np.empty(2)
    return float(smooth_wall_D_kernel(eta, A, N, float(rtol), ax, w.T, w.Qw, w.Q, w.stats, out))


def smooth_edge(A, N, lo, hi, band, *, count=None, xtol=SMOOTH_XTOL):
    """The zero of :func:`smooth_wall_D` in ``eta`` next to the status bracket ``[lo, hi]``.

    The bracket is widened by ``SMOOTH_WIDEN`` noise bands (``band``, relative) until
    ``smooth_wall_D`` is positive at its low end and negative at its high end, then the zero is
    found by Brent's method to ``xtol`` (relative). ``count(n)``, if given, is told of each march.
    Returns the zero, or NaN where no widening brackets one.
    """
    from scipy.optimize import brentq

    def g(eta):
        if count is not None:
            count(1)
        v = smooth_wall_D(eta, A, N)
        if not math.isfinite(v):
            raise FloatingPointError(f"smooth_wall_D failed at eta = {eta!r}")
        return v

    try:
        for k in SMOOTH_WIDEN:
            w = max(k * band, 10.0 * xtol)
            a, b = lo * (1.0 - w), hi * (1.0 + w)
            ga, gb = g(a), g(b)
            if ga > 0.0 and gb < 0.0:
                return float(brentq(g, a, b, xtol=xtol * a, rtol=4 * np.finfo(float).eps))
    except FloatingPointError:
        pass  # a march failed: the caller falls back to the status bisection
    return math.nan


def node_edge_eta(A, N):
    """``eta`` at which the node of the yield condition sits at the wall, and whether it is a node.

    Along a stage-1 path ``dD/dxi = F - (D_delta / eta) sqrt(D)`` with
    ``D = (A^2-1) xi^2 + 2(A+1)(2 N delta - delta^2)`` and
    ``F = 2(A+1) xi [(A-1) + 2(A+1)(N - delta)/eta]``: a path can reach ``D = 0`` only where
    ``F <= 0``, and the point of ``D = 0`` where ``F = 0`` (``N - delta = (1-A) eta / (2(A+1))``)
    is a singular point of ``(xi, sqrt(D))``. Linearised there (``ds/dtau = 2z``,
    ``dz/dtau = -Phi s - gamma z`` with ``gamma = 2(1-A)``, ``Phi = 4(A+1)^3 xi^2 / eta^2``) it is
    a stable node when ``gamma^2 > 8 Phi`` and a focus otherwise. At a node the paths that come
    close to ``D = 0`` run into it with ``sqrt(D)`` falling linearly: beyond the node ``F < 0``
    and ``D`` turns negative. So where the node is reached, the edge is the ``eta`` that puts it
    at the wall: ``D(1) = 0`` and ``F(1) = 0`` give

        eta_node = 2 (A+1) sqrt(N^2 - (1-A)/2) / (1-A)

    and the node condition at the wall reads ``N^2 > (5 + 3A)/2``
    (:func:`~cosserat_channel.physics.analytic.node_focus_switch_N`).
    Whether the path does reach the node is for the data to say (:func:`trace_edge` checks it); at
    a focus the path meets ``D = 0`` past the singular point, transversally, and
    ``eta_max > eta_node``.

    Parameters
    ----------
    A, N : float

    Returns
    -------
    eta : float
        ``eta_node``; NaN unless ``-1 < A < 1`` and ``N^2 > (1-A)/2`` (``A`` above the wall line).
    node : bool
        The singular point at the wall is a node (``N^2 > (5 + 3A)/2``).
    ratio : float
        ``lambda_fast / lambda_slow`` of the node (NaN at a focus): ``sqrt(D(1))`` is linear in
        ``eta_node - eta`` up to a term in its power ``ratio``, so a polynomial extrapolation of
        it is good where the ratio is well above 2 and biased as it approaches 1.
    """
    A = float(A)
    N = float(N)
    arg = N * N - 0.5 * (1.0 - A)
    if not (-1.0 < A < 1.0 and arg > 0.0):
        return math.nan, False, math.nan
    eta = 2.0 * (A + 1.0) * math.sqrt(arg) / (1.0 - A)
    if not N > analytic.node_focus_switch_N(A):
        return eta, False, math.nan
    gamma = 2.0 * (1.0 - A)
    root = math.sqrt(max(gamma * gamma - 32.0 * (A + 1.0) ** 3 / (eta * eta), 0.0))
    return eta, True, (gamma + root) / (gamma - root)


@dataclass
class Probe:
    """``D(1)`` on the ok side of a bracketed transition (:func:`probe_edge`).

    Attributes
    ----------
    root2, root3 : float
        ``eta`` where degree-2 and degree-3 polynomial fits of ``sqrt(D(1))`` extrapolate to zero
        (NaN where a fit has no real root nearby).
    exponent : float
        Local power of ``D(1)`` in the distance to ``root3`` (to the bracket where that is NaN):
        2 at a tangential edge, towards 1 at a transversal one.
    band : float
        Relative distance from the edge within which ``D(1)``, continued by that power law, is
        below its noise (``D_NOISE`` resolutions): the statuses there are not reliable.
    """

    root2: float
    root3: float
    exponent: float
    band: float


def _root_near_zero(coef):
    r = np.roots(coef)
    r = r[np.abs(r.imag) <= 1e-9 * np.maximum(1.0, np.abs(r))].real
    return float(r[np.argmin(np.abs(r))]) if r.size else math.nan


def probe_edge(workspace, t_ok, side, A, N, rtol=EDGE_RTOL, atol=EDGE_ATOL):
    """Sample ``D(1)`` at ``t_ok (1 + side * PROBE_OFFSETS)`` and extrapolate it to the edge.

    Parameters
    ----------
    workspace : Workspace or a stand-in with ``ws``
    t_ok : float
        The ok end of a bracketed transition.
    side : {-1, 1}
        -1 where ok lies below the transition (an upper edge), +1 above it.
    A, N, rtol, atol : float

    Returns
    -------
    Probe or None
        None where a probe is not ok or has ``D(1) <= 0`` (the transition is not one of ``D(1)``
        reaching zero at the wall, or another transition is within 3e-4).
    """
    eps = PROBE_OFFSETS
    etas = t_ok * (1.0 + side * eps)
    status, D1, delta1 = wall_D(workspace, etas, A, N, rtol, atol)
    if not (np.all(status == st.OK) and np.all(D1 > 0.0)):
        return None
    u = eps / eps[-1]
    s = np.sqrt(D1)
    # Roots in u (0 at t_ok, positive into the ok side): the edge is a little beyond t_ok.
    u2 = _root_near_zero(np.polyfit(u, s, 2))
    u3 = _root_near_zero(np.polyfit(u, s, 3))
    # The power is measured from the extrapolated zero where the two fits agree on it, else from
    # the bracket (within PROBE_XTOL plus the band of the edge, ~3 % of the nearest offset).
    agree = math.isfinite(u3) and math.isfinite(u2) and abs(u3 - u2) <= 0.05 * u[0]
    ur = u3 if agree and abs(u3) <= 0.5 * u[0] else 0.0
    exponent = math.log(D1[-1] / D1[0]) / math.log((u[-1] - ur) / (u[0] - ur))
    sens = 4.0 * (A + 1.0) * np.abs(N - delta1) * np.abs(delta1)
    noise = D_NOISE * stage1.STAGE1_RTOL_FLOOR * float(np.max(sens))
    dist0 = (u[0] - ur) * eps[-1]
    band = dist0 * (noise / D1[0]) ** (1.0 / exponent) if exponent > 0.0 else dist0
    to_eta = lambda v: t_ok * (1.0 + side * eps[-1] * v)  # noqa: E731
    return Probe(to_eta(u2), to_eta(u3), exponent, min(band, dist0))


def wall_scalar(workspace, etas, A, N):
    """Stage 1's status and a signed, smooth distance from the edge at each ``eta``.

    One stage-1 march at its floor tolerance per ``eta`` (``stage1.STAGE1_RTOL_FLOOR``). The
    scalar is ``D(1)`` where the path reaches the wall, and ``F(xi_s) (1 - xi_s) <= 0`` where it
    meets ``D = 0`` at ``xi_s < 1`` (``F`` as in :func:`node_edge_eta`: ``D' = F`` where
    ``D = 0``), so it continues ``D(1)`` through its zero at a transversal edge with the same
    slope; NaN where stage 1 says neither (it failed, or the axis condition decides).

    Parameters
    ----------
    workspace : Workspace or a counting stand-in with ``ws`` and ``count``
    etas : array_like
    A, N : float

    Returns
    -------
    status : ndarray of int8
        Stage 1's status.
    G : ndarray
        The scalar.
    sens : ndarray
        ``|dD/d delta| delta`` there: stage 1's noise in ``G`` is ``D_NOISE * STAGE1_RTOL_FLOOR``
        times it.
    """
    ws, etas, status, G, sens = _counted_slots(workspace, etas)
    atol = EDGE_ATOL * stage1.STAGE1_RTOL_FLOOR / EDGE_RTOL  # EDGE_ATOL scaled to the floor rtol
    wall_scalar_kernel(etas, float(A), float(N), atol, ws.ax, ws.T1, ws.Q1, ws.stats1, ws.res,
                       status, G, sens)
    return status, G, sens


def _counted_slots(workspace, etas):
    """The kernels' workspace, ``etas`` as a contiguous array (counted as that many solves when
    ``workspace`` counts them), and the status and two value arrays a wall kernel fills."""
    ws = getattr(workspace, "ws", workspace)
    count = getattr(workspace, "count", None)
    etas = np.ascontiguousarray(np.atleast_1d(np.asarray(etas, dtype=float)))
    if count is not None:
        count(etas.size)
    return ws, etas, np.empty(etas.size, dtype=np.int8), np.empty(etas.size), np.empty(etas.size)
