"""Calibration (cosserat_channel.calibrate): the fit recovers the model's own parameters, its
standard errors are those of an independent Jacobian, its 95 % intervals cover the truth at the
binomial rate, bad data are refused naming row and column, and the warnings say what they
should."""

import math
import pathlib
import warnings

import numpy as np
import pytest
import xarray as xr
from scipy import stats

import cosserat_channel
from cosserat_channel.calibrate import DataError, FitError, FitWarning, fit, read_data
from cosserat_channel.calibrate import model as model_
from cosserat_channel.solver import point as point_
from cosserat_channel.solver.point import solve_point

EXAMPLES = pathlib.Path(cosserat_channel.__file__).parent / "examples"
TRUTH = {"L": 10.0, "K": 0.5}
FIXED = {"A": 1 / 3, "N": 1.0}
XI = np.linspace(0.05, 1.0, 20)
SIGMA = 0.002
RTOL = 1e-10


@pytest.fixture(scope="module")
def profile_truth():
    """u/u(0) of the model at (1/30, 10, 0.5, 1/3, 1) at 20 points."""
    return solve_point(1 / 30, 10.0, 0.5, 1 / 3, 1.0, profile=XI, rtol=RTOL).profile["u_over_u0"]


def profile_data(truth, seed):
    rng = np.random.default_rng(seed)
    return {"quantity": ["u_over_u0"] * XI.size, "value": truth + SIGMA * rng.standard_normal(XI.size),
            "std_error": np.full(XI.size, SIGMA), "xi": XI, "eps": np.full(XI.size, 1 / 30)}


def independent_covariance(L, K):
    """(J^T J)^-1 of the weighted profile residuals, J by central differences of solve_point at
    rtol 1e-12 with a step of 1e-4 (not the fit's code): truncation ~1e-8, noise ~1e-8."""
    cols = []
    for name, value in (("L", L), ("K", K)):
        h = 1e-4 * value
        args = {"L": L, "K": K}
        up, down = dict(args, **{name: value + h}), dict(args, **{name: value - h})
        fp = solve_point(1 / 30, up["L"], up["K"], 1 / 3, 1.0, profile=XI, rtol=1e-12)
        fm = solve_point(1 / 30, down["L"], down["K"], 1 / 3, 1.0, profile=XI, rtol=1e-12)
        cols.append((fp.profile["u_over_u0"] - fm.profile["u_over_u0"]) / (2 * h) / SIGMA)
    J = np.column_stack(cols)
    return np.linalg.inv(J.T @ J)


def test_recovers_known_parameters_within_standard_errors(profile_truth):
    """Noisy profiles of the model itself: L and K come back within 3 standard errors, and the
    errors are those of an independently differenced Jacobian (to 1 %, far above FD error)."""
    for seed in range(4):
        with warnings.catch_warnings():
            warnings.simplefilter("error", FitWarning)
            r = fit(profile_data(profile_truth, seed), "L,K", FIXED, start={"L": 5.0, "K": 1.0})
        assert r.success
        for name in ("L", "K"):
            assert abs(r.params[name] - TRUTH[name]) < 3 * r.errors[name], (seed, name, r)
        cov = independent_covariance(r.params["L"], r.params["K"])
        np.testing.assert_allclose(r.covariance, cov, rtol=1e-2)
        assert r.dof == 18
        np.testing.assert_allclose(r.chi2, np.sum(r.residuals ** 2), rtol=1e-12)
        assert abs(r.correlation[0, 1]) < 1 and r.correlation[0, 0] == pytest.approx(1.0)


def test_confidence_intervals_cover_the_truth(profile_truth):
    """30 data sets: the 95 % intervals of L and K each contain the truth at a rate a binomial
    allows (failing with probability < 1e-3 if the coverage is right), and the mean squared
    z-score is that of chi^2_30/30 (catches errors wrong by a factor 1.5 either way)."""
    n = 30
    z = {"L": [], "K": []}
    for seed in range(100, 100 + n):
        r = fit(profile_data(profile_truth, seed), "L,K", FIXED)
        for name in z:
            z[name].append((r.params[name] - TRUTH[name]) / r.errors[name])
    lo_count = stats.binom.ppf(1e-3, n, 0.95)
    lo_z2, hi_z2 = stats.chi2.ppf([5e-4, 1 - 5e-4], n) / n
    for name, values in z.items():
        values = np.array(values)
        covered = int(np.sum(np.abs(values) < stats.norm.ppf(0.975)))
        assert covered >= lo_count, (name, covered)
        assert lo_z2 < np.mean(values ** 2) < hi_z2, (name, np.mean(values ** 2))


