"""``ds.cosserat``: statuses by name, the solved points, SI values from the file's material and
the status as categories, on a real sweep file; the accessor's module loads no numba."""

import math

import numpy as np
import pytest
import xarray as xr

from cosserat_channel import run_sweep
from cosserat_channel import status as st
from cosserat_channel.physics import closure
from cosserat_channel.results import selection
from support import run_python

MATERIAL = {"d_p": 0.002, "rho_p": 2940.0, "phi": 25.0}
SWEEP = {
    "grid": {"eps": [0.02, 1 / 30, 0.4], "L": 10.0, "K": 0.5, "A": [-2.0, 1 / 3, 0.9],
             "N": [0.5, 1.0]},
    "material": MATERIAL,
    "output": {"variables": ["Delta", "m_wall", "sigma_yx_wall", "nu", "sigma_yx_wall_Pa",
                             "m_wall_Pa_m"], "profile_points": 5},
}


@pytest.fixture(scope="module")
def path(tmp_path_factory):
    p = tmp_path_factory.mktemp("accessor") / "r.nc"
    run_sweep(SWEEP, str(p), workers=1, progress=False)
    return str(p)


@pytest.fixture(scope="module")
def ds(path):
    with selection.open_results(path) as ds:
        yield ds.load()


def test_status_names_decode_every_code(ds):
    """Each point's name is Status(code).name, and the mix has solved and unsolved points."""
    names = ds.cosserat.status_names
    codes = ds["status"].values
    assert names.dims == ds["status"].dims
    expected = np.vectorize(lambda c: st.Status(int(c)).name)(codes)
    assert np.array_equal(names.values, expected)
    assert {"ok", "wall_inadmissible"} <= set(np.unique(names.values))
    counts = ds.cosserat.status_counts()
    assert sum(counts.values()) == codes.size and counts["ok"] == int((codes == st.OK).sum())


def test_solved_keeps_only_ok_points(ds):
    """solved(): every float variable NaN where the status is not ok, unchanged where it is."""
    solved = ds.cosserat.solved()
    ok = ds["status"].values == st.OK
    for name in ("Delta", "m_wall", "nu", "u_over_u0"):
        a, b = solved[name].values, ds[name].values
        okb = np.broadcast_to(ok.reshape(ok.shape + (1,) * (a.ndim - ok.ndim)), a.shape)
        assert np.all(np.isnan(a[~okb])), name
        assert np.array_equal(a[okb], b[okb], equal_nan=True), name
    assert np.array_equal(solved["status"].values, ds["status"].values)


def test_in_si_matches_the_outputs_in_pa_and_the_closed_form(ds):
    """in_si of the scaled wall stresses with the file's material equals the *_Pa outputs to the
    last bit (one scale for both), and rho_p g W nu computed here by hand to round-off."""
    assert ds.cosserat.material["d_p"] == MATERIAL["d_p"] and ds.cosserat.material["Lambda"] == 817.0
    for scaled, pa, unit in (("sigma_yx_wall", "sigma_yx_wall_Pa", "Pa"),
                             ("m_wall", "m_wall_Pa_m", "Pa m")):
        got = ds.cosserat.in_si(scaled)
        assert got.attrs["units"] == unit
        assert np.array_equal(got.transpose(*ds[pa].dims).values, ds[pa].values, equal_nan=True)
    eps, N = 1 / 30, 1.0
    rho_g_W = MATERIAL["rho_p"] * 9.81 * MATERIAL["d_p"] / eps
    nu = closure.solids_fraction(rho_g_W, math.sin(math.radians(25.0)) / N,
                                 {"Lambda": 817.0, "nu_min": 0.5, "nu_max": 0.65, "p": 2.5, "q": 2.2})
    at = dict(eps=eps, L=10.0, K=0.5, A=1 / 3, N=N)
    by_hand = float(ds["sigma_yx_wall"].sel(at)) * rho_g_W * nu
    assert float(ds.cosserat.in_si("sigma_yx_wall").sel(at)) == pytest.approx(by_hand, rel=1e-12)
    profile = ds.cosserat.in_si("m").sel(at).values
    assert profile == pytest.approx(ds["m"].sel(at).values * rho_g_W * nu * MATERIAL["d_p"],
                                    rel=1e-12)


def test_in_si_refuses_what_it_cannot_convert(ds):
    """A variable that is not a scaled stress, or a result without material: one clear error."""
    with pytest.raises(ValueError, match="not a scaled stress"):
        ds.cosserat.in_si("Delta")
    plain = ds.copy()
    plain.attrs["sweep_toml"] = "[grid]\neps = 0.1\n"
    with pytest.raises(ValueError, match="no material"):
        plain.cosserat.in_si("m_wall")


def test_regime_map_draws_the_statuses_as_categories(ds):
    """The status slice as categories: one legend entry per status present, in its colour."""
    from matplotlib.colors import to_rgba

    fig = ds.cosserat.regime_map("A", "N", at={"eps": 1 / 30})
    ax = fig.axes[0]
    handles = ax.get_legend().legend_handles
    present = {st.Status(int(c)).name for c in np.unique(ds["status"].sel(eps=1 / 30).values)}
    patches = {h.get_label(): h for h in handles if h.get_label() in st.Status.__members__}
    assert set(patches) == present
    for name, h in patches.items():
        assert h.get_facecolor() == to_rgba(st.Status[name].color)
    assert ds.cosserat.label("Delta") in ds.cosserat.line_plot("eps", "Delta", at={
        "A": 1 / 3, "N": 1.0}).axes[0].get_ylabel()


def test_the_accessor_module_loads_no_numba(path):
    """Opening a file with plain xarray and using ds.cosserat imports neither numba nor a kernel."""
    code = ("import sys, xarray as xr; import cosserat_channel.results.accessor; "
            f"ds = xr.open_dataset({path!r}); ds.cosserat.status_names; ds.cosserat.solved(); "
            "ds.cosserat.in_si('m_wall'); "
            "print(sorted(m for m in sys.modules if m == 'numba' or m.startswith(("
            "'cosserat_channel.solver', 'cosserat_channel.integrate'))))")
    assert run_python(code) == "[]"


def test_run_sweep_results_have_the_accessor():
    """A Dataset straight from run_sweep (no file) has it too."""
    out = run_sweep({"grid": {"eps": 0.05, "L": 10.0, "K": 0.5, "A": 1 / 3, "N": 1.0}},
                    workers=1, progress=False)
    assert isinstance(out, xr.Dataset) and out.cosserat.status_names.item() == "ok"
