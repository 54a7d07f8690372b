"""Sensitivities of solve_point's outputs against central differences of tight solves.

Each comparison is bounded by what the arithmetic allows: the sensitivity solve's own error
(100 x its rtol, relative) plus the difference quotient's truncation error (estimated from the
quotients at h and 2h, whose difference is 3 times it) and its rounding (the tight solves' error,
taken as 100 x their rtol relative to the output, divided by h).
"""

import math
import warnings

import numpy as np
import pytest

from cosserat_channel.solver.point import solve_point

RTOL_SENS = 1e-8
RTOL_REF = 1e-12
PARAMS = ("eps", "L", "K", "A", "N")


def _central(p, i, h, material=None):
    plus, minus = list(p), list(p)
    plus[i] += h
    minus[i] -= h
    kw = dict(rtol=RTOL_REF, atol=1e-30, material=material)
    return solve_point(*plus, **kw), solve_point(*minus, **kw)


def _check(p, params=PARAMS, material=None, rel_step=1e-4):
    r = solve_point(*p, rtol=RTOL_SENS, sensitivities=True, material=material)
    assert r.ok, r.status.message
    assert set(r.sensitivities) == {n for n in r.sensitivities if n in r.values}
    for i, name in enumerate(PARAMS):
        if name not in params:
            continue
        h = rel_step * max(abs(p[i]), 1e-2)
        one = _central(p, i, h, material)
        two = _central(p, i, 2 * h, material)
        for out, d in r.sensitivities.items():
            fd1 = (getattr(one[0], out) - getattr(one[1], out)) / (2 * h)
            fd2 = (getattr(two[0], out) - getattr(two[1], out)) / (4 * h)
            value = abs(r.values[out])
            bound = (100 * RTOL_SENS * abs(fd1) + abs(fd1 - fd2) / 3
                     + 100 * RTOL_REF * value / h + 1e-300)
            assert abs(d[name] - fd1) <= bound, (p, out, name, d[name], fd1, bound)


def _solvable_draw(rng):
    """The first random (eps, L, K, A, N) with a solution: every seed checks a point."""
    while True:
        p = (float(rng.uniform(0.005, 0.2)), float(rng.uniform(2, 30)), float(rng.uniform(0, 2)),
             float(rng.uniform(-0.5, 3)), float(rng.uniform(0.6, 3)))
        if solve_point(*p).ok:
            return p


@pytest.mark.parametrize("seed", range(4))
def test_random_points_against_central_differences(seed):
    _check(_solvable_draw(np.random.default_rng(seed)))


def test_readme_point_with_a_material():
    _check((1 / 30, 10, 0.5, 1 / 3, 1.0), material={"d_p": 1e-3, "rho_p": 2500.0, "phi": 30.0})


def test_material_inputs_against_central_differences():
    p = (1 / 30, 10, 0.5, 1 / 3, 1.0)
    mat = {"d_p": 1e-3, "rho_p": 2500.0, "phi": 30.0, "Lambda": 817.0, "p": 2.5, "q": 2.2,
           "nu_min": 0.5, "nu_max": 0.65, "g": 9.81}
    r = solve_point(*p, material=mat, sensitivities=True)
    for key in mat:
        h = 1e-5 * mat[key]
        up, down = dict(mat), dict(mat)
        up[key] += h
        down[key] -= h
        ru, rd = solve_point(*p, material=up), solve_point(*p, material=down)
        for out in ("nu", "sigma_xx_wall_Pa", "sigma_xy_wall_Pa", "sigma_yx_wall_Pa", "m_wall_Pa_m"):
            fd = (getattr(ru, out) - getattr(rd, out)) / (2 * h)
            # nu is bisected to round-off: the quotient's rounding is ~1e-16 |value| / h
            bound = 1e-6 * abs(fd) + 1e-13 * abs(r.values[out]) / h
            assert abs(r.sensitivities[out][key] - fd) <= bound, (key, out)


def test_next_to_the_path_edge():
    # eta = 3.25, 2 % below the path edge 3.30886 of A = 1/3, N = 1: D(1) is small there
    _check((0.325, 10, 0.5, 1 / 3, 1.0), rel_step=1e-5)


def test_next_to_delta_vanishing():
    # eps K = 5, the plug edge close to the wall (Delta = 0 from K = 201 at eps = 1/30)
    _check((1 / 30, 10, 150.0, 1 / 3, 1.0))


def test_delta_zero_has_zero_plug_edge_derivatives():
    r = solve_point(1 / 30, 10, 250.0, 1 / 3, 1.0, sensitivities=True)
    assert r.Delta == 0.0
    assert all(v == 0.0 for v in r.sensitivities["Delta"].values())