def test_mixed_rows_noise_free_recovery():
    """Scalar rows at several eps (one vectorised solve), profile rows, and material rows in Pa
    with W and delta_w per row: noise-free data give the truth back to the solver's accuracy, so
    every row got its own prediction."""
    truth = {"L": 7.0, "K": 2.0, "phi": 32.0}
    mat = {"d_p": 0.002, "rho_p": 2500.0}
    rows = {"quantity": [], "value": [], "std_error": [], "xi": [], "eps": [], "W": [],
            "delta_w": []}

    def add(q, v, xi=math.nan, eps=math.nan, W=math.nan, delta_w=math.nan):
        for k, x in zip(rows, (q, v, 0.01 * abs(v) + 1e-3, xi, eps, W, delta_w)):
            rows[k].append(x)

    for eps in (0.01, 0.05, 0.1):
        r = solve_point(eps, truth["L"], truth["K"], 1 / 3, 1.0, rtol=RTOL)
        add("Delta", r.Delta, eps=eps, delta_w=math.degrees(math.atan(math.sin(math.radians(32)))))
        add("slip", r.slip, eps=eps, delta_w=math.degrees(math.atan(math.sin(math.radians(32)))))
    r = solve_point(0.05, truth["L"], truth["K"], 1 / 3, 1.0, rtol=RTOL, profile=[0.5, 0.9])
    for xi, u in zip([0.5, 0.9], r.profile["u_over_u0"]):
        add("u_over_u0", u, xi=xi, eps=0.05, delta_w=math.degrees(math.atan(math.sin(math.radians(32)))))
    for W, dw in ((0.1, 10.0), (0.2, 20.0)):
        N = math.sin(math.radians(truth["phi"])) / math.tan(math.radians(dw))
        r = solve_point(mat["d_p"] / W, truth["L"], truth["K"], 1 / 3, N, rtol=RTOL,
                        material=dict(mat, phi=truth["phi"]))
        add("sigma_yx_wall_Pa", r.sigma_yx_wall_Pa, W=W, delta_w=dw)
        add("nu", r.nu, W=W, delta_w=dw)
    res = fit(rows, "L,K,phi", {"A": 1 / 3, **mat}, start={"L": 9.0, "K": 1.0, "phi": 28.0})
    assert res.chi2 < 1e-8
    for name, value in truth.items():
        assert res.params[name] == pytest.approx(value, rel=1e-5)
    assert res.status == ["ok"] * len(rows["quantity"])


def test_read_data_forms_agree(tmp_path):
    """A CSV file, a mapping of columns and an xarray Dataset of the same table read the same."""
    csv = tmp_path / "d.csv"
    csv.write_text("# comment\nquantity,value,std_error,xi,eps\nu_over_u0,0.9,0.01,0.7,1/30\n"
                   "Delta,10,0.5,,0.05\n")
    cols = {"quantity": ["u_over_u0", "Delta"], "value": [0.9, 10.0], "std_error": [0.01, 0.5],
            "xi": [0.7, None], "eps": [1 / 30, 0.05]}
    ds = xr.Dataset({k: ("row", np.array(v, dtype=object if k == "quantity" else float))
                     for k, v in cols.items() if k != "xi"}).assign(
                         xi=("row", [0.7, np.nan]))
    a, b, c = read_data(csv), read_data(cols), read_data(ds)
    for other in (b, c):
        assert list(other.quantity) == list(a.quantity)
        for name in ("value", "std_error", "xi"):
            np.testing.assert_array_equal(getattr(other, name), getattr(a, name))
        np.testing.assert_array_equal(other.columns["eps"], a.columns["eps"])
    assert a.where(1, "eps") == f"{csv} row 2 (line 4), column 'eps'"


