"""Fuzz of both stages inside the solvable region: integration failures and stage 2's rejections.

Part 1, random points. Draws ``(eta = eps L, A, N)`` from two domains in turn and solves both
stages with :func:`~cosserat_channel.solver.batch.solve_batch` at the given tolerances (default: the package's), in
chunks, on one core, until ``--points`` of them lie inside the solvable region:

- ``domain``: the parameter domain of ``tests/test_domain.py`` (eps log-uniform in [1e-7, 0.5],
  L log-uniform in [0.5, 100], A uniform in [-3, 5], N log-uniform in [0.3, 10]);
- ``stiff start``: eta log-uniform in [1e-3, 3e-2], A uniform in [-0.9, 5], N log-uniform in
  [0.9, 1.2], where stage 1 starts DOP853 with a first trial step many times beyond its
  stability boundary (the region of the reported ``integration_failed`` band).

Inside means: status ok, or ``integration_failed`` where a solve at ``REF_RTOL`` is ok (the
package's own verdict at a tight tolerance; an ``integration_failed`` that stays so there is
reported apart). Reports the ``integration_failed`` inside (target 0) and the distribution of
stage 2's rejected panels: many rejections mean that stage 2 chokes on the stage-1 solution it
integrates, the symptom of a bad stage-1 step. The points with the most rejections are solved
again at ``REF_RTOL`` and their ``J(0)`` compared.

Part 2, bands (``--lines``, 0 to skip). Random points are unlikely to fall into a band ~1e-5
(relative) wide, so the bands are also located: along lines in eta at random ``(A, N)`` of the
stiff-start domain, where the first
trial step of stage 1's DOP853 march sits on a zero of its error estimate (found by bisection
on the estimate's 5th-order part, ``dop853.E5``) beyond 1.5 times its stability boundary, where
a step whose result is useless passes the error test. Each such point is solved, and compared
with a solve at ``REF_RTOL``.

Run:  .venv/bin/python benchmarks/fuzz_stage2.py [--points 1000000] [--lines 300] [--seed 1]
[--json PATH]. A check, not a timing: it exits 1 when an ``integration_failed`` is found inside.
"""

from __future__ import annotations

import math
import sys
import time

import numba
import numpy as np
from numba import njit

from cosserat_channel.measure import harness
from cosserat_channel import status as st
from cosserat_channel.integrate import dop853, stepping
from cosserat_channel.parameters import DEFAULT_ATOL, DEFAULT_RTOL
from cosserat_channel.physics import model
from cosserat_channel.solver import layout, stage1, stage2
from cosserat_channel.solver.batch import solve_batch

REF_RTOL = 1e-12
CHUNK = 20_000
# Points re-solved at REF_RTOL: those with at least this many stage-2 rejections (and the top few).
MANY_REJECTIONS = 8
TOP = 12
EDGES = [0, 1, 2, 4, 8, 16, 32, 64, 128, 256, 10**9]


def draw_domain(rng, n):
    """``(eta, A, N)`` over the domain of tests/test_domain.py."""
    eps = 10.0 ** rng.uniform(-7.0, math.log10(0.5), n)
    L = 10.0 ** rng.uniform(math.log10(0.5), 2.0, n)
    return eps * L, rng.uniform(-3.0, 5.0, n), 10.0 ** rng.uniform(math.log10(0.3), 1.0, n)


def draw_stiff_start(rng, n):
    """``(eta, A, N)`` where DOP853 starts far beyond its stability boundary."""
    eta = 10.0 ** rng.uniform(-3.0, math.log10(3e-2), n)
    return eta, rng.uniform(-0.9, 5.0, n), 10.0 ** rng.uniform(math.log10(0.9), math.log10(1.2), n)


DOMAINS = {"domain": draw_domain, "stiff start": draw_stiff_start}


def solve(eta, A, N, rtol, atol):
    """Both stages for each triple (no plug-edge root): ``(res, stats)`` of solve_batch."""
    n = eta.size
    res = np.empty((n, layout.N_R))
    stats = np.zeros((n, 2, stepping.N_STATS), np.int64)
    solve_batch(np.ascontiguousarray(eta, dtype=float), np.ascontiguousarray(A, dtype=float),
                np.ascontiguousarray(N, dtype=float), np.zeros(n), np.zeros(n + 1, np.int64), rtol,
                atol, stage1.MAX_STEPS_STAGE1, stage2.MAX_STEPS_STAGE2, res, stats, np.empty(0),
                np.empty(0), np.empty((n, layout.N_PROF, 0)), True, False)
    return res, stats


