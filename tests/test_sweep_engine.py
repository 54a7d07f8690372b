"""The sweep engine: reduction, agreement with solve_point, the Dataset and the NetCDF file."""

from __future__ import annotations

import logging
import math

import netCDF4
import numpy as np
import pytest

from cosserat_channel import outputs
from cosserat_channel.parameters import PARAMETERS
from cosserat_channel.solver import batch
from cosserat_channel.solver.point import solve_point
from cosserat_channel import status as st
from cosserat_channel.sweep import run_sweep
from cosserat_channel.sweep.plan import Plan, block_plan
from cosserat_channel.sweep.spec import SweepError, load_sweep
from support import LOCAL_CLUSTER

MATERIAL = {"d_p": 0.002, "rho_p": 2940, "phi": 25}
# eps L = 1/3 three ways, as in model.md's similarity check, plus products of their own.
SHARED = {"eps": [1 / 30, 1 / 15, 1 / 60, 0.1], "L": [5.0, 10.0, 20.0], "K": [0.0, 0.5, 3.0],
          "A": [1 / 3, 1.0], "N": [1.0, 1.5]}
# One point of every status: A = -1 closed form; A = -1.5 with N = 1 (wall_inadmissible) and
# N = 1.5 (axis_spin_unbounded); eps L = 3.9 (path leaves D > 0) and 5 (axis) at A = 1/3, N = 1.
STATUSES = {"eps": [1 / 30, 0.39, 0.5], "L": [10.0], "K": [0.0, 0.5, 300.0],
            "A": [-1.5, -1.0, 1 / 3], "N": [1.0, 1.5]}
POINT_FIELDS = ("Delta", "xi_p", "slip", "u_axis", "m_wall", "sigma_yx_wall", "xi_stop")
MATERIAL_FIELDS = ("nu", "sigma_xx_wall_Pa", "sigma_xy_wall_Pa", "sigma_yx_wall_Pa", "m_wall_Pa_m")


def sweep(grid, **output):
    m = {"grid": dict(grid)}
    if output.pop("material", None):
        m["material"] = MATERIAL
    if output:
        m["output"] = output
    return m


def same(a, b) -> bool:
    return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)


def assert_same_values(ds1, ds2):
    assert set(ds1.data_vars) == set(ds2.data_vars)
    for v in ds1.data_vars:
        assert ds1[v].dtype == ds2[v].dtype, v
        assert same(ds1[v].values, ds2[v].values), v


@pytest.fixture(scope="module")
def status_ds():
    return run_sweep(sweep(STATUSES, material=True, profile_points=6), workers=2)


def test_reduced_equals_unreduced():
    """One integration per eps L product gives exactly the per-point values."""
    spec = load_sweep(sweep(SHARED))
    plan = Plan(spec.coords())
    assert plan.n_triples < spec.size // spec.K.size  # eps L products really are shared
    reduced = run_sweep(spec, workers=2)
    unreduced = run_sweep(spec, workers=2, reduce=False)
    assert reduced.attrs["reduced"] == 1 and unreduced.attrs["reduced"] == 0
    assert_same_values(reduced, unreduced)
    assert np.isfinite(reduced.Delta.values).any()


def test_matches_solve_point_at_every_status(status_ds):
    """Every value, at every status, is solve_point's to the last bit (material included)."""
    ds = status_ds
    codes = set(np.unique(ds.status.values).tolist())
    assert {st.OK, st.WALL_INADMISSIBLE, st.EPS_TOO_LARGE_AXIS, st.EPS_TOO_LARGE_PATH,
            st.AXIS_SPIN_UNBOUNDED} <= codes
    for idx in np.ndindex(ds.status.shape):
        point = {d: float(ds[d].values[i]) for d, i in zip(("eps", "L", "K", "A", "N"), idx)}
        ref = solve_point(**point, material=MATERIAL)
        assert int(ds.status.values[idx]) == int(ref.status), point
        for name in POINT_FIELDS + MATERIAL_FIELDS:
            got = float(ds[name].values[idx])
            want = getattr(ref, name)
            assert got == want or (math.isnan(got) and math.isnan(want)), (name, point, got, want)


