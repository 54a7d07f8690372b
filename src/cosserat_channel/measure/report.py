"""Work-precision report: curves, errors, the matched-error comparison, the targets and the files.

A :class:`Curve` is one method over one set of points at each rtol: time per point and the
median and maximum relative error of each quantity against the reference. Relative error is
``|x - x_ref| / |x_ref|`` over the points the method solved; a point it did not solve (status
not ok, step or evaluation budget spent) is counted in ``failed`` and left out of the errors,
while its time still counts.

"At matched median error" (:func:`matched_ratios`): each peer's ``log(time)`` is interpolated
linearly in ``log(median error)`` at the median errors our curve reaches, inside the peer's
measured range only (no extrapolation); the ratio is the peer's time over ours.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field

import numpy as np

from .harness import Verdict
from ..files import write_text

CSV_COLUMNS = ("method", "stages", "rtol", "quantity", "n_points", "time_per_point_us",
               "median_rel_err", "max_rel_err")
TOLERANCE_RANGE = (1e-10, 1e-4)  # rtol range of the proportionality target
TOLERANCE_FACTOR = 100.0
RK45_TARGET = 300.0
# Matched median errors over which the two-stage target is judged ("from 1e-4 to 1e-10");
# the ratios outside are reported, not judged.
BOTH_STAGES_RANGE = (1e-10, 1e-4)


@dataclass
class Curve:
    """One method on one set of points, at each rtol."""

    method: str
    stages: str  # "both" or "stage1"
    points: str  # which points: "full set" or "subsample"
    n_attempted: int
    rtol: list = field(default_factory=list)
    time_us: list = field(default_factory=list)
    failed: list = field(default_factory=list)
    n_points: dict = field(default_factory=dict)  # quantity -> list
    median: dict = field(default_factory=dict)  # quantity -> list
    max: dict = field(default_factory=dict)

    @property
    def label(self) -> str:
        stage = "both stages" if self.stages == "both" else "stage 1"
        return f"{self.method}, {stage}"

    def add(self, rtol, seconds_per_point, values: dict, ref: dict):
        """Record one rtol: ``values`` and ``ref`` map quantity -> array over the curve's points."""
        self.rtol.append(float(rtol))
        self.time_us.append(seconds_per_point * 1e6)
        failed = np.zeros(self.n_attempted, dtype=bool)
        for q, x in values.items():
            x = np.asarray(x, float)
            good = np.isfinite(x)
            failed |= ~good
            err = np.abs(x[good] - ref[q][good]) / np.abs(ref[q][good])
            self.n_points.setdefault(q, []).append(int(good.sum()))
            self.median.setdefault(q, []).append(float(np.median(err)) if err.size else math.nan)
            self.max.setdefault(q, []).append(float(np.max(err)) if err.size else math.nan)
        self.failed.append(int(failed.sum()))

    def worst_median(self) -> np.ndarray:
        """Per rtol, the largest median error over the curve's quantities."""
        return np.max(np.array([self.median[q] for q in self.median]), axis=0)

    def rows(self):
        for i, r in enumerate(self.rtol):
            for q in self.median:
                yield {
                    "method": self.method, "stages": self.stages, "rtol": r, "quantity": q,
                    "n_points": self.n_points[q][i], "time_per_point_us": self.time_us[i],
                    "median_rel_err": self.median[q][i], "max_rel_err": self.max[q][i],
                }


# ---------------------------------------------------------------------------------------------
# Matched error
# ---------------------------------------------------------------------------------------------
def matched_ratios(ours_err, ours_time, peer_err, peer_time):
    """``[(our median error, our time, peer time at that error, peer/ours)]`` at our points inside
    the peer's error range (log-log linear interpolation)."""
    pe = np.asarray(peer_err, float)
    pt = np.asarray(peer_time, float)
    good = np.isfinite(pe) & (pe > 0) & np.isfinite(pt)
    if good.sum() < 2:
        return []
    x = np.log(pe[good])
    y = np.log(pt[good])
    order = np.argsort(x)
    x, y = x[order], y[order]
    keep = np.concatenate(([True], np.diff(x) > 0))
    x, y = x[keep], y[keep]
    if x.size < 2:
        return []
    out = []
    for e, t in zip(ours_err, ours_time):
        if not (np.isfinite(e) and e > 0):
            continue
        le = math.log(e)
        if x[0] <= le <= x[-1]:
            t_peer = math.exp(float(np.interp(le, x, y)))
            out.append((float(e), float(t), t_peer, t_peer / t))
    return out


