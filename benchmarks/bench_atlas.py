"""The solvability atlas against its targets: accuracy, classification, cost, speed.

On one box of ``(A, N)`` (default A in [-0.5, 0.5], N in [1, 1.5]: one edge eta_max, steep
towards A = -1):

1. builds the atlas (``--tol``, default 1e-8), or reads one (``--atlas-in``), and counts its
   traces and status solves;
2. compares its ``eta_max`` with direct traces (``regimes.trace_edge``: the node's eta at
   tangential edges, the zero of the smooth D(1) (``regimes.smooth_edge``) at transversal edges
   whose status is noise over more than ``regimes.SMOOTH_BAND``, status bisection elsewhere) at
   ``--points`` random ``(A, N)``, against ``tol`` and against each leaf's own estimate. Each
   reference is also sorted: *defined* when it is tangential, a smooth zero, or the status is
   monotone on a ladder 1e-9..1e-6 (relative) either side of it, *ragged* otherwise (the status
   bisection's edge is then only known to the noise of D(1), which the trace states as its
   band); errors are reported for both. Where a point is outside
   its estimate, the status between the two values (``--probe`` etas) is shown;
3. the uniform-grid baseline: traces an ``n x n`` equispaced grid (``--uniform``, default 129),
   interpolates it bicubically (``scipy.interpolate.RectBivariateSpline``) on the nested 5, 9,
   ..., n grids, measures the error at the same random points, and extrapolates with the order
   measured between the two finest grids to the ``n`` that reaches the atlas's maximum error (over
   all points, and over the defined ones). The finest grid is 129 because the order is still
   pre-asymptotic at 33 (4.63 from 17 to 33 on the default box, then 3.79 and 4.03, the bicubic's
   4): extrapolated from 33, the uniform grid's cost came out at 0.6 of what the finer grids
   measure;
4. python-adaptive's ``Learner2D`` (when importable) on the same function, ``log eta_max(A, N)``,
   measured the same way at a third, two thirds and all of ``--learner`` points;
5. ``classify`` against direct solves (``Workspace.status`` at ``regimes.EDGE_RTOL``, one at a
   time) on ``--classify`` random points (eps L log-uniform in [1e-3, 100]) plus a tenth as many
   placed 1e-9 to 1e-2 (relative) from the edge;
6. times ``cosserat-channel plot --regime --atlas`` on a 41 x 26 sweep of the box (a fresh
   process, start-up included).

``--parts`` runs some of ``accuracy,uniform,learner,classify,plot`` (default all; the atlas is
always built or read). The uniform grid's traces are the expensive part (129 x 129 by default:
about 140 s on one core); the 200 reference bisections serve the atlas, the uniform grids and the learner alike.

The targets are printed with PASS/FAIL at the end.

Run: ``PYTHONPATH=src .venv/bin/python benchmarks/bench_atlas.py --atlas-out atlas.nc``.
"""

from __future__ import annotations

import concurrent.futures
import functools
import math
import multiprocessing
import os
import signal
import subprocess
import sys
import tempfile
import time

import numpy as np


def log(msg):
    print(msg, flush=True)


