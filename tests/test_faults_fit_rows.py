"""A fit's rows are handled as arrays: each row's prediction and derivative are those of its own
point solved on its own, bit for bit, and the memory of many rows is that of a few arrays of
them (per-row Python lists took some 770 bytes a row: a million rows passed 1 GiB)."""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from cosserat_channel import solve
from cosserat_channel.calibrate import model as model_
from cosserat_channel.calibrate.data import read_data
from cosserat_channel.solver.point import solve_point

XI = np.linspace(0.05, 1.0, 7)
FIXED = {"A": 1 / 3, "N": 1.0}
THETA = np.array([10.0, 0.5])  # L, K


@pytest.fixture(scope="module")
def table():
    """Profiles (two quantities) repeated at two eps, in shuffled order, and scalar rows, some
    with a material, repeated too."""
    rows = []
    for eps in (1 / 30, 0.05):
        for _ in range(2):
            rows += [("u_over_u0", x, eps) for x in XI] + [("omega_hat", x, eps) for x in XI[::2]]
        rows += [("Delta", np.nan, eps), ("slip", np.nan, eps), ("Delta", np.nan, eps)]
    order = np.random.default_rng(3).permutation(len(rows))
    rows = [rows[i] for i in order]
    q, xi, eps = (list(c) for c in zip(*rows))
    return read_data({"quantity": q, "value": [0.5] * len(q), "std_error": [0.1] * len(q),
                      "xi": xi, "eps": eps})


def _row(data, i, theta):
    return float(data.columns["eps"][i]), float(theta[0]), float(theta[1]), FIXED["A"], FIXED["N"]


def test_each_row_is_predicted_as_its_own_point_solved_alone(table):
    problem = model_.Problem(table, ("L", "K"), FIXED, rtol=1e-10)
    thetas = np.array([THETA, THETA * 1.01])
    pred, status = problem.evaluate(thetas)
    for k, theta in enumerate(thetas):
        for i, q in enumerate(table.quantity):
            pt = _row(table, i, theta)
            if np.isnan(table.xi[i]):
                ref = solve(*pt, outputs=[str(q)], rtol=1e-10)
                want, code = float(ref[str(q)].values), int(ref["status"].values)
            else:
                ref = solve_point(*pt, rtol=1e-10, profile=[table.xi[i]], outputs=[])
                want, code = float(ref.profile[str(q)][0]), int(ref.status)
            assert status[k, i] == code == 0
            assert pred[k, i] == want, (k, i, q)


def test_each_row_is_differentiated_as_its_own_point_alone(table):
    """The analytic Jacobian, row by row: the solver's sensitivity of the row's quantity at its
    own point and xi, times d(input)/d(theta) of the closed-form map as the fit differences it
    (L and K are inputs themselves: ((x + h) - (x - h)) / 2h)."""
    problem = model_.Problem(table, ("L", "K"), FIXED, rtol=1e-10)
    J, info = model_.jacobian(problem, THETA)
    assert info["method"] == "analytic"
    steps = [1e-6 * max(abs(t), 1e-2) for t in THETA]
    d = [((t + h) - (t - h)) / (2 * h) for t, h in zip(THETA, steps)]
    for i, q in enumerate(table.quantity):
        pt = _row(table, i, THETA)
        profile = None if np.isnan(table.xi[i]) else [table.xi[i]]
        r = solve_point(*pt, rtol=1e-10, profile=profile, sensitivities=True)
        sens = (r.sensitivities[str(q)] if profile is None else
                {n: v[0] for n, v in r.profile_sensitivities[str(q)].items()})
        for j, name in enumerate(("L", "K")):
            assert J[i, j] == 0.0 + float(sens[name]) * d[j], (i, q, name)


def test_the_memory_of_many_rows_is_a_few_arrays_of_them():
    """200,000 rows (a 20-point profile measured 10,000 times): the problem, an evaluation at
    three trial points and the analytic Jacobian allocate at their peak what 18 float64 arrays
    of the rows hold (each trial's predictions and statuses are two, the Jacobian two, the index
    arrays from rows to distinct rows and their xi a few, and sorting them a few more); the
    bound is 30. Per-row Python lists and dicts took 73."""
    xi = np.linspace(0.05, 1.0, 20)
    reps = 10_000
    n = xi.size * reps
    truth = solve_point(1 / 30, 10, 0.5, 1 / 3, 1, profile=xi, rtol=1e-10).profile["u_over_u0"]
    data = read_data({"quantity": np.array(["u_over_u0"] * n, dtype=object),
                      "value": np.tile(truth, reps), "std_error": np.full(n, 0.002),
                      "xi": np.tile(xi, reps), "eps": np.full(n, 1 / 30)})
    small = model_.Problem(read_data({"quantity": ["u_over_u0"], "value": [1.0],
                                      "std_error": [0.1], "xi": [0.5], "eps": [1 / 30]}),
                           ("L", "K"), FIXED, rtol=1e-10)
    model_.jacobian(small, THETA)  # kernels loaded, modules imported: not counted below
    small.evaluate(THETA[None, :])
    tracemalloc.start()
    try:
        problem = model_.Problem(data, ("L", "K"), FIXED, rtol=1e-10)
        pred, status = problem.evaluate(np.array([THETA, THETA * 1.01, THETA * 0.99]))
        J, info = model_.jacobian(problem, THETA)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert info["method"] == "analytic" and (status == 0).all()
    np.testing.assert_allclose(pred[0], data.value, rtol=1e-12)
    assert peak <= 30 * 8 * n, f"{peak / (8 * n):.1f} float64 arrays of the rows"


@pytest.mark.parametrize("per_chunk", [1, 2, 5, 10_000])
def test_the_json_written_piece_by_piece_is_the_json_of_the_whole(per_chunk):
    """``fit -o``/``--json`` write a million rows without a dict of each: the pieces joined are
    ``json.dumps(to_dict())`` exactly, whatever the chunk size (5 rows: one chunk ends with
    the last row)."""
    import json

    from cosserat_channel.calibrate import fit

    r = fit({"quantity": ["u_over_u0"] * 5, "value": [1.0, 0.9, 0.8, 0.7, 0.3],
             "std_error": [0.01] * 5, "xi": [0.1, 0.3, 0.5, 0.7, 0.9], "eps": [1 / 30] * 5},
            "L", {"K": 0.5, **FIXED})
    assert "".join(r.json_chunks(per_chunk)) == json.dumps(r.to_dict(), allow_nan=False)
