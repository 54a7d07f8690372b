"""The model's parameters: names, ranges, meanings and units, and the checks that enforce them.

The one home of every parameter's definition. The point API, sweep files, the command line, the
Dataset attributes and the plots all take names, ranges and descriptions from here, so a range
changed here changes everywhere. Pure Python plus numpy: reading a result file or parsing a sweep
never imports numba.

Parameters and their order follow the paper (see ``docs/model.md``): ``(eps, L, K, A, N)``.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Mapping

import numpy as np

__all__ = [
    "DIMS",
    "Described",
    "Parameter",
    "PARAMETERS",
    "MATERIAL",
    "MATERIAL_REQUIRED",
    "TOLERANCES",
    "DEFAULT_RTOL",
    "DEFAULT_ATOL",
    "ParameterError",
    "ETA_MIN",
    "ETA_MAX",
    "check_point",
    "check_eta",
    "check_eta_range",
    "check_values",
    "check_tolerances",
    "check_material",
    "PHYSICAL",
    "eps_from_width",
    "N_from_friction",
    "parse_number",
]

DIMS = ("eps", "L", "K", "A", "N")
# The most points a grid over DIMS may hold: a sweep's (sweep/spec.py says why) and so a result
# file's, which its readers check before reading anything.
MAX_GRID_POINTS = 10_000_000_000


class ParameterError(ValueError):
    """A parameter outside the model's or the solver's domain; the message names it and its range."""


class Described:
    """What files and figures say of a named quantity, from its fields alone.

    A mixin for the dataclasses that define the quantities (:class:`Parameter`,
    :class:`cosserat_channel.outputs.Output` ...). They carry ``name``, ``units``, a short
    ``long_name`` (a good axis label: plain xarray wraps a label at 30 characters, so a
    ``long_name`` and its ``[units]`` stay within that), ``symbol`` (mathtext for figures),
    ``description`` (the sentence), ``unit_label`` (what a figure prints as the unit of a scaled
    value, e.g. ``particle diameters``) and, where the CF conventions have them,
    ``standard_name`` and ``axis``. Files take :attr:`attrs`, figures :attr:`label`.
    """

    @property
    def sentence(self) -> str:
        """The description, or the long name where there is none."""
        return self.description or self.long_name

    @property
    def attrs(self) -> dict:
        """The CF attributes of a variable holding this quantity (empty ones left out)."""
        attrs = {"units": self.units, "long_name": self.long_name}
        for key in ("standard_name", "axis", "description"):
            if getattr(self, key, ""):
                attrs[key] = getattr(self, key)
        return attrs

    @property
    def label(self) -> str:
        """The axis label of a figure: long name, symbol and unit, e.g.
        ``shear-layer thickness $\\Delta$ (particle diameters)``."""
        text = f"{self.long_name} {self.symbol}" if self.symbol else self.long_name
        unit = self.unit_label or ("" if self.units == "1" else self.units)
        return f"{text} ({unit})" if unit else text


@dataclass(frozen=True)
class Parameter(Described):
    """One parameter: its name, meaning, unit and allowed interval.

    Attributes
    ----------
    name : str
        The paper's symbol in ASCII (``eps``, ``L`` ...).
    long_name : str
        What it is, in a few words (the CF ``long_name`` of its coordinate, an axis label).
    units : str
        UDUNITS-parsable unit (``"1"`` when dimensionless).
    lo, hi : float
        Bounds of the allowed interval; ``lo_closed`` / ``hi_closed`` say whether each is allowed.
    default : float or None
        Value used when the parameter is not given (material closure constants only).
    symbol : str
        The paper's symbol in mathtext, for figures (``$\\varepsilon$``).
    description : str
        What it is, in a sentence (error messages, ``--help``, the ``description`` attribute).
    unit_label : str
        What figures print as its unit when that is not ``units`` (``particle diameters``).
    """

    name: str
    long_name: str
    units: str = "1"
    lo: float = -math.inf
    hi: float = math.inf
    lo_closed: bool = False
    hi_closed: bool = False
    default: float | None = None
    symbol: str = ""
    description: str = ""
    unit_label: str = ""

    @property
    def interval(self) -> str:
        """The allowed interval in the usual notation, e.g. ``(0, 1]``."""
        lb = "[" if self.lo_closed else "("
        rb = "]" if self.hi_closed else ")"
        return f"{lb}{self.lo:g}, {self.hi:g}{rb}"

    def contains(self, x):
        """Elementwise: ``x`` is finite and inside the interval (works on floats and arrays)."""
        above = (x >= self.lo) if self.lo_closed else (x > self.lo)
        below = (x <= self.hi) if self.hi_closed else (x < self.hi)
        if type(x) is float:  # one number (solve_point's path): no numpy scalars
            return math.isfinite(x) and above and below
        return np.isfinite(x) & above & below

    def check(self, value, label: str | None = None) -> float:
        """``float(value)`` if it is a real number inside the interval, else :class:`ParameterError`.

        Booleans (Python's and numpy's) and strings are refused even where ``float()`` would
        accept them: ``True`` is not a length and ``"1"`` is not a number.
        """
        label = label or self.name
        # Python floats and ints below 2**1024 (the common case) skip the type checks below.
        if type(value) is float or (type(value) is int and value.bit_length() <= 1023):
            x = float(value)
        else:
            what = f"a number in {self.interval} ({self.sentence})"
            if isinstance(value, (bool, np.bool_, str, bytes)) or not _is_real(value):
                raise ParameterError(f"{label} must be {what}; got {value!r}")
            try:
                x = float(value)
            except (TypeError, ValueError, OverflowError):
                raise ParameterError(f"{label} must be {what}; got {value!r}") from None
        if not self.contains(x):
            raise ParameterError(
                f"{label} = {value!r} is outside the allowed range {self.interval} "
                f"({self.sentence})"
            )
        return x


def _is_real(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) or (
        isinstance(value, np.ndarray) and value.ndim == 0 and value.dtype.kind in "iuf"
    )


# The point's parameters. The ranges are the solver's domain; model.md says which values the paper
# studies and what each status means outside the region with a solution.
PARAMETERS = {
    "eps": Parameter("eps", "relative particle size", "1", 0.0, 1.0, False, True,
                     symbol=r"$\varepsilon$",
                     description="particle diameter / channel half-width, d_p/W"),
    "L": Parameter("L", "Cosserat length", "1", 0.0, math.inf, symbol="$L$",
                   description="Cosserat length in particle diameters",
                   unit_label="particle diameters"),
    "K": Parameter("K", "wall roughness", "1", 0.0, math.inf, True, symbol="$K$",
                   description="wall roughness in u = eps K omega at the wall"),
    # |A| <= 1e3 and N <= 1e6: beyond them the kernels overflow (N^2, A^2 in D) and divided by
    # zero or ran out of steps (fuzzing found ZeroDivisionError from N ~ 1e140 and
    # integration_failed from |A| ~ 1e3.5); within them 15,000 random points never failed.
    "A": Parameter("A", "yield-surface constant", "1", -1e3, 1e3, True, True, symbol="$A$",
                   description="yield-surface constant a2/a1"),
    "N": Parameter("N", "wall friction ratio", "1", 0.0, 1e6, False, True, symbol="$N$",
                   description="wall friction ratio sin(phi)/tan(delta_w)"),
}

# The material, for nu and the dimensional stresses: the particle (required) and the
# critical-state closure sigma_c(nu) of eq:24 with the paper's constants as defaults.
# The bounds are physical (1 nm to a 10 m boulder, aerogel to 4x osmium, 1e-6 to 1000 g, a
# friction angle of at least 0.001 degree): they keep the stress scale rho_p g W = rho_p g d_p /
# eps and tan(delta) Lambda finite, non-zero doubles for every eps and N the solver accepts. Unbounded,
# d_p = 1e308 overflowed the scale and the stresses in Pa went silently missing, and subnormal
# values made the closure take the logarithm of 0.
MATERIAL = {
    "d_p": Parameter("d_p", "particle diameter", "m", 1e-9, 10.0, True, True, symbol="$d_p$",
                     description="particle diameter d_p in m"),
    "rho_p": Parameter("rho_p", "particle density", "kg m-3", 1e-3, 1e5, True, True,
                       symbol=r"$\rho_p$", description="particle density rho_p in kg/m^3"),
    "phi": Parameter("phi", "internal friction angle", "degree", 1e-3, 90.0, True,
                     symbol=r"$\phi$",
                     description="angle of internal friction phi in degrees"),
    "g": Parameter("g", "gravity", "m s-2", 1e-6, 1e4, True, True, default=9.81, symbol="$g$",
                   description="gravity g in m/s^2"),
    # Lambda is a stress in pascals: that reproduces the paper's nu = 0.60 and 0.59 (model.md).
    "Lambda": Parameter("Lambda", "closure stress", "Pa", 1e-9, 1e12, True, True, default=817.0,
                        symbol=r"$\Lambda$", description="closure constant Lambda in Pa (eq:24)"),
    "nu_min": Parameter("nu_min", "loosest solids fraction", "1", 0.0, 1.0, True, default=0.5,
                        symbol=r"$\nu_{\min}$", description="closure nu_min (eq:24)"),
    "nu_max": Parameter("nu_max", "densest solids fraction", "1", 0.0, 1.0, default=0.65,
                        symbol=r"$\nu_{\max}$", description="closure nu_max (eq:24)"),
    "p": Parameter("p", "closure exponent p", "1", 1.0, math.inf, True, default=2.5,
                   symbol="$p$", description="closure exponent p (eq:24)"),
    "q": Parameter("q", "closure exponent q", "1", 0.0, math.inf, True, default=2.2,
                   symbol="$q$", description="closure exponent q (eq:24)"),
}
MATERIAL_REQUIRED = ("d_p", "rho_p", "phi")

# The smallest eps L the solver resolves. Below it the stress path's transitions (the wall
# layer, ~(eps L)^(2/3) wide, and the jump to D = 0 after xi = N when N < 1, ~eps L wide) come
# within a few thousand round-offs of xi, the march gives up or, further down, returns a plug
# edge that double precision cannot place (eps L = 1e-50 gave Delta = 8e7 where the Airy
# asymptote says 5e16), and at eps L ~ 1e-320 the kernels divide by an underflowed zero. On 5000
# random points with eta log-uniform in [1e-12, 1e-5] and rtol in [1e-13, 1e-3] none fails
# (integration_failed); between 1e-16 and 1e-12, 135 of 2000 do.
ETA_MIN = 1e-12
# ... and the largest: far above it eta^2 overflows in the axis series (eps L ~ 1e150 and up gave
# integration_failed and ZeroDivisionError); 9,000 random points in [1e2, 1e15] solved cleanly.
ETA_MAX = 1e12

DEFAULT_RTOL = 1e-8
DEFAULT_ATOL = 1e-12
# The ranges in which a point's status does not depend on the tolerances (tests/test_faults.py
# sweeps both and compares with rtol = 1e-10). The stage-1 state w = delta/xi^2 is O(0.1-10) and
# stage 2's J is O(1) (its atol is scaled by min(1, eps L)), so atol is an absolute error on
# O(1) numbers: at atol = 1e-5 points 1e-3 (relative, in eps L) inside the edge of solvability
# already flip, at 0.1 points far from it do, and at 10 the kernel divided by zero. Measured, at
# atol <= 1e-6 and rtol <= 1e-3 statuses match the tight ones everywhere except within ~1e-4 of
# an edge (1e-5 at the defaults, the resolution of D(1) there); at rtol = 0.5 that band grew to
# 1e-3. atol below 1e-30 buys nothing and at 5e-324 its scaled copy underflows to 0.
TOLERANCES = {
    "rtol": Parameter("rtol", "relative tolerance", "1", 1e-13, 1e-3, True, True,
                      default=DEFAULT_RTOL, description="relative tolerance"),
    "atol": Parameter("atol", "absolute tolerance", "1", 1e-30, 1e-6, True, True,
                      default=DEFAULT_ATOL, description="absolute tolerance"),
}


def check_point(eps, L, K, A, N):
    """Validate ``(eps, L, K, A, N)``; returns them as floats or raises :class:`ParameterError`.

    Besides each parameter's own range, ``eps L`` must lie in ``[ETA_MIN, ETA_MAX]``.
    """
    point = tuple(PARAMETERS[d].check(v) for d, v in zip(DIMS, (eps, L, K, A, N)))
    check_eta(point[0], point[1])
    return point


def check_eta(eps, L, label: str = "eps L") -> float:
    """``eps * L``, or :class:`ParameterError` outside ``[ETA_MIN, ETA_MAX]``."""
    eta = eps * L
    if not ETA_MIN <= eta <= ETA_MAX:
        raise ParameterError(
            f"{label} = {eta:g} (eps = {eps!r}, L = {L!r}) is outside [{ETA_MIN:g}, "
            f"{ETA_MAX:g}], the eps L the solver resolves"
        )
    return eta


def check_eta_range(eta_range, label: str = "eta_range") -> tuple[float, float]:
    """``(lo, hi)`` as floats, or :class:`ParameterError` unless ``lo < hi`` inside
    ``[ETA_MIN, ETA_MAX]`` (a range of ``eps L`` searched for edges of solvability)."""
    try:
        lo, hi = (float(v) for v in eta_range)
    except (TypeError, ValueError, OverflowError):
        raise ParameterError(f"{label} must be two numbers lo, hi; got {eta_range!r}") from None
    if not ETA_MIN <= lo < hi <= ETA_MAX:
        raise ParameterError(f"{label} = {lo:g}:{hi:g} must be lo < hi inside [{ETA_MIN:g}, "
                             f"{ETA_MAX:g}], the eps L the solver resolves")
    return lo, hi


def check_values(name: str, values, label: str | None = None) -> np.ndarray:
    """Validate a whole axis of parameter ``name`` at once; returns it as float64.

    Vectorised, so an axis of 10^8 values takes seconds. The message names the first value
    outside the range, as :meth:`Parameter.check` would for that value alone.
    """
    param = PARAMETERS[name]
    x = np.asarray(values, dtype=np.float64)
    bad = ~param.contains(x)
    if bad.any():
        param.check(x.ravel()[np.flatnonzero(bad.ravel())[0]].item(), label)
    return x


def check_tolerances(rtol, atol):
    """Validate the tolerances; returns them as floats or raises :class:`ParameterError`."""
    return TOLERANCES["rtol"].check(rtol), TOLERANCES["atol"].check(atol)


def check_material(material: Mapping | None) -> dict | None:
    """Validate a material mapping; fill in the closure's defaults; None stays None."""
    if material is None:
        return None
    if not isinstance(material, Mapping):
        raise ParameterError("material must be a mapping with keys " + ", ".join(MATERIAL))
    unknown = sorted(set(material) - set(MATERIAL), key=str)
    if unknown:
        raise ParameterError(
            f"material: unknown key(s) {', '.join(map(repr, unknown))}; allowed: " + ", ".join(MATERIAL)
        )
    missing = [k for k in MATERIAL_REQUIRED if k not in material]
    if missing:
        raise ParameterError(f"material: missing required key(s) {', '.join(missing)}")
    full = {k: p.default for k, p in MATERIAL.items() if p.default is not None}
    for key, value in material.items():
        full[key] = MATERIAL[key].check(value, f"material.{key}")
    if not full["nu_min"] < full["nu_max"]:
        raise ParameterError(
            f"material.nu_min = {full['nu_min']:g} must be below material.nu_max = {full['nu_max']:g}"
        )
    return full