def main():
    from cosserat_channel.measure import harness

    ap = harness.parser(__doc__)
    ap.add_argument("--A", default="-0.5:0.5")
    ap.add_argument("--N", default="1:1.5")
    ap.add_argument("--tol", type=float, default=1e-8)
    ap.add_argument("--max-depth", type=int, default=3)
    ap.add_argument("--max-degree", type=int, default=None, help="default: the package's")
    ap.add_argument("--parts", default="accuracy,uniform,learner,classify,plot",
                    help="comma-separated parts to run after the atlas (also: independent)")
    ap.add_argument("--plane", action="store_true",
                    help="the whole plane: A -1:5, N 0.3:3, max depth 6, 2 workers, parts "
                         "independent,classify")
    ap.add_argument("--independent", type=int, default=300,
                    help="random (A, N) of the independent scipy bisection (part independent)")
    ap.add_argument("--point-seconds", type=float, default=600.0,
                    help="time allowed each (A, N) of part independent (default 600)")
    ap.add_argument("--atlas-in", help="read this atlas instead of building one")
    ap.add_argument("--probe", type=int, default=16,
                    help="statuses probed between atlas and reference where the estimate is exceeded")
    ap.add_argument("--points", type=int, default=200)
    ap.add_argument("--uniform", type=int, default=129, help="finest uniform grid (2^k + 1)")
    ap.add_argument("--learner", type=int, default=300)
    ap.add_argument("--classify", type=int, default=100_000)
    ap.add_argument("--atlas-out", help="also keep the atlas in this file")
    ap.add_argument("--workers", type=int, default=1,
                    help="threads building the atlas (default 1, as the uniform grid is traced)")
    ap.add_argument("--seed", type=int, default=14)
    ap.add_argument("--status-bisection", action="store_true",
                    help="every edge by status bisection, no D(1) probes (the traces before the "
                         "tangential edges were the node's eta), for the atlas and references alike")
    args = ap.parse_args()
    if args.plane:
        args.A, args.N, args.max_depth = "-1:5", "0.3:3", 6
        args.workers = max(args.workers, 2)
        if args.parts == ap.get_default("parts"):
            args.parts = "independent,classify"
    parts = set(args.parts.split(",")) - {""}
    unknown = parts - {"accuracy", "uniform", "learner", "classify", "plot", "independent"}
    if unknown:
        ap.error(f"--parts: unknown {sorted(unknown)}")
    if parts & {"uniform", "learner"}:
        parts.add("accuracy")  # they are measured at its reference points


    from cosserat_channel import atlas as at
    from cosserat_channel import regimes
    from cosserat_channel.measure import machine
    from cosserat_channel.solver.point import Workspace

    if args.status_bisection:
        regimes.trace_edge = functools.partial(regimes.trace_edge, tangential=False)

    A_rng = tuple(float(v) for v in args.A.split(":"))
    N_rng = tuple(float(v) for v in args.N.split(":"))
    rng = np.random.default_rng(args.seed)
    trace_range = (1e-3 / at.TRACE_WIDEN, 100.0 * at.TRACE_WIDEN)
    log(f"machine: {machine.machine()}; {machine.git_revision()}; {uptime()}")
    max_degree = at.MAX_DEGREE if args.max_degree is None else args.max_degree
    log(f"box A {A_rng}, N {N_rng}, tol {args.tol:g}, degree {at.DEGREE}, max degree "
        f"{max_degree}, max depth {args.max_depth}"
        f"{'; status bisection only' if args.status_bisection else ''}; "
        f"load {os.getloadavg()[0]:.1f}")

    # 1. the atlas ---------------------------------------------------------------------------
    # Load the compiled kernels before timing (the smooth D(1) march compiles for ~15 s the
    # first time, when numba's cache is cold).
    regimes.trace_edge(0.0, 1.0)
    regimes.smooth_wall_D(1.0, 0.0, 1.5)
    t0 = time.perf_counter()
    if args.atlas_in:
        atlas = at.load_atlas(args.atlas_in)
        if atlas.box != (*A_rng, *N_rng):
            ap.error(f"--atlas-in covers {atlas.box}, not the box asked for")
    else:
        atlas = at.build_atlas(A_rng, N_rng, tol=args.tol, max_depth=args.max_depth,
                               max_degree=max_degree, workers=args.workers)
    t_build = time.perf_counter() - t0
    n_tr, n_sol = atlas.attrs["n_traces"], atlas.attrs["n_solves"]
    per_trace = n_sol / n_tr
    per_point = atlas.attrs.get("solves_per_edge_point", math.nan)
    degrees = ", ".join(f"{p}x{q}: {c}" for (p, q), c in zip(
        *np.unique(atlas.leaf_degree, axis=0, return_counts=True)))
    log(f"atlas: {t_build:.1f} s{' (read)' if args.atlas_in else f' ({args.workers} threads)'}, "
        f"{atlas.leaf_n.size} cells "
        f"(levels {np.bincount(atlas.leaf_level)}; degrees {degrees}), "
        f"{int((atlas.leaf_n < 0).sum())} unresolved, {n_tr} traces, {n_sol} solves "
        f"({per_trace:.1f} per trace, {per_point:.2f} per edge point; "
        f"{atlas.attrs.get('n_fallback', 0)} of {atlas.attrs.get('n_predicted', 0)} predicted "
        f"traces made afresh), cell estimates {np.min(atlas.leaf_error):.1e} to "
        f"{np.max(atlas.leaf_error):.1e}, {int(np.sum(atlas.leaf_error > args.tol))} above tol; "
        f"{uptime()}")
    summary = []
    if not args.atlas_in:
        summary.append(f"solves per traced edge point <= 6: {per_point:.2f}: "
                       f"{verdict(per_point <= 6)}")
        if args.plane:
            summary.append(f"whole plane at tol {args.tol:g} on {args.workers} threads <= 600 s "
                           f"(moonshot 180 s): {t_build:.0f} s: {verdict(t_build <= 600)} "
                           f"({uptime()})")
    summary.append(f"no cell left unresolved: {int((atlas.leaf_n < 0).sum())} unresolved: "
                   f"{verdict(not (atlas.leaf_n < 0).any())}")
    stated_share(atlas, A_rng, N_rng, args.tol, summary)
    if args.atlas_out:
        at.save_atlas(atlas, args.atlas_out)
    if not parts & {"accuracy", "classify", "plot", "independent"}:
        return report(args, summary)
    ws = Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS)
    if "independent" in parts:
        independent(args, atlas, A_rng, N_rng, np.random.default_rng(args.seed + 1), ws, summary)
    if "accuracy" in parts:
        atlas_rel, A, N, ok, ref, defined = accuracy(args, atlas, A_rng, N_rng, rng, ws,
                                                     trace_range, summary)
        atlas_err = float(np.max(atlas_rel))
    else:
        rng.uniform(size=2 * args.points)  # the classify points stay those of a full run
    if "uniform" in parts:
        uniform(args, atlas, A_rng, N_rng, ws, trace_range, atlas_rel, A, N, ok, ref,
                defined, summary)
    if "learner" in parts:
        learner(args, A_rng, N_rng, ws, trace_range, atlas_err, A, N, ok, ref)
    if "classify" in parts:
        classify(args, atlas, A_rng, N_rng, rng, ws, summary)
    if "plot" in parts:
        plot(atlas, A_rng, N_rng, summary)
    return report(args, summary)


