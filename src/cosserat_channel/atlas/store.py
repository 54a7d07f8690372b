"""Atlas files: the Dataset layout, writing (checksummed NetCDF) and reading, the cache's path.
Imports numpy and xarray, never numba."""

from __future__ import annotations

import numpy as np

from .. import status as st
from ..parameters import ParameterError
from .interpolant import Atlas
from .settings import FORMAT, FORMATS


def cache_path():
    """Where ``atlas --cache`` writes and ``plot --regime`` looks: ``atlas.nc`` in the package's
    cache directory (:func:`cosserat_channel.cache_dir`)."""
    from .. import cache_dir

    return str(cache_dir() / "atlas.nc")


def to_dataset(atlas):
    """The atlas as an :class:`xarray.Dataset` (what :func:`save_atlas` writes)."""
    import xarray as xr

    s = atlas.samples
    return xr.Dataset(
        {
            "sample_A": ("sample", s["A"], {"long_name": "A of a trace"}),
            "sample_N": ("sample", s["N"], {"long_name": "N of a trace"}),
            "sample_low": ("sample", s["low"].astype(np.int8), {
                "long_name": "1 if the lowest traced eta has a solution"}),
            "sample_n": ("sample", s["n"].astype(np.int8), {
                "long_name": "changes of feasibility found in the traced eta range"}),
            "sample_transitions": (("sample", "transition"), s["transitions"], {
                "long_name": "eta where feasibility changes, ascending (NaN-padded)"}),
            "sample_bands": (("sample", "transition"), s["bands"], {
                "long_name": "relative distance from the transition within which the "
                             "solver's status is not reliable (NaN-padded)"}),
            "leaf_level": ("leaf", atlas.leaf_level.astype(np.int8)),
            "leaf_i": ("leaf", atlas.leaf_i.astype(np.int32)),
            "leaf_j": ("leaf", atlas.leaf_j.astype(np.int32)),
            "leaf_low": ("leaf", atlas.leaf_low.astype(np.int8)),
            "leaf_n": ("leaf", atlas.leaf_n.astype(np.int8), {
                "long_name": "transitions in the leaf; -1: unresolved (undecided)"}),
            "leaf_error": ("leaf", atlas.leaf_error, {
                "long_name": "error estimate of the leaf's log eta interpolant"}),
            "leaf_coefficients": (("leaf", "transition", "cheb_A", "cheb_N"), atlas.coef, {
                "long_name": "tensor Chebyshev coefficients of log eta on the leaf"}),
            "leaf_degree": (("leaf", "direction"), atlas.leaf_degree.astype(np.int8), {
                "long_name": "Chebyshev degree of the leaf along A and N"}),
            "leaf_transition_error": (("leaf", "transition"), atlas.leaf_transition_error, {
                "long_name": "error estimate of each transition of the leaf"}),
            "leaf_band": ("leaf", atlas.leaf_band, {
                "long_name": "largest noise band of the traces at the leaf's nodes"}),
        },
        attrs={"title": "cosserat-channel solvability atlas", "format": FORMAT,
               "Conventions": st.CONVENTIONS, "A_min": atlas.box[0], "A_max": atlas.box[1], "N_min": atlas.box[2],
               "N_max": atlas.box[3], "roots_A": atlas.roots[0], "roots_N": atlas.roots[1],
               "degree": atlas.degree, "max_depth": atlas.max_depth, "tol": atlas.tol,
               "eta_min": atlas.eta_range[0], "eta_max": atlas.eta_range[1], **atlas.attrs},
    )


def from_dataset(ds):
    """The inverse of :meth:`to_dataset`; ParameterError if ``ds`` is not an atlas."""
    if ds.attrs.get("format") not in FORMATS:
        raise ParameterError(f"not a solvability atlas (format {ds.attrs.get('format')!r}, "
                             f"expected {FORMAT!r})")
    a = dict(ds.attrs)
    keys = ("title", "format", "A_min", "A_max", "N_min", "N_max", "roots_A", "roots_N",
            "degree", "max_depth", "tol", "eta_min", "eta_max")
    v = {k: np.asarray(ds[k].values) for k in ds.data_vars}
    return Atlas(
        box=(float(a["A_min"]), float(a["A_max"]), float(a["N_min"]), float(a["N_max"])),
        roots=(int(a["roots_A"]), int(a["roots_N"])), degree=int(a["degree"]),
        max_depth=int(a["max_depth"]), tol=float(a["tol"]),
        eta_range=(float(a["eta_min"]), float(a["eta_max"])),
        leaf_level=v["leaf_level"].astype(np.int64), leaf_i=v["leaf_i"].astype(np.int64),
        leaf_j=v["leaf_j"].astype(np.int64), leaf_low=v["leaf_low"].astype(np.int8),
        leaf_n=v["leaf_n"].astype(np.int8), leaf_error=v["leaf_error"].astype(float),
        coef=v["leaf_coefficients"].astype(float),
        samples={"A": v["sample_A"], "N": v["sample_N"], "low": v["sample_low"],
                 "n": v["sample_n"], "transitions": v["sample_transitions"],
                 **({"bands": v["sample_bands"]} if "sample_bands" in v else {})},
        attrs={k: val for k, val in a.items() if k not in keys},
        leaf_degree=v["leaf_degree"].astype(np.int64) if "leaf_degree" in v else None,
        leaf_band=v["leaf_band"].astype(float) if "leaf_band" in v else None,
        leaf_transition_error=(v["leaf_transition_error"].astype(float)
                               if "leaf_transition_error" in v else None),
    )


def save_atlas(atlas, path):
    """Write ``atlas`` to ``path`` (NetCDF, checksummed) through :func:`files.netcdf_output`."""
    from .. import netcdf_policy
    from ..files import netcdf_output

    ds = to_dataset(atlas)
    netcdf_output(path, lambda tmp: ds.to_netcdf(tmp, encoding=netcdf_policy.encoding(ds)))


def load_atlas(path):
    """Read an atlas written by :func:`save_atlas`; ParameterError (one line) if it is not one."""
    import xarray as xr

    try:
        ds = xr.load_dataset(path)
    except (OSError, ValueError, RuntimeError) as exc:
        raise ParameterError(f"cannot read atlas {str(path)!r}: {' '.join(str(exc).split())}") \
            from None
    try:
        return from_dataset(ds)
    except (KeyError, ParameterError) as exc:
        raise ParameterError(f"{str(path)!r} is not a solvability atlas ({exc})") from None