def test_a_minus_one_closed_form():
    # N = 1.5: the code reports A = -1 with N < 1 as wall_inadmissible (docs/model.md, 5)
    _check((1 / 30, 10, 0.5, -1.0, 1.5), params=("eps", "L", "K", "N"))
    r = solve_point(1 / 30, 10, 0.5, -1.0, 1.0, sensitivities=True)
    assert math.isnan(r.sensitivities["Delta"]["A"])


@pytest.mark.parametrize("p", [(0.5, 10, 0.5, 1 / 3, 1.0), (0.1, 10, 0.5, -0.5, 0.3)])
def test_no_solution_gives_nan_and_the_status(p):
    r = solve_point(*p, sensitivities=True, material={"d_p": 1e-3, "rho_p": 2500.0, "phi": 30.0})
    assert not r.ok and r.status.message
    assert r.sensitivities and all(math.isnan(v) for d in r.sensitivities.values() for v in d.values())


def test_only_the_computed_outputs_and_plain_solves_unchanged():
    p = (1 / 30, 10, 0.5, 1 / 3, 1.0)
    r = solve_point(*p, outputs=["m_wall"], sensitivities=True)
    assert set(r.sensitivities) == {"m_wall"}
    plain = solve_point(*p)
    with_s = solve_point(*p, sensitivities=True)
    assert {k: repr(v) for k, v in plain.values.items()} == {k: repr(v) for k, v in with_s.values.items()}
    assert plain.sensitivities is None
    assert with_s.to_dict()["sensitivities"]["Delta"]["eps"] == with_s.sensitivities["Delta"]["eps"]


def _check_profile(p, params=PARAMS, rel_step=1e-4):
    """Profile sensitivities against central differences at the axis, near it, around xi_p and
    at the wall. Each cumulative of the march is resolved relative to its whole magnitude, not
    pointwise, so the sensitivity solve's own error is bounded by 100 rtol of the largest
    derivative over the profile (and the rounding term by the profile's largest value)."""
    xi_p = solve_point(*p).xi_p
    xi = np.clip([0.0, 1e-3, 0.05, 0.3, xi_p - 0.01, xi_p, xi_p + 0.01, 0.99, 1.0], 0.0, 1.0)
    r = solve_point(*p, rtol=RTOL_SENS, profile=xi, sensitivities=True)
    assert r.ok, r.status.message
    ps = r.profile_sensitivities
    assert set(ps) == {"u_over_u0", "omega_hat"}
    assert np.all(ps["u_over_u0"]["eps"][:1] == 0.0)  # u/u(0) = 1 at the axis, for every point
    kw = dict(rtol=RTOL_REF, atol=1e-30, profile=xi)
    for i, name in enumerate(PARAMS):
        if name not in params:
            continue
        h = rel_step * max(abs(p[i]), 1e-2)
        quotients = []
        for step in (h, 2 * h):
            plus, minus = list(p), list(p)
            plus[i] += step
            minus[i] -= step
            a, b = solve_point(*plus, **kw), solve_point(*minus, **kw)
            quotients.append({k: (a.profile[k] - b.profile[k]) / (2 * step) for k in ps})
        for out, d in ps.items():
            fd1, fd2 = quotients[0][out], quotients[1][out]
            bound = (100 * RTOL_SENS * np.max(np.abs(fd1)) + np.abs(fd1 - fd2) / 3
                     + 100 * RTOL_REF * np.max(np.abs(r.profile[out])) / h + 1e-300)
            assert d[name].shape == xi.shape
            assert np.all(np.abs(d[name] - fd1) <= bound), (p, out, name, d[name], fd1, bound)


@pytest.mark.parametrize("p", [(1 / 30, 10, 0.5, 1 / 3, 1.0), (0.05, 4.0, 1.5, -0.4, 1.7),
                               (0.2, 15.0, 0.1, 2.0, 0.8)])
def test_profile_sensitivities_against_central_differences(p):
    _check_profile(p)


def test_profile_sensitivities_a_minus_one_closed_form():
    _check_profile((1 / 30, 10, 0.5, -1.0, 1.5), params=("eps", "L", "K", "N"))


def test_profile_sensitivities_leave_the_rest_unchanged_and_serialise():
    p = (1 / 30, 10, 0.5, 1 / 3, 1.0)
    xi = np.linspace(0, 1, 5)
    with_p = solve_point(*p, profile=xi, sensitivities=True)
    without = solve_point(*p, sensitivities=True)
    assert with_p.sensitivities == without.sensitivities
    assert without.profile_sensitivities is None
    d = with_p.to_dict()["profile_sensitivities"]
    assert d["u_over_u0"]["K"] == with_p.profile_sensitivities["u_over_u0"]["K"].tolist()
    bad = solve_point(0.5, 10, 0.5, 1 / 3, 1.0, profile=xi, sensitivities=True)
    assert not bad.ok
    assert all(np.isnan(a).all() for s in bad.profile_sensitivities.values() for a in s.values())


