"""The critical-state closure and the solids fraction it implies at the wall.

The closure is eq:24, ``sigma_c(nu) = Lambda (nu - nu_min)^p / (nu_max - nu)^q``; the solids
fraction ``nu`` follows from the wall-friction condition eq:35,
``rho_p g W nu = tan(delta) sigma_c(nu)``. Both act once per ``(eps, N)`` after the solve, never
inside an integration, so they are plain Python (no numba): a result can be post-processed, and a
new closure added, without compiling anything.
"""

from __future__ import annotations

import math

__all__ = ["sigma_c", "solids_fraction", "solids_fraction_partials"]

# Bisection halves (nu_min, nu_max) until the midpoint repeats an end: ~60 halvings in double
# precision; the bound only guards against a loop that cannot end.
_MAX_BISECTIONS = 200


def sigma_c(nu: float, material: dict) -> float:
    """Critical-state mean stress of eq:24 in Pa (``Lambda`` is in Pa); 0 at or below ``nu_min``."""
    nu_min = material["nu_min"]
    if nu <= nu_min:
        return 0.0
    return material["Lambda"] * (nu - nu_min) ** material["p"] / (material["nu_max"] - nu) ** material["q"]


def solids_fraction(rho_g_W: float, tan_delta: float, material: dict) -> float:
    """The root of eq:35, ``rho_p g W nu = tan(delta) sigma_c(nu)``, in ``(nu_min, nu_max)``.

    In logarithms the residual ``ln(tan(delta) sigma_c) - ln(rho_p g W nu)`` has derivative
    ``p/(nu - nu_min) + q/(nu_max - nu) - 1/nu > 0`` (as ``p/(nu - nu_min) > 1/nu`` for p >= 1), so
    the root is unique (model.md); bisection to round-off. ``nan`` when the logarithms overflow
    (a channel so wide that ``rho_p g W`` is not a finite number).
    """
    nu_min, nu_max = material["nu_min"], material["nu_max"]
    p, q = material["p"], material["q"]
    log_scale = math.log(tan_delta * material["Lambda"])
    if not (math.isfinite(log_scale) and math.isfinite(rho_g_W) and rho_g_W > 0.0):
        return math.nan
    lo = nu_min
    hi = nu_max
    for _ in range(_MAX_BISECTIONS):
        mid = 0.5 * (lo + hi)
        if mid <= lo or mid >= hi:
            break
        f = log_scale + p * math.log(mid - nu_min) - q * math.log(nu_max - mid) - math.log(rho_g_W * mid)
        if f > 0.0:
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def solids_fraction_partials(nu: float, material: dict) -> dict:
    """Derivatives of the root ``nu`` of eq:35 (:func:`solids_fraction`), by the implicit function
    theorem on its residual in logarithms, ``F = ln(tan(delta) Lambda) + p ln(nu - nu_min)
    - q ln(nu_max - nu) - ln(rho_p g W nu)``: ``dnu = -dF / F_nu``.

    Returns ``d nu`` per unit change of ``ln(rho_p g W)``, ``ln(tan(delta))`` and of the closure's
    ``Lambda``, ``p``, ``q``, ``nu_min`` and ``nu_max``.
    """
    nu_min, nu_max = material["nu_min"], material["nu_max"]
    p, q = material["p"], material["q"]
    above, below = nu - nu_min, nu_max - nu
    inv = 1.0 / (p / above + q / below - 1.0 / nu)  # 1/F_nu > 0 (see solids_fraction)
    return {
        "ln_rho_g_W": inv,
        "ln_tan_delta": -inv,
        "Lambda": -inv / material["Lambda"],
        "p": -math.log(above) * inv,
        "q": math.log(below) * inv,
        "nu_min": p / above * inv,
        "nu_max": q / below * inv,
    }
