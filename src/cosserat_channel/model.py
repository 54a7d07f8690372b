"""The equations of the Cosserat channel-flow model, as Numba scalars.

Source: Mohan, Nott & Rao, "A frictional Cosserat model for the flow of granular materials
through a vertical channel"; the labels (``e-61``, ``eq:56`` ...) are the paper's ``\\label``s and
``docs/model.md`` restates the problem. Nothing here integrates, sweeps or writes files.

Scaled variables
----------------
All stresses are divided by ``rho_p g W nu`` (nu scales out exactly), velocities by the wall spin
``omega_w``. With the exact similarity of model.md, ``eta = eps * L`` and the couple stress is carried
as

    delta = (m + N L) / L = mu + N  >= 0,      mu = m / L,

the cancellation-free state of model.md scaled by ``L``. Stage 1 then reads

    eta d(delta)/d(xi) = (A+1) xi - sqrt(D)                                  (e-61, eq:56, root E-)
    D = (A^2-1) xi^2 + 2(A+1) delta (2N - delta)                             (eq:a3)

and depends on ``(eta, A, N)`` only; ``m = L (delta - N)``. Stage 2 (``e-59``, ``e-60``) uses

    B = -2(A+1) mu / (eta sqrt(D)),    h = (A+1) (1 - (A-1) xi / sqrt(D)).

Near the axis we evaluate ``D`` as ``c0^2 xi^2 + 2(A+1)[2N (delta - y xi^2/2) - delta^2]``, which is the
same polynomial (``c0^2 = A^2 - 1 + 2(A+1) N y``, a consequence of eq:20) but does not subtract two
nearly equal O(xi^2) numbers: ``D`` stays exact to round-off down to ``xi -> 0`` even close to the
axis edge where ``c0 -> 0``.
"""

from __future__ import annotations

import math

from numba import njit
from ._jit import JIT as _JIT

from . import analytic


# Slots of the axis-constants array returned by `axis_constants`.
AX_Y = 0  # mu''(0) = x / L, the curvature of the axis series (eq:20)
AX_C0 = 1  # sqrt(D)/xi at the axis, = A + 1 - eta*y
AX_K = 2  # fourth-order coefficient of the axis series of delta
AX_BETA = 3  # B ~ beta / xi near the axis (Appendix B)
N_AX = 4


# --------------------------------------------------------------------------------------------
# Regimes (Appendix A) and the axis condition (eq:20)
# --------------------------------------------------------------------------------------------
# The plain-Python originals live in analytic.py (the atlas classifies without numba); these are
# their compiled copies for the kernels.
axis_margin = njit(**_JIT)(analytic.axis_margin)
_classify_margin = njit(**_JIT)(analytic.classify_margin)


@njit(**_JIT)
def classify(eta, A, N):
    """Status decided before any integration, for the regimes of Appendix A.

    Returns ``OK`` when stage 1 must be integrated (A > -1, axis series admissible) or when the
    A = -1 closed form applies (:func:`cosserat_channel.analytic.classify_margin`).
    """
    return _classify_margin(axis_margin(eta, A, N), A, N)


@njit(**_JIT)
def axis_constants(eta, A, N, out):
    """Fill ``out[N_AX]`` with the axis series of eq:20 in cancellation-free form (A > -1).

    ``y = mu''(0)`` is the smaller root of ``eta^2 y^2 - 2(A+1)(eta+N) y + 2(A+1) = 0`` (eq:20 with
    ``x = L y``), written as ``y = 2(A+1) / [(A+1)(eta+N) + s]``. ``c0 = A + 1 - eta y`` equals
    ``(A+1) g / (s + (A+1) N)`` with ``g`` the axis margin, so it needs no subtraction. The quartic
    term ``k xi^4`` follows from e-61 at the next order. Requires ``axis_margin >= 0``.
    """
    a1 = A + 1.0
    s = math.sqrt(a1 * a1 * (eta + N) * (eta + N) - 2.0 * a1 * eta * eta)
    y = 2.0 * a1 / (a1 * (eta + N) + s)
    c0 = a1 * axis_margin(eta, A, N) / (s + a1 * N)
    out[AX_Y] = y
    out[AX_C0] = c0
    out[AX_K] = a1 * y * y / (4.0 * (4.0 * eta * c0 + 2.0 * a1 * N))
    out[AX_BETA] = 2.0 * a1 * N / (eta * c0) if c0 > 0.0 else math.inf


@njit(**_JIT)
def axis_relative_margin(A, N, ax):
    """``c0^2`` relative to the terms of ``D/xi^2`` at the axis that it is the difference of.

    ``c0^2 = (A^2 - 1) + 2(A+1) N y``: the two terms are ``O(A+1)``, so the number of digits ``D``
    keeps next to the axis is set by ``c0^2 / (2(A+1) N y)``, not by ``c0^2`` alone. The two differ
    when ``A -> -1``, where ``c0 ~ A + 1`` far from the axis edge (found by the domain tests: the
    bare ``c0^2`` treated every point with ``A + 1 < 1e-5`` as if it sat on the axis edge).
    """
    return ax[AX_C0] * ax[AX_C0] / (2.0 * (A + 1.0) * N * ax[AX_Y])


@njit(**_JIT)
def delta_axis_series(xi, ax):
    """``delta`` near the axis: ``m = -N L + x xi^2 / 2`` (eq:54, eq:20) plus the quartic term."""
    x2 = xi * xi
    return x2 * (0.5 * ax[AX_Y] + ax[AX_K] * x2)