def stated_share(atlas, A_rng, N_rng, tol, summary):
    """Where the atlas states an error above ``tol``: the share of a 1200 x 540 grid over the
    box (interior points) with a transition in the answered range whose stated error is above
    it, and where those points lie."""
    A = np.linspace(*A_rng, 1202)[1:-1]
    N = np.linspace(*N_rng, 542)[1:-1]
    err = atlas.boundary(A, N)["eta_error"].values
    has = np.isfinite(err)
    above = has & (err > tol)
    AA, NN = np.meshgrid(A, N, indexing="ij")
    share = above.sum() / max(has.sum(), 1)
    where = {"A < -0.9": AA < -0.9, "within 0.3 of the wall line": AA < 1 - 2 * NN**2 + 0.3,
             "N in [0.95, 1.05]": (NN > 0.95) & (NN < 1.05)}
    log(f"stated errors on a {A.size} x {N.size} grid: {has.mean():.1%} of points have a transition "
        f"in the answered range; at {share:.2%} of those some transition states an error above "
        f"tol (median {np.median(err[above]) if above.any() else 0:.2g}); of these, " + ", ".join(
            f"{(above & sel).sum() / max(above.sum(), 1):.0%} at {name}" for name, sel in where.items()))
    summary.append(f"points with a transition in range whose stated errors are all within tol: "
                   f"{1 - share:.2%} (grid of {A.size} x {N.size})")


def report(args, summary):
    """Print the targets' lines and, with ``--json PATH``, write them there too."""
    from cosserat_channel.measure import harness

    log("targets:")
    for line in summary:
        log("  " + line)
    rec = harness.Record("bench_atlas", args.json, echo=False)
    rec.add("targets", summary)
    return rec.finish()


def uptime():
    """The machine's load, as ``uptime`` shows it (others share the cores)."""
    return "load average " + " ".join(f"{x:.2f}" for x in os.getloadavg())


def scipy_feasible(eta, A, N, d_atol=1e-20):
    """Whether an independent stage 1 reaches the wall with D(1) > 0: scipy's LSODA at rtol
    1e-13 from next to the axis (stage1.ivp_start) to xi = 0.5 in w = delta/xi^2 (at small eta
    that march is stiff: DOP853 took ~10^6 evaluations where LSODA takes ~500, to the same 1e-15),
    then LSODA in (delta, D) at rtol 1e-12 with D carried as a state of its own and a terminal
    event at D = 0.

    D's absolute tolerance is ``d_atol`` times D at xi = 0.5: next to an edge D(1) is many
    orders below D's scale along the march, and its sign is what is asked. A fixed tiny atol
    (1e-30) costs 10^5-10^6 LSODA evaluations per march where D touches zero at the wall."""
    from scipy.integrate import solve_ivp

    from cosserat_channel.physics import model
    from cosserat_channel.solver import stage1
    from cosserat_channel import status as st

    if model.classify(eta, A, N) != st.OK:
        return False
    ax = np.empty(model.N_AX)
    model.axis_constants(eta, A, N, ax)
    xi1, w1 = stage1.ivp_start(ax)
    xs = max(0.5, xi1)
    # t_eval at the end only: solve_ivp then keeps no step of the march (kept, the tiny steps
    # of one march filled 17 GB).
    sol = solve_ivp(lambda x, w: [model.dw_dxi(x, w[0], eta, A, N, ax)], [xi1, xs], [w1],
                    method="LSODA", rtol=1e-13, atol=1e-16, t_eval=[xs])
    if sol.status != 0:
        return False
    d0 = xs * xs * sol.y[0, -1]
    D0 = model.yield_D(xs, d0, A, N, ax)
    a1 = A + 1.0

    def f(x, y):
        d, D = y
        s = math.sqrt(max(D, 0.0))
        return [(a1 * x - s) / eta, 2 * a1 * x * ((A - 1) + 2 * a1 * (N - d) / eta)
                - 4 * a1 * (N - d) * s / eta]

    def hit(x, y):
        return y[1]

    hit.terminal, hit.direction = True, -1
    try:
        sol = solve_ivp(f, [xs, 1.0], [d0, D0], method="LSODA", rtol=1e-12,
                        atol=[1e-16, d_atol * max(abs(D0), 1e-300)], events=hit, t_eval=[1.0])
    except ValueError:
        # D changed sign over a step but not on scipy's dense output of it (its event root
        # finder then has no bracket): the path met D = 0 inside that step.
        return False
    return sol.status == 0 and sol.y[1, -1] > 0.0


XTOL = 1e-10  # the references' relative width: 1 % of the atlas's tolerance
COARSE = 1e-2  # a transition the atlas states no closer than this is checked by a fresh trace
# What the independent check counts: wrong gaps against the fresh trace and against scipy,
# transitions without a scipy reference, transitions checked against the fresh trace, points
# without an answer in time.
COUNTS = ("fresh", "scipy", "missing", "coarse", "timeout")


def scipy_bisect(t, ok_below, A, N, width=1e-5, xtol=XTOL, d_atol=1e-20):
    """The edge next to ``t`` by bisection of :func:`scipy_feasible` in log eta, from a bracket
    ``width`` (relative) either side (widened up to 1e-2 until it brackets); NaN if none."""
    lo, hi = t * (1 - width), t * (1 + width)
    while not (scipy_feasible(lo, A, N, d_atol) == ok_below
               and scipy_feasible(hi, A, N, d_atol) != ok_below):
        width *= 10
        if width > 1e-2:
            return math.nan
        lo, hi = t * (1 - width), t * (1 + width)
    while hi / lo - 1 > xtol:
        mid = math.sqrt(lo * hi)
        if scipy_feasible(mid, A, N, d_atol) == ok_below:
            lo = mid
        else:
            hi = mid
    return math.sqrt(lo * hi)


