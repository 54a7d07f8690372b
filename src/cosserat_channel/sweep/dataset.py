"""Solved triples -> the labelled grid: an :class:`xarray.Dataset` over ``(eps, L, K, A, N)``.

Every output is derived by :func:`cosserat_channel.outputs.derive`, the function ``solve_point``
uses for one point, so a sweep and ``solve_point`` agree to the last bit (the tests check this).
Only the variables the sweep asks for are computed; ``status`` is always there.
"""

from __future__ import annotations

from datetime import datetime, timezone

import numpy as np
import xarray as xr

from .. import __version__
from .. import outputs as out_
from .. import stages
from .. import status as st
from ..parameters import DIMS, PARAMETERS

XI_LONG_NAME = "distance from the centre line / channel half-width"


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
    status = plan.to_grid(res[:, stages.R_STATUS].astype(np.int8))
    inputs = out_.Inputs(
        status,
        spec.eps.reshape(-1, 1, 1, 1, 1), spec.L.reshape(1, -1, 1, 1, 1),
        spec.K.reshape(1, 1, -1, 1, 1), spec.N.reshape(1, 1, 1, 1, -1),
        J_axis=plan.to_grid(res[:, stages.R_J_AXIS]),
        mu_wall=plan.to_grid(res[:, stages.R_MU_WALL]),
        sigma_yx_wall=plan.to_grid(res[:, stages.R_SIGMA_YX_WALL]),
        xi_stop=plan.to_grid(res[:, stages.R_XI_STOP]),
        one_minus=one_minus, material=spec.material,
    )
    data_vars = {}
    for name in spec.variables:  # file order = the sweep's order
        if name in out_.OUTPUTS:
            o = out_.OUTPUTS[name]
            value = out_.derive([name], inputs)[name]
            data_vars[name] = (DIMS, value, {"units": o.units, "long_name": o.long_name})
        elif name in out_.COUNTERS:
            units, text, stage = out_.COUNTERS[name]
            value = plan.to_grid(per_triple["steps"][:, stage - 1].astype(np.int32))
            data_vars[name] = (DIMS, value, {"units": units, "long_name": text})
    data_vars["status"] = (DIMS, status, {**st.cf_flag_attrs(), "units": "1"})
    if profiles is not None:
        data_vars.update(_profiles(spec, plan, res, xi, profiles))
    coords = {d: (d, np.asarray(v, dtype=np.float64),
                  {"units": PARAMETERS[d].units, "long_name": PARAMETERS[d].long_name})
              for d, v in spec.coords().items()}
    if xi is not None:
        coords["xi"] = ("xi", xi, {"units": "1", "long_name": XI_LONG_NAME})
    return xr.Dataset(data_vars, coords=coords, attrs=global_attrs(spec, plan.reduce))


def _profiles(spec, plan, res, xi, profiles) -> dict:
    """Profiles on (eps, L, K, A, N, xi), as solve._profile computes them for one point."""
    dims = DIMS + ("xi",)
    eps_K = (spec.eps.reshape(-1, 1, 1, 1, 1) * spec.K.reshape(1, 1, -1, 1, 1))[..., None]
    L = spec.L.reshape(1, -1, 1, 1, 1, 1)
    N = spec.N.reshape(1, 1, 1, 1, -1, 1)
    J = plan.to_grid(profiles[:, stages.P_J])
    J_axis = plan.to_grid(res[:, stages.R_J_AXIS])[..., None]
    out = {
        "u_over_u0": (eps_K + J) / (eps_K + J_axis),
        "omega_hat": plan.to_grid(profiles[:, stages.P_OMEGA_HAT]),
        "m": L * (plan.to_grid(profiles[:, stages.P_DELTA]) - N),
        "sigma_yx": plan.to_grid(profiles[:, stages.P_SIGMA_YX]),
    }
    return {k: (dims, v, dict(zip(("units", "long_name"), out_.PROFILES[k]))) for k, v in out.items()}


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
    """NetCDF encoding: no fill value on status and coordinates; zlib level 1 on large floats;
    an HDF5 Fletcher-32 checksum on every array variable.

    With the checksum, a chunk damaged on disk fails to read (netCDF4 raises ``RuntimeError:
    NetCDF: HDF error``) instead of returning changed numbers. It needs chunked storage, which
    HDF5 picks for variables given no chunk sizes here.
    """
    enc = {}
    for name, var in ds.variables.items():
        e = {}
        if name == "status" or name in ds.coords or var.dtype.kind in "iu":
            e["_FillValue"] = None
        if compress and var.dtype.kind in "fiu" and name not in ds.coords and var.size > 4096:
            chunks = _chunks(var.shape, var.dtype.itemsize)
            e.update(zlib=True, complevel=1, shuffle=True, chunksizes=chunks)
        if var.ndim > 0 and var.dtype.kind in "fiub":
            e["fletcher32"] = True
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