# --------------------------------------------------------------------------------------------
# Stage 1: stresses, xi = 0 -> 1
# --------------------------------------------------------------------------------------------
@njit(**_JIT)
def yield_D(xi, delta, A, N, ax):
    """``D`` under the square root of eq:56 / eq:a3 (scaled), evaluated cancellation-free."""
    r = delta - 0.5 * ax[AX_Y] * xi * xi
    c0xi = ax[AX_C0] * xi
    return c0xi * c0xi + 2.0 * (A + 1.0) * (2.0 * N * r - delta * delta)


@njit(**_JIT)
def ddelta_dxi(xi, delta, eta, A, N, ax):
    """Stage-1 right-hand side, e-61 with eq:56 (root ``E-`` of eq:a2): ``eta delta' = (A+1) xi - sqrt(D)``.

    ``D`` is clipped at 0: a trial RK stage may step just outside the admissible region, and the
    ``D = 0`` event (not a NaN) is what reports that the path left it.
    """
    D = yield_D(xi, delta, A, N, ax)
    return ((A + 1.0) * xi - math.sqrt(max(D, 0.0))) / eta


@njit(**_JIT)
def dw_dxi(xi, w, eta, A, N, ax):
    """Stage 1 for the integrator, in ``w = delta / xi^2``: ``w' = (delta' - 2 xi w) / xi^2``.

    ``delta`` grows like ``xi^2`` off the axis, so a relative error control on ``delta`` forces
    geometric steps there (about 230 of them at eta = 1/3, rtol = 1e-8); ``w = y/2 + k xi^2 + ...``
    is smooth and O(1), which leaves only the stability limit ``h < 3.3 xi / (beta + 2)``.
    """
    delta = xi * xi * w
    return (ddelta_dxi(xi, delta, eta, A, N, ax) - 2.0 * xi * w) / (xi * xi)


@njit(**_JIT)
def dw_dxi_jacobian(xi, w, eta, A, N, ax):
    """Exact ``(d f/d w, d f/d xi)`` of :func:`dw_dxi` ``= f(xi, w)``, for the Rosenbrock path.

    With ``g(xi, delta) = ((A+1) xi - sqrt(D))/eta`` and ``delta = xi^2 w``:
    ``df/dw = g_delta - 2/xi = -B - 2/xi`` (model.md: the stage-1 Jacobian is ``-B``), and
    ``df/dxi = (g_xi + 2 xi w g_delta - 2w)/xi^2 - 2 (g - 2 xi w)/xi^3`` with
    ``g_xi = ((A+1) - (A^2-1) xi / sqrt(D))/eta``.
    """
    delta = xi * xi * w
    D = yield_D(xi, delta, A, N, ax)
    sq = math.sqrt(max(D, 1e-300))
    g = ((A + 1.0) * xi - sq) / eta
    g_delta = -2.0 * (A + 1.0) * (N - delta) / (eta * sq)
    g_xi = ((A + 1.0) - (A * A - 1.0) * xi / sq) / eta
    dfdw = g_delta - 2.0 / xi
    dfdxi = (g_xi + 2.0 * xi * w * g_delta - 2.0 * w) / (xi * xi) - 2.0 * (g - 2.0 * xi * w) / (xi * xi * xi)
    return dfdw, dfdxi


@njit(**_JIT)
def sigma_xy(xi):
    """eq:19: ``sigma_xy = -xi`` (scaled by nu)."""
    return -xi


@njit(**_JIT)
def sigma_yx(xi, D, A):
    """eq:56 with the root the paper keeps: ``sigma_yx = A xi - sqrt(D)`` (scaled by nu)."""
    return A * xi - math.sqrt(max(D, 0.0))


# --------------------------------------------------------------------------------------------
# Stage 2: velocities, xi = 1 -> 0
# --------------------------------------------------------------------------------------------
@njit(**_JIT)
def spin_rate_B(delta, D, eta, A, N):
    """``B`` of eq:18 / e-60, ``d omega/d xi = B omega``; with ``s = sigma_yx + A sigma_xy = -sqrt(D)``.

    Also minus the Jacobian of the stage-1 right-hand side with respect to ``delta`` (model.md).
    """
    return 2.0 * (A + 1.0) * (N - delta) / (eta * math.sqrt(D))


@njit(**_JIT)
def shear_rate_h(xi, D, A):
    """``h`` of e-59: ``du/d xi = -h omega``."""
    return (A + 1.0) * (1.0 - (A - 1.0) * xi / math.sqrt(D))


@njit(**_JIT)
def plug_target(J_axis, eps_K):
    """Right-hand side of eq:13 in terms of ``J``: ``J(xi_p) = 0.95 J(0) - 0.05 eps K``.

    ``u(xi)/omega_w = eps K + J(xi)`` (eq:7), so ``u(xi_p) = 0.95 u(0)`` is this. Negative or zero
    means the wall already moves at >= 95 % of the centre: ``xi_p = 1`` and ``Delta = 0``.
    """
    return 0.95 * J_axis - 0.05 * eps_K


# --------------------------------------------------------------------------------------------
# A = -1 (Appendix A): closed form
# --------------------------------------------------------------------------------------------
@njit(**_JIT)
def a_minus_one_xi_B(eta, N):
    """``xi B = c = 2N/eta`` for A = -1: the limit of e-60 on ``m = -N L``, where ``D = 0``."""
    return 2.0 * N / eta


@njit(**_JIT)
def a_minus_one_h():
    """``h = 2`` for A = -1: Appendix A's ``du/dxi = -2 omega`` (e-59 with sigma_yx = -xi)."""
    return 2.0
