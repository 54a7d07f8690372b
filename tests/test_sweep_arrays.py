"""solve: many points in memory, broadcast like numpy/xarray, equal to solve_point to the bit."""

import math

import numpy as np
import pytest
import xarray as xr

import cosserat_channel
from cosserat_channel import outputs as out_
from cosserat_channel import status as st
from cosserat_channel.parameters import PARAMETERS, ParameterError
from cosserat_channel.sweep import arrays
from cosserat_channel.sweep.arrays import solve
from cosserat_channel.solver.point import solve_point

MATERIAL = dict(d_p=0.002, rho_p=2940, phi=25)
# Appendix A's regimes without a solution (as in test_solver_point), then ok points.
NOT_OK = {
    st.Status.wall_inadmissible: (0.05, 10, 0.5, -2.0, 1.0),
    st.Status.axis_spin_unbounded: (0.05, 10, 0.5, -1.5, 2.0),
    st.Status.eps_too_large_axis: (0.45, 10, 0.5, 1 / 3, 1.0),
    st.Status.eps_too_large_path: (0.36, 10, 0.5, 1 / 3, 1.0),
}


def _random_points(n, seed):
    rng = np.random.default_rng(seed)
    return (10 ** rng.uniform(-2.5, -0.5, n), 10 ** rng.uniform(-0.5, 1.5, n),
            np.where(rng.random(n) < 0.1, 0.0, 10 ** rng.uniform(-2, 2, n)),
            rng.uniform(-1.0, 3.0, n), 10 ** rng.uniform(-1, 0.7, n))


def _same(a, b):
    """Equal to the bit, NaN equal to NaN."""
    return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)


def test_exported_from_the_package():
    assert cosserat_channel.solve is solve and "solve" in cosserat_channel.__all__


@pytest.mark.parametrize("workers", [1, 2])
def test_values_equal_solve_point_to_the_bit(monkeypatch, workers):
    """Random points (some of them without a solution) in one call, on one thread and on
    several blocks over two threads: every output and status as solve_point gives it."""
    monkeypatch.setattr(arrays, "MIN_BLOCK_TRIPLES", 3)  # several blocks on a few points
    eps, L, K, A, N = (np.concatenate((v, [p[i] for p in NOT_OK.values()]))
                       for i, v in enumerate(_random_points(40, 1)))
    ds = solve(eps, L, K, A, N, workers=workers)
    assert ds.attrs["n_solves"] == eps.size  # distinct points: no reduction possible
    assert set(ds.status.values.tolist()) > {st.OK}  # the regimes are there
    for i in range(eps.size):
        r = solve_point(eps[i], L[i], K[i], A[i], N[i])
        assert ds.status.values[i] == r.status.value
        for name in r.computed:
            assert _same(ds[name].values[i], r.values[name]), (name, i)


def test_material_and_output_subset_equal_solve_point():
    eps, L, K, A, N = _random_points(6, 2)
    ds = solve(eps, L, K, A, N, material=MATERIAL)
    assert set(ds.data_vars) == set(out_.OUTPUTS) | {"status"}
    sub = solve(eps, L, K, A, N, outputs=["m_wall"])
    assert set(sub.data_vars) == {"m_wall", "status"}
    for i in range(eps.size):
        r = solve_point(eps[i], L[i], K[i], A[i], N[i], material=MATERIAL)
        for name in r.computed:
            assert _same(ds[name].values[i], r.values[name]), name
        assert _same(sub.m_wall.values[i], r.m_wall)
        assert sub.status.values[i] == r.status.value


def test_statuses_other_than_ok_carry_their_status():
    eps, L, K, A, N = (np.array(v) for v in zip(*NOT_OK.values()))
    ds = solve(eps, L, K, A, N)
    assert ds.status.values.tolist() == [s.value for s in NOT_OK]
    assert np.isnan(ds.Delta.values).all() and np.isnan(ds.u_axis.values).all()
    # where the stress path met D = 0 is a value of that status only
    stop = ds.xi_stop.values[list(NOT_OK).index(st.Status.eps_too_large_path)]
    assert 0 < stop <= 1


