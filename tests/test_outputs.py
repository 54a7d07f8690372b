"""The output registry: one definition serves solve_point and a sweep's Dataset, bit for bit."""

import math
import subprocess
import sys

import numpy as np
import pytest

from cosserat_channel import outputs, run_sweep, solve_point
from cosserat_channel import status as st

FIG2 = (1 / 30, 10.0, 0.5, 1 / 3, 1.0)
SWEEP = {
    "grid": {"eps": [0.02, 1 / 30, 0.45], "L": [5.0, 10.0], "K": [0.5, 300.0], "A": 1 / 3, "N": 1.0},
    "material": {"d_p": 0.002, "rho_p": 2940.0, "phi": 25.0},
}


def _throwaway():
    # Delta in channel half-widths: needs the plug edge and a parameter, like a real new output.
    return outputs.Output("Delta_over_L", "1", "Delta / L (test only)",
                          lambda x: x.get("Delta") / x.L, plug_edge=True)


def test_a_new_output_through_the_registry_alone():
    """An output registered in outputs.py alone appears in solve_point and in a sweep's Dataset."""
    with outputs.registered(_throwaway()):
        r = solve_point(*FIG2)
        assert r.Delta_over_L == pytest.approx(r.Delta / 10.0, rel=1e-15)
        assert "Delta_over_L" in r.to_dict()
        ds = run_sweep({**SWEEP, "output": {"variables": ["Delta_over_L", "m_wall"]}},
                       workers=1, progress=False)
        assert ds["Delta_over_L"].attrs["long_name"] == "Delta / L (test only)"
        got = ds["Delta_over_L"].sel(eps=1 / 30, L=10.0, K=0.5).item()
        assert got == r.Delta_over_L
    assert "Delta_over_L" not in outputs.OUTPUTS
    with pytest.raises(AttributeError):
        solve_point(*FIG2).Delta_over_L  # noqa: B018 (the attribute lookup is the test)


def test_sweep_and_solve_point_agree_bit_for_bit_on_every_output():
    """Every registered output of a sweep equals solve_point's to the last bit (NaN where none)."""
    ds = run_sweep(SWEEP, workers=1, progress=False)
    assert set(outputs.OUTPUTS) <= set(ds.data_vars)
    for eps in ds.eps.values:
        for L in ds.L.values:
            for K in ds.K.values:
                r = solve_point(eps, L, K, 1 / 3, 1.0, material=SWEEP["material"])
                at = ds.sel(eps=eps, L=L, K=K, A=1 / 3, N=1.0)
                assert int(at["status"]) == int(r.status)
                for name in outputs.OUTPUTS:
                    a, b = float(at[name]), getattr(r, name)
                    assert (a == b) or (math.isnan(a) and math.isnan(b)), (name, eps, L, K, a, b)


def test_stage_of_each_output():
    """Stage-1 outputs do not ask for stage 2; the plug edge and velocities do."""
    assert not outputs.needs_stage2(["m_wall", "sigma_yx_wall", "xi_stop", "stage1_steps"])
    assert not outputs.needs_stage2(["nu", "sigma_xx_wall_Pa", "sigma_yx_wall_Pa", "m_wall_Pa_m"])
    for name in ("Delta", "xi_p", "slip", "u_axis", "stage2_steps"):
        assert outputs.needs_stage2([name]), name
    assert outputs.needs_plug_edge(["Delta"]) and not outputs.needs_plug_edge(["slip"])


def test_derive_masks_values_of_points_without_solution():
    """A raw value under a status other than ok never leaks into an output."""
    x = outputs.Inputs(np.array([st.OK, st.INTEGRATION_FAILED]), 0.1, 10.0, 0.5, 1.0,
                       J_axis=np.array([2.0, 3.0]), mu_wall=np.array([-0.9, -0.8]),
                       sigma_yx_wall=np.array([-1.1, -1.2]), xi_stop=np.array([np.nan, 0.5]),
                       one_minus=np.array([0.2, np.nan]))
    got = outputs.derive(["u_axis", "m_wall", "Delta", "xi_stop"], x)
    assert got["u_axis"][0] == 0.05 + 2.0 and np.isnan(got["u_axis"][1])
    assert got["m_wall"][0] == 10.0 * -0.9 and np.isnan(got["m_wall"][1])
    assert got["Delta"][0] == 0.2 / 0.1 and np.isnan(got["Delta"][1])
    assert np.isnan(got["xi_stop"]).all()  # xi_stop belongs to eps_too_large_path only


def test_reading_results_does_not_import_numba():
    """Parsing sweeps and querying results stay numba-free (a fresh interpreter proves it)."""
    code = ("import cosserat_channel.results.selection, cosserat_channel.results.render, "
            "cosserat_channel.results.describe, cosserat_channel.results.light, "
            "cosserat_channel.sweep.spec, cosserat_channel.outputs, "
            "cosserat_channel.parameters, sys; assert 'numba' not in sys.modules")
    subprocess.run([sys.executable, "-c", code], check=True)