def test_profiles_match_solve_point(status_ds):
    """Profiles on the xi dimension equal solve_point's, A = -1 closed form included."""
    ds = status_ds
    xi = ds.xi.values
    assert same(xi, np.linspace(0, 1, 6))
    assert ds.u_over_u0.dims == ("eps", "L", "K", "A", "N", "xi")
    sel = dict(eps=1 / 30, L=10.0, K=0.5, N=1.0)
    for A in (-1.0, 1 / 3):
        ref = solve_point(**sel, A=A, profile=xi)
        for name in ("u_over_u0", "omega_hat", "m", "sigma_yx"):
            assert same(ds[name].sel(**sel, A=A).values, ref.profile[name]), (A, name)
    assert np.isnan(ds.u_over_u0.sel(eps=0.5, L=10.0, K=0.5, A=1 / 3, N=1.0).values).all()


def test_only_requested_variables():
    """Only the listed variables (plus status) are computed; no xi without profile_points."""
    ds = run_sweep(sweep(SHARED, variables=["slip", "stage1_steps"]), workers=1)
    assert set(ds.data_vars) == {"slip", "stage1_steps", "status"}
    assert "xi" not in ds.dims
    assert ds.stage1_steps.dtype == np.int32 and (ds.stage1_steps.values > 0).any()
    full = run_sweep(sweep(SHARED), workers=1)
    assert same(ds.slip.values, full.slip.values)
    assert "nu" not in full and "xi_p" in full and "stage1_steps" not in full


def test_workers_and_block_sizes_give_identical_values():
    """1 or 2 workers, any block size: the same numbers."""
    spec = load_sweep(sweep(SHARED))
    a = run_sweep(spec, workers=1)
    b = run_sweep(spec, workers=2, block_size=1)
    c = run_sweep(spec, workers=2, block_size=7)
    assert_same_values(a, b)
    assert_same_values(a, c)


def test_block_plan_balances_cost():
    """Blocks dealt from a skewed cost ranking cost within a few percent of each other."""
    rng = np.random.default_rng(1)
    cost = np.concatenate([rng.uniform(1000, 2000, 50), rng.uniform(10, 20, 950)])
    blocks = block_plan(cost, 100)
    assert len(blocks) == 10
    assert same(np.sort(np.concatenate(blocks)), np.arange(1000))
    totals = np.array([cost[b].sum() for b in blocks])
    assert totals.max() / totals.min() < 1.1
    # a contiguous split of the same ranking would leave one block with all the expensive ones
    assert cost[:100].sum() / totals.mean() > 3


def test_block_plan_is_the_snake_deal():
    """block_plan reads the snake off the cost ranking without a grid-sized array per step; a
    plain deal (the block of every position of the ranking, then each block's triples in order)
    gives the same blocks, for block counts that divide the triples and counts that do not."""
    rng = np.random.default_rng(7)
    for n, size in [(1, 1), (10, 3), (1000, 100), (1001, 7), (997, 1000), (50, 1)]:
        cost = np.round(rng.exponential(1.0, n), 1)  # ties: the ranking's stability counts
        n_blocks = -(-n // size)
        rank = np.argsort(-cost, kind="stable")
        block_of = np.empty(n, dtype=np.int64)
        for i, t in enumerate(rank):
            lap, pos = divmod(i, n_blocks)
            block_of[t] = pos if lap % 2 == 0 else n_blocks - 1 - pos
        got = block_plan(cost, size)
        assert len(got) == n_blocks
        for k, b in enumerate(got):
            assert b.dtype == np.int64 and same(b, np.flatnonzero(block_of == k)), (n, size, k)


@pytest.mark.parametrize("reduce", [True, False])
def test_packed_inputs_unpack_to_the_plans_inputs(reduce):
    """What a worker is sent (each triple's eps values and the K axis) unpacks to the very
    inputs the plan gives, byte for byte, for eta values shared by several (eps, L) pairs; and
    every grid point is one entry, its eps * K, of a triple of its eps * L, A and N."""
    spec = load_sweep(sweep(SHARED))
    plan = Plan(spec.coords(), reduce=reduce, block_size=5)
    assert reduce is False or plan.eta_u.size < plan.shape[0] * plan.shape[1]  # shared products
    covered = np.zeros(plan.size, dtype=int)
    for k in range(len(plan.blocks)):
        want, got = plan.inputs(k), plan.packed_inputs(k).unpack()
        for field in ("eta", "A", "N", "eps_K", "offsets"):
            a, b = getattr(want, field), getattr(got, field)
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), (k, field)
        assert got.flat.size == 0
        assert plan.solve_inputs(k).flat.size == 0
        # Each entry is its grid point's eps * K, of a triple with that point's eps * L, A, N.
        e, l, kk, a, n = np.unravel_index(want.flat, plan.shape)
        owner = np.repeat(np.arange(want.eta.size), np.diff(want.offsets))
        assert np.array_equal(want.eps_K, plan.eps[e] * plan.K[kk]), k
        assert np.array_equal(want.eta[owner], plan.eps[e] * plan.L[l]), k
        assert np.array_equal(want.A[owner], plan.A[a]) and np.array_equal(want.N[owner], plan.N[n])
        covered[want.flat] += 1
    assert (covered == 1).all()