def test_numpy_broadcasting():
    eps = np.array([[0.02], [0.05], [0.1]])
    K = np.array([0.0, 0.5, 2.0, 10.0])
    ds = solve(eps, 10, K, 1 / 3, 1)
    assert ds.Delta.dims == ("dim_0", "dim_1") and ds.Delta.shape == (3, 4)
    np.testing.assert_array_equal(ds.eps.values, np.broadcast_to(eps, (3, 4)))
    np.testing.assert_array_equal(ds.K.values, np.broadcast_to(K, (3, 4)))
    for i, j in [(0, 0), (1, 2), (2, 3)]:
        r = solve_point(float(eps[i, 0]), 10, float(K[j]), 1 / 3, 1)
        assert _same(ds.Delta.values[i, j], r.Delta) and _same(ds.slip.values[i, j], r.slip)
    # all numbers: a 0-d result
    one = solve(1 / 30, 10, 0.5, 1 / 3, 1)
    assert one.Delta.shape == () and _same(one.Delta.values, solve_point(1 / 30, 10, 0.5, 1 / 3, 1).Delta)


def test_dataarrays_broadcast_by_name_and_keep_their_labels():
    eps = xr.DataArray([0.02, 0.1], dims="eps", coords={"eps": [0.02, 0.1]})
    A = xr.DataArray([0.0, 1 / 3, 2.0], dims="A", coords={"A": [0.0, 1 / 3, 2.0]})
    K = xr.DataArray([0.5, 5.0], dims="case", coords={"case": ["smooth", "rough"]})
    ds = solve(eps, 10, K, A, 1.0)
    assert set(ds.Delta.dims) == {"eps", "case", "A"}
    assert list(ds.case.values) == ["smooth", "rough"]
    assert ds.eps.attrs["long_name"] == PARAMETERS["eps"].long_name
    assert ds.status.attrs["flag_meanings"] == st.cf_flag_attrs()["flag_meanings"]
    assert ds.Delta.attrs == out_.OUTPUTS["Delta"].attrs
    for e in eps.values:
        for k, case in zip(K.values, K.case.values):
            for a in A.values:
                r = solve_point(float(e), 10, float(k), float(a), 1.0)
                got = ds.sel(eps=e, case=case, A=a)
                assert got.status == r.status.value and _same(got.Delta.values, r.Delta)
    # a result's own coordinates go back in
    again = solve(ds.eps, ds.L, ds.K, ds.A, ds.N)
    assert _same(again.Delta.transpose(*ds.Delta.dims).values, ds.Delta.values)


