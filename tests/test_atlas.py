"""The solvability atlas against independent references: direct bisection (``trace_edge``),
direct status solves (``Workspace.status``) and the analytic lines of Appendix A.

The atlases here are coarse (one cell of degree 6, tolerance 1e-3, a box of 0.25 x 0.1): the module
costs about a hundred traces; ``benchmarks/bench_atlas.py`` measures the full-size targets.
"""

import math
import subprocess
import sys

import numpy as np
import pytest

from cosserat_channel import atlas as at
from cosserat_channel.atlas import chebyshev
from cosserat_channel import regimes
from cosserat_channel import status as st
from cosserat_channel.cli import main
from cosserat_channel.parameters import ParameterError
from cosserat_channel.solver.point import Workspace

# A < 1 and N < 1: feasible only between eta_min ~ 0.05 and eta_max ~ 2-4 (two transitions).
BOX_A = (0.25, 0.5)
BOX_N = (0.8, 0.9)
TOL = 1e-3


@pytest.fixture(scope="module")
def atlas():
    return at.build_atlas(BOX_A, BOX_N, tol=TOL, degree=6, max_depth=0)


@pytest.fixture(scope="module")
def atlas_file(atlas, tmp_path_factory):
    path = tmp_path_factory.mktemp("atlas") / "atlas.nc"
    at.save_atlas(atlas, path)
    return path


def test_threads_build_the_same_atlas():
    """Two threads trace a cell's nodes at once (the status solves, the D(1) probes and the
    smooth D(1) zeros next to the node/focus switch, each with its own work arrays): the same
    traces in the same order, the same interpolants and the same count of solves as one thread."""
    kw = dict(tol=1e-3, degree=2, max_depth=0)
    box = ((-0.3, -0.2), (1.38, 1.45))  # across the switch: tangential and smooth edges
    one, two = at.build_atlas(*box, **kw), at.build_atlas(*box, **kw, workers=2)
    for key, value in one.samples.items():
        np.testing.assert_array_equal(two.samples[key], value, err_msg=key)
    np.testing.assert_array_equal(two.coef, one.coef)
    assert two.attrs["n_solves"] == one.attrs["n_solves"]
    assert one.samples["bands"].max() > regimes.SMOOTH_BAND  # the smooth zeros were exercised
    with pytest.raises(ParameterError, match="workers"):
        at.build_atlas(*box, **kw, workers=0)


def test_a_stopped_build_resumes_to_the_same_atlas(monkeypatch, tmp_path):
    """A build stopped after some traces holds them in the caller's dict; kept in a file and
    read back (every field of each Edge as it was), they resume a build that traces only the
    rest and gives the atlas of an uninterrupted build, solve counts included, whatever the
    threads. Another key is refused."""
    import dataclasses

    kw = dict(tol=1e-3, degree=2, max_depth=1)
    whole = at.build_atlas(BOX_A, BOX_N, **kw)
    calls, trace = [0], regimes.trace_edge

    def stopping(*args, **kwargs):
        calls[0] += 1
        if calls[0] > 9:
            raise KeyboardInterrupt
        return trace(*args, **kwargs)

    monkeypatch.setattr(regimes, "trace_edge", stopping)
    traces = {}
    with pytest.raises(KeyboardInterrupt):
        at.build_atlas(BOX_A, BOX_N, **kw, traces=traces)
    assert len(traces) == 9
    key = at.traces_key(BOX_A, BOX_N, 1e-3, 2, 1, (0.001, 100.0), at.MAX_DEGREE)
    path = tmp_path / "a.nc.partial"
    at.save_traces(path, traces, key)
    back = at.load_traces(path, key)
    assert list(back) == list(traces)
    for k, tr in traces.items():
        for f in dataclasses.fields(tr.edge):
            np.testing.assert_array_equal(getattr(back[k].edge, f.name), getattr(tr.edge, f.name))
        assert (back[k].low, back[k].solves) == (tr.low, tr.solves)
    with pytest.raises(ParameterError, match="another atlas.*tol 0.001 there, 0.01 here"):
        at.load_traces(path, {**key, "tol": 1e-2})
    calls[0] = -10**6  # no more stops: count what the resumed build traces
    resumed = at.build_atlas(BOX_A, BOX_N, **kw, traces=back, workers=2)
    assert calls[0] + 10**6 == whole.attrs["n_traces"] - 9
    assert len(back) == whole.attrs["n_traces"]  # the caller's dict gets the new traces too
    assert at.to_dataset(resumed).identical(at.to_dataset(whole))


def _status(eta, A, N, ws):
    from cosserat_channel.physics import model

    code = model.classify(eta, A, N)
    if code == st.OK and A != -1.0:
        code = ws.status(eta, A, N, regimes.EDGE_RTOL, regimes.EDGE_ATOL)
    return code


