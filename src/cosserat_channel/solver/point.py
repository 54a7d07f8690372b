"""One point from Python: :func:`solve_point` and its :class:`PointResult`.

The kernels live in :mod:`.batch` and the stage modules beside it, the outputs' definitions in
:mod:`cosserat_channel.outputs`, the parameters' ranges in :mod:`cosserat_channel.parameters`; this
module checks the input, runs the kernels for one point and hands the raw values to
:func:`outputs.derive`, the same function a sweep's Dataset is built with.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np

from .. import outputs as out_
from .. import status as st
from ..integrate import stepping
from . import ahead, batch, layout, plug_edge
from .batch import Workspace
from ..parameters import (
    DEFAULT_ATOL,
    DEFAULT_RTOL,
    ParameterError,
    check_material,
    check_point,
    check_tolerances,
)

__all__ = ["PointResult", "Workspace", "solve_point"]


@dataclass
class PointResult:
    """Everything one point yields. Dimensionless values follow ``docs/model.md``'s scalings.

    Every output of :data:`cosserat_channel.outputs.OUTPUTS` is an attribute (NaN where the point
    has none): among them

    Attributes
    ----------
    status : Status
        Why the point has or has no solution; ``status.message`` explains.
    Delta : float
        Shear-layer thickness ``(1 - xi_p)/eps`` in particle diameters (0 when the wall moves at
        >= 95 % of the centre).
    xi_p : float
        Plug edge, ``u(xi_p) = 0.95 u(0)`` (eq:13).
    slip : float
        ``u(1)/u(0)``.
    u_axis : float
        ``u(0)/omega_w`` (dimensionless, ``eps K + J(0)``).
    m_wall, sigma_yx_wall : float
        ``m(1)/nu`` and ``sigma_yx(1)/nu`` (paper's scalings of eq:54 and eq:56 divided by nu).
    xi_stop : float
        Where the stress path met ``D = 0`` (status ``eps_too_large_path``), NaN otherwise.
    nu : float
        Solids fraction from eq:35 (only with a material).
    sigma_xx_wall_Pa, sigma_xy_wall_Pa, sigma_yx_wall_Pa : float
        Wall stresses in Pa, compressive positive as in the paper (only with a material):
        normal ``sigma_c(nu)``, shear ``-rho_p g W nu`` and ``rho_p g W nu sigma_yx_wall``.
    m_wall_Pa_m : float
        Wall couple stress in Pa m (N/m) (only with a material).
    values : dict
        The computed outputs by name (the attributes above read from here).
    counters : dict
        Accepted/rejected steps and right-hand-side evaluations of both stages, and whether the
        stage-1 stiffness detector fired.
    profile : dict or None
        With ``profile=xi``: arrays ``xi``, ``u_over_u0``, ``omega_hat``, ``m`` (``m/nu``),
        ``sigma_xy``, ``sigma_yx`` (over nu).
    sensitivities : dict or None
        With ``sensitivities=True``: ``{output: {parameter: d output / d parameter}}``.
    sensitivity_flags : dict or None
        With ``sensitivities=True``: ``{output: {parameter: flag}}``, how each derivative was
        computed or why it is NaN: ``adjoint`` (the adjoint quadrature, or the closed form),
        ``differences`` (central differences of tighter solves, where the quadrature missed the
        tolerance), ``unresolved``, ``no_solution`` or ``undefined`` (by A at A = -1).
    profile_sensitivities : dict or None
        With ``profile=xi`` and ``sensitivities=True``: ``{profile: {parameter: ndarray}}`` for
        ``u_over_u0``, ``omega_hat``, ``m`` and ``sigma_yx`` at ``xi``, by ``eps, L, K, A, N``
        (NaN where the point has no solution).
    """

    eps: float
    L: float
    K: float
    A: float
    N: float
    status: st.Status
    values: dict = field(default_factory=dict)
    counters: dict = field(default_factory=dict)
    profile: dict | None = None
    sensitivities: dict | None = None
    sensitivity_flags: dict | None = None
    profile_sensitivities: dict | None = None

    def __getattr__(self, name):
        # Only reached when normal lookup fails: the outputs of the registry, NaN when not computed.
        if name in out_.OUTPUTS:
            return self.__dict__.get("values", {}).get(name, math.nan)
        raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")

    @property
    def computed(self) -> tuple[str, ...]:
        """Names of the outputs that were computed (``solve_point(outputs=...)``); others read NaN."""
        return tuple(self.values)

    @property
    def ok(self) -> bool:
        return self.status == st.Status.ok

    def to_dict(self) -> dict:
        """A JSON-ready dict: parameters, status by name and message, outputs (NaN as None)."""

        def clean(x):
            return None if x is None or (isinstance(x, float) and not math.isfinite(x)) else x

        d = {"eps": self.eps, "L": self.L, "K": self.K, "A": self.A, "N": self.N}
        d["status"] = self.status.name
        d["message"] = self.status.message
        for k in out_.OUTPUTS:  # every output, null where none or not computed
            d[k] = clean(float(getattr(self, k)))
        d["computed"] = list(self.values)
        d["counters"] = dict(self.counters)
        if self.profile is not None:
            d["profile"] = {k: [clean(float(v)) for v in a] for k, a in self.profile.items()}
        if self.sensitivities is not None:
            d["sensitivities"] = {k: {p: clean(v) for p, v in s.items()}
                                  for k, s in self.sensitivities.items()}
            d["sensitivity_flags"] = self.sensitivity_flags
        if self.profile_sensitivities is not None:
            d["profile_sensitivities"] = {
                k: {p: [clean(float(v)) for v in a] for p, a in s.items()}
                for k, s in self.profile_sensitivities.items()}
        return d


def _check_profile(profile) -> np.ndarray:
    try:
        xi = np.atleast_1d(np.asarray(profile))
        ok = xi.ndim == 1 and xi.dtype.kind in "iuf"
        xi = xi.astype(np.float64) if ok else xi
    except (TypeError, ValueError, OverflowError):
        ok = False
    if not ok or not np.all(np.isfinite(xi)) or np.any((xi < 0) | (xi > 1)):
        raise ParameterError("profile must be xi values in [0, 1]")
    return xi


def _check_outputs(names, material) -> list[str]:
    """The outputs to compute: all (with a material, the material's too) or the names given."""
    if names is None:
        return [n for n, o in out_.OUTPUTS.items() if material is not None or not o.material]
    if isinstance(names, str):
        names = [names]
    try:
        names = list(dict.fromkeys(names))
    except TypeError:
        raise ParameterError("outputs must be a list of output names") from None
    for name in names:
        if name not in out_.OUTPUTS:
            raise ParameterError(f"outputs: unknown output {name!r}; valid: {', '.join(out_.OUTPUTS)}")
        if out_.OUTPUTS[name].material and material is None:
            raise ParameterError(f"outputs: {name!r} needs a material (d_p, rho_p, phi)")
    return names


_DEFAULT_PLANS: dict = {}


def _plan_outputs(names, material):
    """``(outputs to compute, whether they need the plug edge, whether stage 2)``; the default
    set's answer is kept per state of the registry (rebuilding it was a tenth of a call)."""
    key = None
    if names is None:
        key = (material is None, tuple(map(id, out_.OUTPUTS.values())))
        if key in _DEFAULT_PLANS:
            return _DEFAULT_PLANS[key]
    names = _check_outputs(names, material)
    plan = names, out_.needs_plug_edge(names), out_.needs_stage2(names)
    if key is not None:
        if len(_DEFAULT_PLANS) > 8:  # the registry keeps changing (tests): keep it small
            _DEFAULT_PLANS.clear()
        _DEFAULT_PLANS[key] = plan
    return plan


def solve_point(eps, L, K, A, N, *, rtol=DEFAULT_RTOL, atol=DEFAULT_ATOL, material=None, profile=None,
                outputs=None, workspace: Workspace | None = None,
                sensitivities: bool = False) -> PointResult:
    """Solve one point ``(eps, L, K, A, N)`` of the channel-flow model through both stages.

    Parameters
    ----------
    eps, L, K, A, N : float
        The model's parameters (``docs/model.md``): ``eps = d_p/W`` in (0, 1], ``L > 0``,
        ``K >= 0``, ``A`` real, ``N > 0``.
    rtol, atol : float
        Tolerances of both integrations (mixed relative/absolute error per step).
    material : mapping, optional
        ``d_p`` (m), ``rho_p`` (kg/m^3), ``phi`` (degrees), optionally ``g``, ``Lambda`` (Pa),
        ``nu_min``, ``nu_max``, ``p``, ``q``. Adds ``nu`` and the dimensional wall stresses.
    profile : array_like, optional
        ``xi`` values in [0, 1] at which to return u/u(0), omega_hat, m, sigma_xy and sigma_yx.
    outputs : list of str, optional
        Compute only these outputs (names of :data:`cosserat_channel.outputs.OUTPUTS`); the others
        read NaN and :attr:`PointResult.computed` lists what was computed. Asking only for
        stage-1 outputs (``m_wall``, ``sigma_yx_wall``, ``xi_stop``, the material's) skips the
        velocity stage wherever it cannot change the status, and without ``Delta`` or ``xi_p``
        no plug-edge root is searched. The status is always computed.
    workspace : Workspace, optional
        Work arrays to reuse across calls (saves their allocation).
    sensitivities : bool, optional
        Also the derivatives of the computed outputs (``Delta``, ``xi_p``, ``slip``, ``u_axis``,
        ``m_wall``, ``sigma_yx_wall`` and, with a material, ``nu`` and the stresses in Pa) with
        respect to ``eps, L, K, A, N`` and, for the material's outputs, to each material input
        (``phi`` per degree), in :attr:`PointResult.sensitivities` as ``{output: {parameter:
        derivative}}``; NaN where the point has no solution. Computed by adjoint quadratures
        over the solution (docs/model.md, section 10) to about the accuracy of the solve; at
        ``A = -1`` from the closed form, with NaN for ``A`` (that form holds at ``A = -1``
        alone). Where the quadrature cannot reach the tolerance, by central differences of
        tighter solves, or NaN; :attr:`PointResult.sensitivity_flags` says which. The status
        is the solve's, with or without derivatives. Where ``eq:13``'s target is not positive
        (``Delta = 0``) the plug edge's derivatives are 0. With ``profile`` also the profiles' derivatives, in
        :attr:`PointResult.profile_sensitivities`. Off by default: the first call compiles its
        kernels.

    Returns
    -------
    PointResult
        Never raises for a point the model has no solution at: the status says why.

    Raises
    ------
    ParameterError
        (a ``ValueError``) for input outside the domain, naming the parameter and its range.

    Examples
    --------
    >>> r = solve_point(1/30, 10, 0.5, 1/3, 1)
    >>> r.status.name, round(r.Delta, 2)
    ('ok', 10.25)
    """
    eps, L, K, A, N = check_point(eps, L, K, A, N)
    rtol, atol = check_tolerances(rtol, atol)
    mat = check_material(material)
    xi_prof = None if profile is None else _check_profile(profile)
    names, wants_plug_edge, wants_stage2 = _plan_outputs(outputs, mat)
    ws = workspace or _thread_workspace()
    # On an empty kernel cache, a child process compiles these parts meanwhile.
    ahead.start(("stage2",) + ("plug_edge",) * wants_plug_edge + ("profile",) * (xi_prof is not None))
    eta = eps * L
    code = ws.run(eta, A, N, rtol, atol, layout.METHOD_AUTO,
                  xi_prof is not None or wants_stage2 or sensitivities)
    res = ws.res
    one_minus = math.nan
    if code == st.OK and wants_plug_edge:
        one_minus = float(plug_edge.one_minus_xi_p(eps * K, res, ws.ax, ws.T2, ws.Q2))
    inputs = out_.Inputs(
        code, eps, L, K, N, J_axis=res[layout.R_J_AXIS], mu_wall=res[layout.R_MU_WALL],
        sigma_yx_wall=res[layout.R_SIGMA_YX_WALL], xi_stop=res[layout.R_XI_STOP],
        one_minus=one_minus, material=mat,
    )
    values = {k: float(v) for k, v in out_.derive(names, inputs).items()}
    result = PointResult(eps=eps, L=L, K=K, A=A, N=N, status=st.Status(code), values=values)
    result.counters = _counters(ws)
    if code == st.OK and xi_prof is not None:
        result.profile = _profile(xi_prof, eps, L, K, A, N, ws)
    if sensitivities:
        from . import sensitivity  # its kernels compile only when asked for

        (result.sensitivities, result.sensitivity_flags,
         result.profile_sensitivities) = sensitivity.point_sensitivities(
            code, eps, L, K, A, N, rtol, atol, ws, one_minus, values, mat,
            None if xi_prof is None else (result.profile or {"xi": xi_prof}))
    return result


_LOCAL = threading.local()


def _thread_workspace() -> Workspace:
    """This thread's default workspace: every call fills what it reads, so one serves all calls
    of a thread (allocating one per call cost a fifth of a call)."""
    ws = getattr(_LOCAL, "workspace", None)
    if ws is None:
        ws = _LOCAL.workspace = Workspace()
    return ws


def _counters(ws: Workspace) -> dict:
    s1, s2 = ws.stats1.tolist(), ws.stats2.tolist()
    return {
        "stage1_accepted": int(s1[stepping.STAT_ACCEPTED]),
        "stage1_rejected": int(s1[stepping.STAT_REJECTED]),
        "stage1_fev": int(s1[stepping.STAT_FEV]),
        "stage1_stiff": bool(s1[stepping.STAT_STIFF]),
        "stage1_path": layout.PATH_NAMES.get(float(ws.res[layout.R_PATH]), "none"),
        "stage2_accepted": int(s2[stepping.STAT_ACCEPTED]),
        "stage2_rejected": int(s2[stepping.STAT_REJECTED]),
        "stage2_fev": int(s2[stepping.STAT_FEV]),
    }


def _profile(xi, eps, L, K, A, N, ws: Workspace) -> dict:
    eta = eps * L
    eps_K = eps * K
    prof = np.empty((layout.N_PROF, xi.size))
    batch.profile_kernel(xi, eta, A, N, ws.ax, ws.res, ws.T1, ws.Q1, ws.T2, ws.Q2, prof)
    derived = out_.derive_profiles(prof[layout.P_J], prof[layout.P_OMEGA_HAT], prof[layout.P_DELTA],
                                   prof[layout.P_SIGMA_YX], ws.res[layout.R_J_AXIS], eps_K, L, N)
    return {"xi": xi.copy(), **derived, "sigma_xy": -xi}
