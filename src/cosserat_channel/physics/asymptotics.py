"""Closed-form and asymptotic solutions used to validate the numerical solver.

Two analytical results of Mohan, Nott & Rao are implemented here:

* the exact solution for ``A = -1`` (Appendix A), and
* the matched-asymptotic composite solution for a fully rough wall (``N = 1``)
  as ``eps -> 0`` (Appendix C, eq:44, eq:29, eq:30, eq:32, eq:10).

Scalings follow ``docs/model.md``: every stress (and the couple stress ``m``)
is divided by ``nu`` so that ``nu`` drops out, i.e. ``m`` means ``m_bar / nu``
and ``sigma_yx`` means ``sigma_bar_yx / nu``. Velocities are per unit wall
spin: ``omega_hat = omega_bar / omega_bar_w`` and
``J(xi) = u(xi) / omega_bar_w - eps*K = int_xi^1 h omega_hat dxi'``.

The module is written for clarity and accuracy, not speed (pure numpy/scipy).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy.optimize import brentq
from scipy.special import airy, airye

__all__ = [
    "AMinusOneProfiles",
    "AMinusOneOutputs",
    "CompositeProfiles",
    "PLUG_FRACTION",
    "a_minus_one",
    "a_minus_one_outputs",
    "airy_I",
    "airy_I_inf",
    "xi_bar_p_limit",
    "xi_bar_p",
    "Delta_asymptotic",
    "composite",
    "composite_profile",
]

#: Plug edge criterion u(xi_p) / u(0) = 0.95 (eq:13).
PLUG_FRACTION = 0.95

# Ai(0) and Ai'(0); evaluated once through scipy so that every identity below
# uses exactly the same numbers as airy_I.
_AI0, _AIP0, _, _ = (float(v) for v in airy(0.0))


# ---------------------------------------------------------------------------
# A = -1: exact solution (Appendix A)
# ---------------------------------------------------------------------------


class AMinusOneProfiles(NamedTuple):
    """Profiles of the exact ``A = -1`` solution (stresses divided by ``nu``)."""

    m: np.ndarray
    sigma_xy: np.ndarray
    sigma_yx: np.ndarray
    omega_hat: np.ndarray
    J: np.ndarray
    u_over_u0: np.ndarray


class AMinusOneOutputs(NamedTuple):
    """Scalar outputs of the exact ``A = -1`` solution."""

    xi_p: float
    Delta: float
    slip: float
    u_axis: float


def _exponent_c(eps, L, N):
    return 2.0 * N / (eps * L)


def a_minus_one(xi, eps, L, K, N):
    """Exact solution for ``A = -1`` (Appendix A).

    Parameters
    ----------
    xi : array_like
        Positions in ``[0, 1]`` (``0`` = axis, ``1`` = wall).
    eps, L, K, N : float
        Parameters (order ``eps, L, K, A, N`` with ``A = -1`` implied).

    Returns
    -------
    AMinusOneProfiles
        ``m = -N L`` (constant), ``sigma_xy = sigma_yx = -xi``,
        ``omega_hat = xi**c``, ``J = 2 (1 - xi**(c+1)) / (c+1)`` and
        ``u_over_u0 = (eps K + J) / (eps K + J(0))`` with ``c = 2N/(eps L)``.

    Notes
    -----
    Appendix A gives ``u = u(0) - 2 omega_w xi**(c+1)/(c+1)``, i.e.
    ``du/dxi = -2 omega_w xi**c`` (``h = 2``); with ``u(1) = eps K omega_w``
    (eq:7) this is ``J`` above. Powers are evaluated as ``exp(c log xi)`` and
    ``1 - xi**(c+1)`` as ``-expm1((c+1) log xi)`` so that ``c`` of order
    ``1e5`` and beyond neither overflows nor loses ``J`` near the wall to
    cancellation; ``xi = 0`` gives ``log xi = -inf`` and the exact limits.
    """
    xi = np.asarray(xi, dtype=float)
    c = _exponent_c(eps, L, N)
    with np.errstate(divide="ignore"):
        log_xi = np.log(xi)
    omega_hat = np.exp(c * log_xi)
    J = -2.0 * np.expm1((c + 1.0) * log_xi) / (c + 1.0)
    J0 = 2.0 / (c + 1.0)
    u_over_u0 = (eps * K + J) / (eps * K + J0)
    m = np.full_like(xi, -N * L)
    sigma = -xi
    return AMinusOneProfiles(m, sigma, sigma.copy(), omega_hat, J, u_over_u0)


def a_minus_one_outputs(eps, L, K, N):
    """Plug edge, shear-layer thickness and slip for ``A = -1`` (Appendix A).

    Parameters
    ----------
    eps, L, K, N : float
        Parameters (``A = -1`` implied).

    Returns
    -------
    AMinusOneOutputs
        ``xi_p``, ``Delta = (1 - xi_p)/eps``, ``slip = u(1)/u(0)`` and
        ``u_axis = u(0)/omega_bar_w = eps K + J(0)``.

    Notes
    -----
    ``u(xi_p)/u(0) = 0.95`` (eq:13) with the profile of :func:`a_minus_one`
    gives ``xi_p**(c+1) = q`` with ``q = 0.05 (1 + eps K (c+1)/2)``. When
    ``q >= 1`` (equivalently ``eps K >= 19 J(0)``) the wall already moves at
    95 % of the axis speed: ``xi_p = 1``, ``Delta = 0``. The thickness
    ``1 - xi_p = -expm1(log(q)/(c+1))`` is formed without the cancellation
    of ``1 - q**(1/(c+1))`` that would ruin it for large ``c``.
    """
    c = _exponent_c(eps, L, N)
    J0 = 2.0 / (c + 1.0)
    u_axis = eps * K + J0
    slip = eps * K / u_axis
    q = (1.0 - PLUG_FRACTION) * (1.0 + eps * K * (c + 1.0) / 2.0)
    if q >= 1.0:
        return AMinusOneOutputs(1.0, 0.0, slip, u_axis)
    one_minus_xi_p = -np.expm1(np.log(q) / (c + 1.0))
    return AMinusOneOutputs(1.0 - one_minus_xi_p, one_minus_xi_p / eps, slip, u_axis)


# ---------------------------------------------------------------------------
# Airy integral I(x) (Appendix C, eq:32)
# ---------------------------------------------------------------------------


def airy_I(x):
    """Airy integral ``I(x) = int_0^x (Ai(z)/Ai(0))**2 dz`` (eq:32).

    Parameters
    ----------
    x : array_like
        Upper limits, ``x >= 0`` (the inner variable ``xi_bar``).

    Returns
    -------
    ndarray
        ``I(x)``.

    Notes
    -----
    Uses the exact antiderivative ``d/dz (z Ai**2 - Ai'**2) = Ai**2`` (from
    ``Ai'' = z Ai``), so no quadrature is needed. For large ``x`` both
    ``Ai`` and ``Ai'`` underflow to zero harmlessly and ``I -> I(inf)``.
    """
    x = np.asarray(x, dtype=float)
    ai, aip, _, _ = airy(x)
    return (x * ai**2 - aip**2 + _AIP0**2) / _AI0**2


def airy_I_inf():
    """Limit ``I(inf) = Ai'(0)**2 / Ai(0)**2`` of :func:`airy_I`.

    Returns
    -------
    float
        ``I(inf)`` (about 0.531).
    """
    return _AIP0**2 / _AI0**2


# ---------------------------------------------------------------------------
# Plug edge and shear-layer thickness (Appendix C, eq:10)
# ---------------------------------------------------------------------------


def _xi_bar_0(eps, L):
    # Axis position in the inner variable (text after eq:10).
    return (2.0 / L**2) ** (1.0 / 3.0) * eps ** (-2.0 / 3.0)


def _J_scale(eps, L):
    # dxi = -(L^2/2)^(1/3) eps^(2/3) dxi_bar and h = 2 turn int h omega_hat
    # dxi into this factor times I(xi_bar); see the Notes of `composite`.
    return 2.0 * (L**2 * eps**2 / 2.0) ** (1.0 / 3.0)


def xi_bar_p_limit(xtol=1e-15):
    """Limit ``eps -> 0`` of the plug edge in the inner variable (Appendix C).

    Solves ``I(x) / I(inf) = 0.95``.

    Parameters
    ----------
    xtol : float, optional
        Absolute tolerance passed to :func:`scipy.optimize.brentq`.

    Returns
    -------
    float
        ``xi_bar_p`` (about 1.2748; the paper prints 1.275).
    """
    target = PLUG_FRACTION * airy_I_inf()
    return brentq(lambda x: airy_I(x) - target, 0.0, 20.0, xtol=xtol, rtol=4 * np.finfo(float).eps)


def xi_bar_p(eps, L, *, K=0.0, xtol=1e-15):
    """Finite-``eps`` plug edge in the inner variable (Appendix C, eq:10).

    Solves ``I(xi_bar_p) / I(xi_bar_0) = 0.95`` with
    ``xi_bar_0 = (2/L**2)**(1/3) * eps**(-2/3)`` (the axis).

    Parameters
    ----------
    eps, L : float
        Parameters.
    K : float, optional, keyword-only
        Wall roughness. The paper's criterion assumes no slip (``K = 0``).
        For ``K > 0`` the slip ``u(1) = eps K omega_w`` (eq:7) is kept:
        ``(eps K + J(xi_bar_p)) / (eps K + J(xi_bar_0)) = 0.95`` with
        ``J = 2 (L**2 eps**2 / 2)**(1/3) I``; it vanishes as ``eps -> 0``
        because ``eps K / J ~ eps**(1/3)``.
    xtol : float, optional
        Absolute tolerance passed to :func:`scipy.optimize.brentq`.

    Returns
    -------
    float
        ``xi_bar_p``; ``0.0`` when the slip alone satisfies the criterion
        (``eps K >= 19 J(0)``: no shear layer).
    """
    x0 = _xi_bar_0(eps, L)
    slip = eps * K / _J_scale(eps, L)  # slip velocity in units of the I-scale
    target = PLUG_FRACTION * (slip + airy_I(x0)) - slip
    if target <= 0.0:
        return 0.0
    return brentq(lambda x: airy_I(x) - target, 0.0, x0, xtol=xtol, rtol=4 * np.finfo(float).eps)


def Delta_asymptotic(eps, L, finite=False, *, K=0.0):
    """Asymptotic shear-layer thickness in particle diameters (Appendix C).

    ``Delta = (L**2/2)**(1/3) * eps**(-1/3) * xi_bar_p``.

    Parameters
    ----------
    eps, L : float
        Parameters (``N = 1``: fully rough wall).
    finite : bool, optional
        If False use ``lim xi_bar_p`` (:func:`xi_bar_p_limit`, the paper's
        1.275); if True use the finite-``eps`` root of :func:`xi_bar_p`.
    K : float, optional, keyword-only
        Wall roughness, used only when ``finite`` is True (see
        :func:`xi_bar_p`).

    Returns
    -------
    float
        ``Delta``.
    """
    xb = xi_bar_p(eps, L, K=K) if finite else xi_bar_p_limit()
    return (L**2 / 2.0) ** (1.0 / 3.0) * eps ** (-1.0 / 3.0) * xb


# ---------------------------------------------------------------------------
# Composite solution (Appendix C)
# ---------------------------------------------------------------------------


class CompositeProfiles(NamedTuple):
    """Composite asymptotic profiles (stresses divided by ``nu``)."""

    xi_bar: np.ndarray
    m: np.ndarray
    sigma_yx: np.ndarray
    omega_hat: np.ndarray
    J: np.ndarray


def _airy_log_derivative(x):
    # Ai'/Ai from the exponentially scaled pair: the scale factors cancel, so
    # the ratio stays finite where Ai and Ai' themselves underflow.
    eai, eaip, _, _ = airye(x)
    return eaip / eai


def composite(xi, eps, L, N=1):
    """Leading-order composite solution for ``N = 1``, ``eps -> 0`` (Appendix C).

    With the inner variable ``xi_bar = (1 - xi) (2/L**2)**(1/3) eps**(-2/3)``
    and ``R = Ai'(xi_bar)/Ai(xi_bar)``:

    * ``m = -L sqrt(1 - xi**2) + (2 eps/L**2)**(1/3) L**2 R + L sqrt(2 (1 - xi))``
      (eq:44, corrected);
    * ``sigma_yx = -2 + xi + (4 eps**2 L**2)**(1/3) R**2``
      ``= -xi + (2 eps/L**2)**(2/3) L**2 (R**2 - xi_bar)`` (eq:29, corrected);
    * ``omega_hat = (Ai(xi_bar)/Ai(0))**2`` (eq:30);
    * ``J = 2 (L**2 eps**2 / 2)**(1/3) I(xi_bar)`` (eq:32, corrected), so
      ``u / omega_bar_w = eps K + J``.

    Parameters
    ----------
    xi : array_like
        Positions in ``[0, 1]``.
    eps, L : float
        Parameters.
    N : float, optional
        Must be 1 (fully rough wall); the expansion does not apply otherwise.

    Returns
    -------
    CompositeProfiles
        ``xi_bar, m, sigma_yx, omega_hat, J``.

    Raises
    ------
    ValueError
        If ``N != 1``.

    Notes
    -----
    Derivation (stresses over ``nu``, ``N = 1``): eq:14 is
    ``eps m' = (A+1) xi - sqrt(D)``. The outer solution is
    ``m_0 = -L sqrt(1 - xi**2)`` (eq:15), for which ``sqrt(D) = (A+1) xi``,
    hence ``sigma_yx = A xi - sqrt(D) = -xi`` and
    ``h = (A+1)(1 - (A-1) xi/sqrt(D)) = 2``. With ``xi_tilde = (1-xi)
    eps**(-2/3)``, ``m = eps**(1/3) m_tilde`` one finds
    ``sqrt(D) = (A+1) - eps**(2/3) ((A-1) xi_tilde + m_tilde**2/L**2)``,
    so ``m_tilde' = 2 xi_tilde - m_tilde**2/L**2`` (eq:27) and, with
    ``C2 = 0``, ``m_tilde = (2/L**2)**(1/3) L**2 R`` (eq:39). The printed
    formulas differ from this derivation as follows.

    1. eq:44 prints the inner term as ``(2 eps/L**2)**(1/3) R``: the factor
       ``nu L**2`` of eq:39 is missing. Without it the inner term would not
       cancel the common part ``L sqrt(2(1-xi))`` (``R ~ -sqrt(xi_bar)``), and
       ``m`` would not reach ``-L`` at the axis.
    2. eq:29 prints ``-2 nu + nu xi + (2 eps**2/L**2)**(1/3) R / (L**2 nu)``.
       The inner expansion of ``sigma_yx = A xi - sqrt(D)`` is
       ``-1 - eps**(2/3) xi_tilde + eps**(2/3) m_tilde**2/L**2``, i.e.
       ``-2 + xi + (4 eps**2 L**2)**(1/3) R**2``: the Airy term must be the
       *square* of ``R`` with prefactor ``nu (4 eps**2 L**2)**(1/3)`` (the
       printed term is linear in ``R`` and ``O(eps**(2/3) L**(-8/3))``, far
       too small). The same result follows from
       ``sigma_yx = sigma_xy + eps dm/dxi`` (e-61) applied to the inner
       solution, using ``dR/dxi_bar = xi_bar - R**2``. Because
       ``R**2 ~ xi_bar`` the corrected expression tends to the outer value
       ``-xi``, so it is itself the composite; the printed one gives
       ``-2 + xi`` in the core instead of ``-xi``.
    3. eq:30 is correct: in the inner region ``B = -2 eps**(-2/3)
       m_tilde/L**2``, so ``d omega/d xi_tilde = 2 (M'/M) omega`` with
       ``M = Ai``, giving ``omega ~ Ai**2``; the outer ``omega`` is
       exponentially small.
    4. eq:32 prints the prefactor ``2 (2 eps**2/L**2)**(1/3)``. Since
       ``dxi = -(L**2/2)**(1/3) eps**(2/3) dxi_bar`` and ``h = 2``,
       ``int_xi^1 h omega_hat dxi' = 2 (L**2 eps**2/2)**(1/3) I(xi_bar)``:
       the printed factor has ``L**2`` and ``2`` swapped (wrong by
       ``(L**2/2)**(2/3)``, 13.6 at ``L = 10``). It also omits the wall slip
       ``u(1) = eps K omega_w`` (eq:7), so it is ``J``, not ``u``. eq:10
       inherits the wrong prefactor; the ratio
       ``I(xi_bar_p)/I(xi_bar_0) = 0.95`` does not (for ``K = 0``).
    """
    if N != 1:
        raise ValueError(f"the Appendix C composite solution is for N = 1 only, got N = {N}")
    xi = np.asarray(xi, dtype=float)
    one_minus_xi = 1.0 - xi
    xi_bar = one_minus_xi * _xi_bar_0(eps, L)
    R = _airy_log_derivative(xi_bar)
    m = (
        -L * np.sqrt((1.0 - xi) * (1.0 + xi))
        + (2.0 * eps / L**2) ** (1.0 / 3.0) * L**2 * R
        + L * np.sqrt(2.0 * one_minus_xi)
    )
    # R**2 - xi_bar decays like -1/(2 sqrt(xi_bar)); forming it first avoids
    # the cancellation of -2 + xi + 2(1 - xi) in the core.
    sigma_yx = -xi + (2.0 * eps / L**2) ** (2.0 / 3.0) * L**2 * (R**2 - xi_bar)
    eai, _, _, _ = airye(xi_bar)
    # Ai = eAi exp(-2/3 xi_bar^1.5): square in log form so that the decay
    # underflows cleanly to zero instead of producing inf * 0.
    with np.errstate(divide="ignore"):
        omega_hat = np.exp(2.0 * np.log(eai / _AI0) - (4.0 / 3.0) * xi_bar**1.5)
    J = _J_scale(eps, L) * airy_I(xi_bar)
    return CompositeProfiles(xi_bar, m, sigma_yx, omega_hat, J)


def composite_profile(name, xi, eps, L, K):
    """Profile ``name`` of the composite solution in the variables of ``solve_point``'s profiles.

    ``name`` is one of ``u_over_u0`` (``(eps K + J)/(eps K + J(0))``, the slip of eq:7 kept),
    ``omega_hat``, ``m``, ``sigma_xy`` (``-xi``, exact) and ``sigma_yx``; stresses over ``nu``.
    ``N = 1`` (:func:`composite`).
    """
    if name == "sigma_xy":
        return -np.asarray(xi, dtype=float)
    c = composite(xi, eps, L)
    if name == "u_over_u0":
        J0 = composite(np.array([0.0]), eps, L).J[0]
        return (eps * K + c.J) / (eps * K + J0)
    if name not in ("omega_hat", "m", "sigma_yx"):
        raise ValueError(f"no composite profile {name!r}")
    return getattr(c, name)