class Tally:
    """What part 1 keeps of one domain."""

    def __init__(self):
        self.drawn = self.inside = 0
        self.failed = []  # (eta, A, N, stage-2 accepted, rejected, J(0) at REF_RTOL), inside
        self.failed_tight = []  # integration_failed at REF_RTOL too
        self.rejections = []
        self.worst = []  # (rejections, eta, A, N, J(0))

    def add(self, eta, A, N, rtol, atol, room):
        res, stats = solve(eta, A, N, rtol, atol)
        self.drawn += eta.size
        code = res[:, layout.R_STATUS]
        bad = np.flatnonzero(code == st.INTEGRATION_FAILED)
        ok_ref = np.zeros(eta.size, bool)
        if bad.size:
            ref, _ = solve(eta[bad], A[bad], N[bad], REF_RTOL, atol)
            ok_ref[bad] = ref[:, layout.R_STATUS] == st.OK
            for j, i in enumerate(bad):
                row = (eta[i], A[i], N[i], int(stats[i, 1, stepping.STAT_ACCEPTED]),
                       int(stats[i, 1, stepping.STAT_REJECTED]), ref[j, layout.R_J_AXIS])
                (self.failed if ok_ref[i] else self.failed_tight).append(row)
        keep = np.flatnonzero((code == st.OK) | ok_ref)[:room]
        self.inside += keep.size
        rej = stats[keep, 1, stepping.STAT_REJECTED]
        self.rejections.append(rej)
        for i in keep[rej >= MANY_REJECTIONS]:
            self.worst.append((int(stats[i, 1, stepping.STAT_REJECTED]), eta[i], A[i], N[i],
                               res[i, layout.R_J_AXIS]))
        return keep.size

    def report(self, name, atol):
        rej = np.concatenate(self.rejections) if self.rejections else np.zeros(0, np.int64)
        print(f"\n## {name}: {self.drawn:,} drawn, {self.inside:,} inside the solvable region")
        print(f"integration_failed inside: {len(self.failed)} (target 0)")
        for eta, A, N, n_acc, n_rej, J_ref in self.failed:
            print(f"  eta = {eta!r}, A = {A!r}, N = {N!r}: stage 2 {n_acc} accepted, {n_rej} "
                  f"rejected; J(0) at rtol {REF_RTOL:g} = {J_ref:.10g}")
        print(f"integration_failed also at rtol {REF_RTOL:g} (not counted inside): "
              f"{len(self.failed_tight)}")
        for eta, A, N, n_acc, n_rej, _ in self.failed_tight[:TOP]:
            print(f"  eta = {eta!r}, A = {A!r}, N = {N!r}: stage 2 {n_acc} accepted, {n_rej} "
                  "rejected")
        print("stage-2 rejected panels per point inside:")
        for lo, hi in zip(EDGES[:-1], EDGES[1:]):
            count = int(((rej >= lo) & (rej < hi)).sum())
            if count:
                label = f"{lo}" if hi == lo + 1 else f"{lo}-{min(hi, int(rej.max()) + 1) - 1}"
                print(f"  {label:>9}: {count:>9,} ({100 * count / rej.size:.4f} %)")
        if rej.size:
            print(f"  mean {rej.mean():.3f}, 99th percentile {np.percentile(rej, 99):.0f}, "
                  f"99.99th {np.percentile(rej, 99.99):.0f}, max {rej.max()}")
        self.worst.sort(key=lambda w: -w[0])
        if self.worst:
            top = self.worst[:TOP]
            print(f"{len(self.worst)} points inside with >= {MANY_REJECTIONS} rejections; the "
                  f"{len(top)} with most, J(0) against rtol {REF_RTOL:g}:")
            ref, _ = solve(np.array([w[1] for w in top]), np.array([w[2] for w in top]),
                           np.array([w[3] for w in top]), REF_RTOL, atol)
            for w, J_ref in zip(top, ref[:, layout.R_J_AXIS]):
                diff = (f"J(0) rel. diff {abs(w[4] / J_ref - 1.0):.1e}" if math.isfinite(w[4])
                        else "integration_failed")
                print(f"  {w[0]:>5} rejected: eta = {w[1]!r}, A = {w[2]!r}, N = {w[3]!r}; {diff}")


