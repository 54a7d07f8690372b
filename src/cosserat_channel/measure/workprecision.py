"""Work-precision report: error against run time, ours side by side with the usual alternatives.

``cosserat-channel bench [--quick] [-o DIR]`` runs :func:`run`, which writes into ``DIR``:

- ``reference_cache.npz``: the validation set and its scipy references (:mod:`.validation`),
  reused by later runs with the same set definition and ``reference.py``; while it is built,
  ``reference_cache.partial.npz`` keeps each reference as it is computed, so an interrupted
  run (:func:`kept` says what it left) resumes;
- ``work_precision.csv``: long format, columns ``method, stages, rtol, quantity, n_points,
  time_per_point_us, median_rel_err, max_rel_err`` (stage-1 rows have ``m_wall`` only;
  ``n_points`` counts the points that entered the error statistics, the time is per attempted
  point, failures included);
- ``work_precision.png``: median relative error against time per point, one curve per method;
- ``tolerance.png``: our achieved error against the requested rtol, with y = x and the
  factor-100 band;
- ``work_precision.md``: machine, versions, date, command, tables, the acceptance targets with
  PASS/FAIL and by how much (copied to ``docs/work_precision.md`` after a full run).

Every number in one report comes from one run, so the ratios hold on a shared, noisy machine.
The modules: :mod:`.validation` (set and references), :mod:`.runners` (the timed solvers),
:mod:`.report` (errors, matched-error ratios, targets, files), :mod:`.machine` (where it ran);
the figures live in :mod:`cosserat_channel.plot.workprecision`.
"""

from __future__ import annotations

import datetime
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..files import write_text
from . import machine, report, runners, validation
from .report import CSV_COLUMNS, Curve
from .validation import SetSpec

DEFAULT_OUTPUT = "bench-report"
CSV_NAME = "work_precision.csv"
WP_FIGURE = "work_precision.png"
TOL_FIGURE = "tolerance.png"
MD_NAME = "work_precision.md"


@dataclass(frozen=True)
class Settings:
    """What one report measures."""

    spec: SetSpec
    rtols: tuple
    repeat: int  # best of this many rounds over all rtols, for the compiled solvers
    scipy_points: int  # subsample for the scipy loops (they are ~1000x slower)
    scipy_methods: tuple
    max_nfev: int  # per point and call, for the scipy loops
    mxstep: int = 100_000  # per point and call, for numbalsoda


FULL = Settings(spec=SetSpec(size=300), rtols=tuple(10.0**-k for k in range(3, 12)), repeat=7,
                scipy_points=60, scipy_methods=runners.SCIPY_METHODS, max_nfev=60_000)
QUICK = Settings(spec=SetSpec(size=12), rtols=(1e-4, 1e-6, 1e-8), repeat=2, scipy_points=3,
                 scipy_methods=("RK45", "LSODA"), max_nfev=20_000)


@dataclass
class Report:
    """What :func:`run` measured and wrote."""

    settings: Settings
    validation_set: validation.ValidationSet
    curves: list  # every Curve written to the CSV
    ours_subsample: Curve
    comparisons: list  # report.Comparison, ours against each peer
    targets: list
    figures: dict = field(default_factory=dict)  # name -> matplotlib Figure
    paths: dict = field(default_factory=dict)  # name -> path written
    notes: list = field(default_factory=list)


def subsample(eta: np.ndarray, k: int) -> np.ndarray:
    """``k`` indices spread evenly over the set in ``eta`` order (so stiff points are in)."""
    order = np.argsort(eta, kind="stable")
    if k >= eta.size:
        return order
    return np.unique(order[np.linspace(0, eta.size - 1, k).round().astype(int)])