def test_transitions_agree_with_direct_bisection(atlas):
    """At random (A, N) the atlas has the traced transitions, each within its stated error."""
    rng = np.random.default_rng(14)
    A = rng.uniform(*BOX_A, 8)
    N = rng.uniform(*BOX_N, 8)
    leaf, low, eta, err = atlas.transitions(A, N)
    assert (leaf >= 0).all() and (atlas.leaf_n[leaf] == 2).all()
    for k in range(A.size):
        edge = regimes.trace_edge(A[k], N[k], eta_range=(5e-4, 200))
        assert edge.transitions.size == 2 and not low[k]
        rel = np.abs(np.log(eta[k] / edge.transitions))
        assert rel.max() <= max(TOL, err[k]), (A[k], N[k], eta[k], edge.transitions)


def test_classify_agrees_with_direct_solves(atlas_file):
    """Every decided point has the status a solve gives; points within 1e-7 of an edge are
    undecided, points 1 % from it are decided; K does not enter."""
    atlas = at.load_atlas(atlas_file)
    rng = np.random.default_rng(3)
    n = 120
    A = rng.uniform(*BOX_A, n)
    N = rng.uniform(*BOX_N, n)
    _, _, t, _ = atlas.transitions(A, N)
    pick = rng.integers(0, 2, n)
    edge = t[np.arange(n), pick]
    factor = np.r_[np.full(40, 1 + 1e-7), np.full(40, 1.01), np.full(40, 0.99)]
    eta = np.r_[edge[:40] * factor[:40], edge[40:] * factor[40:]]
    eta[::7] = 10 ** rng.uniform(-3, 2, eta[::7].size)  # and some anywhere in the range
    L = 100.0
    codes = at.classify(eta / L, L, rng.uniform(0, 5, n), A, N, atlas=atlas_file)
    ws = Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS)
    direct = np.array([_status(e, a, b, ws) for e, a, b in zip(eta, A, N)])
    decided = codes != at.UNDECIDED
    assert np.array_equal(codes[decided], direct[decided])
    near = np.abs(factor - 1) < 1e-6
    near[::7] = False
    assert not decided[near].any()
    assert decided[~near].mean() > 0.95
    assert {st.OK, st.EPS_TOO_LARGE_PATH} <= set(codes[decided].tolist())


def test_classify_decides_analytic_regimes_exactly(atlas):
    """Outside the atlas's box Appendix A still decides; the rest there is undecided."""
    A = np.array([-2.0, -0.9, 0.3, -1.0, 3.0, 0.3])
    N = np.array([0.5, 0.5, 1.0, 2.0, 2.0, 0.85])
    eta = np.array([0.1, 0.1, 100.0, 1.0, 1.0, 2e-4])  # (0.3, 1): axis edge at 3.71
    codes = at.classify(eta / 100.0, 100.0, 0.5, A, N, atlas=atlas)
    assert codes.tolist() == [st.WALL_INADMISSIBLE, st.WALL_INADMISSIBLE, st.EPS_TOO_LARGE_AXIS,
                              st.OK, at.UNDECIDED, at.UNDECIDED]


def test_a_mixed_cell_at_the_deepest_level_is_an_envelope():
    """A cell at depth 0 where the window of solutions closes (eta_min and eta_max meet next to
    the wall line near A = -0.9, N = 0.97: some nodes have both, some none) is not left
    unresolved: its leaf decides where every node agrees (below and above every node's window:
    no solution, as a solve says) and leaves the cluster of transitions undecided, with its
    width as its error."""
    box_a, box_n = (-0.90625, -0.890625), (0.9609375, 0.975)
    a = at.build_atlas(box_a, box_n, tol=1e-3, degree=2, max_depth=0)
    assert set(zip(a.samples["low"].tolist(), a.samples["n"].tolist())) == {(0, 0), (0, 2)}
    assert (a.leaf_n >= 0).all() and a.leaf_degree.tolist() == [[0, 0]] and a.leaf_error[0] > 1e-3
    A, N = [-0.893, -0.8915], [0.974, 0.9745]  # beside the wall line A = 1 - 2 N^2
    ws = Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS)
    for eta in (0.0012, 0.05):  # below and above every node's window
        codes = at.classify(eta, 1.0, 0.5, A, N, atlas=a)
        assert codes.tolist() == [_status(eta, x, y, ws) for x, y in zip(A, N)]
        assert codes.tolist() == [st.EPS_TOO_LARGE_PATH] * 2
    lo, hi = np.exp(a.coef[0, :, 0, 0])
    assert (at.classify(math.sqrt(lo * hi), 1.0, 0.5, A, N, atlas=a) == at.UNDECIDED).all()
    assert a.boundary([-0.893], [0.974, 0.9745])["resolved"].values.all()


