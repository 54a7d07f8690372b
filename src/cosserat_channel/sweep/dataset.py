"""Solved triples -> the labelled grid: an :class:`xarray.Dataset` over ``(eps, L, K, A, N)``.

Every value is computed with the same floating-point operations, in the same order, as
:func:`solve.solve_point` and :func:`solve._add_material` compute it for one point, so a sweep and
``solve_point`` agree to the last bit (the tests check this). Only the variables the sweep asks
for are computed; ``status`` is always there.
"""

from __future__ import annotations

import math
from datetime import datetime, timezone

import numpy as np
import xarray as xr

from .. import __version__, model
from .. import solve
from .. import status as st
from ..solve import MATERIAL_OUTPUTS, OUTPUTS
from .spec import DIMS

COORD_ATTRS = {
    "eps": "particle diameter / channel half-width, d_p/W",
    "L": "Cosserat length in particle diameters",
    "K": "wall roughness in u = eps K omega at the wall",
    "A": "yield-surface constant a2/a1",
    "N": "sin(phi)/tan(delta)",
}
COUNTERS = {
    "stage1_steps": ("1", "accepted steps of the stage-1 integration (0 where none ran)"),
    "stage2_steps": ("1", "accepted steps of the stage-2 integration (0 where none ran)"),
}
PROFILES = {
    "u_over_u0": ("1", "velocity profile u(xi)/u(0)"),
    "omega_hat": ("1", "spin profile omega(xi)/omega_w"),
    "m": ("1", "couple-stress profile m(xi)/nu (rho_p g W d_p units)"),
    "sigma_yx": ("1", "shear-stress profile sigma_yx(xi)/nu (rho_p g W units)"),
}
XI_LONG_NAME = "distance from the centre line / channel half-width"
# Variables that need the per-point eps K root search (1 - xi_p).
NEED_ONE_MINUS = {"Delta", "xi_p"}


def build_dataset(spec, plan, per_triple: dict, one_minus: np.ndarray | None, xi=None,
                  profiles: np.ndarray | None = None) -> xr.Dataset:
    """The result Dataset of ``spec``.

    Parameters
    ----------
    spec : SweepSpec
    plan : Plan
    per_triple : dict
        ``res`` (n_triples, N_R) and ``steps`` (n_triples, 2), gathered from all blocks.
    one_minus : ndarray or None
        ``1 - xi_p`` on the grid (C order), or None when no requested variable needs it.
    xi, profiles : ndarray, optional
        Profile abscissae and per-triple profiles (n_triples, N_PROF, xi.size).
    """
    res = per_triple["res"]
    want = set(spec.variables)
    status = plan.to_grid(res[:, solve.R_STATUS].astype(np.int8))
    ok = status == st.OK

    def grid(slot):
        # A per-triple slot on the grid, NaN where the point has no solution (as solve_point).
        return plan.to_grid(np.where(res[:, solve.R_STATUS] == st.OK, res[:, slot], np.nan))

    eps = spec.eps.reshape(-1, 1, 1, 1, 1)
    L = spec.L.reshape(1, -1, 1, 1, 1)
    K = spec.K.reshape(1, 1, -1, 1, 1)
    eps_K = eps * K  # the same product as solve_point's eps * K
    out: dict[str, np.ndarray] = {}

    if "Delta" in want:
        out["Delta"] = one_minus / eps
    if "xi_p" in want:
        out["xi_p"] = 1.0 - one_minus
    if want & {"u_axis", "slip"}:
        u_axis = eps_K + grid(solve.R_J_AXIS)
        if "u_axis" in want:
            out["u_axis"] = u_axis
        if "slip" in want:
            out["slip"] = eps_K / u_axis
            del u_axis
    m_wall = sigma_yx_wall = None
    if want & {"m_wall", "m_wall_Pa_m"}:
        m_wall = L * grid(solve.R_MU_WALL)
        if "m_wall" in want:
            out["m_wall"] = m_wall
    if want & {"sigma_yx_wall", "sigma_yx_wall_Pa"}:
        sigma_yx_wall = grid(solve.R_SIGMA_YX_WALL)
        if "sigma_yx_wall" in want:
            out["sigma_yx_wall"] = sigma_yx_wall
    if "xi_stop" in want:
        path = res[:, solve.R_STATUS] == st.EPS_TOO_LARGE_PATH
        out["xi_stop"] = plan.to_grid(np.where(path, res[:, solve.R_XI_STOP], np.nan))
    if spec.material is not None and want & set(MATERIAL_OUTPUTS):
        out.update(_material(spec, want, ok, m_wall, sigma_yx_wall))
    for name, col in (("stage1_steps", 0), ("stage2_steps", 1)):
        if name in want:
            out[name] = plan.to_grid(per_triple["steps"][:, col].astype(np.int32))

    data_vars = {}
    for name in spec.variables:  # file order = the sweep's order
        if name not in out:
            continue
        units, text = OUTPUTS.get(name) or COUNTERS[name]
        data_vars[name] = (DIMS, out[name], {"units": units, "long_name": text})
    data_vars["status"] = (DIMS, status, {**st.cf_flag_attrs(), "units": "1"})
    if profiles is not None:
        data_vars.update(_profiles(spec, plan, res, xi, profiles))
    coords = {d: (d, np.asarray(v, dtype=np.float64), {"units": "1", "long_name": COORD_ATTRS[d]})
              for d, v in spec.coords().items()}
    if xi is not None:
        coords["xi"] = ("xi", xi, {"units": "1", "long_name": XI_LONG_NAME})
    ds = xr.Dataset(data_vars, coords=coords, attrs=global_attrs(spec, plan.reduce))
    return ds