def run(output_dir=DEFAULT_OUTPUT, *, quick: bool = False, scipy_points: int | None = None,
        numbalsoda: bool = True, command: str | None = None, progress=None) -> Report:
    """Measure everything, write the files into ``output_dir`` and return the :class:`Report`.

    Parameters
    ----------
    output_dir : path
        Created if missing; holds the reference cache and the outputs.
    quick : bool
        The tiny set (:data:`QUICK`: 12 points, 3 rtols, scipy RK45 and LSODA on 3 points).
    scipy_points : int, optional
        Size of the scipy loops' subsample (default 60, quick 3).
    numbalsoda : bool
        Measure numbalsoda when it is importable (it is skipped, with a note, when it is not).
    command : str, optional
        The command line to print in the report.
    progress : callable, optional
        ``progress(done, total, text)`` (the package's progress protocol): the stages done (the
        reference set, ours, each peer) and a one-line message, at each step of a stage too.
    """
    import numba

    settings = QUICK if quick else FULL
    if scipy_points is not None:
        settings = replace(settings, scipy_points=scipy_points)
    out = Path(output_dir)
    out.mkdir(parents=True, exist_ok=True)
    started = datetime.datetime.now().astimezone()
    nbs, nbs_note = runners.numbalsoda_status() if numbalsoda else (None, "not requested")
    total = 2 + len(settings.scipy_methods) + (nbs is not None)
    done = 0

    def say(text, finished=False):
        nonlocal done
        done += finished
        if progress is not None:
            progress(done, total, text)

    vs = validation.get(settings.spec, out, say)
    n = vs.size
    say(f"reference: {n} points ready", True)
    eps, L, A, N = vs.eps, vs.L, vs.A, vs.N
    ref = vs.ref

    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        runners.warm_up()
        everything = np.arange(n)
        ours_both, both_values = _ours_both_curve(vs, everything, settings, "full set")
        ours_s1 = _ours_stage1_curve(vs, everything, settings, "full set")
        say(f"ours: {n} points x {len(settings.rtols)} rtols done", True)

        sub = subsample(vs.eta, settings.scipy_points)
        ours_sub = _ours_stage1_curve(vs, sub, settings, "subsample")
        peers, comparisons = [], []
        for method in settings.scipy_methods:
            runs = [runners.scipy_loop(eps[sub], L[sub], A[sub], N[sub], method, rtol,
                                       max_nfev=settings.max_nfev) for rtol in settings.rtols]
            c = _peer_curve(f"scipy-{method}", "subsample", sub, settings.rtols, runs, ref)
            peers.append(c)
            solved = _solved(runs)
            if solved.all():
                comparisons.append(report.Comparison(c, ours_sub, c, ours_sub))
            else:
                runs_s = [(float(each[solved].mean()) if solved.any() else np.nan, m[solved], None)
                          for _, m, each in runs]
                c_solved = _peer_curve(c.method, "solved", sub[solved], settings.rtols, runs_s, ref)
                ours_solved = _ours_stage1_curve(vs, sub[solved], settings, "solved")
                comparisons.append(report.Comparison(c, ours_sub, c_solved, ours_solved))
            say(f"scipy {method}: {sub.size} points x {len(settings.rtols)} rtols done", True)
        if nbs is not None:
            try:
                comparisons += _numbalsoda(nbs, vs, settings, ours_s1, ours_both, peers)
                say("numbalsoda: done", True)
            except Exception as exc:  # an installed but broken numbalsoda must not sink the report
                nbs_note = f"{nbs_note}, but measuring it failed ({type(exc).__name__}: {exc})"
                peers = [p for p in peers if not p.method.startswith("numbalsoda")]
                comparisons = [c for c in comparisons if not c.peer.method.startswith("numbalsoda")]
                nbs = None
    finally:
        numba.set_num_threads(threads)

    targets = report.tolerance_target(ours_both)
    speed, matched = report.speed_targets(comparisons, nbs_note)
    targets += speed
    curves = [ours_both, ours_s1] + peers
    notes = _notes(settings, vs, sub, nbs_note)

    date = started.strftime("%Y-%m-%d %H:%M %Z")
    from ..plot import workprecision as wp_plot

    stage1_curves = [ours_s1, ours_sub] + peers
    fig_wp = wp_plot.work_precision_figure(ours_both, stage1_curves, comparisons,
                                           title=f"Work-precision, {n} points, {date}")
    fig_tol = wp_plot.tolerance_figure(ours_both, factor=report.TOLERANCE_FACTOR,
                                       title=f"Tolerance proportionality, ours, {n} points, {date}")
    paths = {
        "csv": out / CSV_NAME,
        "work_precision_png": out / WP_FIGURE,
        "tolerance_png": out / TOL_FIGURE,
        "markdown": out / MD_NAME,
        "cache": out / validation.CACHE_NAME,
    }
    report.write_csv(curves, paths["csv"])
    wp_plot.save_figure(fig_wp, paths["work_precision_png"])
    wp_plot.save_figure(fig_tol, paths["tolerance_png"])
    elapsed = (datetime.datetime.now().astimezone() - started).total_seconds()
    meta = {
        "command": (f"`{command}`" if command
                    else "`cosserat_channel.measure.workprecision.run()`"),
        "date": date,
        "machine": machine.machine() + "; one thread (numba.set_num_threads(1)); shared, so compare "
                   "ratios within this run, not absolute times across runs",
        "versions": machine.versions(numbalsoda=nbs_note),
        "set": f"{n} points, seed {settings.spec.seed}"
               + (" (quick)" if quick else "") + f"; rtol {', '.join(f'{r:.0e}' for r in settings.rtols)}"
               + f"; atol {runners.ATOL:g} for every method",
        "run time": f"{elapsed:.0f} s" + (" (references reused from the cache)" if vs.reused
                                          else " (including the references)"),
    }
    title = "Work-precision report" + (" (quick)" if quick else "")
    text = report.markdown(title=title, meta=meta, vs=vs, curves=curves, ours_both=ours_both,
                           stage1=stage1_curves, targets=targets, matched=matched, notes=notes,
                           figures=[WP_FIGURE, TOL_FIGURE],
                           strata=report.stratum_lines(both_values, ref, vs.stratum,
                                                       validation.STRATA))
    write_text(paths["markdown"], text)
    return Report(settings=settings, validation_set=vs, curves=curves, ours_subsample=ours_sub,
                  comparisons=comparisons, targets=targets,
                  figures={"work_precision": fig_wp, "tolerance": fig_tol}, paths=paths,
                  notes=notes)