def test_next_to_the_wall_line():
    # A = 0: wall_inadmissible below N = sqrt(1/2); at N = 0.7072 (1.3e-4 above it) the points
    # with a solution are a window eta in (0.3487, 0.3729) (regimes.trace_edge), where D(1) is
    # at most (A+1)(2N^2 - 1) = 2.8e-4
    from cosserat_channel.physics.analytic import classify_margin

    assert classify_margin(1.0, 0.0, 0.7071) != 0 and classify_margin(1.0, 0.0, 0.7072) == 0
    _check((0.0361, 10, 0.5, 0.0, 0.7072), rel_step=1e-6)


@pytest.mark.parametrize("A, N", [(0.0, 1.0), (0.5, 1.0), (-0.5, 1.0), (-0.99, 1.5), (0.0, 0.72),
                                  (0.9, 0.5), (-0.9, 3.0)])
def test_no_solution_next_to_the_axis_edge(A, N):
    # eps_too_large_axis has no point with a solution next to it (A > -1): every eta above
    # analytic.wall_bound_eta, which lies strictly below the axis edge, fails at the wall
    # (the proof is in wall_bound_eta's docstring). Its only solvable neighbour is A = -1,
    # the closed form's line (the A -> -1 limit of the axis edge is eta -> 0), checked with
    # its parameters other than A in test_a_minus_one_closed_form.
    from cosserat_channel.physics.analytic import axis_edge_eta, wall_bound_eta
    from cosserat_channel.regimes import trace_edge

    bound, axis = float(wall_bound_eta(A, N)), float(axis_edge_eta(A, N))
    assert bound < axis
    for eta in (bound * (1 + 1e-6), 0.5 * (bound + axis), axis * (1 - 1e-9), axis * (1 + 1e-9)):
        r = solve_point(eta / 100, 100, 0.5, A, N)
        assert r.status.name in ("eps_too_large_path", "eps_too_large_axis"), (eta, r.status.name)
    assert trace_edge(A, N).eta_max <= bound


def test_axis_spin_unbounded_has_only_the_a_minus_one_line_next_to_it():
    # 1 - 2N^2 <= A < -1: its neighbours at fixed eta are A = -1 (closed form) and, for
    # A > -1, eps_too_large_axis once eta > wall_bound_eta(A, N) -> 0 as A -> -1: no solvable
    # point with A != -1 (derivatives by A at A = -1 are NaN; by eps, L, K, N checked in
    # test_a_minus_one_closed_form)
    from cosserat_channel.physics.analytic import wall_bound_eta

    p = [1 / 30, 10, 0.5, None, 1.5]
    for A, name in ((-1 - 1e-9, "axis_spin_unbounded"), (-1.0, "ok"),
                    (-1 + 1e-9, "eps_too_large_axis")):
        p[3] = A
        assert solve_point(*p).status.name == name
    assert wall_bound_eta(-1 + 1e-3, 1.5) < 1e-2 < p[0] * p[1]
    r = solve_point(*p[:3], -1.0, 1.5, sensitivities=True)
    assert math.isnan(r.sensitivities["Delta"]["A"]) and math.isfinite(r.sensitivities["Delta"]["N"])


@pytest.mark.parametrize("seed", range(6))
def test_profile_sensitivities_at_random_points(seed):
    _check_profile(_solvable_draw(np.random.default_rng(100 + seed)))


def test_profile_sensitivities_next_to_the_path_edge():
    _check_profile((0.325, 10, 0.5, 1 / 3, 1.0), rel_step=1e-5)


@pytest.mark.parametrize("p", [(0.0130432335, 10, 0.5, 0.921618019, 1.54290037),
                               (0.0207407829, 10, 0.5, 0.522676899, 1.94290226)])
def test_steep_spin_with_the_axis_series_to_xi_0_9(p):
    # beta ~ 25 and stage 1 on its axis series up to xi = 0.9: omega_hat falls by 1e-12 within
    # the sensitivity march, where J(0) - J is the difference of two quadratures (stage 2's and
    # the march's) and has to give way to the axis asymptotics
    r = solve_point(*p, sensitivities=True)
    assert r.ok and math.isfinite(r.sensitivities["Delta"]["eps"])
    _check(p)
    _check_profile(p)