def _fmt_ratio(r):
    return f"{r:.3g}x"


def tolerance_target(curve: Curve) -> list[Verdict]:
    """Achieved median (and, informatively, max) error at most a factor 100 above rtol, for rtol
    1e-10..1e-4.

    Less accurate than that is a miss. More accurate than the band's lower side (error below
    rtol / 100) is not: the answers are better than asked, and the verdict says so in its note
    and its detail (work spent that was not requested) without failing.
    """
    lo, hi = TOLERANCE_RANGE
    idx = [i for i, r in enumerate(curve.rtol) if lo * (1 - 1e-9) <= r <= hi * (1 + 1e-9)]
    out = []
    for kind, table in (("median", curve.median), ("max", curve.max)):
        required = kind == "median"
        text = (f"{kind} error of ours (both stages) at most a factor {TOLERANCE_FACTOR:g} above "
                f"rtol for rtol {lo:g}..{hi:g}" + ("" if required else " (informative)"))
        if not idx:
            out.append(Verdict(text, None, "no rtol of this run lies in the range",
                               required=required))
            continue
        ranges, above, below = [], [], []
        for q in table:
            ratios = [table[q][i] / curve.rtol[i] for i in idx]
            ranges.append(f"{q} error/rtol {min(ratios):.2g}..{max(ratios):.2g}")
            for i, ratio in zip(idx, ratios):
                where = f"{q} at rtol {curve.rtol[i]:.0e}"
                if not ratio <= TOLERANCE_FACTOR:
                    above.append(f"{where} by {ratio / TOLERANCE_FACTOR:.3g}x")
                elif ratio < 1 / TOLERANCE_FACTOR:
                    below.append(f"{where} by {1 / (ratio * TOLERANCE_FACTOR):.3g}x")
        detail = "; ".join(ranges)
        if above:
            detail += "; not met, less accurate than the band: " + ", ".join(above)
        note = ""
        if below:
            note = "more accurate than the band"
            detail += ("; more accurate than the band (error below rtol/"
                       f"{TOLERANCE_FACTOR:g}: work not asked for, no failure): " + ", ".join(below))
        out.append(Verdict(text, not above, detail, required=required, note=note))
    return out


def stratum_lines(values_by_rtol: dict, ref: dict, stratum: np.ndarray, names) -> list[str]:
    """Markdown rows: median / max relative error of each quantity per stratum and rtol."""
    qs = list(ref)
    lines = ["| rtol | stratum (points) | " + " | ".join(qs) + " | unanswered |",
             "|---|---|" + "---|" * (len(qs) + 1)]
    for rtol, values in values_by_rtol.items():
        for s, name in enumerate(names):
            pick = stratum == s
            if not pick.any():
                continue
            cells = []
            unanswered = np.zeros(int(pick.sum()), dtype=bool)
            for q in qs:
                unanswered |= ~np.isfinite(values[q][pick])
                x = values[q][pick]
                good = np.isfinite(x)
                err = np.abs(x[good] - ref[q][pick][good]) / np.abs(ref[q][pick][good])
                cells.append(f"{_e(np.median(err))} / {_e(np.max(err))}" if err.size else "-")
            lines.append(f"| {rtol:.0e} | {name} ({int(pick.sum())}) | " + " | ".join(cells)
                         + f" | {int(unanswered.sum())} |")
    return lines


@dataclass
class Comparison:
    """Ours against one peer, on the peer's points and on the subset it solved at every rtol.

    The verdicts use ``*_solved``: there both sides answer every point, so neither the peer's
    work cap (which makes its time a lower bound) nor the points it gave up on (which leave its
    error statistics to the easy points) can flatter either side.
    """

    peer: Curve
    ours: Curve
    peer_solved: Curve
    ours_solved: Curve

    @staticmethod
    def _err(c: Curve):
        return c.worst_median() if c.stages == "both" else c.median["m_wall"]

    def ratios(self, solved: bool = True):
        o, p = (self.ours_solved, self.peer_solved) if solved else (self.ours, self.peer)
        return matched_ratios(self._err(o), o.time_us, p.median["m_wall"], p.time_us)


