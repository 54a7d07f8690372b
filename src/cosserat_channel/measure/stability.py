"""The stability report: cost and accuracy of one point from eps L = 1e-8 to the edge.

For each ``(A, N)`` series, ``eta = eps L`` runs log-spaced from 1e-8 to the largest feasible value
(:func:`feasible_eta_max`, by bisection on the status), plus points next to each regime boundary
(the path edge from both sides, the axis edge, A = -1 at c = 2N/eta up to 1e5, A just above -1,
A just above 1 - 2N^2). Each row records the path stage 1 took (explicit: Dormand-Prince, or
DOP853 at rtol <= 1e-6; or stiff RODAS4P2), both stages' accepted/rejected steps, the
right-hand-side evaluations, the kernel time per point (best of several repeats, microseconds)
and the relative error of ``Delta`` and
``m_wall`` against an independent reference:

- scipy Radau at rtol 1e-12 (:func:`cosserat_channel.physics.reference.reference`), ``ref = radau``;
- Appendix A's closed form for A = -1, ``ref = closed form``;
- where Radau cannot start (it stops with "step size less than spacing between numbers" when
  ``beta = 2N/(eta c0)`` is ~1e8 and beyond), our own solver at rtol 1e-12, ``ref = ours 1e-12``
  (a self-convergence check, labelled as such).

Each row is kept in ``stability.partial.json`` as soon as it is measured, so a run that is
interrupted (Ctrl-C, a kill) resumes with the rows it finished, when the sources and settings are
the same. Only numbers and markdown here; the figure is
:func:`cosserat_channel.plot.stability.stability_figure`, drawn from the :class:`Report`.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field

import numpy as np

from ..physics import asymptotics
from .. import parameters, regimes
from ..solver import point as sv
from .. import status as st
from ..physics.reference import reference
from . import machine
from .harness import best_of, word
from ..files import write_text

L_REPORT = 10.0  # eps = eta / L; the outputs depend on eta only (model.md's similarity)
K_REPORT = 0.5
RTOL = parameters.DEFAULT_RTOL
ATOL = parameters.DEFAULT_ATOL
SERIES = ((1 / 3, 1.0), (2.0, 3.0))  # (A, N): the paper's, and a smoother wall with large A
ETA_MIN = 1e-8
ETA_STIFFEST = 1e-6  # the acceptance's "stiffest point"
ETA_TYPICAL = 0.3  # and its "typical point"
COST_RATIO_LIMIT = 20.0
# "Flat": a log-log slope of stage-1 steps against eta on the stiff path below this magnitude
# (an explicit method has slope -1 there).
FLAT_SLOPE_LIMIT = 0.1

COLUMNS = ("case", "A", "N", "eta", "status", "path", "s1_acc", "s1_rej", "s2_acc", "s2_rej",
           "fev", "us", "D_wall", "err_Delta", "err_m_wall", "ref")
ETA_CAP = 50.0  # eps 0.5 x L 100: the top of the domain
EDGE_SEARCH_MIN = 1e-3  # feasible_eta_max searches [EDGE_SEARCH_MIN, ETA_CAP]
EDGE_XTOL = 1e-12  # its relative bracket: the rows 1e-6 either side of the edge stay on their side


def report_L(eta):
    """L of a row: L_REPORT, raised so that eps = eta/L stays <= 0.5 (only eta matters)."""
    return max(L_REPORT, 2.0 * eta)


@dataclass
class Report:
    """Rows (dicts keyed by :data:`COLUMNS`) and the verdict numbers."""

    rows: list = field(default_factory=list)
    rtol: float = RTOL
    quick: bool = False
    verdict: dict = field(default_factory=dict)
    # The fixed parameters, for the figure's title (L is raised above eta = 5, see report_L).
    L: float = L_REPORT
    K: float = K_REPORT
    resumed: int = 0  # rows taken from an interrupted run's partial file


def _status(ws, eta, A, N):
    return ws.run(eta, A, N, RTOL, ATOL)


def feasible_eta_max(A, N, ws=None, eta_cap=ETA_CAP):
    """Largest ``eta <= eta_cap`` (domain: eps 0.5 x L 100) with status ok, by bisection in log eta.

    Returns ``(eta_max, next_status)`` where ``next_status`` is the status just beyond it (None
    when the whole range up to ``eta_cap`` is feasible).
    """
    ws = ws or sv.Workspace()
    if _status(ws, eta_cap, A, N) == st.OK:
        return eta_cap, None
    lo = EDGE_SEARCH_MIN
    if _status(ws, lo, A, N) != st.OK:
        raise ValueError(f"A = {A}, N = {N}: no solution even at eta = {lo}")
    lo, hi = regimes.bisect_edge(lambda eta: _status(ws, eta, A, N) == st.OK, lo, eta_cap,
                                 EDGE_XTOL)
    return lo, st.Status(_status(ws, hi, A, N)).name


def _time_us(ws, eta, A, N, repeats, rtol=RTOL):
    """Best-of-``repeats`` kernel time per point in microseconds (each timing at least 2 ms)."""
    return 1e6 * best_of(lambda: ws.run(eta, A, N, rtol, ATOL), repeats, min_seconds=2e-3,
                         max_inner=200).seconds


def _reference(eps, L, K, A, N):
    if A == -1.0:
        cf = asymptotics.a_minus_one_outputs(eps, L, K, N)
        return {"status": "ok", "Delta": cf.Delta, "m_wall": -N * L}, "closed form"
    try:
        return reference(eps, L, K, A, N, method="Radau", rtol=1e-12), "radau"
    except (AssertionError, ValueError, ZeroDivisionError):
        r = sv.solve_point(eps, L, K, A, N, rtol=1e-12)
        return {"status": r.status.name, "Delta": r.Delta, "m_wall": r.m_wall}, "ours 1e-12"


def _rel_err(x, ref):
    if not (math.isfinite(x) and math.isfinite(ref)):
        return math.nan
    if ref == 0.0:
        return abs(x)
    return abs(x / ref - 1.0)


def measure(case, eta, A, N, ws, repeats=5, with_reference=True, rtol=RTOL):
    """One row of the report for ``(eta, A, N)`` at ``eps = eta/L``, ``K = K_REPORT``, solved at
    ``rtol`` (the reference is always at 1e-12).

    ``D_wall = (sigma_yx(1) - A)^2``: the outputs' condition number near the path edge is ~1/D_wall
    (tests/test_domain.py), so a large error next to that edge is the problem's, not the solver's.
    """
    L = report_L(eta)
    eps = eta / L
    r = sv.solve_point(eps, L, K_REPORT, A, N, rtol=rtol, workspace=ws)
    c = r.counters
    row = {
        "case": case, "A": A, "N": N, "eta": eta, "status": r.status.name, "path": c["stage1_path"],
        "s1_acc": c["stage1_accepted"], "s1_rej": c["stage1_rejected"],
        "s2_acc": c["stage2_accepted"], "s2_rej": c["stage2_rejected"],
        "fev": c["stage1_fev"] + c["stage2_fev"], "us": _time_us(ws, eta, A, N, repeats, rtol),
        "D_wall": (r.sigma_yx_wall - A) ** 2 if (r.ok and A != -1.0) else math.nan,
        "err_Delta": math.nan, "err_m_wall": math.nan, "ref": "-",
    }
    if with_reference:
        ref, source = _reference(eps, L, K_REPORT, A, N)
        row["ref"] = source
        if ref["status"] != r.status.name:
            row["status"] = f"{r.status.name} (ref: {ref['status']})"
        elif r.ok:
            row["err_Delta"] = _rel_err(r.Delta, ref["Delta"])
            row["err_m_wall"] = _rel_err(r.m_wall, ref["m_wall"])
    return row


def eta_grid(eta_max, quick):
    """Log-spaced eta from ETA_MIN to eta_max, always with ETA_STIFFEST and ETA_TYPICAL."""
    if quick:
        base = [ETA_MIN, ETA_STIFFEST, ETA_TYPICAL]
    else:
        base = list(10.0 ** np.arange(-8.0, 1.01, 0.5))
        base += [ETA_STIFFEST, ETA_TYPICAL]
    grid = sorted({round(float(e), 15) for e in base if e < eta_max * (1 - 1e-3)})
    return grid + [eta_max * (1 - 1e-6)]


PARTIAL_NAME = "stability.partial.json"


def _run_key(quick, repeats, rtol=RTOL) -> dict:
    """What a row depends on besides its point: the sources, the settings, the tolerances."""
    return {"sources": machine.source_digest(), "quick": bool(quick), "repeats": int(repeats),
            "rtol": rtol, "atol": ATOL}


def _row_key(case, eta, A, N):
    return json.dumps([case, eta, A, N])


def _read_partial(path, key) -> dict:
    """The rows kept at ``path`` by a run with the same ``key``, by point; {} otherwise."""
    try:
        with open(path, encoding="utf-8") as fh:
            data = json.load(fh)
        if data.get("key") != key:
            return {}
        return {_row_key(r["case"], r["eta"], r["A"], r["N"]): r for r in data["rows"]}
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        return {}


def kept(directory, quick=False, repeats=5, rtol=RTOL) -> int:
    """How many rows an interrupted run left in ``directory`` for a run with these settings."""
    return len(_read_partial(os.path.join(directory, PARTIAL_NAME), _run_key(quick, repeats, rtol)))


def build_report(quick=False, repeats=5, progress=None, partial=None, rtol=RTOL) -> Report:
    """Measure every row; ``progress(done, total, text)`` (the package's progress protocol) is
    called after each, ``text`` naming the row just measured (optional).

    ``partial``: a path where the rows are kept as they are measured, and read back from: rows
    of a run with the same sources and settings are taken from it instead of measured again.
    ``rtol``: the tolerance every row is solved at (the edges are found at the default).
    """
    key = _run_key(quick, repeats, rtol)
    done = _read_partial(partial, key) if partial is not None else {}
    ws = sv.Workspace()
    plan = []
    for A, N in SERIES[:1] if quick else SERIES:
        eta_max, beyond = feasible_eta_max(A, N, ws)
        grid = eta_grid(eta_max, quick)
        for eta in grid:
            plan.append(("path edge - 1e-6" if eta == grid[-1] and beyond else "sweep", eta, A, N))
        if beyond is not None:
            plan.append((f"{beyond} + 1e-6", eta_max * (1 + 1e-6), A, N))
        if A < 1.0 and not quick:
            eta_axis = 2 * (A + 1) * N / (1 - A)
            plan.append(("axis edge - 1e-3", eta_axis * (1 - 1e-3), A, N))
    # Next to the other regime boundaries (A = -1 at large c; just above A = -1; just above
    # A = 1 - 2N^2, where the wall is barely admissible; N = 10 at the smallest eta).
    for c in ((1e5,) if quick else (1e3, 1e5, 1e7)):
        plan.append((f"A = -1, c = {c:.0e}", 2.0 / c, -1.0, 1.0))
    if not quick:
        plan.append(("A = -1 + 1e-4", 5e-7, -1 + 1e-4, 1.0))
        plan.append(("A = 1 - 2N^2 + 1e-6", 0.1, 1 - 2 * 0.7**2 + 1e-6, 0.7))
        plan.append(("N = 10", 5e-8, 1 / 3, 10.0))
    rep = Report(rtol=rtol, quick=quick)
    for i, (case, eta, A, N) in enumerate(plan):
        row = done.get(_row_key(case, eta, A, N))
        if row is None:
            row = measure(case, eta, A, N, ws, repeats=repeats, rtol=rtol)
        else:
            rep.resumed += 1
        rep.rows.append(row)
        if partial is not None:
            # NaN stays NaN (json's extension): this file is read back by this module only.
            write_text(partial, json.dumps({"key": key, "rows": rep.rows},
                                           default=lambda x: x.item()) + "\n")
        if progress is not None:
            progress(i + 1, len(plan), f"points; last: {row['case']} eta = {row['eta']:.3g}: "
                     f"{row['status']}, {row['path']} path")
    rep.verdict = verdict(rep.rows, rtol)
    return rep


def verdict(rows, rtol=RTOL) -> dict:
    """Max error / rtol, max steps, the cost ratio stiffest/typical and the stiff-path slope."""
    def max_err(sel):
        errs = [max(r["err_Delta"], r["err_m_wall"]) for r in sel
                if r["status"] == "ok" and math.isfinite(r["err_Delta"])
                and math.isfinite(r["err_m_wall"])]
        return (max(errs) / rtol) if errs else math.nan

    well = [r for r in rows if not (math.isfinite(r["D_wall"]) and r["D_wall"] < 1e-2)]
    out = {
        "max_err_over_rtol": max_err(well),
        "max_err_over_rtol_all": max_err(rows),
        "mismatches": [r["case"] for r in rows if "(ref:" in r["status"]],
        "max_steps": max(r["s1_acc"] + r["s1_rej"] + r["s2_acc"] + r["s2_rej"] for r in rows),
        "series": {},
    }
    for A, N in {(r["A"], r["N"]) for r in rows if r["case"] == "sweep"}:
        series = [r for r in rows if r["A"] == A and r["N"] == N and r["case"] == "sweep"]
        by_eta = {r["eta"]: r for r in series}
        entry = {}
        if ETA_STIFFEST in by_eta and ETA_TYPICAL in by_eta:
            ratio = by_eta[ETA_STIFFEST]["us"] / by_eta[ETA_TYPICAL]["us"]
            entry["cost_ratio"] = ratio
            entry["cost_pass"] = ratio <= COST_RATIO_LIMIT
        stiff = [r for r in series if r["path"] == "stiff" and r["status"] == "ok"]
        if len(stiff) >= 2:
            x = np.log10([r["eta"] for r in stiff])
            y = np.log10([r["s1_acc"] for r in stiff])
            slope = float(np.polyfit(x, y, 1)[0])
            entry["stiff_slope"] = slope
            entry["stiff_steps_range"] = (min(r["s1_acc"] for r in stiff), max(r["s1_acc"] for r in stiff))
            entry["flat_pass"] = abs(slope) < FLAT_SLOPE_LIMIT
        out["series"][(A, N)] = entry
    return out


def _fmt(value, col):
    if isinstance(value, str):
        return value
    if col in ("A", "N"):
        return f"{value:.6g}"
    if col == "eta":
        return f"{value:.6g}"
    if col == "us":
        return f"{value:.1f}"
    if col.startswith("err") or col == "D_wall":
        return "-" if not math.isfinite(value) else f"{value:.1e}"
    return str(value)


def markdown(rep: Report) -> str:
    """The report as markdown: parameters, table, verdict."""
    lines = [
        "# Stability report",
        "",
        f"L = {L_REPORT:g} (2 eta above eta = 5, so that eps <= 0.5), K = {K_REPORT:g}, eps = eta/L, "
        f"rtol = {rep.rtol:g}, atol = {ATOL:g}; "
        "time = kernel (both stages) per point, best of repeats, microseconds; errors relative to "
        "the reference named in `ref` (Radau rtol 1e-12, Appendix A's closed form, or our solver "
        "at rtol 1e-12 where Radau cannot start)." + (" Quick version." if rep.quick else "")
        + (f" {rep.resumed} of the {len(rep.rows)} rows were measured by an interrupted run of "
           "the same sources and settings, and taken from it." if rep.resumed else ""),
        "",
        "| " + " | ".join(COLUMNS) + " |",
        "|" + "|".join("---" for _ in COLUMNS) + "|",
    ]
    for row in rep.rows:
        lines.append("| " + " | ".join(_fmt(row[c], c) for c in COLUMNS) + " |")
    v = rep.verdict
    lines += ["", "## Verdict", ""]
    lines.append("- max relative error (Delta, m_wall) / rtol over ok rows with D_wall >= 1e-2: "
                 f"{v['max_err_over_rtol']:.2f}; over all ok rows (including those next to the "
                 f"path edge, condition ~1/D_wall): {v['max_err_over_rtol_all']:.3g}")
    lines.append("- status disagreements with the reference: "
                 + (", ".join(v["mismatches"]) if v["mismatches"] else "none"))
    lines.append(f"- max steps per point (both stages, accepted + rejected): {v['max_steps']}")
    for (A, N), e in sorted(v["series"].items()):
        head = f"- A = {A:.6g}, N = {N:.6g}:"
        if "cost_ratio" in e:
            head += (f" cost at eta = {ETA_STIFFEST:g} / cost at eta = {ETA_TYPICAL:g} = "
                     f"{e['cost_ratio']:.2f} (limit {COST_RATIO_LIMIT:g}: "
                     f"{word(e['cost_pass'])});")
        if "stiff_slope" in e:
            lo, hi = e["stiff_steps_range"]
            head += (f" stiff-path stage-1 steps {lo}..{hi}, log-log slope vs eta "
                     f"{e['stiff_slope']:+.3f} (flat if |slope| < {FLAT_SLOPE_LIMIT:g}: "
                     f"{word(e['flat_pass'])})")
        lines.append(head)
    return "\n".join(lines) + "\n"


def directory_problem(directory) -> str | None:
    """Why the report cannot be written into ``directory`` (created if missing), or None."""
    if os.path.exists(directory) and not os.path.isdir(directory):
        return f"{directory!r} exists and is not a directory"
    try:
        os.makedirs(directory, exist_ok=True)
    except OSError as exc:
        return f"cannot create directory {directory!r}: {exc.strerror or exc}"
    if not os.access(directory, os.W_OK | os.X_OK):
        return f"directory {directory!r} is not writable"
    return None


def write_report(directory, quick=False, repeats=5, progress=None, rtol=RTOL) -> Report:
    """Build the report and write ``directory/stability.md`` and ``directory/stability.png``;
    the rows are kept in ``directory/stability.partial.json`` until both are written."""
    from ..plot.stability import stability_figure

    partial = os.path.join(directory, PARTIAL_NAME)
    rep = build_report(quick=quick, repeats=repeats, progress=progress, partial=partial,
                       rtol=rtol)
    write_text(os.path.join(directory, "stability.md"), markdown(rep))
    stability_figure(rep, os.path.join(directory, "stability.png"))
    os.unlink(partial)
    return rep


__all__ = ["Report", "build_report", "directory_problem", "feasible_eta_max", "kept", "markdown",
           "measure", "verdict", "write_report", "COLUMNS", "PARTIAL_NAME"]