def _material(spec, want, ok, m_wall, sigma_yx_wall) -> dict:
    """nu (eq:35) per (eps, N) and the Pa values, exactly as solve._add_material computes them."""
    mat = spec.material
    nE, nN = spec.eps.size, spec.N.size
    nu = np.empty((nE, nN))
    rho_g_W = np.empty((nE, nN))
    tan_delta = np.empty((nE, nN))
    for i, eps in enumerate(spec.eps.tolist()):
        W = mat["d_p"] / eps
        for j, N in enumerate(spec.N.tolist()):
            td = math.sin(math.radians(mat["phi"])) / N
            rgw = mat["rho_p"] * mat["g"] * W
            nu[i, j] = model.solids_fraction(
                rgw, td, mat["Lambda"], mat["nu_min"], mat["nu_max"], mat["p"], mat["q"]
            )
            rho_g_W[i, j], tan_delta[i, j] = rgw, td
    shape = (nE, 1, 1, 1, nN)
    full = (nE, spec.L.size, spec.K.size, spec.A.size, nN)
    scale = (rho_g_W * nu).reshape(shape)
    out = {}
    if "nu" in want:
        out["nu"] = np.broadcast_to(nu.reshape(shape), full).copy()
    if "sigma_xx_wall_Pa" in want:
        out["sigma_xx_wall_Pa"] = np.broadcast_to(scale / tan_delta.reshape(shape), full).copy()
    if "sigma_xy_wall_Pa" in want:
        out["sigma_xy_wall_Pa"] = np.broadcast_to(-scale, full).copy()
    if "sigma_yx_wall_Pa" in want:
        out["sigma_yx_wall_Pa"] = np.where(ok, scale * sigma_yx_wall, np.nan)
    if "m_wall_Pa_m" in want:
        out["m_wall_Pa_m"] = np.where(ok, scale * mat["d_p"] * m_wall, np.nan)
    return out


def _profiles(spec, plan, res, xi, profiles) -> dict:
    """Profiles on (eps, L, K, A, N, xi), as solve._profile computes them for one point."""
    dims = DIMS + ("xi",)
    eps_K = (spec.eps.reshape(-1, 1, 1, 1, 1) * spec.K.reshape(1, 1, -1, 1, 1))[..., None]
    L = spec.L.reshape(1, -1, 1, 1, 1, 1)
    N = spec.N.reshape(1, 1, 1, 1, -1, 1)
    J = plan.to_grid(profiles[:, solve.P_J])
    J_axis = plan.to_grid(res[:, solve.R_J_AXIS])[..., None]
    out = {
        "u_over_u0": (eps_K + J) / (eps_K + J_axis),
        "omega_hat": plan.to_grid(profiles[:, solve.P_OMEGA_HAT]),
        "m": L * (plan.to_grid(profiles[:, solve.P_DELTA]) - N),
        "sigma_yx": plan.to_grid(profiles[:, solve.P_SIGMA_YX]),
    }
    return {k: (dims, v, dict(zip(("units", "long_name"), PROFILES[k]))) for k, v in out.items()}


def global_attrs(spec, reduced: bool) -> dict:
    """Provenance: what was solved, how, by which version, from which sweep file."""
    return {
        "title": "cosserat-channel sweep" + (f" {spec.source}" if spec.source else ""),
        "Conventions": "CF-1.8",
        "source": "cosserat-channel run",
        "cosserat_channel_version": __version__,
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "rtol": spec.rtol,
        "atol": spec.atol,
        "reduced": 1 if reduced else 0,
        "sweep_sha256": spec.sha256,
        "sweep_toml": spec.text,
    }


def encoding(ds: xr.Dataset, compress: bool = True) -> dict:
    """NetCDF encoding: no fill value on status and coordinates; zlib level 1 on large floats."""
    enc = {}
    for name, var in ds.variables.items():
        e = {}
        if name == "status" or name in ds.coords or var.dtype.kind in "iu":
            e["_FillValue"] = None
        if compress and var.dtype.kind in "fiu" and name not in ds.coords and var.size > 4096:
            chunks = _chunks(var.shape, var.dtype.itemsize)
            e.update(zlib=True, complevel=1, shuffle=True, chunksizes=chunks)
        enc[name] = e
    return enc


def _chunks(shape, itemsize, target=1 << 20) -> tuple:
    """Chunks of about ``target`` bytes in C order: whole trailing axes, a slab of the leading."""
    chunks = list(shape)
    n = itemsize
    for i in range(len(shape) - 1, -1, -1):
        if n * shape[i] > target:
            chunks[i] = max(1, target // n)
            for j in range(i):
                chunks[j] = 1
            break
        n *= shape[i]
    return tuple(int(c) for c in chunks)