# Engineers' inputs, from which eps and N follow (docs/model.md, "Parameters"): the channel's
# half-width W with the particle diameter d_p (eps = d_p/W), and the angle of wall friction
# delta_w with the angle of internal friction phi (N = sin(phi)/tan(delta_w)). Their ranges are
# physical; what they give is then checked against eps's and N's own.
PHYSICAL = {
    "W": Parameter("W", "channel half-width W in m", "m", 0.0, 1e6),
    "delta_w": Parameter("delta_w", "angle of wall friction delta_w in degrees", "degree", 0.0,
                         90.0),
}


def eps_from_width(d_p, W):
    """``eps = d_p / W`` from the particle diameter and the channel's half-width, both in m.

    ``W`` may be an array (a sweep's axis): the result has its shape. Each input is checked
    against its own range (``MATERIAL["d_p"]``, ``PHYSICAL["W"]``) and the quotient against
    eps's; :class:`ParameterError` names the first value outside.
    """
    d = MATERIAL["d_p"].check(d_p)
    w = _checked(PHYSICAL["W"], W)
    return _checked(PARAMETERS["eps"], d / w, "eps = d_p/W")


def N_from_friction(phi, delta_w):
    """``N = sin(phi) / tan(delta_w)`` (the paper's relation) from the angles of internal and of
    wall friction, in degrees; ``delta_w`` may be an array, and everything is checked as in
    :func:`eps_from_width`."""
    p = MATERIAL["phi"].check(phi)
    d = _checked(PHYSICAL["delta_w"], delta_w)
    return _checked(PARAMETERS["N"], math.sin(math.radians(p)) / np.tan(np.radians(d)),
                    "N = sin(phi)/tan(delta_w)")