def test_a_transition_leaving_the_range_keeps_the_others_interpolated():
    """Across N = 1 eta_min leaves the traced range: the nodes below have two transitions, those
    above one. The cell is not an envelope: eta_max is interpolated to tol over the whole box
    (the paper's point A = 1/3, N = 1 against a fresh trace), and where eta_min reaches into the
    answered range of a deepest cell it is that cell's envelope, its error stated."""
    a = at.build_atlas((0.3, 0.36), (0.96, 1.02), tol=1e-8, max_depth=2)
    assert set(zip(a.samples["low"].tolist(), a.samples["n"].tolist())) == {(0, 2), (1, 1)}
    assert (a.leaf_degree > 0).all()  # no envelope leaf
    last = a.leaf_transition_error[np.arange(a.leaf_n.size), a.leaf_n - 1]
    assert (last <= 1e-8).all()  # eta_max everywhere
    edge = regimes.trace_edge(1 / 3, 1.0, eta_range=(5e-4, 200))
    got = a.boundary([1 / 3], [1.0])
    assert abs(math.log(float(got["eta_max"].values.ravel()[0]) / edge.transitions[-1])) \
        <= at.SAFETY * 1e-8
    # eta_min is answered for where it is above 1e-3: within its stated error of a fresh trace
    rng = np.random.default_rng(4)
    A, N = rng.uniform(0.3, 0.36, 6), rng.uniform(0.96, 1.0, 6)
    leaf, _, eta, _ = a.transitions(A, N)
    for k in range(A.size):
        edge = regimes.trace_edge(A[k], N[k], eta_range=(5e-4, 200))
        for t in edge.transitions[edge.transitions >= 1e-3]:
            d = np.abs(np.log(eta[k] / t))
            m = int(np.nanargmin(d))
            assert d[m] <= at.SAFETY * max(1e-8, a.leaf_transition_error[leaf[k], m]), (A[k], N[k])


def test_boundary_dataset_matches_traced_boundary(atlas):
    """Atlas.boundary gives trace_boundary's eta_max, eta_min and kind (within the tolerance)."""
    A, N = [0.3, 0.45], [0.82, 0.88]
    got = atlas.boundary(A, N)
    ref = regimes.trace_boundary(A, N)
    assert np.array_equal(got["edge_kind"].values, ref["edge_kind"].values)
    for v in ("eta_max", "eta_min"):
        np.testing.assert_allclose(got[v].values, ref[v].values, rtol=10 * TOL)
    np.testing.assert_array_equal(got["axis_edge_eta"].values, ref["axis_edge_eta"].values)
    # The stated error: the leaf's largest per-transition error, never below the tolerance.
    leaf, _, _, _ = atlas.transitions(*np.meshgrid(A, N, indexing="ij"))
    want = np.fmax(np.max(atlas.leaf_transition_error[leaf], axis=-1), atlas.tol)
    np.testing.assert_array_equal(got["eta_error"].values, want)


def test_boundary_below_the_wall_line_has_no_solution(atlas):
    bds = atlas.boundary([-0.5, 0.0], [0.3, 0.5])  # all four points: A < 1 - 2 N^2
    assert (bds["edge_kind"].values == 2).all() and bds["resolved"].values.all()
    assert np.isnan(bds["eta_error"].values).all()  # no transition: no error to state


def test_file_round_trip_and_reading_without_numba(atlas, atlas_file, tmp_path):
    """The file gives back the atlas; reading it and classifying never imports numba."""
    b = at.load_atlas(atlas_file)
    for name in ("leaf_level", "leaf_i", "leaf_j", "leaf_n", "leaf_error", "coef"):
        np.testing.assert_array_equal(getattr(b, name), getattr(atlas, name))
    assert b.samples["A"].size == atlas.attrs["n_traces"] > 0
    code = ("import sys, cosserat_channel.atlas as a; "
            f"print(a.classify(0.1, 10, 0.5, 0.3, 0.85, atlas={str(atlas_file)!r})); "
            "assert 'numba' not in sys.modules, 'numba imported'")
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)
    bad = tmp_path / "x.nc"
    regimes.trace_boundary([0.3], [1.0], n_coarse=4).to_netcdf(bad)
    with pytest.raises(ParameterError, match="not a solvability atlas"):
        at.load_atlas(bad)


@pytest.mark.parametrize("kwargs, match", [
    (dict(tol=1e-9), "tol"), (dict(degree=3), "degree"), (dict(max_depth=9), "max_depth"),
    (dict(A_range=(1, 0)), "A range"), (dict(N_range=(1, 0.5)), "N range"),
    # The ranges of parameters.py, as for a point: beyond them the kernels overflow.
    (dict(N_range=(0, 1)), r"N = 0\S* is outside the allowed range \(0, 1e\+06\]"),
    (dict(A_range=(0, 5000)), r"A = 5000\S* is outside the allowed range \[-1000, 1000\]"),
    (dict(N_range=(0.5, 1e300)), r"N = 1e\+300 is outside"),
    (dict(max_degree=4), "max_degree"), (dict(max_degree=128), "max_degree"),
])
def test_build_rejects_bad_arguments(kwargs, match):
    with pytest.raises(ParameterError, match=match):
        at.build_atlas(**kwargs)