@njit
def first_trial(eta, A, N, rtol):
    """``(E5 part of the error estimate, h |lambda|)`` of stage 1's first DOP853 trial step as
    :func:`~cosserat_channel.solver.stage1.solve_stage1` takes it (NaN where stage 1 does not start with DOP853)."""
    if model.classify(eta, A, N) != st.OK or A == -1.0:
        return math.nan, 0.0
    ax = np.empty(model.N_AX)
    model.axis_constants(eta, A, N, ax)
    rtol1 = stage1.stage1_rtol(rtol, A, N, ax)
    if rtol1 > stage1.DOP853_RTOL:
        return math.nan, 0.0
    xi1, w1 = stage1.stage1_start(ax, rtol1)
    if stage1.use_stiff_path(eta, A, N, ax, xi1, rtol1):
        return math.nan, 0.0
    split = xi1 + stage1.SPLIT_MARGIN < N < 1.0 - stage1.SPLIT_MARGIN
    h = min(xi1, (N if split else 1.0) - xi1)  # the first trial: xi1, clipped to the stretch
    args = (eta, A, N, ax)
    K = np.empty((dop853.N_STAGES_EXTENDED, 1))
    y = np.full(1, w1)
    y_new = np.empty(1)
    ys = np.empty(1)
    stage1._stage1_rhs(xi1, y, args, K[0])
    dop853.dop853_step(stage1._stage1_rhs, xi1, y, h, args, K, y_new, ys)
    e5 = 0.0
    for j in range(dop853.N_STAGES + 1):
        e5 += dop853.E5[j] * K[j, 0]
    return e5, h * abs(model.dw_dxi_jacobian(xi1, w1, eta, A, N, ax)[0])


def bands(rng, lines, rtol, samples=400):
    """Points where the first DOP853 trial of stage 1 sits on a zero of E5 beyond 1.5 times the
    stability boundary: ``(eta, A, N)`` arrays, bisected along lines in eta in [1e-4, 0.1] at
    random ``(A, N)`` of the stiff-start domain."""
    found = []
    beyond = 1.5 * dop853.STIFF_THRESHOLD
    for _ in range(lines):
        _, A, N = draw_stiff_start(rng, 1)
        A, N = float(A[0]), float(N[0])
        etas = np.geomspace(1e-4, 0.1, samples)
        vals = [first_trial(e, A, N, rtol) for e in etas]
        for k in range(samples - 1):
            (a, za), (b, zb) = vals[k], vals[k + 1]
            if not (a * b < 0.0 and min(za, zb) > beyond):
                continue
            lo, hi = etas[k], etas[k + 1]
            while hi - lo > 1e-15 * lo:
                mid = 0.5 * (lo + hi)
                m = first_trial(mid, A, N, rtol)[0]
                if not math.isfinite(m):
                    break
                if (m > 0.0) == (a > 0.0):
                    lo = mid
                else:
                    hi = mid
            found.append((lo, A, N))
    found = np.array(found).reshape(-1, 3)
    return found[:, 0], found[:, 1], found[:, 2]


