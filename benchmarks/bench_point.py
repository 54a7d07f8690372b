"""Microseconds per point: ours (both stages, stage 1) against numbalsoda and scipy, in one run.

Grid: eps log-spaced in [1/600, 0.2] (50 values) x L in [2, 20] (20 values), A = 1/3,
N = 1, K = 0.5: 1000 points, one core. Ours runs the whole grid inside one Numba kernel
(`solve_batch`, no reduction: every point integrated). scipy runs the same two-stage problem
(same formulation: stage 1 in w = delta/xi^2 from the axis series, stage 2 in ln xi) point by
point in a Python loop, on an evenly spread subsample (it is ~1000x slower). Everything is
measured in one run, so the ratios hold on a noisy shared machine. With numbalsoda installed
(``pip install -e '.[bench]'``, needs gfortran) its LSODA and DOP853 solve stage 1 of the same
points at rtol 1e-6 and 1e-8, and the ratios to numbalsoda LSODA are checked against the targets.

On a shared machine one method's time moves by tens of percent between calls, so the peers'
table is measured in rounds: each round times every method once, one after the other, and the
ratios are taken within a round, of the CPU time of this thread (``time.thread_time``: time spent
waiting for a core does not count). The table gives each method's fastest round and the median
of the per-round ratios, with their range; the targets are judged on that median.

Run:  .venv/bin/python benchmarks/bench_point.py [--scipy-points 40] [--repeat 7] [--json PATH]
"""

from __future__ import annotations

import math
import os
import time

import numba
import numpy as np
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

from cosserat_channel.physics import model
from cosserat_channel.solver import stage1, stage2
from cosserat_channel.measure import harness, runners

RTOL = 1e-8
ATOL = 1e-12


def grid():
    eps = np.logspace(np.log10(1 / 600), np.log10(0.2), 50)
    L = np.linspace(2, 20, 20)
    E, LL = np.meshgrid(eps, L, indexing="ij")
    return E.ravel(), LL.ravel()


def _scipy_stage1_run(eps, L, A, N, method, dense):
    """Stage 1 with solve_ivp in our formulation: (solution, ax, xi1), or None where classify says no."""
    eta = eps * L
    if model.classify(eta, A, N) != 0:
        return None
    ax = np.empty(model.N_AX)
    model.axis_constants(eta, A, N, ax)
    xi1, w0 = stage1.ivp_start(ax)

    def f1(xi, w):
        return [model.dw_dxi(xi, w[0], eta, A, N, ax)]

    def hit(xi, w):
        return model.yield_D(xi, xi * xi * w[0], A, N, ax)

    hit.terminal = True
    s1 = solve_ivp(f1, [xi1, 1.0], [w0], method=method, rtol=RTOL, atol=ATOL, events=hit,
                   dense_output=dense)
    return s1, ax, xi1


def scipy_stage1(eps, L, A, N, method):
    """Stage 1 alone with solve_ivp (same formulation); returns m(1)/(nu L) or NaN."""
    run = _scipy_stage1_run(eps, L, A, N, method, dense=False)
    if run is None or run[0].status != 0:
        return math.nan
    return run[0].y[0, -1] - N


def scipy_point(eps, L, K, A, N, method):
    """Both stages with solve_ivp, the same formulation as ours; returns Delta (NaN if no solution)."""
    eta = eps * L
    run = _scipy_stage1_run(eps, L, A, N, method, dense=True)
    if run is None or run[0].status != 0:
        return math.nan
    s1, ax, xi1 = run

    def delta_at(xi):
        return model.delta_axis_series(xi, ax) if xi <= xi1 else xi * xi * s1.sol(xi)[0]

    def f2(t, z):
        xi = math.exp(t)
        d = delta_at(xi)
        r = 1.0 / math.sqrt(model.yield_D(xi, d, A, N, ax))
        return [xi * model.spin_rate_B(d, r, eta, A, N),
                -xi * model.shear_rate_h(xi, r, A) * math.exp(z[0])]

    def gone(t, z):
        return z[0] - math.log(1e-3 * RTOL)

    gone.terminal = True
    s2 = solve_ivp(f2, [0.0, math.log(stage2.XI_FLOOR)], [0.0, 0.0], method=method, rtol=RTOL,
                   atol=[RTOL, ATOL], events=gone, dense_output=True)
    J0 = s2.y[1, -1]
    target = model.plug_target(J0, eps * K)
    if target <= 0:
        return 0.0
    tp = brentq(lambda t: s2.sol(t)[1] - target, s2.t[-1], 0.0, xtol=1e-14)
    return -math.expm1(tp) / eps