def test_classify_rejects_bad_points(atlas):
    with pytest.raises(ParameterError, match="eps"):
        at.classify([0.1, 2.0], 1.0, 0.5, 0.3, 0.85, atlas=atlas)


def test_whole_plane_at_a_shallow_depth_saves_and_loads(tmp_path):
    """Cells with different numbers of transitions side by side (the whole plane, split once)
    make one file: saving once failed there on the transition dimension's size."""
    a = at.build_atlas((-1.0, 5.0), (0.3, 3.0), tol=1e-3, degree=4, max_depth=1, workers=2)
    assert len({int(n) for n in a.leaf_n if n >= 0}) > 1  # leaves with 0, 1 and 2 transitions
    path = tmp_path / "plane.nc"
    at.save_atlas(a, path)
    b = at.load_atlas(path)
    assert at.to_dataset(b).identical(at.to_dataset(a))


def test_cli_atlas_and_regime_map_from_it(tmp_path, capsys, monkeypatch, atlas_file):
    """atlas: bad input is one line, an existing file is kept; plot --regime --atlas traces
    nothing; the cached atlas is used when it covers the map."""
    out = tmp_path / "a.nc"
    assert main(["atlas", "-o", str(out), "--tol", "1e-12"]) == 2
    assert "tol = 1e-12 is outside [1e-08, 0.1]" in capsys.readouterr().err
    assert main(["atlas", "-o", str(out), "--workers", "0"]) == 2
    assert "--workers must be a positive integer; got 0" in capsys.readouterr().err
    assert not out.exists()
    out.write_text("keep")
    assert main(["atlas", "-o", str(out)]) == 2
    assert "exists; kept" in capsys.readouterr().err and out.read_text() == "keep"

    from cosserat_channel.sweep import run_sweep

    res = tmp_path / "r.nc"
    ds = run_sweep({"grid": {"eps": 0.1, "L": 10, "K": 0.5, "A": {"linspace": [0.25, 0.5, 4]},
                             "N": {"linspace": [0.8, 0.9, 3]}}}, workers=1)
    ds.to_netcdf(res)
    monkeypatch.setattr(regimes, "trace_boundary", lambda *a, **k: pytest.fail("traced"))
    png = tmp_path / "map.png"
    assert main(["plot", str(res), "--regime", "--x", "A", "--y", "N", "--atlas",
                 str(atlas_file), "-o", str(png)]) == 0
    assert png.stat().st_size > 0
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    (tmp_path / "cache" / "cosserat-channel").mkdir(parents=True)
    (tmp_path / "cache" / "cosserat-channel" / "atlas.nc").write_bytes(atlas_file.read_bytes())
    assert main(["plot", str(res), "--regime", "--x", "A", "--y", "N", "-o", str(png)]) == 2
    assert "--overwrite" in capsys.readouterr().err  # the map drawn above is kept
    assert main(["plot", str(res), "--regime", "--x", "A", "--y", "N", "-o", str(png),
                 "--overwrite"]) == 0
    assert "cached atlas" in capsys.readouterr().err
    bnd = tmp_path / "b.nc"
    assert main(["boundary", "--A", "0.3,0.4", "--N", "0.85", "--atlas", str(atlas_file),
                 "-o", str(bnd), "--plot", str(tmp_path / "b.png")]) == 0


def test_scalars_give_scalars(atlas):
    leaf, low, eta, err = atlas.transitions(0.3, 0.85)
    assert leaf.shape == low.shape == err.shape == () and eta.shape == (2,)
    assert at.classify(0.01, 10.0, 0.5, 0.3, 0.85, atlas=atlas).shape == ()


def test_classify_margins_is_classify_margin_on_arrays():
    """The array version gives the scalar one's code at every point, the boundaries included."""
    from cosserat_channel.physics import analytic

    rng = np.random.default_rng(5)
    A = np.r_[rng.uniform(-3, 3, 2000), -1.0, -1.0, 1 - 2 * 0.7**2, 0.5, 0.5, -2.0]
    N = np.r_[rng.uniform(0.05, 2, 2000), 0.5, 2.0, 0.7, 1.0, 1.0, 0.1]
    margin = np.r_[rng.uniform(-2, 2, 2000), 0.0, -1.0, 0.3, 0.0, np.nan, 1.0]
    got = analytic.classify_margins(margin, A, N)
    want = [analytic.classify_margin(m, a, n) for m, a, n in zip(margin, A, N)]
    assert got.dtype == np.int8 and got.tolist() == want
    assert len(set(want)) == 4


