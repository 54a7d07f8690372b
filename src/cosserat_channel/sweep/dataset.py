"""Solved triples -> the labelled grid: an :class:`xarray.Dataset` over ``(eps, L, K, A, N)``.

Every output is derived by :func:`cosserat_channel.outputs.derive`, the function ``solve_point``
uses for one point, so a sweep and ``solve_point`` agree to the last bit (the tests check this).
Only the variables the sweep asks for are computed; ``status`` is always there.
"""

from __future__ import annotations

import math
from datetime import datetime, timezone

import numpy as np

from .. import __version__
from .. import netcdf_policy
from .. import outputs as out_
from ..solver import layout
from .. import status as st
from ..parameters import DIMS, PARAMETERS

# Uncompressed bytes of one chunk of a result variable: 1 MiB, the HDF5 chunk cache's default
# size, so one chunk is decompressed once per read however the read crosses it.
CHUNK_BYTES = 1 << 20

def build_dataset(spec, plan, per_triple: dict, one_minus: np.ndarray | None, xi=None,
                  profiles: np.ndarray | None = None):
    """The result Dataset of ``spec``, whole, in memory.

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
    # xarray is imported here, not by the module: the process that writes a file tile by tile
    # (a cluster's client) never needs it.
    import xarray as xr

    from ..results import accessor  # noqa: F401 (registers ds.cosserat on every result Dataset)

    data_vars = grid_values(spec, plan, per_triple, one_minus, xi, profiles)
    return xr.Dataset(data_vars, coords=coordinates(spec, xi),
                      attrs=global_attrs(spec, plan.reduce))


def grid_values(spec, grid, per_triple: dict, one_minus: np.ndarray | None, xi=None,
                profiles: np.ndarray | None = None, spread: bool = True) -> dict:
    """``{name: (dims, values, attrs)}`` of every result variable on ``grid``.

    ``grid`` is the :class:`.plan.Plan` (the whole grid) or a :class:`.plan.Region` of it (one
    tile of a file written piece by piece); ``one_minus`` is then on that region. Every value is
    elementwise in the grid point, so a region's values are the whole grid's to the last bit.
    ``spread=False``: a variable that is constant along an axis (``m_wall`` and ``status`` along
    ``K``) is a read-only broadcast view of its values, not a copy on the whole grid.
    """
    res = per_triple["res"]
    # Per-triple values enter without their K axis (to_grid's spread=False): an output that needs
    # no eps K (m_wall, the stresses, ...) is computed once per (eps, L, A, N), and derive's final
    # broadcast spreads it. Elementwise either way: the same bits.
    status = grid.to_grid(res[:, layout.R_STATUS], spread=False).astype(np.int8)
    inputs = out_.Inputs(
        status,
        grid.eps.reshape(-1, 1, 1, 1, 1), grid.L.reshape(1, -1, 1, 1, 1),
        grid.K.reshape(1, 1, -1, 1, 1), grid.N.reshape(1, 1, 1, 1, -1),
        J_axis=grid.to_grid(res[:, layout.R_J_AXIS], spread=False),
        mu_wall=grid.to_grid(res[:, layout.R_MU_WALL], spread=False),
        sigma_yx_wall=grid.to_grid(res[:, layout.R_SIGMA_YX_WALL], spread=False),
        xi_stop=grid.to_grid(res[:, layout.R_XI_STOP], spread=False),
        one_minus=one_minus, material=spec.material,
    )
    status = np.broadcast_to(status, inputs.shape)
    if spread:
        status = status.copy()
    data_vars = {}
    for name in spec.variables:  # file order = the sweep's order
        if name in out_.OUTPUTS:
            data_vars[name] = output_variable(inputs, name, DIMS, spread)
        elif name in out_.COUNTERS:
            c = out_.COUNTERS[name]
            # Constant along K where the status is (a broadcast view with spread=False).
            value = grid.to_grid(per_triple["steps"][:, c.stage - 1], spread=False)
            value = np.broadcast_to(value.astype(np.int32), inputs.shape)
            data_vars[name] = (DIMS, value.copy() if spread else value, c.attrs)
    data_vars["status"] = status_variable(status, DIMS)
    if profiles is not None:
        data_vars.update(_profiles(grid, res, profiles))
    return data_vars


def output_variable(inputs, name: str, dims, spread: bool = True) -> tuple:
    """``(dims, values, attrs)`` of output ``name`` on the whole shape of ``inputs`` (a broadcast
    view, with ``spread=False``, of values that are constant along an axis)."""
    # derive's values, without its copy of those already on the whole grid (a tile's Delta,
    # slip, ...: one pass over the tile fewer each).
    value = inputs.get(name)
    if value.shape != inputs.shape:
        value = (out_.derive([name], inputs)[name] if spread
                 else np.broadcast_to(value, inputs.shape))
    return (dims, value, out_.OUTPUTS[name].attrs)


def status_variable(status: np.ndarray, dims) -> tuple:
    """``(dims, status codes, CF flag attributes)`` of a result's ``status`` variable."""
    return (dims, status, {**st.cf_flag_attrs(), "units": "1"})