BAD = [
    ("quantity,value,std_error\nDelta,nan,0.1\n", "row 1 (line 2), column 'value'"),
    ("quantity,value,std_error\nDelta,1,0.1\nDelta,1,0\n", "row 2 (line 3), column 'std_error'"),
    ("quantity,value,std_error\nDelta,1,0\n", "positive finite number; got 0.0"),
    ("quantity;value;std_error\nDelta;1;0.1\n", "separated by ';'; the file must be comma-separated"),
    ("quantity,value,std_error\nDelta,1,-0.1\n", "column 'std_error'"),
    ("quantity,value,std_error\nDeltaa,1,0.1\n", "column 'quantity': unknown quantity 'Deltaa'"),
    ("quantity,value,std_error\nxi_stop,1,0.1\n", "unknown quantity 'xi_stop'"),
    ("quantity,value,std_error,xi\nu_over_u0,1,0.1,1.5\n", "column 'xi'"),
    ("quantity,value,std_error,xi\nu_over_u0,1,0.1,\n", "needs xi in [0, 1]; got nothing"),
    ("quantity,value,std_error,xi\nDelta,1,0.1,0.5\n", "xi is for profile quantities"),
    ("quantity,value,std_error,eps\nDelta,1,0.1,2\n", "column 'eps'"),
    ("quantity,value,std_error,eps\nDelta,1,0.1,abc\n", "column 'eps': expected a number"),
    ("quantity,value,std_error,colour\nDelta,1,0.1,red\n", "unknown column 'colour'"),
    ("quantity,value\nDelta,1\n", "missing column(s) std_error"),
    ("quantity,value,std_error\nDelta,1\n", "line 2: 2 cells where the header has 3"),
    ("quantity,value,std_error\n", "no measurements"),
]


@pytest.mark.parametrize("text,expected", BAD)
def test_bad_data_names_row_and_column(tmp_path, text, expected):
    """Each bad table is a DataError (a ParameterError, a ValueError) whose one line names the
    row (and the file's line) and the column."""
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(DataError) as info:
        fit(path, "L", FIXED)
    message = str(info.value)
    assert expected in message
    assert "\n" not in message
    assert isinstance(info.value, cosserat_channel.ParameterError)


@pytest.mark.parametrize("kwargs,expected", [
    (dict(free="Q"), "free: unknown input 'Q'"),
    (dict(free="L,L"), "names an input twice"),
    (dict(free="L", fixed={"L": 3}), "L is both free and fixed"),
    (dict(free="L", bounds={"K": (0, 1)}), "bounds: 'K' is not a free input"),
    (dict(free="L", bounds={"L": (5, 1)}), "must be lo < hi"),
    (dict(free="L", start={"L": 50}, bounds={"L": (1, 20)}), "outside its bounds"),
    (dict(free="phi"), "start: give a start value for phi"),
    (dict(free="L", fixed={"A": 1 / 3}), "no value for K, N (or delta_w with phi)"),
    (dict(free="L", fixed={"A": 1 / 3, "N": 1, "delta_w": 8}), "N and delta_w"),
])
def test_bad_fit_arguments(kwargs, expected):
    """free/fixed/bounds/start errors, and a row lacking an input, are one-line FitErrors or
    DataErrors naming what is wrong."""
    data = {"quantity": ["Delta"], "value": [10.0], "std_error": [0.5], "eps": [1 / 30]}
    kwargs = dict(kwargs)
    kwargs.setdefault("fixed", FIXED)
    with pytest.raises((FitError, DataError), match=None) as info:
        fit(data, **kwargs)
    assert expected in str(info.value)


@pytest.mark.parametrize("kwargs,expected", [
    (dict(fixed="A=1/3"), "fixed must be a mapping"),
    (dict(bounds=[1, 2]), "bounds must be a mapping"),
    (dict(start=5), "start must be a mapping"),
    (dict(fixed={**FIXED, "K": "1e400/1"}), "fixed K = inf is outside the allowed range"),
    (dict(bounds={"L": 5}), "bounds L: expected two numbers lo, hi"),
])
def test_arguments_of_the_wrong_kind_are_fit_errors(kwargs, expected):
    """fit's arguments of the wrong type or beyond a double are one-line FitErrors, not
    AttributeError, TypeError or OverflowError."""
    data = {"quantity": ["Delta"], "value": [10.0], "std_error": [0.5], "eps": [1 / 30]}
    kwargs = dict(kwargs)
    kwargs.setdefault("fixed", {**FIXED, "K": 0.5})
    with pytest.raises(FitError) as info:
        fit(data, "L", **kwargs)
    assert expected in str(info.value)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("value,std_error", [(1e300, 0.5), (10.0, 1e-300)])
def test_residuals_beyond_a_double_are_one_data_error(value, std_error):
    """A value or standard error whose squared residual overflows (wrong units) is refused in
    one line naming the row, before scipy meets an infinite chi2."""
    data = {"quantity": ["Delta"], "value": [value], "std_error": [std_error], "eps": [1 / 30]}
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        with pytest.raises(DataError, match=r"data row 1: .*beyond the range of a double"):
            fit(data, "L", {**FIXED, "K": 0.5})