def test_regime_map_takes_an_edge_on_its_own_grid_as_it_is(atlas):
    """An edge given on the map's contouring grid is used without interpolation, and agrees with
    the same edge interpolated from a coarser grid (to the interpolation's error)."""
    from cosserat_channel.plot import regimes as pr

    A = np.linspace(*BOX_A, pr.MAP_GRID)
    N = np.linspace(*BOX_N, pr.MAP_GRID)
    exact = pr._traced_on_grid("A", "N", A, N, {}, atlas.boundary(A, N))
    want = atlas.boundary(A, N)["eta_max"].values.T
    np.testing.assert_array_equal(exact["eta_max"], want)
    coarse = pr._traced_on_grid("A", "N", A, N, {}, atlas.boundary(np.linspace(*BOX_A, 41),
                                                                     np.linspace(*BOX_N, 41)))
    np.testing.assert_allclose(coarse["eta_max"], exact["eta_max"], rtol=1e-4)
    # One plotted direction, the other fixed: a column broadcast along the fixed axis.
    line = pr._traced_on_grid("A", "eps", A, np.array([0.01, 0.02]), {"N": 0.85},
                              atlas.boundary(A, [0.85]))
    np.testing.assert_array_equal(line["eta_max"][0], atlas.boundary(A, [0.85])["eta_max"].values[:, 0])
    assert line["eta_max"].shape == (2, A.size)


def test_regime_map_from_an_atlas_needs_no_scipy(atlas_file, tmp_path):
    """plot --regime --atlas in a fresh process imports neither scipy.optimize (line plots'
    asymptotics) nor scipy.interpolate (the edge is evaluated on the map's grid)."""
    from cosserat_channel.sweep import run_sweep

    res = tmp_path / "r.nc"
    run_sweep({"grid": {"eps": 0.1, "L": 10, "K": 0.5, "A": {"linspace": [*BOX_A, 4]},
                        "N": {"linspace": [*BOX_N, 3]}}}, workers=1).to_netcdf(res)
    code = ("import sys; from cosserat_channel.cli import main; "
            f"assert main(['plot', {str(res)!r}, '--regime', '--x', 'A', '--y', 'N', '--atlas', "
            f"{str(atlas_file)!r}, '-o', {str(tmp_path / 'm.png')!r}]) == 0; "
            "bad = [m for m in ('scipy.optimize', 'scipy.interpolate', 'numba') if m in sys.modules]; "
            "assert not bad, bad")
    subprocess.run([sys.executable, "-c", code], check=True, capture_output=True)


# ---------------------------------------------------------------------------------------------
# The error estimate and the refinement, on edges whose truth is known exactly
# ---------------------------------------------------------------------------------------------
def _synthetic_edge(monkeypatch, noise=0.0, switch=False):
    """Replace trace_edge by an analytic edge (one transition), with optional noise of relative
    size ``noise`` that is a fixed function of (A, N) (as the solver's is): returns log eta.
    The edge is analytic across the node/focus switch too, so the atlas is told that no cell
    crosses it unless ``switch``."""
    def log_eta(A, N):
        return np.log(0.5 + A + N) - 0.3 * np.log1p(0.25 * (A - 2.2) ** 2 * N)

    def fake(A, N, *, eta_range, workspace=None, **kw):
        e = np.exp(log_eta(A, N))
        if noise:
            e *= 1.0 + noise * np.sin(1e4 * A + 3e4 * N)
        return regimes.Edge(A, N, e, regimes.EDGE_BOUNDED, eta_range[0], st.EPS_TOO_LARGE_PATH,
                            np.array([e]))

    monkeypatch.setattr(regimes, "trace_edge", fake)
    if not switch:
        monkeypatch.setattr(at.build, "_crosses_switch", lambda *cell: False)
    return log_eta


def test_estimate_bounds_the_error_and_is_tighter_than_the_tail_sum():
    """On analytic and on nearly singular functions the estimate is above the interpolant's
    measured error; where the coefficients decay geometrically it is at least 3 times below the
    sum of the two highest degrees' coefficients (the old estimate), elsewhere at most
    PLATEAU_SAFETY times the cell's degree times that sum."""
    x = np.linspace(-1, 1, 201)
    cases = [(lambda a, n: np.log(3.0 + a + 0.5 * n), True),
             (lambda a, n: 1.0 / (2.5 - a - 0.3 * n), True),
             (lambda a, n: np.exp(0.7 * a) * np.cos(n), False),
             (lambda a, n: np.log(1.2 + a) + np.sqrt(2.2 - n), False)]
    for f, geometric in cases:
        for p, q in ((8, 8), (16, 8), (8, 16), (16, 16), (32, 32)):
            xa, xn = at.lobatto(p), at.lobatto(q)
            coef = chebyshev._coefficients(f(xa[:, None], xn[None, :])[None], p, q)
            err, _, _, _ = chebyshev._estimate(coef)
            old = chebyshev._tail(coef)[0]
            got = chebyshev._vandermonde(x, p) @ coef[0] @ chebyshev._vandermonde(x, q).T
            actual = np.abs(got - f(x[:, None], x[None, :])).max()
            assert actual <= err, (p, q, actual, err)
            # (the corner degrees count in both directions: 1.01)
            assert err <= 1.01 * at.PLATEAU_SAFETY * max(p, q) * old + at.ROUNDOFF
            if geometric and err > 1e3 * at.ROUNDOFF:
                assert err * 3 <= old, (p, q, err, old)


