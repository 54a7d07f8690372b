"""CF metadata of the files we write: cf_xarray decodes them, UDUNITS-2 parses every unit.

The units are parsed by ``cf_units`` (SciTools; its wheels bundle the UDUNITS-2 C library, so
this is the real UDUNITS parser). ``cfunits`` would need the C library installed separately.
"""

import cf_units
import cf_xarray  # noqa: F401  (registers the .cf accessor)
import numpy as np
import pytest
import xarray as xr

from cosserat_channel import outputs, regimes
from cosserat_channel.parameters import MATERIAL, PARAMETERS
from cosserat_channel.sweep import run_sweep
from cosserat_channel.sweep.spec import allowed_variables

SWEEP = {
    "grid": {"eps": [0.02, 0.3, 0.5], "L": 10.0, "K": [0.5, 5.0], "A": [0.3333333333333333, -2.0],
             "N": 1.0},
    "material": {"d_p": 0.002, "rho_p": 2940, "phi": 25},
    "output": {"variables": list(allowed_variables(True)), "profile_points": 5},
}


def udunits(unit: str) -> cf_units.Unit:
    """The parsed unit; fails for what UDUNITS cannot parse (cf_units raises ValueError)."""
    u = cf_units.Unit(unit)
    assert not u.is_unknown() and not u.is_no_unit(), unit
    return u


@pytest.fixture(scope="module")
def result(tmp_path_factory):
    path = tmp_path_factory.mktemp("cf") / "r.nc"
    run_sweep(SWEEP, str(path), workers=1)
    with xr.open_dataset(path) as ds:
        yield ds.load()


@pytest.fixture(scope="module")
def boundary(tmp_path_factory):
    path = tmp_path_factory.mktemp("cf") / "b.nc"
    regimes.trace_boundary([1 / 3, 3.0], [0.5, 1.0], n_coarse=8).to_netcdf(path)
    with xr.open_dataset(path) as ds:
        yield ds.load()


def test_every_declared_unit_is_udunits():
    """The units of every parameter, material input, output, counter and profile parse."""
    units = [p.units for p in PARAMETERS.values()] + [m.units for m in MATERIAL.values()]
    units += [o.units for o in outputs.OUTPUTS.values()]
    units += [c.units for c in outputs.COUNTERS.values()] + [q.units for q in outputs.PROFILES.values()]
    units += [outputs.XI.units] + [s.units for s in outputs.SCALES.values()]
    for u in units:
        udunits(u)
    assert udunits(outputs.OUTPUTS["Delta"].units) == cf_units.Unit("1")
    assert "particle diameters" in outputs.OUTPUTS["Delta"].description
    assert udunits("Pa").is_convertible(cf_units.Unit("kg m-1 s-2"))


def test_units_in_files_parse(result, boundary):
    """Every non-flag variable and every coordinate of a sweep and a boundary file has units
    that UDUNITS parses; stresses in Pa convert to SI."""
    for ds in (result, boundary):
        for name, v in ds.variables.items():
            if "flag_meanings" in v.attrs:
                continue
            assert "units" in v.attrs, name
            udunits(v.attrs["units"])
    assert cf_units.Unit(result["m_wall_Pa_m"].attrs["units"]).is_convertible("N m-1")


def test_cf_xarray_decodes_the_status_flags(result):
    """``status.cf == name`` is ``status == code`` for every flag; every code is a flag."""
    status = result["status"]
    assert status.cf.is_flag_variable
    flags = dict(zip(status.attrs["flag_meanings"].split(), status.attrs["flag_values"]))
    for name, code in flags.items():
        assert np.array_equal((status.cf == name).values, (status == code).values), name
    assert set(np.unique(status.values)) <= set(flags.values())
    assert (status.cf == "ok").any() and (status.cf != "ok").any()
    assert set(status.cf.flags.data_vars) == set(flags)


def test_cf_xarray_decodes_the_boundary_flags(boundary):
    """edge_kind and status_above: every value in the file is one of its flag_values (no_edge
    for -1), and cf_xarray's decoding agrees with the codes."""
    for name in ("edge_kind", "status_above"):
        da = boundary[name]
        assert da.cf.is_flag_variable, name
        values = set(np.asarray(da.attrs["flag_values"]).tolist())
        assert set(np.unique(da.values).tolist()) <= values, name
    above = boundary["status_above"]
    assert np.array_equal((above.cf == "no_edge").values, (above == -1).values)
    assert (above.cf == "eps_too_large_path").any()


def test_cf_xarray_sees_the_coordinates(result):
    """The dimension coordinates carry long names; cf_xarray's summary of the file works."""
    for d in ("eps", "L", "K", "A", "N", "xi"):
        assert d in result.coords and result[d].attrs.get("long_name")
    assert "Coordinates" in repr(result.cf)


# xarray's own label: "long_name [units]", wrapped at this many characters.
XARRAY_WRAP = 30


def test_long_names_are_axis_labels_and_the_sentence_is_the_description(result):
    """Every variable and coordinate of a result has a long_name that plain xarray prints on one
    line with its units, and the sentence it used to carry as its description."""
    for name, v in result.variables.items():
        text = f"{v.attrs['long_name']} [{v.attrs.get('units', '1')}]"
        assert len(text) <= XARRAY_WRAP, (name, text)
        if name != "status":
            q = outputs.definition(name)
            assert v.attrs["description"] == q.description and q.description, name
            assert len(q.description) > len(q.long_name), name
    assert result["xi"].attrs["axis"] == "X"
    assert result["status"].attrs["standard_name"] == "status_flag"
    assert result.attrs["Conventions"] == "CF-1.8"


def test_plain_xarray_plots_keep_their_labels_inside_the_figure(result):
    """``ds.Delta.sel(...).plot()`` with xarray alone: the y label of every output is one line
    and lies inside the figure (a sentence as long_name was wrapped and clipped at the edge)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    for name in [*outputs.OUTPUTS, "u_over_u0", "m"]:
        da = result[name].isel({d: 0 for d in result[name].dims if d not in ("eps", "xi")})
        if "xi" in da.dims:
            da = da.isel(eps=0)
        fig, ax = plt.subplots()
        try:
            da.plot(ax=ax)
            fig.canvas.draw()
            label = ax.yaxis.label
            box = label.get_window_extent(fig.canvas.get_renderer())
            assert "\n" not in label.get_text(), (name, label.get_text())
            assert box.x0 >= 0 and box.y0 >= 0 and box.y1 <= fig.bbox.height, (name, box)
        finally:
            plt.close(fig)


def test_every_file_of_the_tool_carries_conventions(boundary, tmp_path):
    """Boundary files (traced, or drawn from an atlas) and atlas files say which CF version, and
    every variable of an atlas file has a long_name."""
    from cosserat_channel import atlas

    assert boundary.attrs["Conventions"] == "CF-1.8"
    a = atlas.build_atlas((0.25, 0.5), (0.8, 0.9), tol=1e-3, degree=2, max_depth=0)
    ds = atlas.to_dataset(a)
    assert ds.attrs["Conventions"] == "CF-1.8"
    assert [v for v in ds.variables if "long_name" not in ds[v].attrs] == []
    assert a.boundary([0.3], [1.0]).attrs["Conventions"] == "CF-1.8"