def test_start_without_solution_is_refused():
    """A start at which a row has no solution is a FitError naming the row and the status."""
    data = {"quantity": ["Delta"], "value": [0.3], "std_error": [0.01], "eps": [0.3]}
    with pytest.raises(FitError, match=r"row 1: no solution at the start \(L = 12\): "
                       r"eps_too_large_path"):
        fit(data, "L", {"A": 1 / 3, "N": 1, "K": 0.5}, start={"L": 12})


def _warned(*args, **kwargs):
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        r = fit(*args, **kwargs)
    notes = [str(w.message) for w in seen if issubclass(w.category, FitWarning)]
    assert notes == r.warnings
    assert all("\n" not in n for n in notes)
    return r, notes


def test_warns_at_a_bound():
    """Truth L = 10, bounds L in [1, 8]: the estimate sits on the bound, and one line says so."""
    r, notes = _warned(EXAMPLES / "fit_profile.csv", "L,K", FIXED, bounds={"L": (1, 8)})
    assert r.params["L"] == pytest.approx(8.0)
    assert any(n.startswith("L = 8 is at its upper bound 8 (the given range)") for n in notes)


def test_warns_at_the_edge_of_the_solvable_region():
    """Delta = 0.3 at eps = 0.3 needs L beyond the edge (eps L = 3.309 for A = 1/3, N = 1,
    docs/model.md): the fit stops at the edge and names the status it met."""
    data = {"quantity": ["Delta"], "value": [0.3], "std_error": [0.01], "eps": [0.3]}
    r, notes = _warned(data, "L", {"A": 1 / 3, "N": 1, "K": 0.5}, start={"L": 10.9})
    assert 0.3 * r.params["L"] == pytest.approx(3.30886, rel=1e-3)
    assert any("ran into the region without a solution: eps_too_large_path" in n for n in notes)


def test_warns_when_a_parameter_does_not_matter():
    """m_wall is a stress-stage output: it does not depend on K, which the warning names."""
    eps = np.array([0.01, 0.02, 0.05])
    vals = [solve_point(e, 10, 0.5, 1 / 3, 1).m_wall for e in eps]
    data = {"quantity": ["m_wall"] * 3, "value": vals, "std_error": [1e-3] * 3, "eps": eps}
    r, notes = _warned(data, "L,K", FIXED)
    assert "K does not change any prediction: these data cannot determine it" in notes
    assert math.isnan(r.errors["K"]) and math.isfinite(r.errors["L"])


def test_a_start_where_the_model_is_flat_is_named_and_another_start_suggested():
    """Data in % (x100) from a start at eps L = 1e-6, where Delta is exactly 0 for every L near
    it: the fit cannot move, and the warning says that L does matter elsewhere (at its usual
    start), not that the data cannot determine it."""
    eps = np.array([0.01, 0.02, 0.05])
    vals = [100 * solve_point(e, 10, 0.5, 1 / 3, 1).Delta for e in eps]
    assert solve_point(0.01, 1e-4, 0.5, 1 / 3, 1).Delta == 0.0
    data = {"quantity": ["Delta"] * 3, "value": vals, "std_error": [1e-2] * 3, "eps": eps}
    r, notes = _warned(data, "L", {**FIXED, "K": 0.5}, start={"L": 1e-4})
    assert r.params["L"] == 1e-4
    assert ("L does not change any prediction at L = 0.0001, but does at L = 10: the fit is "
            "stuck where the model is flat; give another start") in notes
    assert not any("cannot determine" in n for n in notes)


def test_warns_of_a_combination_the_data_do_not_determine():
    """sigma_yx_wall depends on eps L = d_p L / W only: L and d_p are determined only as a
    product, and the warning names the combination dL/L - dd_p/d_p (up to sign)."""
    W = np.array([0.05, 0.1, 0.2])
    vals = [solve_point(0.002 / w, 10, 0.5, 1 / 3, 1).sigma_yx_wall for w in W]
    data = {"quantity": ["sigma_yx_wall"] * 3, "value": vals, "std_error": [1e-4] * 3, "W": W}
    r, notes = _warned(data, "L,d_p", {**FIXED, "K": 0.5}, start={"d_p": 0.003, "L": 8})
    assert r.condition_number > 1e6
    assert r.params["L"] * r.params["d_p"] == pytest.approx(10 * 0.002, rel=1e-6)
    combo = [n for n in notes if n.startswith("not identifiable from these data")]
    assert len(combo) == 1
    assert ("-1.000 dL/L +1.000 dd_p/d_p" in combo[0]) or ("+1.000 dL/L -1.000 dd_p/d_p" in combo[0])