def _checked(param: Parameter, values, label: str | None = None):
    """``values`` as a float (a scalar) or a float64 array, each inside ``param``'s range."""
    if np.ndim(values) == 0:
        if isinstance(values, np.floating):
            values = float(values)  # named as a number in the message, not as np.float64(...)
        return param.check(values, label)  # refuses booleans and strings, as everywhere
    x = np.asarray(values, dtype=np.float64)
    bad = ~param.contains(x)
    if bad.any():
        param.check(x.ravel()[np.flatnonzero(bad.ravel())[0]].item(), label)
    return x


def parse_number(text: str) -> float:
    """A number as a person writes it: ``0.5``, ``1e-3``, ``nan``, or an exact fraction ``1/30``
    (rounded once, to the nearest double: ``parse_number("1/30") == 1/30``).

    ValueError for anything else. Ranges are not checked here (see :meth:`Parameter.check`).
    """
    text = text.strip()
    try:
        return float(text)
    except ValueError:
        pass
    num, sep, den = text.partition("/")
    if sep:
        try:
            return _fraction(num.strip(), den.strip())
        except (ValueError, ZeroDivisionError, ArithmeticError):
            pass
    raise ValueError(f"not a number or a fraction a/b: {text!r}")


# Decimal exponents beyond this are far outside every double (1e-324 .. 1.8e308) whatever the
# other side of the fraction, unless both sides are as large: such a fraction is divided in
# decimal arithmetic, not made exact (10**99999999 as an integer takes minutes to build).
_EXACT_EXPONENT = 1000
_EXPONENT = re.compile(r"[eE]([+-]?\d+)\s*$")


def _fraction(num: str, den: str) -> float:
    """``num/den`` rounded once to the nearest double (inf where it overflows, 0 where it
    underflows); ValueError if a side is not a number, ZeroDivisionError for ``den`` 0."""
    import decimal
    from fractions import Fraction

    sides = (num, den)
    for side in sides:
        float(side)  # ValueError for what is not a number (Decimal would take "snan")
    exps = [int(m.group(1)) if (m := _EXPONENT.search(s)) else 0 for s in sides]
    if max(map(abs, exps)) <= _EXACT_EXPONENT:
        q = Fraction(num) / Fraction(den)
        try:
            return float(q)
        except OverflowError:
            return math.inf if q > 0 else -math.inf
    ctx = decimal.Context(prec=60, Emax=decimal.MAX_EMAX, Emin=decimal.MIN_EMIN,
                          traps=[decimal.DivisionByZero, decimal.InvalidOperation])
    a, b = (ctx.create_decimal(s) for s in sides)
    if b == 0:
        raise ZeroDivisionError(den)
    return float(ctx.divide(a, b))