# ---------------------------------------------------------------------------------------------
# Over the whole domain and every tolerance: the status is the solve's, and each derivative is
# within 100 rtol of central differences of the independent reference, or NaN with its reason.
# ---------------------------------------------------------------------------------------------
def _domain_draw(rng):
    """A random point with a solution: eps L log-uniform from 1e-6 (stiff stage 1) to 3, A and
    N over the range where the model has solutions, and an rtol log-uniform in [1e-12, 1e-6]."""
    while True:
        eta = 10 ** rng.uniform(-6, 0.5)
        eps = 10 ** rng.uniform(max(-6.5, math.log10(eta) - 2), min(-0.3, math.log10(eta) + 1))
        p = (float(eps), float(eta / eps), float(10 ** rng.uniform(-2, 2)),
             float(rng.uniform(-0.9, 4)), float(10 ** rng.uniform(-0.3, 1)))
        if solve_point(*p).ok:
            return p, float(10 ** rng.uniform(-12, -6))


def _flags_explain_every_nan(r):
    for out, d in r.sensitivities.items():
        for name, v in d.items():
            flag = r.sensitivity_flags[out][name]
            assert math.isnan(v) == (flag not in ("adjoint", "differences")), (out, name, v, flag)


@pytest.mark.parametrize("seed", range(3))
def test_sensitivities_never_change_the_status(seed):
    rng = np.random.default_rng(700 + seed)
    for _ in range(12):
        p, rtol = _domain_draw(rng)
        plain = solve_point(*p, rtol=rtol)
        r = solve_point(*p, rtol=rtol, sensitivities=True)
        assert r.status == plain.status, (p, rtol, r.status.name)
        assert {k: repr(v) for k, v in plain.values.items()} == \
            {k: repr(v) for k, v in r.values.items()}
        _flags_explain_every_nan(r)


@pytest.mark.parametrize("rtol", [1e-8, 1e-10, 1e-12])
def test_stiff_point_that_lost_its_status_to_derivatives(rtol):
    # eps L = 1.2e-4: on stage 1's slow manifold the A partials were differences of near-equal
    # terms whose rounding no panel of the march could resolve
    p = (9.765e-05, 1.239, 86.07, 2.653, 2.225)
    r = solve_point(*p, rtol=rtol, sensitivities=True)
    assert r.ok
    assert all(f == "adjoint" for d in r.sensitivity_flags.values() for f in d.values())


def _reference_outputs(p):
    from cosserat_channel.physics.reference import reference

    # Radau where stage 1 is stiff (scipy's explicit pairs would crawl), DOP853 elsewhere; None
    # where the reference has no solution or cannot give one (its own checks, its root bracket)
    try:
        ref = reference(*p, method="Radau" if p[0] * p[1] < 1e-2 else "DOP853")
    except (AssertionError, ValueError, ZeroDivisionError):
        return None
    return ref if ref["status"] == "ok" else None


@pytest.mark.slow
@pytest.mark.parametrize("seed", range(2))
def test_random_domain_against_reference_differences(seed):
    """Richardson-extrapolated central differences of the reference (scipy at rtol 1e-12) with
    steps h, 2h, 4h: the difference of the extrapolations from (h, 2h) and (2h, 4h) bounds the
    first's truncation error, and the reference's own error (100 x its rtol, relative) divided
    by h its rounding. Each derivative is within 100 rtol of the output over the parameter,
    plus that bound. The two draws cover both stage-1 paths and both reference methods: seed 0
    eps L ~ 1e-6 with A < 0 (stiff path, Radau), seed 1 eps L ~ 0.05 at rtol ~ 1e-11 (explicit
    path, DOP853); further draws land on the stiff path again."""
    from cosserat_channel.physics.reference import RTOL as RTOL_REF

    rng = np.random.default_rng(900 + seed)
    p, rtol = _domain_draw(rng)
    r = solve_point(*p, rtol=rtol, sensitivities=True)
    assert r.ok
    _flags_explain_every_nan(r)
    outs = ("Delta", "xi_p", "slip", "u_axis", "m_wall", "sigma_yx_wall")
    compared = 0
    for i, name in enumerate(PARAMS):
        h = 2e-3 * max(abs(p[i]), 1e-2)
        if name == "A":
            h = min(h, 0.2 * (p[3] + 1.0))
        refs = {}
        for k in (-4, -2, -1, 1, 2, 4):
            q = list(p)
            q[i] += k * h
            refs[k] = _reference_outputs(tuple(q))
        if any(v is None for v in refs.values()):
            continue  # an edge within 4h: the differences do not apply
        for out in outs:
            d1, d2, d4 = ((refs[k][out] - refs[-k][out]) / (2 * k * h) for k in (1, 2, 4))
            r1, r2 = (4 * d1 - d2) / 3, (4 * d2 - d4) / 3
            value = abs(r.values[out])
            # the output over the parameter (A, which may be near 0, over at least 0.01)
            bound = (100 * rtol * value / max(abs(p[i]), 1e-2 if name == "A" else 0.0)
                     + abs(r1 - r2) + 100 * RTOL_REF * value / h + 1e-300)
            d = r.sensitivities[out][name]
            if r.sensitivity_flags[out][name] in ("adjoint", "differences"):
                assert abs(d - r1) <= bound, (p, rtol, out, name, d, r1, bound)
                compared += 1
    assert compared >= len(outs), (p, rtol)  # at least one parameter's worth