@pytest.mark.parametrize("reduce", [True, False])
def test_a_plan_takes_what_plan_memory_says(monkeypatch, reduce):
    """The plan of a grid with one long axis (every eps its own integration) peaks within
    plan_memory: 146 bytes per integration before its per-integration work went slice by slice
    (74 now); and count_triples counts the integrations before any plan exists."""
    import tracemalloc

    from cosserat_channel.sweep import plan as plan_mod

    monkeypatch.setattr(plan_mod, "SLICE", 1 << 12)  # slices far smaller than the grid
    n = 200_000
    axes = {"eps": np.logspace(-3, -1, n), "L": np.array([10.0]), "K": np.array([0.5, 1.0]),
            "A": np.array([1.0]), "N": np.array([1.0])}
    Plan({d: v[:10] for d, v in axes.items()})  # the classify kernel loaded before measuring
    tracemalloc.start()
    try:
        p = Plan(axes, reduce=reduce, tile=(4096, 1, 2, 1, 1))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert plan_mod.count_triples(axes, reduce) == p.n_triples == (n if reduce else 2 * n)
    assert peak <= plan_mod.plan_memory(p.shape, p.n_triples, reduce)
    assert peak > 0.3 * plan_mod.plan_memory(p.shape, p.n_triples, reduce)  # not a loose bound


def test_count_triples_is_exact_or_an_upper_bound(monkeypatch):
    """Exact for a small reduced grid (shared eps L products counted once); beyond COUNT_PAIRS
    pairs, every product counted (an upper bound, no grid-sized work)."""
    from cosserat_channel.sweep import plan as plan_mod

    axes = {d: np.asarray(v, dtype=float) for d, v in SHARED.items()}
    exact = Plan(axes).n_triples
    assert plan_mod.count_triples(axes) == exact
    assert plan_mod.count_triples(axes, reduce=False) == Plan(axes, reduce=False).n_triples
    monkeypatch.setattr(plan_mod, "COUNT_PAIRS", 4)
    assert plan_mod.count_triples(axes) == 4 * 3 * 2 * 2 > exact


def test_netcdf_file_is_cf_and_plain_readable(tmp_path):
    """The file carries the CF attributes; plain netCDF4 reads int8 status without _FillValue."""
    out = tmp_path / "r.nc"
    ds = run_sweep(sweep(STATUSES, material=True, profile_points=3), out, workers=2)
    with netCDF4.Dataset(out) as nc:
        assert nc.Conventions == "CF-1.8"
        assert nc.source == "cosserat-channel run"
        for key in ("cosserat_channel_version", "rtol", "atol", "sweep_toml", "sweep_sha256",
                    "created", "title", "reduced"):
            assert key in nc.ncattrs(), key
        spec = load_sweep(sweep(STATUSES, material=True, profile_points=3))
        assert nc.sweep_sha256 == spec.sha256 and nc.sweep_toml == spec.text
        status = nc["status"]
        assert status.dtype == np.int8
        assert "_FillValue" not in status.ncattrs()
        assert list(status.flag_values) == [s.value for s in st.Status]
        assert status.flag_meanings.split() == [s.name for s in st.Status]
        assert status.dimensions == ("eps", "L", "K", "A", "N")
        for name, var in nc.variables.items():
            assert "units" in var.ncattrs(), name
            assert "long_name" in var.ncattrs(), name
        assert nc["eps"].long_name == PARAMETERS["eps"].long_name
        assert nc["eps"].description == "particle diameter / channel half-width, d_p/W"
        assert nc["Delta"].units == outputs.OUTPUTS["Delta"].units
        assert same(nc["Delta"][:].filled(np.nan), ds.Delta.values)
        assert same(nc["status"][:], ds.status.values)
        assert nc["u_over_u0"].dimensions[-1] == "xi"


