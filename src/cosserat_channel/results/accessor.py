"""``ds.cosserat``: the package's xarray accessor on a result Dataset.

Registered when this module is imported; :func:`cosserat_channel.results.selection.open_results`
and :func:`cosserat_channel.run_sweep` import it, so every result they return has it. A file
opened with plain ``xarray.open_dataset`` gets it after ``import cosserat_channel.results.accessor``.
Imports xarray, numpy and the vocabulary modules only (never numba, never the solver); matplotlib
only when a figure is asked for.

>>> ds = open_results("demo/quickstart.nc")                        # doctest: +SKIP
>>> ds.cosserat.status_names.sel(L=10)                               # doctest: +SKIP
>>> ds.cosserat.solved()["Delta"].sel(K=0.5, A=1/3, N=1).plot()      # doctest: +SKIP
>>> ds.cosserat.in_si("m_wall")                                      # doctest: +SKIP
>>> ds.cosserat.regime_map("A", "N", at={"eps": 0.05, "L": 10, "K": 0.5})   # doctest: +SKIP
"""

from __future__ import annotations

import json
import tomllib

import numpy as np
import xarray as xr

from .. import outputs
from .. import status as st
from ..parameters import ParameterError, check_material
from .flags import flag_names, status_counts


@xr.register_dataset_accessor("cosserat")
class CosseratAccessor:
    """``ds.cosserat``: statuses by name, the solved points, SI values and the figures of a result.

    Parameters
    ----------
    ds : xarray.Dataset
        A result of ``run`` or :func:`cosserat_channel.run_sweep` (a ``status`` flag variable over
        ``eps, L, K, A, N``), or a selection of one.
    """

    def __init__(self, ds: xr.Dataset):
        self._ds = ds

    # -- status ------------------------------------------------------------------------------
    def _status(self) -> xr.DataArray:
        if "status" not in self._ds:
            raise ValueError("the Dataset has no 'status' variable: not a cosserat-channel result")
        return self._ds["status"]

    @property
    def status_names(self) -> xr.DataArray:
        """The status of each point by name (``ok``, ``eps_too_large_path`` ...), read from the
        variable's ``flag_values``/``flag_meanings`` (``other`` for a code that is not a flag)."""
        status = self._status()
        flags = flag_names(status) if "flag_meanings" in status.attrs else {
            s.name: s.value for s in st.Status}
        codes = np.asarray(status.values, dtype=np.int64)
        lo = min(min(flags.values()), int(codes.min(initial=0)))
        hi = max(max(flags.values()), int(codes.max(initial=0)))
        table = np.full(hi - lo + 1, "other", dtype=object)
        for name, code in flags.items():
            table[code - lo] = name
        names = table[codes - lo].astype(str)
        return xr.DataArray(names, coords=status.coords, dims=status.dims, name="status",
                            attrs={"long_name": "solution status"})

    def status_counts(self) -> dict[str, int]:
        """Points per status name."""

        return status_counts(self._ds)

    def solved(self) -> xr.Dataset:
        """The Dataset with every float variable NaN where the status is not ``ok`` (``status``
        itself kept: it says why the others have no value)."""
        ok = self._status() == st.OK
        ds = self._ds.copy()
        for name, da in ds.data_vars.items():
            if name != "status" and da.dtype.kind == "f":
                ds[name] = da.where(ok)
        return ds

    # -- units ---------------------------------------------------------------------------------
    @property
    def material(self) -> dict | None:
        """The material the result was solved with (closure defaults filled in), read from the
        sweep text the file carries; None when it has none."""
        text = self._ds.attrs.get("sweep_toml")
        if not text:
            return None
        try:
            data = tomllib.loads(str(text))
        except tomllib.TOMLDecodeError:
            try:  # a sweep given as a mapping is stored as JSON
                data = json.loads(str(text))
            except ValueError:
                raise ValueError("the file's sweep_toml attribute is neither TOML nor JSON") from None
        try:
            return check_material(data.get("material"))
        except ParameterError as exc:
            raise ValueError(f"the file's material: {exc}") from None

    def in_si(self, name: str) -> xr.DataArray:
        """Variable ``name``, a stress or couple stress scaled as the paper scales them (eq:54's
        bars, divided by ``nu``), in Pa or Pa m with the file's material.

        The factor is the one the ``*_Pa`` outputs use (:data:`cosserat_channel.outputs.SCALES`),
        ``rho_p g W nu`` (times ``d_p`` for a couple stress), with ``W = d_p/eps`` and ``nu`` from
        eq:35 at each ``(eps, N)``.

        Raises
        ------
        ValueError
            If ``name`` is not a scaled stress or the file has no material.
        """
        q = outputs.definition(name)
        if q is None or not getattr(q, "scale", ""):
            have = [n for n in self._ds.data_vars if getattr(outputs.definition(n), "scale", "")]
            raise ValueError(f"{name!r} is not a scaled stress of the result (have: "
                             f"{', '.join(have) or 'none'})")
        material = self.material
        if material is None:
            raise ValueError("the result has no material ([material] in its sweep): no Pa")
        scale = outputs.SCALES[q.scale]
        da = self._ds[name]
        eps, N = xr.broadcast(da["eps"], da["N"])
        x = outputs.Inputs(np.zeros(eps.shape, dtype=np.int8), eps.values, 1.0, 0.0, N.values,
                           material=material)
        factor = xr.DataArray(np.broadcast_to(scale.factor(x), eps.shape), coords=eps.coords,
                              dims=eps.dims)
        out = da * factor
        out.name = f"{name}_{scale.units.replace(' ', '_')}"
        out.attrs = {"units": scale.units, "long_name": q.long_name,
                     "description": f"{q.sentence}, times {scale.label}: in {scale.units}"}
        return out

    # -- figures -------------------------------------------------------------------------------
    def label(self, name: str) -> str:
        """The axis label of variable ``name`` (long name, symbol, unit), as the package's
        figures print it."""
        from ..plot import axis_label

        return axis_label(name, self._ds[name] if name in self._ds.variables else None)

    def regime_map(self, x: str = "A", y: str = "N", at: dict | None = None, *, boundary=None,
                   path=None):
        """The status over a 2-D slice as categories in the status colours, one legend entry per
        status (:func:`cosserat_channel.plot.regimes.regime_map`)."""
        from ..plot.regimes import regime_map

        return regime_map(self._ds, x, y, at, boundary=boundary, path=path)

    def line_plot(self, x: str, y: str = "Delta", hue: str | None = None, at: dict | None = None,
                  **kwargs):
        """``y`` against ``x``, one line per ``hue`` (:func:`cosserat_channel.plot.lines.line_plot`)."""
        from ..plot.lines import line_plot

        return line_plot(self._ds, x, y, hue, at, **kwargs)
