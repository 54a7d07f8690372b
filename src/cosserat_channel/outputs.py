"""Every output of a point, defined once: name, CF attributes, the stage it needs, its formula.

The kernels return a few raw numbers per ``(eta, A, N)`` (the status, ``J(0)``, the wall values of
stage 1, ``xi_stop``) and, per ``eps K``, the plug edge ``1 - xi_p``. Every output a user sees is
derived from those here, by one broadcasting function, :func:`derive`, which serves one point
(:func:`cosserat_channel.solver.point.solve_point`) and a whole grid (the sweep's Dataset) alike: the two
agree to the last bit because they run the same operations. Adding an output is one
:class:`Output` in :data:`OUTPUTS` (or :func:`register` at run time): the point API, sweep files,
the Dataset, the command line and ``query`` pick it up from here.

Pure Python plus numpy (the closure of :mod:`.closure` included): reading or describing a result
file never imports numba.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import KW_ONLY, dataclass
from typing import Callable

import numpy as np

from .physics import closure
from . import status as st
from .parameters import MATERIAL, PARAMETERS, Described

__all__ = ["Output", "Quantity", "Counter", "Scale", "Inputs", "OUTPUTS", "COUNTERS", "PROFILES",
           "SCALES", "XI", "definition", "register", "registered", "derive", "derive_profiles",
           "material_outputs",
           "needs_plug_edge", "needs_stage2"]

STAGE_NONE = 0  # needs no integration (material only)
STAGE_STRESS = 1  # stage 1: stresses, axis -> wall
STAGE_VELOCITY = 2  # stage 2: velocities, wall -> axis


@dataclass(frozen=True)
class Scale:
    """What turns a scaled, dimensionless value into SI units with a material.

    Attributes
    ----------
    label : str
        The scale in the paper's symbols, as figures print it (``$\\rho_p g W$``).
    units : str
        The SI unit of a scaled value times :meth:`factor` (UDUNITS).
    factor : callable
        ``factor(x)`` with ``x`` an :class:`Inputs` with a material: the scale, broadcastable.
    """

    label: str
    units: str
    factor: Callable[["Inputs"], np.ndarray]


@dataclass(frozen=True)
class Quantity(Described):
    """A named quantity with no formula here: a profile over ``xi``, or the ``xi`` axis itself.

    Attributes
    ----------
    name, units, long_name
        As for :class:`Output`.
    symbol, description, unit_label, standard_name, axis : str
        As for :class:`Output`; ``axis`` is the CF axis (``X``) of a coordinate.
    scale : str
        Key of :data:`SCALES` that makes it dimensional, or empty.
    """

    name: str
    units: str
    long_name: str
    _: KW_ONLY
    symbol: str = ""
    description: str = ""
    unit_label: str = ""
    standard_name: str = ""
    axis: str = ""
    scale: str = ""


@dataclass(frozen=True)
class Output(Quantity):
    """One scalar output per point.

    Attributes
    ----------
    name : str
        Variable name in results and files.
    units : str
        UDUNITS-parsable unit (``"1"`` when dimensionless).
    long_name : str
        What it is, in a few words: the CF ``long_name`` and a figure's axis label, short enough
        that plain xarray draws ``long_name [units]`` on one line (30 characters).
    compute : callable
        ``compute(x)`` with ``x`` an :class:`Inputs`: the value, broadcast over the inputs' shape,
        NaN where the point has none.
    stage : int
        The last solver stage it depends on: 0 (none), 1 (stresses) or 2 (velocities).
    plug_edge : bool
        Needs the plug edge ``1 - xi_p`` of eq:13 (a root search per ``eps K``).
    material : bool
        Needs a material (``nu`` and the stresses in Pa).
    differentiable : bool
        Has derivatives by the parameters (``solve_point(sensitivities=True)``): its chain rule
        from the marched quantities lives in :mod:`cosserat_channel.solver.sensitivity`, which a
        test holds to this flag.
    valued_when_ok : bool
        Has a value at every point whose status is ok (False: it may be NaN there too); a
        reader takes a missing value there as damage of the file (:mod:`.results.damage`).
    symbol : str
        The paper's symbol in mathtext, for figures (``$\\Delta$``).
    description : str
        What it is, in a sentence (the ``description`` attribute in files, ``point``'s table).
    unit_label : str
        What figures print as its unit when that is not ``units``: the scale of a scaled value.
    standard_name : str
        CF standard name, where the CF table has one.
    scale : str
        Key of :data:`SCALES` that makes a scaled value dimensional, or empty.
    """

    compute: Callable[["Inputs"], np.ndarray]
    stage: int = STAGE_VELOCITY
    plug_edge: bool = False
    material: bool = False
    differentiable: bool = False
    valued_when_ok: bool = True


@dataclass(frozen=True)
class Counter(Quantity):
    """A per-point work counter (stored in a sweep only on request); ``stage`` as for :class:`Output`."""

    stage: int = STAGE_VELOCITY


class _cached:
    """``functools.cached_property`` without its lock (Python 3.11 takes one per first read,
    a tenth of a one-point ``derive``): an :class:`Inputs` is never shared between threads."""

    def __init__(self, func):
        self.func = func
        self.name = func.__name__
        self.__doc__ = func.__doc__

    def __get__(self, obj, owner=None):
        if obj is None:
            return self
        value = obj.__dict__[self.name] = self.func(obj)
        return value


class Inputs:
    """What the outputs are derived from: raw solver values and parameters, all broadcastable.

    Parameters
    ----------
    status : array_like of int
        Status codes (:class:`cosserat_channel.status.Status`).
    eps, L, K, N : array_like
        The point's parameters (``A`` enters only through the solve).
    J_axis, mu_wall, sigma_yx_wall, xi_stop : array_like, optional
        The kernel's per-triple values: ``J(0)``, ``m(1)/(nu L)``, ``sigma_yx(1)/nu`` and where a
        stress path met D = 0. Values where the status is not ``ok`` are ignored.
    one_minus : array_like, optional
        ``1 - xi_p`` (NaN where the point has no solution).
    material : dict, optional
        A checked material (:func:`cosserat_channel.parameters.check_material`).
    """

    def __init__(self, status, eps, L, K, N, *, J_axis=None, mu_wall=None, sigma_yx_wall=None,
                 xi_stop=None, one_minus=None, material=None):
        self._raw = {"J_axis": J_axis, "mu_wall": mu_wall, "sigma_yx_wall": sigma_yx_wall,
                     "xi_stop": xi_stop, "one_minus": one_minus}
        self.material = material
        self._values: dict[str, np.ndarray] = {}
        self._one = (type(status) is int and type(eps) is float and type(L) is float
                     and type(K) is float and type(N) is float)
        if self._one:
            # One point (solve_point): numpy float64 scalars, whose arithmetic is that of 0-d
            # arrays to the bit (and on division by zero), at a fraction of their cost.
            self.status = status
            self.eps, self.L, self.K, self.N = (np.float64(v) for v in (eps, L, K, N))
            self.shape = ()
            return
        self.status = np.asarray(status)
        self.eps, self.L, self.K, self.N = (np.asarray(v, dtype=np.float64) for v in (eps, L, K, N))
        self.shape = np.broadcast_shapes(self.status.shape, self.eps.shape, self.L.shape,
                                         self.K.shape, self.N.shape)

    def raw(self, name: str) -> np.ndarray:
        """A raw solver value, NaN where the status is not ``ok`` (as ``solve_point`` reports)."""
        value = self._raw[name]
        if value is None:
            raise ValueError(f"output needs the solver value {name!r}, which was not computed")
        if self._one:
            return np.float64(value if self.ok else math.nan)
        return np.where(self.ok, value, np.nan)

    def get(self, name: str) -> np.ndarray:
        """Output ``name`` (computed once, then reused by the outputs derived from it)."""
        if name not in self._values:
            self._values[name] = OUTPUTS[name].compute(self)
        return self._values[name]

    @_cached
    def ok(self) -> np.ndarray:
        return self.status == st.OK

    @_cached
    def eps_K(self) -> np.ndarray:
        return self.eps * self.K

    @_cached
    def one_minus(self) -> np.ndarray:
        value = self._raw["one_minus"]
        if value is None:
            raise ValueError("output needs the plug edge 1 - xi_p, which was not computed")
        return np.float64(value) if self._one else np.asarray(value, dtype=np.float64)

    # The material's quantities depend on (eps, N) only: eq:35 is solved once per pair.
    @_cached
    def tan_delta(self) -> np.ndarray:
        return math.sin(math.radians(self.material["phi"])) / self.N

    @_cached
    def rho_g_W(self) -> np.ndarray:
        mat = self.material
        return mat["rho_p"] * mat["g"] * (mat["d_p"] / self.eps)

    @_cached
    def nu(self) -> np.ndarray:
        rho_g_W, tan_delta = np.broadcast_arrays(self.rho_g_W, self.tan_delta)
        nu = np.empty(rho_g_W.shape)
        for i in np.ndindex(nu.shape):
            nu[i] = closure.solids_fraction(float(rho_g_W[i]), float(tan_delta[i]), self.material)
        return nu

    @_cached
    def stress_scale_Pa(self) -> np.ndarray:
        """``rho_p g W nu``: a scaled stress times this is in Pa."""
        return self.rho_g_W * self.nu


def _xi_stop(x: Inputs):
    value = x._raw["xi_stop"]
    if x._one:
        return np.float64(value if x.status == st.EPS_TOO_LARGE_PATH else math.nan)
    return np.where(x.status == st.EPS_TOO_LARGE_PATH, value, np.nan)


# The scales of the paper's dimensionless stresses (eq:54's bars), divided by nu as the outputs
# are: a value times the factor is in SI units.
SCALES = {
    "stress": Scale(r"$\rho_p g W$", "Pa", lambda x: x.stress_scale_Pa),
    "couple": Scale(r"$\rho_p g W d_p$", "Pa m", lambda x: x.stress_scale_Pa * x.material["d_p"]),
}

# Table order is the order of the command line's table, of a sweep's default variables and of the
# variables in a file.
OUTPUTS: dict[str, Output] = {o.name: o for o in (
    Output("Delta", "1", "shear-layer thickness", lambda x: x.one_minus / x.eps, plug_edge=True,
           symbol=r"$\Delta$", unit_label="particle diameters",
           description="shear-layer thickness (1 - xi_p)/eps, in particle diameters",
           differentiable=True),
    Output("xi_p", "1", "plug edge", lambda x: 1.0 - x.one_minus, plug_edge=True,
           symbol=r"$\xi_p$", description="plug edge, u(xi_p) = 0.95 u(0) (eq:13)",
           differentiable=True),
    Output("slip", "1", "wall slip", lambda x: x.eps_K / x.get("u_axis"),
           symbol="$u(1)/u(0)$", description="wall slip u(1)/u(0)", differentiable=True),
    Output("u_axis", "1", "centre-line velocity", lambda x: x.eps_K + x.raw("J_axis"),
           symbol=r"$u(0)/\bar\omega_w$", description="centre-line velocity u(0)/omega_w",
           differentiable=True),
    Output("m_wall", "1", "wall couple stress", lambda x: x.L * x.raw("mu_wall"),
           stage=STAGE_STRESS, symbol=r"$\bar m(1)/\nu$", unit_label=r"$\rho_p g W d_p$",
           scale="couple", description="wall couple stress m(1)/nu (rho_p g W d_p units)",
           differentiable=True),
    Output("sigma_yx_wall", "1", "wall shear stress, yx", lambda x: x.raw("sigma_yx_wall"),
           stage=STAGE_STRESS, symbol=r"$\bar\sigma_{yx}(1)/\nu$", unit_label=r"$\rho_p g W$",
           scale="stress", description="wall shear stress sigma_yx(1)/nu (rho_p g W units)",
           differentiable=True),
    Output("xi_stop", "1", "end of the stress path", _xi_stop, stage=STAGE_STRESS,
           valued_when_ok=False,
           symbol=r"$\xi_{\mathrm{stop}}$", description="where the stress path met D = 0"),
    Output("nu", "1", "solids fraction", lambda x: x.nu, stage=STAGE_NONE, material=True,
           symbol=r"$\nu$", description="solids fraction (eq:35)", differentiable=True),
    Output("sigma_xx_wall_Pa", "Pa", "wall normal stress",
           lambda x: x.stress_scale_Pa / x.tan_delta, stage=STAGE_NONE, material=True,
           symbol=r"$\sigma_{xx}(1)$",
           description="wall normal stress sigma_xx, compressive positive", differentiable=True),
    Output("sigma_xy_wall_Pa", "Pa", "wall shear stress, xy",
           lambda x: -x.stress_scale_Pa, stage=STAGE_NONE, material=True,
           symbol=r"$\sigma_{xy}(1)$", description="wall shear stress sigma_xy", differentiable=True),
    Output("sigma_yx_wall_Pa", "Pa", "wall shear stress, yx",
           lambda x: np.where(x.ok, SCALES["stress"].factor(x) * x.get("sigma_yx_wall"), np.nan),
           stage=STAGE_STRESS, material=True, symbol=r"$\sigma_{yx}(1)$",
           description="wall shear stress sigma_yx", differentiable=True),
    Output("m_wall_Pa_m", "Pa m", "wall couple stress",
           lambda x: np.where(x.ok, SCALES["couple"].factor(x) * x.get("m_wall"), np.nan),
           stage=STAGE_STRESS, material=True, symbol="$m(1)$", description="wall couple stress m",
           differentiable=True),
)}

# Per-point work counters, stored in a sweep only on request.
COUNTERS: dict[str, Counter] = {c.name: c for c in (
    Counter("stage1_steps", "1", "stage-1 steps", stage=STAGE_STRESS,
            description="accepted steps of the stage-1 integration (0 where none ran)"),
    Counter("stage2_steps", "1", "stage-2 panels", stage=STAGE_VELOCITY,
            description="accepted panels of the stage-2 quadrature (0 where none ran)"),
)}

# The profile coordinate.
XI = Quantity("xi", "1", "cross-channel position", symbol=r"$\xi = x/W$", axis="X",
              description="distance from the centre line / channel half-width")

# Profiles over xi: those of solve_point's ``profile``. A sweep with ``profile_points`` writes
# all but sigma_xy, which is -xi everywhere.
PROFILES: dict[str, Quantity] = {q.name: q for q in (
    Quantity("u_over_u0", "1", "velocity", symbol="$u/u(0)$",
             description="velocity profile u(xi)/u(0)"),
    Quantity("omega_hat", "1", "angular velocity", symbol=r"$\hat\omega=\bar\omega/\bar\omega_w$",
             description="spin profile omega(xi)/omega_w"),
    Quantity("m", "1", "couple stress", symbol=r"$\bar m/\nu$", unit_label=r"$\rho_p g W d_p$",
             scale="couple", description="couple-stress profile m(xi)/nu (rho_p g W d_p units)"),
    Quantity("sigma_xy", "1", "shear stress, xy", symbol=r"$\bar\sigma_{xy}/\nu$",
             unit_label=r"$\rho_p g W$", scale="stress",
             description="shear-stress profile sigma_xy(xi)/nu = -xi (rho_p g W units)"),
    Quantity("sigma_yx", "1", "shear stress, yx", symbol=r"$\bar\sigma_{yx}/\nu$",
             unit_label=r"$\rho_p g W$", scale="stress",
             description="shear-stress profile sigma_yx(xi)/nu (rho_p g W units)"),
)}


def definition(name: str):
    """The definition behind a variable name, with its ``long_name``, ``symbol``, ``units``,
    ``label`` ...: an output, profile, counter, parameter, material input or ``xi``; None for
    any other name. Looked up at each call, so an output registered at run time is found."""
    for table in (OUTPUTS, PROFILES, COUNTERS, PARAMETERS, MATERIAL):
        if name in table:
            return table[name]
    return XI if name == XI.name else None


def derive_profiles(J, omega_hat, delta, sigma_yx, J_axis, eps_K, L, N) -> dict:
    """The profiles of :data:`PROFILES` from the kernel's rows, broadcast like :func:`derive`.

    ``J``, ``omega_hat``, ``delta`` and ``sigma_yx`` are the kernel's profile rows over ``xi``
    (``J = u/omega_w - eps K``, ``delta = (m/nu + N L)/L``); ``J_axis`` is ``J(0)``. One point and
    a whole grid run the same operations, so they agree to the last bit.
    """
    return {
        "u_over_u0": (eps_K + J) / (eps_K + J_axis),
        "omega_hat": omega_hat,
        "m": L * (delta - N),
        "sigma_yx": sigma_yx,
    }


def register(output: Output) -> None:
    """Add an output (or replace one of the same name) for every caller from now on."""
    OUTPUTS[output.name] = output


@contextlib.contextmanager
def registered(output: Output):
    """Register ``output`` for the duration of a ``with`` block (tests, experiments)."""
    previous = OUTPUTS.get(output.name)
    register(output)
    try:
        yield output
    finally:
        if previous is None:
            OUTPUTS.pop(output.name, None)
        else:
            OUTPUTS[output.name] = previous


def material_outputs() -> tuple[str, ...]:
    """Names of the outputs that need a material."""
    return tuple(name for name, o in OUTPUTS.items() if o.material)


def needs_plug_edge(names) -> bool:
    """Whether any of ``names`` needs the plug-edge root ``1 - xi_p``."""
    return any(OUTPUTS[n].plug_edge for n in names if n in OUTPUTS)


def needs_stage2(names) -> bool:
    """Whether any of ``names`` (outputs or counters) needs the velocity stage."""
    stages = [OUTPUTS[n].stage for n in names if n in OUTPUTS]
    stages += [COUNTERS[n].stage for n in names if n in COUNTERS]
    return needs_plug_edge(names) or any(s >= STAGE_VELOCITY for s in stages)


def derive(names, inputs: Inputs) -> dict[str, np.ndarray]:
    """The outputs ``names`` from ``inputs``, each broadcast to the inputs' full shape."""
    if inputs._one:  # one point: its values as computed, numpy scalars
        return {name: inputs.get(name) for name in names}
    return {name: np.broadcast_to(inputs.get(name), inputs.shape).copy() for name in names}