def scipy_reference(t, ok_below, A, N):
    """The independent edge next to ``t`` and its own uncertainty (relative): a bisection
    (:func:`scipy_bisect`), checked at a 100 times tighter tolerance on D; where that moves the
    edge out of the bracket (small eta, where the march is stiff), bisected again there, and
    the two references' distance is the uncertainty. ``(NaN, NaN)`` where nothing brackets."""
    ref = scipy_bisect(t, ok_below, A, N)
    if not math.isfinite(ref):
        return math.nan, math.nan
    lo, hi = ref * (1 - XTOL), ref * (1 + XTOL)
    if (scipy_feasible(lo, A, N, 1e-22) == ok_below
            and scipy_feasible(hi, A, N, 1e-22) != ok_below):
        return ref, XTOL
    tight = scipy_bisect(ref, ok_below, A, N, width=1e-8, d_atol=1e-22)
    return tight, max(abs(math.log(tight / ref)), XTOL)


def independent(args, atlas, A_rng, N_rng, rng, ws, summary):
    """The atlas against independent references at random (A, N): a quarter uniform over the
    box, the rest next to A = -1, the wall line A = 1 - 2 N^2, the node/focus switch
    N^2 = (5 + 3A)/2 and in N in [0.9, 1.1] (within the box).

    At each point, a fresh trace (regimes.trace_edge) gives the transitions in the answered
    range; each is bisected again with scipy (:func:`scipy_bisect`), and the atlas's nearest
    transition is compared with that reference. Between every two transitions of either, the
    atlas must agree with the fresh trace and with scipy's feasibility at the gap's middle,
    wherever the gap lies outside the atlas's stated uncertainty (classify's band: SAFETY x
    max(tol, the transition's error, the noise band)); inside it the atlas decides nothing.
    """
    n = args.independent
    k = n // 4
    A = list(rng.uniform(*A_rng, k))
    N = list(rng.uniform(*N_rng, k))
    m = n - k
    for which in range(m):
        kind = which % 4
        if kind == 0:  # next to A = -1
            a, b = -1 + 10 ** rng.uniform(-3, -0.5), rng.uniform(max(N_rng[0], 1.0), N_rng[1])
        elif kind == 1:  # next to the wall line, above it
            b = rng.uniform(max(N_rng[0], 0.3), 1.0)
            a = 1 - 2 * b * b + 10 ** rng.uniform(-4, -0.5)
        elif kind == 2:  # next to the node/focus switch
            a = rng.uniform(-0.99, 0.99)
            b = math.sqrt((5 + 3 * a) / 2) * (1 + rng.choice([-1, 1]) * 10 ** rng.uniform(-4, -1))
        else:
            a, b = rng.uniform(*A_rng), rng.uniform(0.9, 1.1)
        A.append(min(max(a, A_rng[0]), A_rng[1]))
        N.append(min(max(b, N_rng[0]), N_rng[1]))
    A, N = np.array(A), np.array(N)
    leaf, low, eta, _ = atlas.transitions(A, N)
    terr = atlas.leaf_transition_error[np.maximum(leaf, 0)]
    band = atlas.undecided_band(leaf)
    lo, hi = atlas.eta_range
    t0 = time.perf_counter()
    job = functools.partial(_independent_point, lo=lo, hi=hi, tol=args.tol,
                            seconds=args.point_seconds)
    work = [(A[i], N[i], int(low[i]), eta[i], terr[i], band[i]) for i in range(n)]
    rows, stated, finished = [], [], []
    counts = dict.fromkeys(COUNTS, 0)

    def done(i, result):
        # Each point is reported as it finishes, so that a stopped run still tells what it saw.
        lines, rel, within, c, seconds = result
        finished.append(i)
        log(f"  [{len(finished)}/{n}] A = {A[i]:.6f}, N = {N[i]:.6f}: {len(rel)} "
            f"transitions, max {max(rel, default=0.0):.1e}, {seconds:.1f} s")
        for line in lines:
            log(line)
        rows.extend(rel)
        stated.extend(within)
        for key in counts:
            counts[key] += c[key]

    if args.workers > 1:
        # scipy's marches hold the GIL: processes, forked with the atlas's values in hand
        ctx = multiprocessing.get_context("fork")
        with concurrent.futures.ProcessPoolExecutor(args.workers, mp_context=ctx) as pool:
            futures = {pool.submit(job, w): i for i, w in enumerate(work)}
            for f in concurrent.futures.as_completed(futures):
                done(futures[f], f.result())
    else:
        for i, w in enumerate(work):
            done(i, job(w))
    worst = max(rows, default=0.0)
    above = sum(r > args.tol for r in rows)
    beyond = above - sum(stated)
    wrong = counts["fresh"] + counts["scipy"]
    unref = counts["missing"] + counts["timeout"]
    log(f"independent: {len(rows)} transitions at {n} random (A, N) against scipy bisections to "
        f"{XTOL:g} (the {counts['coarse']} the atlas states no closer than {COARSE:g} against the "
        f"fresh trace): max {worst:.2e}, median {np.median(rows) if rows else math.nan:.1e}; "
        f"{above} beyond tol, of which {beyond} beyond the atlas's stated uncertainty; "
        f"feasibility outside that uncertainty: {counts['fresh']} gaps against a fresh trace, "
        f"{counts['scipy']} against scipy; {counts['missing']} transitions without a scipy "
        f"reference; {counts['timeout']} points without an answer within {args.point_seconds:g} "
        f"s; {time.perf_counter() - t0:.0f} s on {args.workers} processes; {uptime()}")
    summary.append(f"every transition within tol ({args.tol:g}) of an independent bisection at "
                   f"{n} random (A, N): max {worst:.2e}, {above} of {len(rows)} beyond tol: "
                   f"{verdict(above == 0 and unref == 0)}; within the atlas's stated "
                   f"uncertainty, and feasibility right outside it: {beyond} beyond, {wrong} wrong "
                   f"gaps, {counts['missing']} transitions and {counts['timeout']} points "
                   f"unreferenced: {verdict(beyond == 0 and wrong == 0 and unref == 0)}")