def test_paper_table1():
    """The paper's table 1 (7.97 kPa normal, 1.12 kPa shear at W = 0.155 m ...) and Delta ~ 10.5
    at its reference point, fitting delta_w, the closure's Lambda and L (three data, three
    parameters): the estimates reproduce the data, delta_w is the closed form
    atan(1.12/7.97) = 8.00 deg (the stresses' ratio is tan delta_w), and Lambda moves from the
    closure's 817 Pa to where nu is the paper's 0.625 (what its numbers were computed with).
    Its summary has no chi2/dof to state."""
    r = fit(EXAMPLES / "fit_table1.csv", "delta_w,Lambda,L", {"K": 0.5, "A": 1 / 3},
            start={"delta_w": 8.0})
    assert r.dof == 0 and r.chi2 < 1e-12
    # No degrees of freedom: no chi2/dof printed as nan; scipy's message without its backticks.
    text = r.summary()
    assert "no chi2/dof (as many free parameters as measurements)" in text
    assert "nan" not in text.split("\n")[-2] and "`" not in text
    assert r.params["delta_w"] == pytest.approx(math.degrees(math.atan(1120 / 7970)), rel=1e-6)
    nu = 1120 / (1180 * 9.81 * 0.155)  # sigma_xy = -rho_p g W nu
    N = math.sin(math.radians(30)) / math.tan(math.radians(r.params["delta_w"]))
    p = solve_point(0.00229 / 0.155, 10, 0.5, 1 / 3, N,
                    material={"d_p": 0.00229, "rho_p": 1180, "phi": 30,
                              "Lambda": r.params["Lambda"]})
    assert p.nu == pytest.approx(nu, rel=1e-6)
    assert 0.62 < nu < 0.63
    assert solve_point(1 / 30, r.params["L"], 0.5, 1 / 3, 1).Delta == pytest.approx(10.5, rel=1e-6)
    assert 300 < r.params["Lambda"] < 700


def test_example_profile_is_the_model_plus_its_stated_noise():
    """examples/fit_profile.csv is what its header says: the model at L = 10, K = 0.5 plus
    Gaussian noise of sigma 0.002 from numpy.random.default_rng(2026), to its 6 printed digits."""
    data = read_data(EXAMPLES / "fit_profile.csv")
    truth = solve_point(1 / 30, 10, 0.5, 1 / 3, 1, profile=data.xi, rtol=RTOL).profile["u_over_u0"]
    noise = 0.002 * np.random.default_rng(2026).standard_normal(data.xi.size)
    np.testing.assert_allclose(data.value, truth + noise, atol=5.1e-7)


def test_analytic_sensitivities_are_used(monkeypatch):
    """solve_point's sensitivities=True is what the analytic Jacobian uses, with the chain rule
    through N = sin(phi)/tan(delta_w) and the material; its Jacobian matches central differences
    (the stand-in computes its derivatives by differencing at rtol 1e-12, independently)."""
    real = point_.solve_point
    inputs = ("eps", "L", "K", "A", "N")

    def with_sensitivities(eps, L, K, A, N, *, sensitivities=False, **kw):
        r = real(eps, L, K, A, N, **kw)
        if not sensitivities:
            return r
        kw = dict(kw, rtol=1e-12)
        base = dict(zip(inputs, (eps, L, K, A, N)))
        sens, prof = {}, {}
        mat = kw.get("material")
        names = list(base) + (list(mat) if mat else [])
        for name in names:
            value = base[name] if name in base else mat[name]
            h = 1e-5 * max(abs(value), 1e-2)
            out = []
            for sign in (1, -1):
                b = dict(base)
                m = dict(mat) if mat else None
                if name in b:
                    b[name] = value + sign * h
                else:
                    m[name] = value + sign * h
                out.append(real(*b.values(), **dict(kw, material=m)))
            for q in r.computed:
                sens.setdefault(q, {})[name] = (out[0].values[q] - out[1].values[q]) / (2 * h)
            if r.profile is not None:
                prof.setdefault("u_over_u0", {})[name] = (
                    out[0].profile["u_over_u0"] - out[1].profile["u_over_u0"]) / (2 * h)
        r.sensitivities = sens
        r.profile_sensitivities = prof
        return r

    monkeypatch.setattr(point_, "solve_point", with_sensitivities)
    data = read_data({"quantity": ["Delta", "sigma_yx_wall_Pa", "u_over_u0"],
                      "value": [10.0, -1000.0, 0.9], "std_error": [0.5, 10.0, 0.01],
                      "xi": [None, None, 0.8], "eps": [1 / 30, None, 0.05],
                      "W": [None, 0.155, None]})
    problem = model_.Problem(data, ("L", "delta_w", "phi"),
                             {"K": 0.5, "A": 1 / 3, "d_p": 0.00229, "rho_p": 1180}, rtol=1e-10)
    theta = np.array([10.0, 12.0, 30.0])
    J, info = model_.jacobian(problem, theta)
    assert info["method"] == "analytic"
    J_fd, info_fd = model_._central(problem, theta, None)
    assert info_fd["method"] == "central differences"
    assert np.all(np.abs(J_fd) > 0)
    # both are differences: at rtol 1e-10 and steps 2e-3 (fit) and 1e-5 (stand-in), each is good
    # to ~1e-5 relative of the column
    np.testing.assert_allclose(J, J_fd, rtol=2e-4)