def test_p_refinement_reuses_every_trace_and_meets_tol(monkeypatch):
    """A smooth edge is met by raising the degree (nested nodes: every trace is a node of the
    final cell), within tol of the exact edge at random points."""
    log_eta = _synthetic_edge(monkeypatch)
    a = at.build_atlas((0.0, 1.0), (1.0, 2.0), tol=1e-8, degree=4, max_depth=2, max_degree=32)
    assert a.leaf_n.tolist() == [1] and a.leaf_degree.max() > 4
    assert a.attrs["n_traces"] == np.prod(a.leaf_degree[0] + 1)
    rng = np.random.default_rng(1)
    A, N = rng.uniform(0, 1, 500), rng.uniform(1, 2, 500)
    _, _, eta, err = a.transitions(A, N)
    rel = np.abs(np.log(eta[:, 0]) - log_eta(A, N))
    assert rel.max() <= 1e-8 and (rel <= err).all() and (err <= 1e-8).all()


def test_a_cell_the_node_focus_switch_crosses_is_split_not_raised(monkeypatch):
    """The same smooth edge on (0, 1) x (1, 2), which the switch N = sqrt((5 + 3A)/2) crosses:
    the root cell is split at degree 4 (no trace spent on a higher degree there), children the
    switch does not cross raise their degree, and tol is met."""
    log_eta = _synthetic_edge(monkeypatch, switch=True)
    a = at.build_atlas((0.0, 1.0), (1.0, 2.0), tol=1e-8, degree=4, max_depth=1, max_degree=32)
    assert (a.leaf_level == 1).all() and len(a.leaf_level) == 4
    lo = a.leaf_of(np.array([0.25]), np.array([1.25]))[0]  # below the switch: not crossed
    assert not at.build._crosses_switch(0.0, 0.5, 1.0, 1.5) and a.leaf_degree[lo].max() > 4
    rng = np.random.default_rng(4)
    A, N = rng.uniform(0, 1, 500), rng.uniform(1, 2, 500)
    _, _, eta, err = a.transitions(A, N)
    rel = np.abs(np.log(eta[:, 0]) - log_eta(A, N))
    assert (rel <= np.fmax(a.tol, err)).all()


def test_crosses_switch_against_the_sampled_curve():
    """Random cells (some reaching past A = -1 or 1): crossed exactly when the curve, sampled
    densely in A, has a value strictly inside the cell's N range."""
    rng = np.random.default_rng(6)
    for _ in range(400):
        a0, a1 = np.sort(rng.uniform(-1.5, 1.5, 2))
        n0, n1 = np.sort(rng.uniform(0.8, 2.2, 2))
        A = np.linspace(max(a0, -1.0), min(a1, 1.0), 4001)
        curve = np.sqrt(0.5 * (5.0 + 3.0 * A)) if a0 < 1.0 and a1 > -1.0 else np.empty(0)
        sampled = bool(np.any((curve > n0) & (curve < n1)))
        near = curve.size and min(abs(curve[0] - n1), abs(curve[-1] - n0)) < 1e-3
        if not near:
            assert at.build._crosses_switch(a0, a1, n0, n1) == sampled, (a0, a1, n0, n1)


def test_refinement_stops_where_the_traces_are_noisier_than_tol(monkeypatch):
    """Traces with 1e-6 noise: refinement stops once it no longer cuts the estimate (far fewer
    traces than splitting to max_depth), and the estimate covers the error against the exact edge."""
    log_eta = _synthetic_edge(monkeypatch, noise=1e-6)
    a = at.build_atlas((0.0, 1.0), (1.0, 2.0), tol=1e-8, degree=8, max_depth=3, max_degree=16)
    uniform = (8 * 8 + 1) ** 2
    assert a.attrs["n_traces"] < uniform / 4
    assert (a.leaf_error > 1e-8).any() and (a.leaf_level < 3).all()
    rng = np.random.default_rng(2)
    A, N = rng.uniform(0, 1, 500), rng.uniform(1, 2, 500)
    _, _, eta, err = a.transitions(A, N)
    rel = np.abs(np.log(eta[:, 0]) - log_eta(A, N))
    assert (rel <= err + 1e-6).all()


