"""Many points from Python, in memory: :func:`solve` on numbers, numpy arrays or DataArrays.

The points are broadcast as numpy (or xarray, by dimension name) broadcasts them, and solved as
a sweep solves its grid: one integration per distinct ``(eps L, A, N)`` (model.md's similarity;
``eps`` and ``K`` enter afterwards through :func:`batch.solve_batch`'s ``eps K`` runs), the
triples dealt into blocks of equal expected cost (:func:`..sweep.plan.block_plan`) and the blocks
solved by :func:`..sweep.block.solve_block` on threads (the kernel releases the GIL). Outputs,
their attributes and the status variable come from :mod:`..sweep.dataset`'s builders, so the
values equal ``solve_point``'s and a sweep's to the last bit.
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import xarray as xr

from .. import outputs as out_
from ..parameters import (DEFAULT_ATOL, DEFAULT_RTOL, DIMS, ETA_MAX, ETA_MIN, PARAMETERS,
                          ParameterError, check_eta, check_material, check_tolerances,
                          check_values)
from ..solver import layout
from ..results import accessor  # noqa: F401 (registers ds.cosserat on the Datasets made here)
from ..solver.point import _check_outputs
from . import block as block_
from . import dataset
from .plan import BlockInputs, block_plan, triple_costs

__all__ = ["solve"]

# Triples per block: enough blocks for the threads to balance, each long enough that its work
# arrays and Python overhead (a few tens of microseconds) stay below a percent of its solves.
MIN_BLOCK_TRIPLES = 256
BLOCKS_PER_WORKER = 4
# Points one call solves in memory, checked from the shapes before anything is broadcast: each
# point holds its five inputs, eta, its status and its outputs (about 200 bytes with every
# output), so this is some 20 GB. A larger grid is a sweep (``run``), which writes in tiles.
MAX_SOLVE_POINTS = 100_000_000


def solve(eps, L, K, A, N, *, rtol=DEFAULT_RTOL, atol=DEFAULT_ATOL, material=None, outputs=None,
          workers=None, reduce=True, sensitivities=False) -> xr.Dataset:
    """Solve every point of the broadcast ``(eps, L, K, A, N)`` in memory; a labelled Dataset.

    Parameters
    ----------
    eps, L, K, A, N : float, array_like or xarray.DataArray
        The model's parameters (ranges as for :func:`.point.solve_point`). Numbers and numpy
        arrays broadcast as numpy broadcasts them (the result's dimensions are then ``dim_0``,
        ``dim_1`` ...); DataArrays broadcast by dimension name and must agree on the
        coordinates they share. Numbers mix with either; numpy arrays and DataArrays do not mix.
    rtol, atol : float
        Tolerances of both integrations.
    material : mapping, optional
        As for :func:`.point.solve_point`: adds ``nu`` and the stresses in Pa.
    outputs : list of str, optional
        Names of :data:`cosserat_channel.outputs.OUTPUTS` to compute (default: all, with the
        material's when one is given); what is not needed is not integrated.
    workers : int, optional
        Threads to solve on (default: every core).
    reduce : bool
        One integration per distinct ``(eps L, A, N)`` (True) or per point (False); the values
        are the same to the bit.
    sensitivities : bool
        Also ``d<output>_d<param>`` (``dDelta_deps`` ...) for every computed output that
        :func:`.point.solve_point` differentiates and each of ``eps, L, K, A, N``, equal to its
        ``sensitivities`` (NaN without a solution): one more solve per distinct ``(eps L, A, N)``
        and one sensitivity march per point, on this thread. ``sensitivity_flags`` (over the
        points and a ``derivative`` dimension naming them) says how each was computed or why
        it is NaN, as ``solve_point``'s ``sensitivity_flags``; the status is the solve's.

    Returns
    -------
    xarray.Dataset
        The outputs and ``status`` (CF flags) over the broadcast dimensions, with the
        parameters as coordinates, attributes as a sweep's result has them; ``attrs["n_solves"]``
        is the number of integrations run.

    Raises
    ------
    ParameterError
        For a value outside its parameter's range (the message names the first), arrays that
        cannot broadcast, or DataArrays with different coordinates on a shared dimension.

    Examples
    --------
    >>> import numpy as np
    >>> ds = solve(1/30, 10, np.array([0.5, 1.0]), 1/3, 1)
    >>> ds.status.values.tolist(), ds.Delta.dims
    ([0, 0], ('dim_0',))
    """
    rtol, atol = check_tolerances(rtol, atol)
    mat = check_material(material)
    names = _check_outputs(outputs, mat)
    workers = _check_workers(workers)
    dims, coords, values = _broadcast(dict(zip(DIMS, (eps, L, K, A, N))))
    shape = values["eps"].shape
    flat = {d: np.ascontiguousarray(v, dtype=np.float64).ravel() for d, v in values.items()}
    eta = flat["eps"] * flat["L"]  # the product solve_point and a sweep integrate: same bits
    bad = ~((eta >= ETA_MIN) & (eta <= ETA_MAX))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        check_eta(float(flat["eps"][i]), float(flat["L"][i]))
    need = (out_.needs_stage2(names), out_.needs_plug_edge(names))
    status, per_point, one_minus, n_solves = _solve_flat(flat, eta, rtol, atol, need, workers,
                                                         bool(reduce))
    inputs = out_.Inputs(status, flat["eps"], flat["L"], flat["K"], flat["N"],
                         one_minus=one_minus, material=mat, **per_point)
    data_vars = {}
    for name in names:
        d, value, attrs = dataset.output_variable(inputs, name, dims)
        data_vars[name] = (d, value.reshape(shape), attrs)
    if sensitivities:
        sens, labels = _sensitivities(flat, eta, names, mat, rtol, atol, shape, dims, status,
                                      one_minus, per_point)
        if labels:
            coords["derivative"] = ("derivative", labels,
                                    {"long_name": "derivative of sensitivity_flags"})
        data_vars.update(sens)
    data_vars["status"] = dataset.status_variable(status.reshape(shape), dims)
    attrs = dataset.provenance("cosserat-channel solve", "cosserat_channel.solve", rtol, atol,
                               bool(reduce))
    attrs["n_solves"] = n_solves
    return xr.Dataset(data_vars, coords=coords, attrs=attrs)


def _sensitivities(flat, eta, names, mat, rtol, atol, shape, dims, status, one_minus,
                   per_point):
    """``({d<output>_d<param>: (dims, values, attrs)}`` with ``sensitivity_flags``, their
    names)``:
    :func:`..solver.sensitivity.sensitivity_batch` on the distinct triples (one solve each, one
    sensitivity march per point), then :func:`..solver.sensitivity.assemble` on whole arrays,
    as for ``solve_point``. The status is the solve's."""
    from ..solver import sensitivity as sv
    from ..solver import stage1, stage2

    diff = sv.differentiable(names)
    n = eta.size
    order, starts = _triples(flat, eta, True)
    offsets = np.append(starts, n).astype(np.int64)
    first = order[starts]
    eps_K = (flat["eps"] * flat["K"])[order]
    out_sorted = np.empty((n, sv.N_S))
    sv.sensitivity_batch(eta[first], flat["A"][first], flat["N"][first], eps_K, offsets,
                         np.ascontiguousarray(one_minus[order]), rtol, atol,
                         stage1.MAX_STEPS_STAGE1, stage2.MAX_STEPS_STAGE2, out_sorted)
    out = np.empty_like(out_sorted)
    out[order] = out_sorted
    x = dict(flat, J0=per_point["J_axis"], mu=per_point["mu_wall"],
             sig=per_point["sigma_yx_wall"], one_minus=one_minus)
    result, flags = sv.assemble(diff, out, status, x, mat, rtol, atol)
    variables = {}
    labels = []
    for o in diff:
        for p in sv.PARAMETERS:
            units = out_.OUTPUTS[o].attrs.get("units", "1")
            p_units = PARAMETERS[p].attrs.get("units", "1")
            if p_units != "1":
                units = f"({units}) / ({p_units})"
            attrs = {"long_name": f"derivative of {out_.OUTPUTS[o].attrs.get('long_name', o)} "
                                  f"by {p}", "units": units}
            variables[f"d{o}_d{p}"] = (dims, result[o][p].reshape(shape), attrs)
            labels.append(f"d{o}_d{p}")
    if labels:  # one flag per derivative and point
        codes = np.stack([flags[o][p] for o in diff for p in sv.PARAMETERS], axis=-1)
        variables["sensitivity_flags"] = (
            dims + ("derivative",), codes.reshape(shape + (len(labels),)),
            {"long_name": "how each derivative was computed", "flag_values":
             np.arange(len(sv.FLAGS), dtype=np.int8), "flag_meanings": " ".join(sv.FLAGS)})
    return variables, labels


def _check_workers(workers) -> int:
    if workers is None:
        return os.cpu_count() or 1
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ParameterError(f"workers must be a positive integer; got {workers!r}")
    return int(workers)


def _checked(name: str, value):
    """``value`` as a float or a float64 array (a DataArray keeps its labels), each inside
    ``name``'s range; :class:`ParameterError` names the first value outside."""
    param = PARAMETERS[name]
    if isinstance(value, xr.DataArray):
        data = _checked(name, value.values)
        return value.copy(data=np.broadcast_to(data, value.shape))
    if np.ndim(value) == 0 and not isinstance(value, np.ndarray):
        return param.check(value)  # refuses booleans and strings, names the value
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be numbers in {param.interval} ({param.sentence})") \
            from None
    if arr.dtype.kind not in "iuf":
        raise ParameterError(f"{name} must be numbers in {param.interval} ({param.sentence}); "
                             f"got an array of {arr.dtype}")
    return check_values(name, arr)


def _check_size(shapes: dict, shape: tuple) -> None:
    """ParameterError (one line naming the parameters' shapes and the limit) when the broadcast
    ``shape`` holds more than :data:`MAX_SOLVE_POINTS` points; checked before it is made."""
    size = math.prod(shape)
    if size > MAX_SOLVE_POINTS:
        given = ", ".join(f"{d} {s}" for d, s in shapes.items() if len(s))
        raise ParameterError(f"eps, L, K, A, N broadcast to {size:,} points ({given}), beyond "
                             f"the {MAX_SOLVE_POINTS:,} one call solves in memory: solve fewer "
                             "at a time, or run them as a sweep (cosserat-channel run)")


def _broadcast(given: dict):
    """``(dims, coords, {name: broadcast values})`` of the five parameters."""
    checked = {d: _checked(d, v) for d, v in given.items()}
    labelled = [d for d, v in checked.items() if isinstance(v, xr.DataArray)]
    arrays = [d for d, v in checked.items() if isinstance(v, np.ndarray) and v.ndim > 0]
    if labelled and arrays:
        raise ParameterError(f"{arrays[0]} is a numpy array and {labelled[0]} a DataArray: give "
                             "every array parameter as a DataArray (with named dimensions) or "
                             "none")
    if labelled:
        try:
            aligned = xr.align(*(checked[d] for d in labelled), join="exact")
        except ValueError as exc:
            raise ParameterError("the DataArrays must have the same coordinates on the "
                                 f"dimensions they share: {str(exc).splitlines()[0]}") from None
        sizes: dict = {}
        for v in aligned:
            sizes.update(v.sizes)
        _check_size(dict(zip(labelled, (v.shape for v in aligned))), tuple(sizes.values()))
        with_labels = dict(zip(labelled, aligned))
        ref = xr.broadcast(*aligned)[0]
        dims = ref.dims
        coords = dict(ref.coords)
        values = {}
        for d, v in checked.items():
            if d in with_labels:
                values[d] = with_labels[d].broadcast_like(ref).transpose(*dims).values
            else:
                values[d] = np.full(ref.shape, v)
    else:
        shapes = {d: np.shape(v) for d, v in checked.items()}
        try:
            shape = np.broadcast_shapes(*shapes.values())
        except ValueError:
            shown = ", ".join(f"{d} {s}" for d, s in shapes.items())
            raise ParameterError(f"the parameters' shapes do not broadcast: {shown}") from None
        _check_size(shapes, shape)
        bcast = np.broadcast_arrays(*(np.asarray(v, dtype=np.float64)
                                      for v in checked.values()))
        values = dict(zip(checked, bcast))
        dims = tuple(f"dim_{i}" for i in range(bcast[0].ndim))
        coords = {}
    for d in DIMS:
        if d in coords:
            # A coordinate named like a parameter (an axis eps, or a previous result's
            # coordinates) must hold the values solved for.
            c = coords[d]
            if not np.array_equal(c.broadcast_like(ref).transpose(*dims).values, values[d]):
                raise ParameterError(f"{d}: the inputs' coordinate {d!r} differs from the values "
                                     f"given for {d}")
            coords[d] = c.assign_attrs(PARAMETERS[d].attrs)
        else:
            coords[d] = (dims, values[d], PARAMETERS[d].attrs)
    return dims, coords, values


def _triples(flat: dict, eta: np.ndarray, reduce: bool):
    """``(order, starts)``: the points sorted so that those sharing a triple are adjacent, and
    where each triple's run starts. Triples are equal when their bits are (as a sweep's)."""
    n = eta.size
    if not reduce or n == 0:
        return np.arange(n), np.arange(n)
    keys = [np.ascontiguousarray(k).view(np.int64) for k in (flat["N"], flat["A"], eta)]
    order = np.lexsort(keys)
    change = np.zeros(n, dtype=bool)
    change[0] = True
    for k in keys:
        ks = k[order]
        change[1:] |= ks[1:] != ks[:-1]
    return order, np.flatnonzero(change)


def _solve_flat(flat: dict, eta, rtol, atol, need, workers, reduce):
    """Run the kernel on the distinct triples of the points; per-point raw values."""
    n = eta.size
    order, starts = _triples(flat, eta, reduce)
    n_t = starts.size
    offsets = np.append(starts, n).astype(np.int64)
    first = order[starts]
    t_eta, t_A, t_N = eta[first], flat["A"][first], flat["N"][first]
    entries = np.diff(offsets)
    eps_K = (flat["eps"] * flat["K"])[order]
    res = np.empty((n_t, layout.N_R))
    one_minus_sorted = np.full(n, math.nan)
    if n_t:
        n_blocks = max(1, min(BLOCKS_PER_WORKER * workers, n_t // MIN_BLOCK_TRIPLES))
        blocks = block_plan(triple_costs(t_eta, t_A, t_N, entries), -(-n_t // n_blocks))

        def run(b):
            lo, counts = offsets[b], entries[b]
            b_offsets = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
            # the block's entries: each triple's run of sorted points, one after another
            idx = np.repeat(lo - b_offsets[:-1], counts) + np.arange(b_offsets[-1])
            inp = BlockInputs(t_eta[b], t_A[b], t_N[b], eps_K[idx], b_offsets, idx)
            out = block_.solve_block(inp, rtol, atol, None, *need)
            return b, idx, out

        if workers > 1 and len(blocks) > 1:
            block_.warm_up()  # load the kernels once, before the threads race to
            with ThreadPoolExecutor(min(workers, len(blocks))) as pool:
                done = list(pool.map(run, blocks))
        else:
            done = [run(b) for b in blocks]
        for b, idx, out in done:
            res[b] = out["res"]
            one_minus_sorted[idx] = out["one_minus"]
    owner = np.empty(n, dtype=np.int64)
    owner[order] = np.repeat(np.arange(n_t), entries)
    one_minus = np.empty(n)
    one_minus[order] = one_minus_sorted
    per_triple = res[owner]
    status = per_triple[:, layout.R_STATUS].astype(np.int8)
    per_point = {"J_axis": per_triple[:, layout.R_J_AXIS],
                 "mu_wall": per_triple[:, layout.R_MU_WALL],
                 "sigma_yx_wall": per_triple[:, layout.R_SIGMA_YX_WALL],
                 "xi_stop": per_triple[:, layout.R_XI_STOP]}
    return status, per_point, one_minus, n_t
