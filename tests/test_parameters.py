"""Parameter ranges and checks: one definition for the API, sweep files and the command line."""

import math

import numpy as np
import pytest

from cosserat_channel.parameters import (
    DIMS,
    PARAMETERS,
    ParameterError,
    check_material,
    check_point,
    check_tolerances,
    check_values,
)

FIG2 = (1 / 30, 10.0, 0.5, 1 / 3, 1.0)


@pytest.mark.parametrize("name, value", [
    ("eps", 0.0),  # open at 0
    ("eps", 1.5),  # above 1
    ("L", -1.0),
    ("K", -1e-300),  # K = 0 is allowed, anything below is not
    ("N", 0.0),
    ("A", math.inf),
    ("L", math.nan),
    ("L", 10**400),  # a Python int too large for a float
    ("L", True),  # a bool is not a length
    ("L", np.bool_(True)),
    ("L", "10"),  # nor is a string
    ("A", 1 + 2j),
])
def test_bad_values_name_the_parameter_and_its_range(name, value):
    """Each bad value raises ParameterError naming the parameter and its interval."""
    point = dict(zip(DIMS, FIG2), **{name: value})
    with pytest.raises(ParameterError) as info:
        check_point(*(point[d] for d in DIMS))
    assert str(info.value).startswith(f"{name} ")
    assert PARAMETERS[name].interval in str(info.value)


def test_good_values_come_back_as_floats():
    """Accepted values are returned as Python floats, numpy scalars included."""
    got = check_point(np.float32(0.5), np.int64(10), 0, 1 / 3, 1)
    assert all(type(v) is float for v in got) and got[2] == 0.0


def test_check_values_matches_the_scalar_check():
    """The vectorised axis check accepts and rejects exactly what the scalar check does."""
    assert check_values("eps", np.logspace(-7, 0, 1000)).dtype == np.float64
    with pytest.raises(ParameterError, match=r"^eps = 1.5 is outside the allowed range \(0, 1\]"):
        check_values("eps", [0.1, 1.5, 2.0])


def test_tolerances_and_material():
    """Tolerance ranges and the material's defaults and cross-check."""
    assert check_tolerances(1e-8, 1e-12) == (1e-8, 1e-12)
    with pytest.raises(ParameterError, match="rtol"):
        check_tolerances(1e-14, 1e-12)
    full = check_material({"d_p": 0.002, "rho_p": 2940, "phi": 25})
    assert full["Lambda"] == 817.0 and full["g"] == 9.81
    with pytest.raises(ParameterError, match="nu_min"):
        check_material({"d_p": 0.002, "rho_p": 2940, "phi": 25, "nu_min": 0.7})
    with pytest.raises(ParameterError, match="unknown key"):
        check_material({"d_p": 0.002, "rho_p": 2940, "phi": 25, "colour": 1})


# ---------------------------------------------------------------------------------------------
# Issue 13, item 1: a point's status must not depend on the tolerances within their range.
# ---------------------------------------------------------------------------------------------
# Every edge of solvability named by (A, N, eta_max) (regimes.trace_edge at rtol 1e-10); points
# are taken 1e-3 (relative, in eps L) on each side: the status there is decided by D(1), which
# the solver resolves to ~1e-5 at the defaults and ~1e-4 at the loosest accepted tolerances.
EDGES = [(1 / 3, 1.0, 3.308860555489726), (0.0, 2.0, 3.741643761878816),
         (0.9, 0.5, 17.467539553915614), (0.9, 0.5, 0.3975087920526119),
         (-0.5, 1.0, 0.344410076390575), (3.0, 0.5, 0.2351051210787608)]
# The corners of the accepted box and the ranges along each axis.
TOLERANCE_SWEEP = (
    [(1e-8, a) for a in (1e-30, 1e-20, 1e-14, 1e-9, 1e-7, 1e-6)]
    + [(r, 1e-12) for r in (1e-13, 1e-12, 1e-11, 1e-9, 1e-7, 1e-5, 1e-4, 1e-3)]
    + [(1e-13, 1e-30), (1e-13, 1e-6), (1e-3, 1e-30), (1e-3, 1e-6)]
)
TIGHT = dict(rtol=1e-10, atol=1e-12)


def _tolerance_points(corner: bool):
    """Random points of the tested domain (model.md), plus the near-edge ones; ``corner``: only
    those with N < 1 < A and eps L < 1e-5, where the closure once took the logarithm of 0, else only the others."""
    rng = np.random.default_rng(13)
    points = []
    while len(points) < 60:
        eps, L = 10 ** rng.uniform(-7, math.log10(0.5)), 10 ** rng.uniform(math.log10(0.5), 2)
        A, N = rng.uniform(-3, 5), 10 ** rng.uniform(-3 if corner else math.log10(0.3), 1)
        if corner:
            eps = min(1.0, 10 ** rng.uniform(-12, -6) / L)
        in_corner = N < 1 < A and eps * L < 1e-5
        if in_corner == corner:
            points.append((eps, L, 0.5, A, N))
    if not corner:
        points += [(eta * (1 + s * 1e-3) / 100, 100.0, 0.5, A, N)
                   for A, N, eta in EDGES for s in (-1, 1)]
    else:  # the issue's own example: integration_failed at rtol 1e-10
        points.append((1.610256468145839e-08, 0.002791177180070797, 254990.67731324708,
                       5.319350767681383, 0.001285971688229784))
    return points