def _cells(m):
    return ", ".join(f"{e:.1e} -> {r:.3g}x" for e, _, _, r in m) or "no overlap"


def speed_targets(comparisons: list[Comparison], numbalsoda_note: str):
    """The three speed targets and the matched-ratio table rows behind them."""
    table = []
    for c in comparisons:
        table.append({
            "peer": c.peer.label, "ours": c.ours.label,
            "all": f"{c.peer.points}, {c.peer.n_attempted} points "
                   f"(peer failed up to {max(c.peer.failed, default=0)}): {_cells(c.ratios(False))}",
            "solved": f"{c.peer_solved.n_attempted} points: {_cells(c.ratios(True))}",
        })
    stage1 = [c for c in comparisons if c.ours.stages == "stage1"]
    targets = []

    def where(c):
        return (f"on the {c.peer_solved.n_attempted} of {c.peer.n_attempted} points it solved at "
                "every rtol")

    # 1. stage 1 below every peer.
    lines, ok, measured = [], True, False
    for c in stage1:
        m = c.ratios()
        if not m:
            lines.append(f"{c.peer.method}: no overlap in median error")
            continue
        measured = True
        r = min(x[3] for x in m)
        line = f"{c.peer.method} min {_fmt_ratio(r)} ({where(c)})"
        if r <= 1.0:
            ok = False
            worst = min(m, key=lambda x: x[3])
            line += f", not met: ours {1 / r:.3g}x slower at median error {worst[0]:.2g}"
        lines.append(line)
    targets.append(Verdict("at matched median error our stage-1 time per point is below every "
                          "peer's", ok if measured else None, "; ".join(lines) or "no peers"))

    # 2. >= 300x below scipy RK45.
    text = f"our stage-1 time >= {RK45_TARGET:g}x below scipy RK45 in a loop at matched median error"
    rk = [c for c in stage1 if c.peer.method == "scipy-RK45"]
    m = rk[0].ratios() if rk else []
    if not m:
        targets.append(Verdict(text, None, "scipy RK45 not measured or no overlap in median error"))
    else:
        rs = [x[3] for x in m]
        r = min(rs)
        detail = (f"{_fmt_ratio(r)} .. {_fmt_ratio(max(rs))} over {len(rs)} matched errors "
                  f"{where(rk[0])}")
        m_all = rk[0].ratios(False)
        if m_all:
            detail += (f" (on all {rk[0].peer.n_attempted}, RK45's time capped: "
                       f"{_fmt_ratio(min(x[3] for x in m_all))} .. "
                       f"{_fmt_ratio(max(x[3] for x in m_all))})")
        if r < RK45_TARGET:
            worst = min(m, key=lambda x: x[3])
            short = sum(x < RK45_TARGET for x in rs)
            detail += (f"; not met: {_fmt_ratio(r)} at median error {worst[0]:.2g}, "
                       f"{RK45_TARGET / r:.3g}x short of {RK45_TARGET:g}x ({short} of {len(rs)} "
                       "matched errors below the target)")
        targets.append(Verdict(text, r >= RK45_TARGET, detail))

    # 3. both stages of ours no slower than numbalsoda LSODA's stage 1.
    lo, hi = BOTH_STAGES_RANGE
    text = ("our two-stage time per point <= numbalsoda LSODA's stage-1 time at matched median "
            f"error from {hi:g} to {lo:g} (ours: worst of the Delta, m_wall, slip medians; "
            "numbalsoda: m_wall)")
    nbs = [c for c in comparisons if c.ours.stages == "both" and c.peer.method == "numbalsoda-LSODA"]
    if not nbs:
        targets.append(Verdict(text, None, f"numbalsoda {numbalsoda_note}"))
    else:
        every = nbs[0].ratios()
        m = [x for x in every if lo <= x[0] <= hi]
        outside = [x for x in every if not lo <= x[0] <= hi]
        if not m:
            targets.append(Verdict(text, None, "no overlap in median error within the range"))
        else:
            r = min(x[3] for x in m)
            detail = (f"numbalsoda LSODA / ours = {_fmt_ratio(r)} .. "
                      f"{_fmt_ratio(max(x[3] for x in m))} over {len(m)} matched errors "
                      f"{max(x[0] for x in m):.2g} .. {min(x[0] for x in m):.2g} "
                      f"{where(nbs[0])}")
            if r < 1.0:
                worst = min(m, key=lambda x: x[3])
                detail += (f"; not met: ours is {1 / r:.3g}x slower at median error "
                           f"{worst[0]:.2g}")
            if outside:
                detail += ("; outside the range (not judged): "
                           + ", ".join(f"{x[0]:.2g} -> {_fmt_ratio(x[3])}" for x in outside))
            targets.append(Verdict(text, r >= 1.0, detail))
    return targets, table