def coordinates(spec, xi=None) -> dict:
    """The coordinate variables of a result: the five axes (and ``xi`` with profiles)."""
    coords = {d: (d, np.asarray(v, dtype=np.float64), PARAMETERS[d].attrs)
              for d, v in spec.coords().items()}
    if xi is not None:
        coords["xi"] = ("xi", xi, out_.XI.attrs)
    return coords


def _profiles(grid, res, profiles) -> dict:
    """Profiles on (eps, L, K, A, N, xi): :func:`outputs.derive_profiles` on the grid."""
    dims = DIMS + ("xi",)
    eps_K = (grid.eps.reshape(-1, 1, 1, 1, 1) * grid.K.reshape(1, 1, -1, 1, 1))[..., None]
    L = grid.L.reshape(1, -1, 1, 1, 1, 1)
    N = grid.N.reshape(1, 1, 1, 1, -1, 1)
    row = {name: grid.to_grid(profiles[:, slot]) for name, slot in
           (("J", layout.P_J), ("omega_hat", layout.P_OMEGA_HAT), ("delta", layout.P_DELTA),
            ("sigma_yx", layout.P_SIGMA_YX))}
    out = out_.derive_profiles(**row, J_axis=grid.to_grid(res[:, layout.R_J_AXIS])[..., None],
                               eps_K=eps_K, L=L, N=N)
    return {k: (dims, v, out_.PROFILES[k].attrs) for k, v in out.items()}


def global_attrs(spec, reduced: bool) -> dict:
    """Provenance: what was solved, how, by which version, from which sweep file."""
    title = "cosserat-channel sweep" + (f" {spec.source}" if spec.source else "")
    return {
        **provenance(title, "cosserat-channel run", spec.rtol, spec.atol, reduced),
        "sweep_sha256": spec.sha256,
        "sweep_toml": spec.text,
    }


def provenance(title: str, source: str, rtol: float, atol: float, reduced: bool) -> dict:
    """The attributes every result carries: what made it, with which version and tolerances."""
    return {
        "title": title,
        "Conventions": st.CONVENTIONS,
        "source": source,
        "cosserat_channel_version": __version__,
        "created": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "rtol": rtol,
        "atol": atol,
        "reduced": 1 if reduced else 0,
    }


def variable_encoding(name: str, shape: tuple, dtype, is_coord: bool, compress=True) -> dict:
    """NetCDF encoding of one variable of a result: the package's policy
    (:func:`cosserat_channel.netcdf_policy.variable_encoding`: codec, checksum, fill value) in
    chunks shaped for the reads people do (:func:`chunk_shape`).

    ``name`` is the variable's (kept for the callers' symmetry with ``to_netcdf``'s encoding).
    """
    # Grid variables of every type share the float64 chunks: the file is written in tiles of
    # whole float64 chunks (.writer.Tiles), and a chunk that straddles tiles would be compressed
    # again (and read back) each time a tile reaches it.
    itemsize = 8 if len(shape) == len(DIMS) else np.dtype(dtype).itemsize
    return netcdf_policy.variable_encoding(shape, dtype, coordinate=is_coord, compress=compress,
                                           chunks=chunk_shape(shape, itemsize))


def chunk_shape(shape, itemsize, target=CHUNK_BYTES) -> tuple:
    """Chunks of about ``target`` bytes with about as many chunks along every axis.

    The reads people do are a 2-D slice (``A`` x ``N`` at fixed ``eps, L, K``) and a curve along
    one axis; with ``m`` chunks per axis either touches about ``m**2`` or ``m`` chunks whatever
    the axes, where C-order slabs make the read across the leading axis touch every slab.
    ``m`` is the smallest count that keeps a chunk within ``target``.
    """
    shape = tuple(max(1, int(n)) for n in shape)
    limit = max(1, target // itemsize)

    def chunks(m):
        return tuple(-(-n // m) for n in shape)

    lo, hi = 1, max(shape, default=1)  # the chunk count shrinks as m grows: bisect
    while lo < hi:
        mid = (lo + hi) // 2
        if math.prod(chunks(mid)) <= limit:
            hi = mid
        else:
            lo = mid + 1
    return chunks(lo)