def kept(output_dir=DEFAULT_OUTPUT, *, quick: bool = False) -> str:
    """What an interrupted :func:`run` left in ``output_dir`` for the next one, as a sentence.

    The references are kept (whole, or each candidate's as it was computed); the timings are
    not: every ratio of the report compares numbers measured in one run.
    """
    spec = (QUICK if quick else FULL).spec
    cache = Path(output_dir) / validation.CACHE_NAME
    if validation.load(spec, cache) is not None:
        return (f"the reference set is kept in {cache}: run the same command again to reuse it "
                "(the timings start over: a report compares timings of one run)")
    n = validation.partial_count(spec, output_dir)
    if n:
        return (f"the references of {n} candidate points are kept in "
                f"{Path(output_dir) / validation.PARTIAL_NAME}: run the same command again to "
                "continue from them")
    return "no reference was finished, nothing is kept"


# ---------------------------------------------------------------------------------------------
# Curves of each solver over a set of point indices
# ---------------------------------------------------------------------------------------------
def _rounds(measure, rtols, repeat):
    """``{rtol: measure(rtol)}`` keeping the fastest of ``repeat`` rounds over all rtols.

    Rounds sweep every rtol in turn, so a burst of load from other jobs on the shared machine
    slows one call of each rtol, not every call of one rtol. ``measure`` returns ``(t, result)``.
    """
    best = {}
    for _ in range(max(1, repeat)):
        for rtol in rtols:
            t, result = measure(rtol)
            if rtol not in best or t < best[rtol][0]:
                best[rtol] = (t, result)
    return best