# ---------------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------------
def write_csv(curves: list[Curve], path) -> None:
    """``work_precision.csv``: long format, one row per method, stages, rtol and quantity."""
    import io

    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, lineterminator="\n")
    w.writeheader()
    for c in curves:
        for row in c.rows():
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})
    write_text(path, buf.getvalue())


def _e(x):
    return "-" if not np.isfinite(x) else f"{x:.1e}"


def markdown(*, title, meta: dict, vs, curves: list[Curve], ours_both: Curve,
             stage1: list[Curve], targets: list[Verdict], matched: list[dict], notes: list[str],
             figures: list[str], strata: list[str] = ()) -> str:
    """The docs-ready report."""
    L = [f"# {title}", ""]
    L.append("Generated by `cosserat_channel.measure.workprecision`; do not edit by hand, rerun "
             "instead.")
    L.append("")
    for k, v in meta.items():
        L.append(f"- {k}: {v}")
    L.append("")
    L.append("## Acceptance targets (measured in this run)")
    L.append("")
    for t in targets:
        L.append(f"- {t.line(bold=True)}")
    L.append("")
    L.append("## Ours, both stages (full set)")
    L.append("")
    L.append("Relative error against the reference, median / max over the points.")
    L.append("")
    L.append("`failed`: points ours answered without a solution at that rtol (the reference has "
             "one); the errors are over the others.")
    L.append("")
    L.append("| rtol | us/point | Delta | m_wall | slip | failed |")
    L.append("|---|---|---|---|---|---|")
    c = ours_both
    for i, r in enumerate(c.rtol):
        cells = [f"{_e(c.median[q][i])} / {_e(c.max[q][i])}" for q in ("Delta", "m_wall", "slip")]
        L.append(f"| {r:.0e} | {c.time_us[i]:.1f} | " + " | ".join(cells) + f" | {c.failed[i]} |")
    L.append("")
    if strata:
        L.append("By stratum (median / max relative error):")
        L.append("")
        L.extend(strata)
        L.append("")
    L.append("## Stage 1 alone: m_wall")
    L.append("")
    L.append("us/point, then median / max relative error of m_wall; `failed` points had no answer "
             "(their time counts).")
    L.append("")
    L.append("| method | points | rtol | us/point | median err | max err | failed |")
    L.append("|---|---|---|---|---|---|---|")
    for c in stage1:
        for i, r in enumerate(c.rtol):
            L.append(f"| {c.method} | {c.points} ({c.n_attempted}) | {r:.0e} | {c.time_us[i]:.4g} | "
                     f"{_e(c.median['m_wall'][i])} | {_e(c.max['m_wall'][i])} | {c.failed[i]} |")
    L.append("")
    L.append("## Matched median error: peer time / our time")
    L.append("")
    L.append("Our median error -> the peer's time over ours at that error (log-log interpolation "
             "of the peer's curve, never extrapolated). First on the peer's points, counting the "
             "time of points it gave up on at its work cap; then on the points it solved at every "
             "rtol, ours re-timed on exactly those (the verdicts above use these).")
    L.append("")
    L.append("| peer | ours | on its points | on the points it solved |")
    L.append("|---|---|---|---|")
    for row in matched:
        L.append(f"| {row['peer']} | {row['ours']} | {row['all']} | {row['solved']} |")
    L.append("")
    L.append("## Validation set and reference")
    L.append("")
    for n in notes:
        L.append(f"- {n}")
    L.append("")
    if figures:
        L.append("Figures: " + ", ".join(f"`{f}`" for f in figures)
                 + " in the report directory (`cosserat-channel bench -o DIR`).")
        L.append("")
    return "\n".join(L)