def _merged(intervals):
    """Overlapping ``(start, end)`` intervals merged, in order."""
    out = []
    for s, e in sorted(intervals):
        if out and s <= out[-1][1]:
            out[-1][1] = max(out[-1][1], e)
        else:
            out.append([s, e])
    return out


def _independent_point(work, lo, hi, tol, seconds=600.0):
    """One (A, N) of :func:`independent`: ``(log lines, relative errors, [within the stated
    uncertainty] for each beyond tol, {COUNTS: count}, seconds taken)``. ``work`` is ``(A, N,
    low, transitions, their errors, their bands)``, as :meth:`Atlas.transitions` and
    :meth:`Atlas.undecided_band` give them."""
    a, b, low, eta, terr, band = work
    t0 = time.perf_counter()
    where = f"A = {a:.6f}, N = {b:.6f}"

    def out_of_time(signum, frame):
        raise TimeoutError

    # A worker runs its jobs in its main thread, where the alarm interrupts scipy's callbacks.
    previous = signal.signal(signal.SIGALRM, out_of_time)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        return _check_point(a, b, low, eta, terr, band, lo, hi, tol, where, t0)
    except TimeoutError:
        return ([f"  {where}: no answer within {seconds:g} s (the scipy marches there are stiff)"],
                [], [], dict(dict.fromkeys(COUNTS, 0), timeout=1), time.perf_counter() - t0)
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _check_point(a, b, low, eta, terr, band, lo, hi, tol, where, t0):
    """The body of :func:`_independent_point`."""
    from cosserat_channel import regimes
    from cosserat_channel.solver.point import Workspace

    ws = Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS)
    fresh = regimes.trace_edge(a, b, eta_range=(lo, hi), workspace=ws)
    ft = np.log(fresh.transitions)
    keep = np.isfinite(eta)
    at, band = np.log(eta[keep]), band[keep]
    counts = dict.fromkeys(COUNTS, 0)
    lines, rels, within = [], [], []
    if low < 0:
        return [f"  {where}: the atlas does not know this point"], [], [], counts, 0.0
    x_lo, x_hi = math.log(lo), math.log(hi)
    unsure = _merged(zip(at - band, at + band))
    cuts = np.unique(np.clip(np.r_[x_lo, x_hi, at, ft], x_lo, x_hi))
    for x0, x1 in zip(cuts[:-1], cuts[1:]):
        if any(s <= x0 and x1 <= e for s, e in unsure):
            continue  # the atlas states it does not decide this gap
        x = 0.5 * (x0 + x1)
        mine = bool(low) ^ (int(np.sum(at < x)) % 2 == 1)
        theirs = fresh.feasible_low ^ (int(np.sum(ft < x)) % 2 == 1)
        scipy_ok = scipy_feasible(math.exp(x), a, b)
        for key, other in (("fresh", theirs), ("scipy", scipy_ok)):
            if other != mine:
                counts[key] += 1
                lines.append(f"  wrong gap at {where}: eta {math.exp(x0):.9g} to {math.exp(x1):.9g}"
                             f" is {'feasible' if mine else 'infeasible'} in the atlas, not in "
                             f"the {key} (atlas {np.exp(at)}, errors {terr[keep]}; fresh trace "
                             f"{fresh.transitions})")
    ok_below = not fresh.feasible_low  # flipped at each transition: its side below it
    for f in ft:
        ok_below = not ok_below
        j = int(np.argmin(np.abs(at - f))) if at.size else -1
        if j >= 0 and band[j] > COARSE:
            # The atlas states this transition no closer than COARSE: the fresh trace (~1e-9)
            # says whether it keeps to that, and a scipy bisection (~10^2 stiff marches at small
            # eta next to A = -1, minutes) would add nothing.
            ref, who = math.exp(f), "fresh trace"
            counts["coarse"] += 1
        else:
            ref, spread = scipy_reference(math.exp(f), ok_below, a, b)
            who = "scipy"
            if not spread <= 0.5 * tol:
                counts["missing"] += 1
                lines.append(f"  no scipy reference at {where} next to the fresh trace's "
                             f"{math.exp(f):.12g} (atlas {np.exp(at)}): " + (
                                 f"scipy's edge {ref:.12g} moves by {spread:.1e} with a tighter "
                                 f"tolerance on D" if math.isfinite(ref) else
                                 "no bracket within 1e-2"))
                continue
        if j < 0:
            continue  # the gaps above say whether the atlas may lack it
        j = int(np.argmin(np.abs(at - math.log(ref))))
        rel = abs(at[j] - math.log(ref))
        rels.append(rel)
        if rel > tol:
            within.append(rel <= band[j])
            lines.append(f"  beyond tol at {where}: atlas {math.exp(at[j]):.12g}, {who} "
                         f"{ref:.12g} ({rel:.2e}; stated uncertainty {band[j]:.1e})")
    return lines, rels, within, counts, time.perf_counter() - t0