@pytest.mark.parametrize("node", [(3, 5), (0, 4), (8, 8)])
def test_one_trace_off_is_covered_by_the_estimate(monkeypatch, node):
    """One trace 1e-6 low (a node inside, on a side, in a corner of the root cell), as where the
    solver's edge is ragged: the atlas's estimate covers its error against the exact edge, next
    to that node too."""
    log_eta = _synthetic_edge(monkeypatch)
    fake = regimes.trace_edge
    x = at.lobatto(8)
    bad = ((x[node[0]] + 1) / 2, 1.0 + (x[node[1]] + 1) / 2)

    def off(A, N, **kw):
        e = fake(A, N, **kw)
        if (A, N) == bad:
            e.transitions = e.transitions * (1 - 1e-6)
        return e

    monkeypatch.setattr(regimes, "trace_edge", off)
    a = at.build_atlas((0.0, 1.0), (1.0, 2.0), tol=1e-8, degree=8, max_depth=2, max_degree=16)
    rng = np.random.default_rng(3)
    A = np.r_[rng.uniform(0, 1, 400), np.clip(bad[0] + rng.normal(0, 0.02, 100), 0, 1)]
    N = np.r_[rng.uniform(1, 2, 400), np.clip(bad[1] + rng.normal(0, 0.02, 100), 1, 2)]
    _, _, eta, err = a.transitions(A, N)
    rel = np.abs(np.log(eta[:, 0]) - log_eta(A, N))
    assert (rel <= np.fmax(a.tol, err)).all(), (rel / np.fmax(a.tol, err)).max()


# ---------------------------------------------------------------------------------------------
# Tangential edges: noise bands
# ---------------------------------------------------------------------------------------------
def test_noise_bands_widen_the_undecided_band(monkeypatch, tmp_path):
    """Synthetic traces that state a noise band of 1e-6 at A > 0.5 and none below: the leaf keeps
    the largest band of its nodes, classify leaves points within SAFETY bands undecided and
    decides those beyond (from the exact edge); the bands survive the file, and an atlas of an
    older format reads with none."""
    log_eta = _synthetic_edge(monkeypatch)
    fake = regimes.trace_edge

    def banded(A, N, **kw):
        e = fake(A, N, **kw)
        e.bands = np.array([1e-6 if A > 0.5 else 0.0])
        return e

    monkeypatch.setattr(regimes, "trace_edge", banded)
    a = at.build_atlas((0.0, 1.0), (1.0, 2.0), tol=1e-8, degree=4, max_depth=1, max_degree=32)
    leaf = a.leaf_of(np.array([0.9, 0.1]), np.array([1.5, 1.5]))
    assert a.leaf_band[leaf[0]] == 1e-6
    assert np.all(a.samples["bands"][a.samples["A"] > 0.5] == 1e-6)
    rng = np.random.default_rng(5)
    A, N = rng.uniform(0.0, 1.0, 400), rng.uniform(1.0, 2.0, 400)
    rel = rng.choice([-1, 1], 400) * 10 ** rng.uniform(-8, -4, 400)
    eta = np.exp(log_eta(A, N)) * (1 + rel)
    codes = at.classify(eta / 100, 100.0, 0.5, A, N, atlas=a)
    band = np.maximum(a.leaf_band[a.leaf_of(A, N)], a.tol)
    assert np.all(codes[np.abs(rel) < at.SAFETY * band * 0.99] == at.UNDECIDED)
    far = np.abs(rel) > 1.01 * at.SAFETY * np.maximum(band, a.leaf_error[a.leaf_of(A, N)])
    assert far.sum() > 100
    truth = np.where(rel < 0, st.OK, st.EPS_TOO_LARGE_PATH)
    assert np.array_equal(codes[far], truth[far])
    path = tmp_path / "a.nc"
    at.save_atlas(a, path)
    b = at.load_atlas(path)
    np.testing.assert_array_equal(b.leaf_band, a.leaf_band)
    np.testing.assert_array_equal(b.samples["bands"], a.samples["bands"])
    ds = at.to_dataset(a).drop_vars(["leaf_band", "sample_bands"])
    ds.attrs["format"] = "cosserat-channel atlas 2"
    old = at.from_dataset(ds)
    assert not old.leaf_band.any() and not old.samples["bands"].any()


NODE_BOX_A = (-0.5, -0.45)
NODE_BOX_N = (1.45, 1.5)  # a tangential edge all over (N^2 > (5 + 3A)/2)


@pytest.fixture(scope="module")
def node_atlas():
    return at.build_atlas(NODE_BOX_A, NODE_BOX_N, tol=1e-8, degree=6, max_depth=0)