def test_differences_stand_in_where_the_march_leaves_a_parameter_unresolved():
    """The fallback on its own: the adjoint's results with the A row marked unresolved give the
    derivatives by A from differences (flagged so), within 10 rtol of the adjoint's own."""
    from cosserat_channel.solver import sensitivity as sv

    p = (1 / 30, 10, 0.5, 1 / 3, 1.0)
    rtol = 1e-8
    full = solve_point(*p, rtol=rtol, sensitivities=True)
    eps, L, K, A, N = p
    r = solve_point(*p, rtol=rtol)
    x = {k: np.array([v]) for k, v in dict(zip(PARAMS, p)).items()}
    from cosserat_channel.solver.point import Workspace

    ws = Workspace()
    ws.run(eps * L, A, N, rtol, 1e-12)
    x.update(J0=np.array([r.u_axis - eps * K]), mu=np.array([r.m_wall / L]),
             sig=np.array([r.sigma_yx_wall]), one_minus=np.array([1 - r.xi_p]))
    out = np.empty((1, sv.N_S))
    sv.sensitivity_kernel(eps * L, A, N, eps * K, 1 - r.xi_p, rtol, 1e-12, ws.ax, ws.res, ws.T1,
                          ws.Q1, out[0], np.empty(0), np.empty(3), np.empty((sv.N_PS, 1)))
    out[0, sv.S_UNRESOLVED + 1] = 1.0
    values, flags = sv.assemble(list(full.sensitivities), out, np.array([0]), x, None, rtol, 1e-12)
    for o in ("Delta", "u_axis", "m_wall", "sigma_yx_wall"):
        assert sv.FLAGS[flags[o]["A"][0]] == "differences"
        assert sv.FLAGS[flags[o]["N"][0]] == "adjoint"
        want = full.sensitivities[o]["A"]
        assert abs(values[o]["A"][0] - want) <= 10 * rtol * (abs(full.values[o]) + abs(want)), o


def test_differentiable_outputs_are_marked_in_the_registry():
    from cosserat_channel import outputs

    r = solve_point(1 / 30, 10, 0.5, 1 / 3, 1.0, sensitivities=True,
                    material={"d_p": 1e-3, "rho_p": 2500.0, "phi": 30.0})
    assert set(r.sensitivities) == {n for n, o in outputs.OUTPUTS.items() if o.differentiable}
    assert "xi_stop" not in r.sensitivities
    plain = outputs.Output("Delta_twice", "1", "twice Delta", lambda x: 2 * x.get("Delta"),
                           plug_edge=True)
    with outputs.registered(plain):
        r = solve_point(1 / 30, 10, 0.5, 1 / 3, 1.0, sensitivities=True)
        assert "Delta_twice" in r.values and "Delta_twice" not in r.sensitivities
    marked = outputs.Output("Delta_marked", "1", "twice Delta", lambda x: 2 * x.get("Delta"),
                            plug_edge=True, differentiable=True)
    with outputs.registered(marked), pytest.raises(ValueError, match="Delta_marked"):
        solve_point(1 / 30, 10, 0.5, 1 / 3, 1.0, sensitivities=True)


@pytest.mark.parametrize("K", [1e160, 1e300])
def test_derivatives_at_a_wall_roughness_beyond_the_square_of_a_double(K):
    """K has no upper bound: at K where u(0)^2 overflows, the derivatives are finite with no
    warning, and d slip/dK lies in [0, 1/K] (slip = eps K/(eps K + J(0)))."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        r = solve_point(1 / 30, 10, K, 1 / 3, 1, sensitivities=True)
    assert r.status.name == "ok"
    for name, by in r.sensitivities.items():
        for p, x in by.items():
            assert np.isfinite(x), (name, p, x)
    assert 0.0 <= r.sensitivities["slip"]["K"] <= 1.0 / K