def test_no_output_writes_nothing(tmp_path, monkeypatch):
    """Without output (and no path in the sweep) only the Dataset is returned."""
    monkeypatch.chdir(tmp_path)
    ds = run_sweep(sweep({"eps": 0.05, "L": 10, "K": 1, "A": 1 / 3, "N": 1}))
    assert ds.status.shape == (1, 1, 1, 1, 1)  # length-1 dimensions are kept
    assert list(tmp_path.iterdir()) == []


def test_output_path_from_spec(tmp_path):
    """The sweep's [output] path is used when no output is given; the store is removed after."""
    out = tmp_path / "from_spec.nc"
    run_sweep(sweep({"eps": 0.05, "L": 10, "K": 1, "A": 1 / 3, "N": 1}, path=str(out)))
    assert out.exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["from_spec.nc"]


def test_progress_counts_the_blocks_in_the_one_progress_protocol(tmp_path):
    """progress(done, total, text): once before any block, then once per stored block from the
    solving threads, in order, ending at the plan's block count; anything else is refused."""
    calls = []
    spec = load_sweep(sweep(SHARED))
    run_sweep(spec, tmp_path / "p.nc", workers=2, block_size=4,
              progress=lambda *call: calls.append(call))
    total = calls[0][1]
    assert total > 2
    assert calls == [(done, total, "blocks solved") for done in range(total + 1)]
    with pytest.raises(SweepError, match="progress must be a callable"):
        run_sweep(spec, progress=True)


def test_kernel_exception_costs_one_triple(monkeypatch):
    """A kernel that raises on one triple loses that triple only, as integration_failed."""
    real = batch.solve_batch
    bad_eta = 0.5

    def flaky(eta, *args):
        if np.any(eta == bad_eta):
            raise ZeroDivisionError("division by zero")
        return real(eta, *args)

    monkeypatch.setattr(batch, "solve_batch", flaky)
    grid = {"eps": [0.05], "L": [5.0, 10.0, 20.0], "K": [0.5, 1.0], "A": [1 / 3], "N": [1.0]}
    ds = run_sweep(sweep(grid), workers=1, block_size=3)
    status = ds.status.sel(eps=0.05, A=1 / 3, N=1.0).values
    assert (status[1] == st.INTEGRATION_FAILED).all()  # eps L = 0.5
    assert (status[[0, 2]] == st.OK).all()
    assert np.isnan(ds.Delta.sel(eps=0.05, L=10.0).values).all()


def test_bad_arguments_raise_sweep_error():
    """Invalid workers or block sizes are rejected before any work."""
    with pytest.raises(SweepError):
        run_sweep(sweep(SHARED), workers=0)
    with pytest.raises(SweepError):
        run_sweep(sweep(SHARED), block_size=0)
    with pytest.raises(SweepError, match="compress"):
        run_sweep(sweep(SHARED), compress="gzip")


def test_distributed_scheduler_gives_identical_values(tmp_path, caplog):
    """Blocks run in worker processes of a dask.distributed cluster come back to the client with
    the threaded run's values, bit for bit; the run counts the workers' CPU and threads (4
    here, whatever this machine's cores), not its own idle threads'."""
    distributed = pytest.importorskip("distributed")
    spec = load_sweep(sweep(SHARED, profile_points=3))
    out, calls = tmp_path / "d.nc", []
    with distributed.LocalCluster(n_workers=2, threads_per_worker=2, processes=True,
                                  **LOCAL_CLUSTER) as cluster, \
            caplog.at_level(logging.INFO, logger="cosserat_channel.sweep"):
        ds = run_sweep(spec, out, scheduler=cluster.scheduler_address, block_size=4,
                       progress=lambda *call: calls.append(call))
    assert out.exists() and not (tmp_path / "d.nc.partial").exists()
    assert [done for done, _, _ in calls] == list(range(len(calls))) and calls[-1][1] == len(calls) - 1
    assert_same_values(ds, run_sweep(spec, workers=2))
    phase = next(r for r in caplog.records if "solving threads" in r.msg)
    cpu, threads = phase.args[2], phase.args[3]
    assert cpu > 0 and threads == 4, phase.getMessage()