def test_registered_outputs_are_fittable_and_nan_is_a_status():
    """A quantity registered at run time is fittable (the registry is read at each call), and
    one that is NaN at a solved point is the status no_value, refused at the start by name."""
    from cosserat_channel import outputs

    twice = outputs.Output("Delta_twice", "1", "twice Delta", lambda x: 2 * x.get("Delta"),
                           plug_edge=True)
    nothing = outputs.Output("nothing", "1", "no value", lambda x: x.eps * math.nan, stage=1)
    with outputs.registered(twice), outputs.registered(nothing):
        value = 2 * solve_point(0.05, 10, 0.5, 1 / 3, 1).Delta
        data = {"quantity": ["Delta_twice"], "value": [value], "std_error": [0.01], "eps": [0.05]}
        r = fit(data, "L", {"K": 0.5, **FIXED}, start={"L": 8.0})
        assert r.params["L"] == pytest.approx(10.0, rel=1e-6)
        data["quantity"] = ["nothing"]
        with pytest.raises(FitError, match=r"row 1: no solution at the start \(L = 8\): no_value"):
            fit(data, "L", {"K": 0.5, **FIXED}, start={"L": 8.0})


def test_exported_lazily_and_reading_data_is_light():
    """``cosserat_channel.fit`` is the calibration's own function, and reading a table imports
    neither numba nor scipy."""
    from support import run_python

    assert cosserat_channel.fit is fit
    assert cosserat_channel.FitResult.__module__ == "cosserat_channel.calibrate.estimate"
    code = ("import sys, cosserat_channel.calibrate as c; c.read_data({'quantity': ['Delta'], "
            "'value': [1.0], 'std_error': [0.1]}); "
            "print(sorted(m for m in ('numba', 'scipy') if m in sys.modules))")
    assert run_python(code) == "[]"


def test_solver_sensitivities_match_central_differences():
    """With solve_point's own sensitivities, the analytic Jacobian of scalar rows (chained
    through N = sin(phi)/tan(delta_w), eps = d_p/W and the material) agrees with the central
    differences: both are good to ~1e-7 of a column at rtol 1e-10 (step ~5e-4 relative:
    truncation ~h^2, noise ~rtol/h), bounded here at 1e-5."""
    data = read_data({"quantity": ["Delta", "sigma_yx_wall_Pa", "slip", "nu", "m_wall"],
                      "value": [10.0, -1000.0, 0.1, 0.6, -5.0],
                      "std_error": [0.5, 10.0, 0.01, 0.01, 0.1],
                      "eps": [1 / 30, None, 0.05, None, 0.02],
                      "W": [None, 0.155, None, 0.155, None]})
    problem = model_.Problem(data, ("L", "K", "A", "delta_w", "phi"),
                             {"d_p": 0.00229, "rho_p": 1180}, rtol=1e-10)
    theta = np.array([10.0, 0.5, 1 / 3, 12.0, 30.0])
    J, info = model_.jacobian(problem, theta)
    assert info["method"] == "analytic"
    J_fd, _ = model_._central(problem, theta, None)
    scale = np.max(np.abs(J_fd), axis=0)
    assert np.all(np.abs(J - J_fd) <= 1e-5 * scale)