def main(argv=None) -> int:
    ap = harness.parser(__doc__)
    ap.add_argument("--points", type=int, default=1_000_000, help="points inside to reach")
    ap.add_argument("--lines", type=int, default=300, help="lines in eta searched for bands")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--rtol", type=float, default=DEFAULT_RTOL)
    ap.add_argument("--atol", type=float, default=DEFAULT_ATOL)
    ap.add_argument("--max-seconds", type=float, default=1800.0,
                    help="stop part 1 after this much CPU time, whatever the count (default 1800)")
    args = ap.parse_args(argv)
    rec = harness.Record("fuzz_stage2", args.json,
                         argv=sys.argv if argv is None else [sys.argv[0], *argv])
    numba.set_num_threads(1)
    rng = np.random.default_rng(args.seed)
    one = np.ones(1)
    solve(0.3 * one, one / 3, one, args.rtol, args.atol)  # compile outside the timing
    solve(0.3 * one, one / 3, one, REF_RTOL, args.atol)

    tallies = {name: Tally() for name in DOMAINS}
    t0 = time.process_time()
    inside = 0
    while inside < args.points and time.process_time() - t0 < args.max_seconds:
        for name, draw in DOMAINS.items():
            room = (args.points - inside + 1) // 2 if name == "domain" else args.points - inside
            inside += tallies[name].add(*draw(rng, CHUNK), args.rtol, args.atol, room)
        print(f"# {inside:,} inside, integration_failed inside: "
              f"{sum(len(t.failed) for t in tallies.values())} "
              f"({time.process_time() - t0:.0f} s)", file=sys.stderr, flush=True)
    seconds = time.process_time() - t0
    drawn = sum(t.drawn for t in tallies.values())
    print(f"# fuzz_stage2: seed {args.seed}, rtol {args.rtol:g}, atol {args.atol:g}; part 1: "
          f"{drawn:,} points drawn, {inside:,} inside the solvable region, {seconds:.0f} s CPU "
          f"({1e6 * seconds / max(drawn, 1):.1f} us per point drawn)")
    for name, tally in tallies.items():
        tally.report(name, args.atol)
        rec.row("part1", domain=name, drawn=tally.drawn, inside=tally.inside,
                integration_failed_inside=len(tally.failed),
                integration_failed_also_tight=len(tally.failed_tight))
    failed = sum(len(t.failed) for t in tallies.values())
    rec.check("part 1: no integration_failed inside the solvable region", failed == 0,
              f"{failed} of {inside:,} points inside")

    if args.lines > 0:
        t0 = time.process_time()
        eta, A, N = bands(rng, args.lines, args.rtol)
        res, stats = solve(eta, A, N, args.rtol, args.atol)
        ref, _ = solve(eta, A, N, REF_RTOL, args.atol)
        code, code_ref = res[:, layout.R_STATUS], ref[:, layout.R_STATUS]
        ok = (code == st.OK) & (code_ref == st.OK)
        band_failed = np.flatnonzero((code == st.INTEGRATION_FAILED) & (code_ref == st.OK))
        J = np.abs(res[ok, layout.R_J_AXIS] / ref[ok, layout.R_J_AXIS] - 1.0)
        m = np.abs(res[ok, layout.R_MU_WALL] / ref[ok, layout.R_MU_WALL] - 1.0)
        rej = stats[:, 1, stepping.STAT_REJECTED]
        print(f"\n## part 2, bands: {args.lines} lines in eta, {eta.size} points where the first "
              f"DOP853 trial sits on a zero of its error estimate "
              f"({time.process_time() - t0:.0f} s CPU)")
        print("statuses: " + ", ".join(f"{st.Status(int(c)).name} {int((code == c).sum())}"
                                       for c in np.unique(code))
              + f"; differing from rtol {REF_RTOL:g}: {int((code != code_ref).sum())}")
        print(f"integration_failed where rtol {REF_RTOL:g} is ok: {band_failed.size} (target 0)")
        for i in band_failed[:TOP]:
            print(f"  eta = {eta[i]!r}, A = {A[i]!r}, N = {N[i]!r}: stage 2 "
                  f"{stats[i, 1, stepping.STAT_ACCEPTED]} accepted, {rej[i]} rejected")
        if ok.any():
            print(f"ok at both: {int(ok.sum())}; rel. diff to rtol {REF_RTOL:g}: J(0) median "
                  f"{np.median(J):.1e}, max {J.max():.1e}; m_wall max {m.max():.1e}")
        print(f"stage-2 rejected panels: max {rej.max() if rej.size else 0}, points with >= "
              f"{MANY_REJECTIONS}: {int((rej >= MANY_REJECTIONS).sum())}")
        failed += band_failed.size
        rec.add("part2", {"lines": args.lines, "points": eta.size,
                          "integration_failed_where_tight_ok": band_failed.size})
        rec.check("part 2: no integration_failed in the bands", band_failed.size == 0,
                  f"{band_failed.size} of {eta.size} points")
    for v in rec.verdicts:
        print(v.line())
    rec.finish()
    return 0 if not failed else 1


if __name__ == "__main__":
    sys.exit(main())