def test_similarity_reduction_is_used():
    """Points sharing eps L (and A, N) share one integration; unreduced, every point has one;
    the values are the same bits."""
    eps = np.array([0.01, 0.02, 0.04, 0.05])
    L = 0.4 / eps  # eps L = 0.4 for all (products rounded the same way or not: counted)
    K = np.array([[0.0], [0.3], [3.0]])
    eta_distinct = np.unique(eps * L).size
    red = solve(eps, L, K, 1 / 3, 1.0)
    full = solve(eps, L, K, 1 / 3, 1.0, reduce=False)
    assert red.attrs["n_solves"] == eta_distinct < 12 and full.attrs["n_solves"] == 12
    assert red.attrs["reduced"] == 1 and full.attrs["reduced"] == 0
    for name in red.data_vars:
        assert _same(red[name].values, full[name].values), name


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(K=np.array([0.5, -1.0])), ["K = -1.0", "[0, inf)"]),
        (dict(eps=np.array([0.1, 1.5])), ["eps = 1.5", "(0, 1]"]),
        (dict(N=np.array([1.0, np.nan])), ["N = nan", "(0, 1e+06]"]),
        (dict(A=xr.DataArray([0.0, 2e3], dims="A")), ["A = 2000.0", "[-1000, 1000]"]),
        (dict(A=True), ["A must be a number"]),
        (dict(L=np.array([True, False])), ["L must be numbers", "(0, inf)"]),
        (dict(L=np.array(["1", "2"])), ["L must be numbers"]),
        (dict(eps=1e-13, L=np.array([1.0, 2.0])), ["eps L", "1e-12"]),
        (dict(K=np.zeros(3), A=np.zeros(2)), ["do not broadcast", "K (3,)", "A (2,)"]),
        (dict(K=np.zeros(2), A=xr.DataArray([0.0, 1.0], dims="A")), ["numpy array", "DataArray"]),
        (dict(K=xr.DataArray([0.0, 1.0], dims="A", coords={"A": [0, 1]}),
              A=xr.DataArray([0.0, 1.0], dims="A", coords={"A": [0, 2]})), ["same coordinates"]),
        (dict(K=xr.DataArray([0.5, 1.0], dims="A", coords={"A": [0.0, 1.0]}), A=0.0),
         ["coordinate 'A' differs"]),
        (dict(rtol=1.0), ["rtol"]),
        (dict(outputs=["Delta", "nu"]), ["'nu' needs a material"]),
        (dict(workers=0), ["workers must be a positive integer"]),
    ],
)
def test_bad_input_is_one_line_naming_the_parameter(kwargs, words):
    args = dict(eps=1 / 30, L=10.0, K=0.5, A=1 / 3, N=1.0)
    args.update(kwargs)
    with pytest.raises(ParameterError) as info:
        solve(**args)
    msg = str(info.value)
    assert "\n" not in msg
    for w in words:
        assert w in msg, msg


def test_empty_arrays_give_an_empty_result():
    ds = solve(np.array([]), 10, 0.5, 1 / 3, 1)
    assert ds.Delta.shape == (0,) and ds.attrs["n_solves"] == 0
    assert math.isnan(float(solve(0.36, 10, 0.5, 1 / 3, 1).Delta))


def test_sensitivities_are_solve_points_with_attributes():
    from cosserat_channel.solver.point import solve_point

    mat = {"d_p": 1e-3, "rho_p": 2500.0, "phi": 30.0}
    K = np.array([0.5, 1.0, 250.0])
    A = np.array([[1 / 3], [-0.4], [-1.0], [-0.5]])  # with A = -1 and, at eps 1/30 N 0.3, none
    N = np.array([[1.2], [1.2], [1.5], [0.3]])
    ds = solve(1 / 30, 10, K, A, N, material=mat, sensitivities=True, workers=1)
    plain = solve(1 / 30, 10, K, A, N, material=mat, workers=1)
    assert not [v for v in plain.data_vars if v.startswith("d")]
    np.testing.assert_array_equal(ds.status.values, plain.status.values)
    assert (ds.status.values[3] != 0).all() and (ds.status.values[:3] == 0).all()
    names = [v for v in plain.data_vars if v not in ("status", "xi_stop")]
    for name in names:
        np.testing.assert_array_equal(ds[name].values, plain[name].values)
    for i in range(4):
        for j in range(3):
            r = solve_point(1 / 30, 10, K[j], A[i, 0], N[i, 0], material=mat, sensitivities=True)
            for name in names:
                for p in ("eps", "L", "K", "A", "N"):
                    var = ds[f"d{name}_d{p}"]
                    assert var.dims == ds[name].dims
                    assert var.attrs["long_name"] and var.attrs["units"]
                    got, want = var.values[i, j], r.sensitivities[name][p]
                    assert got == want or (math.isnan(got) and math.isnan(want)), (name, p, i, j)
                    flag = ds.sensitivity_flags.sel(derivative=f"d{name}_d{p}").values[i, j]
                    meanings = ds.sensitivity_flags.attrs["flag_meanings"].split()
                    assert meanings[flag] == r.sensitivity_flags[name][p], (name, p, i, j)