def errors_of(interp, A, N, ref):
    got = np.array([interp(a, n) for a, n in zip(A, N)])
    return np.abs(got - np.log(ref))


LADDER = np.array([1e-9, 3e-9, 1e-8, 3e-8, 1e-7, 3e-7, 1e-6])


def status_is_monotone(ws, edge, A, N):
    """The status is ok on ``edge (1 - LADDER)`` and not ok on ``edge (1 + LADDER)``."""
    from cosserat_channel import regimes
    from cosserat_channel import status as st

    def ok(eta):
        return ws.status(eta, A, N, regimes.EDGE_RTOL, regimes.EDGE_ATOL) == st.OK

    return all(ok(edge * (1 - d)) for d in LADDER) and not any(ok(edge * (1 + d)) for d in LADDER)

def verdict(ok):
    return "PASS" if ok else "FAIL"


def accuracy(args, atlas, A_rng, N_rng, rng, ws, trace_range, summary):
    """2. eta_max of the atlas against direct traces at random (A, N)."""
    from cosserat_channel import regimes
    from cosserat_channel import status as st

    A = rng.uniform(*A_rng, args.points)
    N = rng.uniform(*N_rng, args.points)
    t0 = time.perf_counter()
    direct = [regimes.trace_edge(a, n, eta_range=trace_range, workspace=ws) for a, n in zip(A, N)]
    t_direct = time.perf_counter() - t0
    _, low, eta, err = atlas.transitions(A, N)
    ref = np.array([e.eta_max if e.kind == 0 else np.nan for e in direct])
    n_ref = np.array([e.transitions.size for e in direct])
    ours = np.array([row[np.isfinite(row)][-1] if np.isfinite(row).any() else np.nan for row in eta])
    same = n_ref == np.sum(np.isfinite(eta), axis=1)
    rel = np.abs(np.log(ours / ref))
    ok = same & np.isfinite(rel)
    bound = np.fmax(args.tol, err)
    within = rel[ok] <= bound[ok]
    atlas_err = float(np.max(rel[ok]))
    clean = bound <= args.tol
    log(f"eta_max at {args.points} random (A, N): {ok.sum()} compared ({(~same).sum()} with "
        f"another number of transitions), max relative error {atlas_err:.2e} (tol {args.tol:g}), "
        f"median {np.median(rel[ok]):.1e}, {within.sum()} within max(tol, cell estimate), "
        f"{np.sum(rel[ok] <= args.tol)} within tol; in leaves whose estimate is within tol "
        f"({np.sum(clean & ok)} points) max {np.max(rel[ok & clean], initial=0):.2e}; where the "
        f"estimate is above tol ({np.sum(~clean & ok)} points) max "
        f"{np.max(rel[ok & ~clean], initial=0):.2e}, largest error / estimate "
        f"{np.max(rel[ok & ~clean] / bound[ok & ~clean], initial=0):.2f}; direct bisection "
        f"{t_direct / args.points * 1e3:.0f} ms per (A, N); load {os.getloadavg()[0]:.1f}")
    tangential = np.array([bool(e.tangential[-1]) if e.kind == 0 else False for e in direct])
    smooth = np.array([bool(e.smooth[-1]) if e.kind == 0 else False for e in direct])
    band = np.array([e.bands[-1] if e.kind == 0 else np.nan for e in direct])
    monotone = np.array([bool(ok[k]) and status_is_monotone(ws, ref[k], A[k], N[k])
                         for k in range(A.size)])
    defined = ok & (tangential | smooth | monotone)
    ragged = ok & ~defined
    log(f"  references: {np.sum(ok & tangential)} tangential (the node's eta), "
        f"{np.sum(ok & smooth)} the zero of the smooth D(1) (of which {np.sum(ok & smooth & ~monotone)} "
        f"with a status not monotone 1e-9..1e-6 either side: the solver's noise band), "
        f"{np.sum(defined & ~tangential & ~smooth)} status bisection with a monotone status "
        f"1e-9..1e-6 either side, {ragged.sum()} ragged (status bisection, status not monotone; bands "
        f"{np.min(band[ragged], initial=np.inf):.1e} to {np.max(band[ragged], initial=0):.1e}); "
        f"max error at the defined {np.max(rel[defined], initial=0):.2e} (tangential "
        f"{np.max(rel[defined & tangential], initial=0):.2e}), at the ragged "
        f"{np.max(rel[ragged], initial=0):.2e}, {np.sum(rel[ragged] <= band[ragged])} of "
        f"{ragged.sum()} within their trace's noise band")
    summary.append(f"eta_max within tol ({args.tol:g}) of direct traces at {ok.sum()} random "
                   f"(A, N): max {atlas_err:.2e}: {verdict(atlas_err <= args.tol)} "
                   f"({atlas_err / args.tol:.2g} x tol); at the {defined.sum()} with a defined "
                   f"reference: max {np.max(rel[defined], initial=0):.2e}: "
                   f"{verdict(np.max(rel[defined], initial=0) <= args.tol)}")
    # Where a point is outside its estimate: is the solver's edge itself ragged between the
    # atlas's value and the reference (ok and not ok alternating)?
    for k in np.flatnonzero(ok & (rel > bound)):
        lo, hi = sorted((ours[k], ref[k]))
        etas = np.geomspace(lo / (1 + 1e-6), hi * (1 + 1e-6), args.probe)
        flags = [ws.status(e, A[k], N[k], regimes.EDGE_RTOL, regimes.EDGE_ATOL) == st.OK
                 for e in etas]
        flips = int(np.sum(np.diff(flags) != 0))
        log(f"  outside its estimate: A = {A[k]:.6f}, N = {N[k]:.6f}: atlas {ours[k]:.10g}, "
            f"direct {ref[k]:.10g} (relative {rel[k]:.2e}, estimate {bound[k]:.2e}); status over "
            f"{args.probe} etas between them: {''.join('o' if f else 'x' for f in flags)} "
            f"({flips} changes{': the edge is ragged there' if flips > 1 else ''})")
    return rel[ok], A[ok], N[ok], ok, ref[ok], defined[ok]