def _status_changes(points):
    from cosserat_channel import solve_point
    from cosserat_channel.solver.point import Workspace

    ws = Workspace()
    changes = []
    for p in points:
        ref = solve_point(*p, **TIGHT, workspace=ws).status
        if ref.name == "integration_failed":  # "never seen inside the solvable region"
            changes.append((p, TIGHT["rtol"], TIGHT["atol"], "-", ref.name))
        for rtol, atol in TOLERANCE_SWEEP:
            got = solve_point(*p, rtol=rtol, atol=atol, workspace=ws).status
            if got != ref:
                changes.append((p, rtol, atol, ref.name, got.name))
    return changes


def test_tolerance_range_bounds():
    """The accepted box: atol in [1e-30, 1e-6], rtol in [1e-13, 1e-3]; outside is refused."""
    assert check_tolerances(1e-3, 1e-6) == (1e-3, 1e-6)
    assert check_tolerances(1e-13, 1e-30) == (1e-13, 1e-30)
    for rtol, atol, name in ((2e-3, 1e-12, "rtol"), (1e-8, 1.1e-6, "atol"),
                             (1e-8, 1e-31, "atol"), (1e-8, 0.1, "atol")):
        with pytest.raises(ParameterError, match=name):
            check_tolerances(rtol, atol)


def test_statuses_do_not_depend_on_the_tolerances():
    """Over the whole accepted box, every point gets the status of rtol = 1e-10, atol = 1e-12:
    66 points (60 random in the tested domain, 6 pairs 1e-3 either side of an edge) x 18 pairs."""
    assert _status_changes(_tolerance_points(corner=False)) == []


def test_statuses_do_not_depend_on_the_tolerances_for_N_below_one():
    """The corner of item 6 (N < 1 < A, small eps L): at tight rtol stage 1 gave up in the jump
    to D = 0 after xi = N and said integration_failed where the answer is eps_too_large_path."""
    assert _status_changes(_tolerance_points(corner=True)) == []


# ---------------------------------------------------------------------------------------------
# Engineers' inputs: W with d_p, delta_w with phi; exact fractions
# ---------------------------------------------------------------------------------------------
def test_eps_and_N_from_the_physical_inputs():
    """eps = d_p/W and N = sin(phi)/tan(delta_w): the paper's table 1 (W = 0.155 m, d_p = 2.29 mm,
    phi = 30, delta_w = 8 degrees) gives N = 3.558, and arrays convert elementwise."""
    from cosserat_channel.parameters import N_from_friction, eps_from_width

    assert eps_from_width(0.00229, 0.155) == 0.00229 / 0.155
    assert math.isclose(N_from_friction(30, 8), 0.5 / math.tan(math.radians(8)), rel_tol=1e-15)
    assert round(N_from_friction(30, 8), 3) == 3.558  # table 1's N
    # N = 1 where tan(delta_w) = sin(phi): the fully rough wall
    assert math.isclose(N_from_friction(25, math.degrees(math.atan(math.sin(math.radians(25))))),
                        1.0, rel_tol=1e-14)
    np.testing.assert_array_equal(eps_from_width(0.002, np.array([0.06, 0.1])),
                                  [0.002 / 0.06, 0.002 / 0.1])


@pytest.mark.parametrize("call, named", [
    (lambda f, g: f(0.002, 0.001), "eps = d_p/W = 2"),           # W below d_p: eps > 1
    (lambda f, g: f(0.002, -1.0), "W = -1.0 is outside"),
    (lambda f, g: f(0.002, True), "W must be a number"),
    (lambda f, g: f(20.0, 1.0), "d_p = 20.0 is outside"),
    (lambda f, g: g(30, 0.0), "delta_w = 0.0 is outside"),
    (lambda f, g: g(30, 90.0), "delta_w = 90.0 is outside"),
    (lambda f, g: g(30, np.array([10.0, np.nan])), "delta_w = nan"),
    (lambda f, g: g(60.0, 1e-5), "N = sin(phi)/tan(delta_w) = 496"),  # N above 1e6
])
def test_physical_inputs_out_of_range_name_themselves(call, named):
    from cosserat_channel.parameters import N_from_friction, eps_from_width

    with pytest.raises(ParameterError) as info:
        call(eps_from_width, N_from_friction)
    assert named in str(info.value), str(info.value)


def test_exact_fractions_are_rounded_once():
    from cosserat_channel.parameters import parse_number

    assert parse_number("1/30") == 1 / 30 and parse_number("1/3") == 1 / 3
    assert parse_number(" -1/600 ") == -1 / 600 and parse_number("2.5e-1") == 0.25
    assert math.isnan(parse_number("nan")) and parse_number("inf") == math.inf
    for bad in ("1/0", "a/3", "", "1//3", "0.1.2"):
        with pytest.raises(ValueError):
            parse_number(bad)