def test_atlas_on_a_tangential_edge(node_atlas):
    """Every trace of the box is the node's eta; the atlas meets 1e-8 against direct traces at
    random points, with a stated noise band of the size the statuses flip in (~1e-6)."""
    a = node_atlas
    assert a.leaf_n.tolist() == [1] and a.leaf_error[0] <= 1e-8
    assert 3e-7 < a.leaf_band[0] < 1e-5
    rng = np.random.default_rng(11)
    A, N = rng.uniform(*NODE_BOX_A, 6), rng.uniform(*NODE_BOX_N, 6)
    _, _, eta, _ = a.transitions(A, N)
    for k in range(A.size):
        e = regimes.trace_edge(A[k], N[k], eta_range=(5e-4, 200))
        assert e.tangential[-1]
        assert abs(eta[k, -1] / e.eta_max - 1) <= 1e-8


def test_classify_next_to_a_tangential_edge(node_atlas):
    """Points 1e-9..1e-4 (relative) from the edge: every decided one has the status of a solve,
    those within the noise band are undecided, and most beyond 1e-5 are decided."""
    a = node_atlas
    rng = np.random.default_rng(12)
    n = 300
    A, N = rng.uniform(*NODE_BOX_A, n), rng.uniform(*NODE_BOX_N, n)
    _, _, t, _ = a.transitions(A, N)
    rel = rng.choice([-1, 1], n) * 10 ** rng.uniform(-9, -4, n)
    eta = t[:, -1] * (1 + rel)
    codes = at.classify(eta / 100, 100.0, 0.5, A, N, atlas=a)
    ws = Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS)
    direct = np.array([_status(e, x, y, ws) for e, x, y in zip(eta, A, N)])
    decided = codes != at.UNDECIDED
    assert np.array_equal(codes[decided], direct[decided])
    assert not decided[np.abs(rel) < a.leaf_band[0]].any()
    assert decided[np.abs(rel) > 1e-5].mean() > 0.9


# ---------------------------------------------------------------------------------------------
# Continuation: accuracy against an independent solver, leaves that may not be split
# ---------------------------------------------------------------------------------------------
def test_continued_atlas_against_an_independent_solver():
    """An atlas at tol 1e-8 over a box with an upper and a lower edge, built by continuation
    (almost every trace predicted and corrected): at random (A, N) an independent scipy solver
    (reference.py, rtol 1e-12) has a solution 2 tol inside each interpolated transition and none
    2 tol beyond it; the file states the cost per edge point."""
    from cosserat_channel.physics.reference import reference

    box = ((0.3, 0.35), (0.84, 0.86))
    a = at.build_atlas(*box, tol=1e-8, degree=6, max_depth=0)
    # Every node but the first 3 x 3 grid's continues from a traced neighbour (the neighbour
    # search must reach NEAR_NODE on a box narrower than that: 24 of 49 when it did not).
    assert a.attrs["n_predicted"] >= a.attrs["n_traces"] - 9
    assert a.attrs["solves_per_edge_point"] == a.attrs["n_solves"] / a.attrs["n_edge_points"]
    assert a.leaf_n.tolist() == [2] and a.leaf_error.max() <= 1e-8
    rng = np.random.default_rng(25)
    A, N = rng.uniform(*box[0], 3), rng.uniform(*box[1], 3)
    _, low, eta, _ = a.transitions(A, N)
    for k in range(A.size):
        for t, ok_below in zip(eta[k], (False, True)):
            for f, ok in ((1 - 2e-8, ok_below), (1 + 2e-8, not ok_below)):
                e = t * f
                got = reference(e / 10.0, 10.0, 0.5, A[k], N[k], method="Radau",
                                status_only=True)["status"]
                assert (got == "ok") == ok, (A[k], N[k], t, f, got)


def test_index_finds_the_nearest_node_of_each_signature():
    """The build's bucketed index against a brute-force search over the nine buckets around a
    point: one node per signature, the nearest, nearest first."""
    from cosserat_channel.atlas.tracer import _Index, _Trace

    rng = np.random.default_rng(9)
    size = (0.125, 0.1)
    index, nodes = _Index(size), []
    for _ in range(600):
        key = (float(rng.uniform(0, 1)), float(rng.uniform(0, 1)))
        tr = _Trace(bool(rng.integers(2)), np.ones(int(rng.integers(3))), np.zeros(0))
        index.add(key, tr)
        nodes.append((key, tr))
    for _ in range(50):
        a, n = rng.uniform(0, 1, 2)
        ia, jn = math.floor(a / size[0]), math.floor(n / size[1])
        best = {}
        for (x, y), tr in nodes:
            if abs(math.floor(x / size[0]) - ia) <= 1 and abs(math.floor(y / size[1]) - jn) <= 1:
                d = ((x - a) / size[0]) ** 2 + ((y - n) / size[1]) ** 2
                if tr.signature not in best or d < best[tr.signature][0]:
                    best[tr.signature] = (d, tr)
        want = [tr for _, tr in sorted(best.values(), key=lambda v: v[0])]
        got = index.nearest((a, n))
        assert [id(t) for t in got] == [id(t) for t in want]