def _ours_both_curve(vs, idx, settings, points):
    c = Curve("ours", "both", points, idx.size)
    ref = {q: vs.ref[q][idx] for q in vs.ref}
    best = _rounds(lambda rtol: runners.ours_both(vs.eps[idx], vs.L[idx], vs.K[idx], vs.A[idx],
                                                  vs.N[idx], rtol, repeat=1),
                   settings.rtols, settings.repeat)
    for rtol, (t, v) in best.items():
        c.add(rtol, t, v, ref)
    return c, {rtol: v for rtol, (_, v) in best.items()}


def _ours_stage1_curve(vs, idx, settings, points):
    c = Curve("ours", "stage1", points, idx.size)
    ref = {"m_wall": vs.ref["m_wall"][idx]}
    best = _rounds(lambda rtol: runners.ours_stage1(vs.eps[idx], vs.L[idx], vs.A[idx], vs.N[idx],
                                                    rtol, repeat=1),
                   settings.rtols, settings.repeat)
    for rtol, (t, m) in best.items():
        c.add(rtol, t, {"m_wall": m}, ref)
    return c


def _peer_curve(method, points, idx, rtols, runs, ref):
    """A stage-1 Curve from ``runs[i] = (s per point, m_wall, ...)`` at ``rtols[i]``."""
    c = Curve(method, "stage1", points, idx.size)
    for rtol, (t, m, *_) in zip(rtols, runs):
        c.add(rtol, t, {"m_wall": m}, {"m_wall": ref["m_wall"][idx]})
    return c


def _solved(runs) -> np.ndarray:
    """Points a peer answered at every rtol."""
    return np.all([np.isfinite(m) for _, m, *_ in runs], axis=0)


def _numbalsoda(nbs, vs, settings, ours_s1, ours_both, peers):
    """numbalsoda LSODA and DOP853 on the full set; appends their curves to ``peers`` and returns
    the comparisons (stage 1 against ours' stage 1; LSODA also against ours' both stages)."""
    everything = np.arange(vs.size)
    out = []
    for method in runners.NUMBALSODA_METHODS:
        def measure(idx, method=method):
            return [runners.numbalsoda_stage1(nbs, vs.eps[idx], vs.L[idx], vs.A[idx], vs.N[idx],
                                              method, rtol, repeat=settings.repeat,
                                              mxstep=settings.mxstep) + (None,)
                    for rtol in settings.rtols]

        runs = measure(everything)
        c = _peer_curve(f"numbalsoda-{method}", "full set", everything, settings.rtols, runs,
                        vs.ref)
        peers.append(c)
        solved = _solved(runs)
        idx = everything[solved]
        if solved.all():
            c_s, o_s1, o_both = c, ours_s1, ours_both
        else:
            c_s = _peer_curve(c.method, "solved", idx, settings.rtols, measure(idx), vs.ref)
            o_s1 = _ours_stage1_curve(vs, idx, settings, "solved")
            o_both = _ours_both_curve(vs, idx, settings, "solved")[0]
        out.append(report.Comparison(c, ours_s1, c_s, o_s1))
        if method == "LSODA":
            out.append(report.Comparison(c, ours_both, c_s, o_both))
    return out