def uniform(args, atlas, A_rng, N_rng, ws, trace_range, atlas_rel, A, N, ok, ref, defined,
            summary):
    """3. uniform grids, bicubic."""
    from scipy.interpolate import RectBivariateSpline

    from cosserat_channel import regimes

    n_tr = atlas.attrs["n_traces"]
    n = args.uniform
    ga, gn = np.linspace(*A_rng, n), np.linspace(*N_rng, n)
    t0 = time.perf_counter()
    solves = _CountingStatus(ws)
    grid = np.array([[regimes.trace_edge(a, b, eta_range=trace_range, workspace=solves).eta_max
                      for b in gn] for a in ga])
    t_grid = time.perf_counter() - t0
    uni_per_trace = solves.n / grid.size
    uni = []
    m = n
    while m >= 5:
        step = (n - 1) // (m - 1)
        spline = RectBivariateSpline(ga[::step], gn[::step], np.log(grid[::step, ::step]), kx=3,
                                     ky=3)
        uni.append((m, errors_of(lambda a, b, s=spline: float(s(a, b)[0, 0]), A, N, ref)))
        m = (m - 1) // 2 + 1
    uni.sort(key=lambda u: u[0])
    # The same comparison over all points and over those whose reference is defined (tangential,
    # or a monotone status next to it): at the ragged ones both interpolate the solver's noise.
    ratios = []
    for label, sel in (("all points", np.ones(A.size, dtype=bool)), ("defined references", defined)):
        target = float(np.max(atlas_rel[sel]))
        errs = [(m, float(np.max(e[sel]))) for m, e in uni]
        (m1, e1), (m2, e2) = errs[-2], errs[-1]
        order = math.log(e1 / e2) / math.log((m2 - 1) / (m1 - 1))
        need = (m2 - 1) * (e2 / target) ** (1.0 / order) + 1
        ratio = atlas.attrs["n_solves"] / (need * need * uni_per_trace)
        ratios.append((label, sel.sum(), target, ratio))
        log(f"uniform bicubic grid, {label} ({sel.sum()}): " + ", ".join(
            f"{m}x{m}: {e:.2e}" for m, e in errs) + f" (tracing {n}x{n}: {t_grid:.0f} s, "
            f"{uni_per_trace:.1f} solves per trace, load {os.getloadavg()[0]:.1f}); measured "
            f"order {order:.2f}; for the atlas's {target:.2e}: about {need:.0f}x{need:.0f} = "
            f"{need * need:.3g} traces, {need * need * uni_per_trace:.3g} solves; atlas/uniform = "
            f"{n_tr / need**2:.4f} in traces, {ratio:.4f} in solves")
    summary.append("cost: atlas/uniform solves at the atlas's max error <= 0.1: " + "; ".join(
        f"{label} ({k}, max {t:.2e}): {r:.3g} {verdict(r <= 0.1)}" for label, k, t, r in ratios))
    d = int(np.max(atlas.leaf_level))
    cheb = (atlas.roots[0] * 2**d * atlas.degree + 1) * (atlas.roots[1] * 2**d * atlas.degree + 1)
    log(f"uniform Chebyshev cells of degree {atlas.degree} at the atlas's finest level {d}: "
        f"{cheb} traces (atlas/uniform = {n_tr / cheb:.3f})")


class _CountingStatus:
    """A Workspace stand-in that counts the status solves of trace_edge."""

    def __init__(self, ws):
        self.ws = ws
        self.n = 0

    def status(self, *args):
        self.n += 1
        return self.ws.status(*args)

    def count(self, n):  # the stage-1 solves of regimes.wall_D (the probes of D(1))
        self.n += n