# numbalsoda's stage 1 at (rtol, atol) = (1e-6, 1e-8) and (1e-8, 1e-10); ours
# at the same tolerances. Targets: ours, both stages <= 0.75 x numbalsoda LSODA's stage 1; ours,
# stage 1 <= 0.5 x.
TOLERANCES = ((1e-6, 1e-8), (1e-8, 1e-10))
TARGET_BOTH = 0.75
TARGET_STAGE1 = 0.5


def _rel(a, b):
    ok = np.isfinite(a) & np.isfinite(b) & (b != 0)
    return float(np.max(np.abs(a[ok] / b[ok] - 1))) if ok.any() else math.nan


def _cpu(call, n):
    """``(CPU seconds of this thread per point, result)`` of one runner call (one pass over the
    points; numbalsoda's runner adds one point's warm call): blind to waiting for a core."""
    t0 = time.thread_time()
    _, result = call()
    return (time.thread_time() - t0) / n, result


def _round(eps, L, K, A, N, rtol, atol, nbs):
    """One round: each method timed once (one call over all points), in a fixed order."""
    t = {}
    n = eps.size
    t["ours, both stages"], both = _cpu(lambda: runners.ours_both(eps, L, K, A, N, rtol, atol, 1), n)
    t["ours, stage 1"], m1 = _cpu(lambda: runners.ours_stage1(eps, L, A, N, rtol, atol, 1), n)
    m = {}
    if nbs is not None:
        for method in ("LSODA", "DOP853"):
            name = f"numbalsoda {method}, stage 1"
            t[name], m[name] = _cpu(lambda m=method: runners.numbalsoda_stage1(
                nbs, eps, L, A, N, m, rtol, atol, 1), n)
    return t, both, m1, m


def peers(eps, L, repeat, rec):
    """Ours (both stages, stage 1) and numbalsoda LSODA / DOP853 (stage 1), one table per rtol,
    from ``repeat`` interleaved rounds (module docstring)."""
    n = eps.size
    A, N, K = np.full(n, 1 / 3), np.ones(n), np.full(n, 0.5)
    nbs, nbs_note = runners.numbalsoda_status()
    base_name = "numbalsoda LSODA, stage 1"
    lines = []
    for rtol, atol in TOLERANCES:
        rounds = []
        _round(eps, L, K, A, N, rtol, atol, nbs)  # untimed: compiles numbalsoda's loop, warms caches
        for _ in range(max(1, repeat)):
            t, both, m1, m = _round(eps, L, K, A, N, rtol, atol, nbs)
            rounds.append(t)
        names = list(rounds[0])
        fastest = {k: min(r[k] for r in rounds) for k in names}
        ratios = {k: np.array([r[k] / r[base_name] for r in rounds]) if nbs is not None else None
                  for k in names}
        diffs = {"ours, both stages": _rel(both["m_wall"], m1), "ours, stage 1": 0.0}
        diffs.update({k: _rel(v, m1) for k, v in m.items()})
        lines.append(f"\nrtol = {rtol:g}, atol = {atol:g} ({n} points, one core, {len(rounds)} "
                     "interleaved rounds, CPU time)\n")
        lines.append(f"| {'method':<28} | {'us/point':>9} | {'x numbalsoda LSODA stage 1':>26} "
                     f"| {'ratio range':>11} | {'max rel. diff of m_wall vs ours':>31} |")
        lines.append(f"|{'-' * 30}|{'-' * 11}|{'-' * 28}|{'-' * 13}|{'-' * 33}|")
        for name in names:
            r = ratios[name]
            med = "-" if r is None else f"{np.median(r):.2f}"
            spread = "-" if r is None else f"{r.min():.2f}-{r.max():.2f}"
            lines.append(f"| {name:<28} | {fastest[name] * 1e6:>9.1f} | {med:>26} | {spread:>11} "
                         f"| {diffs[name]:>31.1e} |")
            rec.row("peers", rtol=rtol, atol=atol, method=name, us_per_point=fastest[name] * 1e6,
                    us_per_point_rounds=[x[name] * 1e6 for x in rounds],
                    x_numbalsoda_lsoda=None if r is None else float(np.median(r)),
                    x_numbalsoda_lsoda_rounds=None if r is None else r.tolist(),
                    max_rel_diff_m_wall=diffs[name])
        for label, name, target in (("both stages", "ours, both stages", TARGET_BOTH),
                                    ("stage 1", "ours, stage 1", TARGET_STAGE1)):
            text = (f"rtol {rtol:g}: ours, {label} <= {target:g} x numbalsoda LSODA's stage 1 "
                    "(median of rounds)")
            if nbs is None:
                v = rec.check(text, None, f"numbalsoda not available ({nbs_note})")
            else:
                r = float(np.median(ratios[name]))
                v = rec.check(text, r <= target,
                              f"{r:.2f}" + ("" if r <= target else f", {r / target:.2f}x over"))
            lines.append("target: " + v.line())
    return lines