def _notes(settings: Settings, vs, sub, nbs_note: str) -> list[str]:
    spec = settings.spec
    c = vs.counts
    strata = ", ".join(f"{s} {int(np.sum(vs.stratum == i))}"
                       for i, s in enumerate(validation.STRATA))
    eta = vs.eta
    checked = vs.cross_checked
    max_dis = float(np.nanmax(vs.disagreement)) if checked.any() else float("nan")
    med_dis = float(np.nanmedian(vs.disagreement)) if checked.any() else float("nan")
    notes = [
        f"Set: seed {spec.seed}, {vs.size} points ({strata}); eps in [{spec.eps[0]:g}, "
        f"{spec.eps[1]:g}], L in [{spec.L[0]:g}, {spec.L[1]:g}], K in [{spec.K[0]:g}, {spec.K[1]:g}] "
        f"(log-uniform; K = 0 left out: slip = 0 has no relative error), A in ({spec.A[0]:g}, "
        f"{spec.A[1]:g}], N in [{spec.N[0]:g}, {spec.N[1]:g}]; eta = eps L from {eta.min():.2g} to "
        f"{eta.max():.2g}; stiff stratum eta in [{spec.stiff_eta[0]:g}, {spec.stiff_eta[1]:g}], "
        f"edge stratum a relative gap 10^U(-3,-1) below the largest eta whose stress path "
        "reaches the wall. See `cosserat_channel/measure/validation.py`.",
        f"Candidates tried: {c.get('candidates')}; dropped: {c.get('status')} without a solution "
        f"(reference status), {c.get('conditioning')} ill-conditioned (slip > "
        f"{validation.MAX_SLIP:g} or |m_wall| < {validation.MIN_ABS_M_OVER_NL:g} N L), "
        f"{c.get('disagree')} where Radau and DOP853 disagreed beyond "
        f"{validation.CROSS_CHECK_TOL:g}" + (
            f" (largest dropped disagreement {c.get('max_disagreement_dropped'):.2g})"
            if c.get('disagree') else "") + ".",
        f"Reference: `reference.reference` at rtol {validation.REF_RTOL:g} (scipy solve_ivp; its "
        "stage 2 is DOP853 in both variants). Radau and DOP853 stage 1 cross-checked on the "
        f"{int(checked.sum())} points with eta >= {validation.DOP853_MIN_ETA:g}: relative "
        f"disagreement over Delta, m_wall, slip median {med_dis:.1g}, max {max_dis:.2g} (DOP853 is "
        "the reference there); errors below about that are the reference's, not the method's. "
        f"The {int((~checked).sum())} points with eta < {validation.DOP853_MIN_ETA:g} rest on "
        "Radau alone (DOP853 needs O(1/eta) steps there: minutes per point in Python).",
        f"Ours: the whole set in one kernel call per rtol, best of {settings.repeat} rounds over all "
        "rtols (a burst of load from other jobs hits one call of each rtol), after a warm-up. "
        "The both-stages curve in the figure and in target 3 is the worst of the three medians. "
        "Where ours answers `eps_too_large_path` for a point the reference solves (`failed`, "
        "`unanswered`: edge points at loose rtol), it is because D(1) is below what stage 1 "
        "resolves at that rtol (the solver reports such a point as meeting D = 0 at the wall); "
        "next to the path edge the outputs' condition number is ~1/D(1) (docs/performance.md), "
        "which is also why the edge stratum dominates the max errors.",
        f"scipy solve_ivp ({', '.join(settings.scipy_methods)}): stage 1 alone in a Python loop "
        f"over {sub.size} points spread evenly over the set in eta order (eta "
        f"{eta[sub].min():.2g}..{eta[sub].max():.2g}), one pass, bench_point's formulation, "
        "Radau and LSODA with the exact Jacobian; a point needing more than "
        f"{settings.max_nfev} right-hand-side evaluations is abandoned and counted as failed "
        "(the explicit methods on the stiff points), its time up to then counted, so the scipy "
        "explicit times are lower bounds there and their errors cover only what they solved. "
        "Ours is compared with each peer on the same points: on the whole subsample (row "
        "`ours, stage 1 (subsample)`) and, for the verdicts, on the points the peer solved at "
        "every rtol, ours re-timed on exactly those.",
        f"numbalsoda: {nbs_note}. When installed it runs on the full set, stage 1 alone, in a "
        f"Numba loop (cfunc right-hand side), mxstep {settings.mxstep}, no D = 0 event (every "
        "point of the set reaches the wall). It needs a Fortran compiler to build on Linux "
        "(`pip install -e '.[bench]'`).",
    ]
    return notes


__all__ = ["run", "kept", "Report", "Settings", "FULL", "QUICK", "CSV_COLUMNS", "DEFAULT_OUTPUT"]