def learner(args, A_rng, N_rng, ws, trace_range, atlas_err, A, N, ok, ref):
    """4. python-adaptive's Learner2D on the same function."""
    from cosserat_channel import regimes

    try:
        import adaptive
    except ImportError:
        log("python-adaptive: not importable, skipped")
    else:
        def f(xy):
            return math.log(regimes.trace_edge(xy[0], xy[1], eta_range=trace_range,
                                               workspace=ws).eta_max)

        learner = adaptive.Learner2D(f, bounds=[A_rng, N_rng])
        res = []
        t0 = time.perf_counter()
        for target in (args.learner // 3, 2 * args.learner // 3, args.learner):
            adaptive.runner.simple(learner, npoints_goal=target)
            ip = learner.interpolator(scaled=False)
            res.append((learner.npoints, float(np.max(errors_of(
                lambda a, b, ip=ip: float(np.ravel(ip(a, b))[0]), A, N, ref)))))
        t_learn = time.perf_counter() - t0
        (p1, q1), (p2, q2) = res[-2], res[-1]
        order_l = math.log(q1 / q2) / math.log(p2 / p1)
        need_l = p2 * (q2 / atlas_err) ** (1.0 / order_l)
        log(f"Learner2D (adaptive {adaptive.__version__}): " + ", ".join(
            f"{p} points: {q:.2e}" for p, q in res) + f" ({t_learn:.0f} s); measured order "
            f"{order_l:.2f} in points; for {atlas_err:.2e}: about {need_l:.3g} points")



def classify(args, atlas, A_rng, N_rng, rng, ws, summary):
    """5. classify against direct solves."""
    from cosserat_channel import atlas as at
    from cosserat_channel.physics import model
    from cosserat_channel import regimes
    from cosserat_channel import status as st

    k = args.classify
    kn = k // 10
    cA = np.r_[rng.uniform(*A_rng, k), rng.uniform(*A_rng, kn)]
    cN = np.r_[rng.uniform(*N_rng, k), rng.uniform(*N_rng, kn)]
    ceta = 10 ** rng.uniform(-3, 2, k)
    _, _, t, _ = atlas.transitions(cA[k:], cN[k:])
    last = np.array([row[np.isfinite(row)][-1] if np.isfinite(row).any() else 1.0 for row in t])
    delta = rng.choice([-1, 1], kn) * 10 ** rng.uniform(-9, -2, kn)
    ceta = np.r_[ceta, np.clip(last * (1 + delta), 1e-3, 100)]
    L = 100.0
    t0 = time.perf_counter()
    codes = at.classify(ceta / L, L, 0.5, cA, cN, atlas=atlas)
    t_cls = time.perf_counter() - t0
    t0 = time.perf_counter()
    truth = np.empty(ceta.size, dtype=np.int8)
    for i in range(ceta.size):
        c = model.classify(ceta[i], cA[i], cN[i])
        if c == st.OK and cA[i] != -1.0:
            c = ws.status(ceta[i], cA[i], cN[i], regimes.EDGE_RTOL, regimes.EDGE_ATOL)
        truth[i] = c
    t_solve = time.perf_counter() - t0
    dec = codes != at.UNDECIDED
    wrong = int(np.sum(codes[dec] != truth[dec]))
    for label, sl in (("random", slice(0, k)), ("near the edge", slice(k, None))):
        d_ = dec[sl]
        log(f"classify, {label}: {d_.size} points, {int(np.sum(codes[sl][d_] != truth[sl][d_]))} "
            f"decided wrongly, {100 * (1 - d_.mean()):.3f} % undecided")
    log(f"classify: {ceta.size} points in {t_cls:.2f} s; direct solves {t_solve:.0f} s "
        f"(Workspace.status in a loop); wrong decided points {wrong}; statuses "
        f"{dict(zip(*np.unique(truth, return_counts=True)))}; load {os.getloadavg()[0]:.1f}")
    # Undecided points farther than SAFETY tol from every interpolated transition: undecided
    # for a noise band or an envelope leaf (a cell mixed at the deepest level), not for tol.
    _, _, t_all, _ = atlas.transitions(cA[:k], cN[:k])
    with np.errstate(invalid="ignore"):
        dist = np.nanmin(np.abs(np.log(ceta[:k, None]) - np.log(t_all)), axis=-1, initial=np.inf)
    und = ~dec[:k]
    far = und & (dist > at.SAFETY * args.tol)
    log(f"classify, random: undecided {100 * und.mean():.3f} %, of which farther than SAFETY tol "
        f"from an interpolated edge {100 * far.mean():.3f} % of all points")
    summary.append(f"classify right on every decided point of {ceta.size}: {wrong} wrong: "
                   f"{verdict(wrong == 0)}; undecided <= 1 % of random points: "
                   f"{100 * und.mean():.2f} %: {verdict(und.mean() <= 0.01)} "
                   f"({100 * far.mean():.2f} % farther than SAFETY tol from an edge)")


def plot(atlas, A_rng, N_rng, summary):
    """6. a regime map from the atlas, in a fresh process."""
    from cosserat_channel import atlas as at
    from cosserat_channel.sweep import run_sweep

    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "atlas.nc")
        at.save_atlas(atlas, path)
        res = os.path.join(tmp, "map.nc")
        run_sweep({"grid": {"eps": 0.01, "L": 10, "K": 0.5, "A": {"linspace": [*A_rng, 41]},
                            "N": {"linspace": [*N_rng, 26]}}}, workers=1).to_netcdf(res)
        cmd = [sys.executable, "-m", "cosserat_channel.cli", "plot", res, "--regime", "--x", "A",
               "--y", "N", "--atlas", path, "-o", os.path.join(tmp, "map.png"), "--overwrite"]
        times = []
        for _ in range(5):
            t0 = time.perf_counter()
            run = subprocess.run(cmd, capture_output=True, text=True)
            if run.returncode:
                raise SystemExit(f"bench_atlas: plot --regime failed: {run.stderr.strip()}")
            times.append(time.perf_counter() - t0)
        log(f"plot --regime --atlas (fresh process): best of 5 {min(times):.2f} s, median "
            f"{np.median(times):.2f} s; load {os.getloadavg()[0]:.1f}")
    summary.append(f"regime map from a cached atlas < 3 s: best of 5 {min(times):.2f} s, median "
                   f"{np.median(times):.2f} s: {verdict(min(times) < 3)}")


if __name__ == "__main__":
    main()