def _load(when):
    """The machine's load average, to read the times by (other jobs share the cores)."""
    one, five, fifteen = os.getloadavg()
    return f"load average {when}: {one:.2f} / {five:.2f} / {fifteen:.2f} (1 / 5 / 15 min)"


def main():
    ap = harness.parser(__doc__)
    ap.add_argument("--scipy-points", type=int, default=40)
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    numba.set_num_threads(1)
    eps, L = grid()
    n = eps.size
    rec = harness.Record("bench_point", args.json)
    runners.warm_up()
    print(f"{n} points, eps in [1/600, 0.2] x L in [2, 20], A = 1/3, N = 1, K = 0.5, one core")
    print(_load("before the peers"))
    for line in peers(eps, L, args.repeat, rec):
        print(line)
    print(_load("after the peers"))

    # scipy solve_ivp in a Python loop, at RTOL, on an evenly spread subsample.
    A, N, K = np.full(n, 1 / 3), np.ones(n), np.full(n, 0.5)
    t_both, both = runners.ours_both(eps, L, K, A, N, RTOL, ATOL, args.repeat)
    t_s1, m1 = runners.ours_stage1(eps, L, A, N, RTOL, ATOL, args.repeat)
    pick = np.linspace(0, n - 1, args.scipy_points).round().astype(int)
    rows = [("ours, both (DP5/DOP853 or RODAS, panels)", n, t_both * 1e6, math.nan, t_both * 1e6),
            ("ours, stage 1 alone", n, t_s1 * 1e6, math.nan, t_s1 * 1e6)]
    for method in ("RK45", "LSODA"):
        t0 = time.perf_counter()
        d = np.array([scipy_point(eps[i], L[i], 0.5, 1 / 3, 1.0, method) for i in pick])
        us = (time.perf_counter() - t0) / pick.size * 1e6
        rows.append((f"scipy solve_ivp {method} loop, both stages", pick.size, us,
                     _rel(d, both["Delta"][pick]), t_both * 1e6))
        t0 = time.perf_counter()
        m = np.array([scipy_stage1(eps[i], L[i], 1 / 3, 1.0, method) for i in pick])
        us = (time.perf_counter() - t0) / pick.size * 1e6
        rows.append((f"scipy solve_ivp {method} loop, stage 1", pick.size, us,
                     _rel(L[pick] * m, m1[pick]), t_s1 * 1e6))
    print(f"\nscipy loops at rtol = {RTOL:g}, atol = {ATOL:g}\n")
    print(f"| {'method':<42} | {'points':>6} | {'us/point':>9} | {'x ours (same stages)':>20} "
          f"| {'max rel. diff vs ours':>21} |")
    print(f"|{'-' * 44}|{'-' * 8}|{'-' * 11}|{'-' * 22}|{'-' * 23}|")
    for name, npts, us, err, base in rows:
        err_s = "-" if math.isnan(err) else f"{err:.1e}"
        print(f"| {name:<42} | {npts:>6} | {us:>9.1f} | {us / base:>20.1f} | {err_s:>21} |")
        rec.row("scipy_loops", method=name, points=npts, us_per_point=us, x_ours=us / base,
                max_rel_diff=err)
    print("\n(max rel. diff: Delta for both stages, m_wall for stage 1)")
    return rec.finish()


if __name__ == "__main__":
    raise SystemExit(main())
