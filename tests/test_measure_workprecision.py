"""Work-precision report (measure/workprecision.py and its modules): the files, the CSV contract,
the figures' artists and the target logic.

The quick report runs once per module on the tiny set (timings are not checked: the machine is
shared); it takes about 15 s, so the tests that read it are marked slow, as is the interrupted
run. numbalsoda is made to look absent so the test does not depend on the optional extra.
"""

import csv
import math
import signal

import numpy as np
import pytest
from matplotlib.collections import PolyCollection

from cosserat_channel import cli
from cosserat_channel.measure import report, runners, validation, workprecision
from cosserat_channel.measure.report import Curve
from cosserat_channel.outputs import OUTPUTS
from support import start_cli, wait_until

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def quick(tmp_path_factory):
    """The quick report, written into a fresh directory, with numbalsoda absent."""
    out = tmp_path_factory.mktemp("bench")
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(runners, "numbalsoda_status",
                   lambda: (None, "not installed (simulated by the test)"))
        rep = workprecision.run(out, quick=True, command="pytest quick")
    return out, rep


@pytest.fixture(scope="module")
def rows(quick):
    """The CSV rows as dicts."""
    with open(quick[1].paths["csv"], newline="") as fh:
        return list(csv.DictReader(fh))


@pytest.mark.slow
def test_files_written(quick):
    """CSV, both PNGs, the markdown and the reference cache exist; the PNGs are PNGs."""
    out, rep = quick
    for name in ("work_precision.csv", "work_precision.png", "tolerance.png", "work_precision.md",
                 "reference_cache.npz"):
        assert (out / name).is_file(), name
    for name in ("work_precision.png", "tolerance.png"):
        assert (out / name).read_bytes()[:8] == PNG_SIGNATURE


@pytest.mark.slow
def test_no_temporary_files_left(quick):
    """Every file went through files.atomic_output: nothing but the outputs in the directory."""
    out, _ = quick
    assert not [p.name for p in out.iterdir() if p.name.startswith(".") or "tmp" in p.name]


@pytest.mark.slow
def test_csv_columns_are_the_contract(quick):
    """The header is exactly the columns the notebook reads, in order."""
    with open(quick[1].paths["csv"], newline="") as fh:
        header = next(csv.reader(fh))
    assert header == ["method", "stages", "rtol", "quantity", "n_points", "time_per_point_us",
                      "median_rel_err", "max_rel_err"]


@pytest.mark.slow
def test_csv_rows(quick, rows):
    """Ours has both stages (three quantities) and stage 1; peers stage 1 with m_wall only."""
    rtols = set(workprecision.QUICK.rtols)
    by = {}
    for r in rows:
        by.setdefault((r["method"], r["stages"]), set()).add((float(r["rtol"]), r["quantity"]))
        assert int(r["n_points"]) >= 1
        assert float(r["time_per_point_us"]) > 0
        assert float(r["median_rel_err"]) <= float(r["max_rel_err"])
    assert by[("ours", "both")] == {(t, q) for t in rtols for q in ("Delta", "m_wall", "slip")}
    for key in (("ours", "stage1"), ("scipy-RK45", "stage1"), ("scipy-LSODA", "stage1")):
        assert by[key] == {(t, "m_wall") for t in rtols}, key
    assert {m for m, _ in by} == {"ours", "scipy-RK45", "scipy-LSODA"}  # numbalsoda absent


@pytest.mark.slow
def test_validation_set_is_cross_checked(quick):
    """Every kept point has finite references; the cross-checked ones agree to 1e-9."""
    vs = quick[1].validation_set
    assert vs.size == validation.SetSpec(size=12).size
    for q in validation.QUANTITIES:
        assert np.all(np.isfinite(vs.ref[q]))
    assert np.all(vs.disagreement[vs.cross_checked] <= validation.CROSS_CHECK_TOL)
    assert set(vs.stratum) == {0, 1, 2}  # bulk, stiff and edge points are all there


@pytest.mark.slow
def test_work_precision_figure(quick):
    """Log-log error against time, one labelled line per curve, ours first."""
    rep = quick[1]
    ax = rep.figures["work_precision"].axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    assert "time per point" in ax.get_xlabel() and r"\mu" in ax.get_xlabel()
    assert "relative error" in ax.get_ylabel()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels[0].startswith("ours, both stages")
    for method in ("scipy-RK45", "scipy-LSODA"):
        assert sum(lab.startswith(method) for lab in labels) == 1, method
    assert any("scipy subsample" in lab for lab in labels)
    assert len(ax.get_lines()) == len(labels) == 5  # ours both, ours s1 x2, two peers
    assert "12 points" in rep.figures["work_precision"].get_suptitle()


@pytest.mark.slow
def test_work_precision_figure_pairs_each_peer_with_ours_on_its_points(quick):
    """The second panel draws each peer on the points it solved next to ours on the same points."""
    fig = quick[1].figures["work_precision"]
    assert len(fig.axes) == 2
    ax = fig.axes[1]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert len(ax.get_lines()) == len(labels) == 4  # (peer, ours) for RK45 and LSODA
    assert sum(lab.startswith("ours on the same") for lab in labels) == 2
    for c in quick[1].comparisons:
        line = next(ln for ln in ax.get_lines() if ln.get_label().startswith(c.peer.method))
        assert np.allclose(line.get_xdata(), c.peer_solved.time_us)


@pytest.mark.slow
def test_tolerance_figure(quick):
    """Achieved error against rtol with the ideal line y = x and the factor-100 band."""
    ax = quick[1].figures["tolerance"].axes[0]
    assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
    assert "rtol" in ax.get_xlabel() and "error" in ax.get_ylabel()
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    ideal = [ln for ln in ax.get_lines() if ln.get_label().startswith("ideal")]
    assert len(ideal) == 1 and np.allclose(ideal[0].get_xdata(), ideal[0].get_ydata())
    assert any(isinstance(c, PolyCollection) for c in ax.collections)
    assert any("factor 100" in lab for lab in labels)
    for q in ("Delta", "m_wall", "slip"):  # each curve is named by its output's symbol
        symbol = OUTPUTS[q].symbol
        assert f"{symbol}, median" in labels and f"{symbol}, max" in labels


@pytest.mark.slow
def test_markdown_has_provenance_and_verdicts(quick):
    """The report names the command, date, machine and versions and gives a verdict per target."""
    text = quick[1].paths["markdown"].read_text()
    for word in ("command: `pytest quick`", "date:", "machine:", "versions:", "numba", "scipy",
                 "seed 20261121"):
        assert word in text, word
    verdicts = [line for line in text.splitlines() if line.startswith("- **")]
    assert len(verdicts) == 5
    assert "NOT MEASURED" in text and "numbalsoda not installed (simulated" in text


@pytest.mark.slow
def test_cli_rerun_reuses_the_cache(quick, capsys):
    """``bench --quick -o DIR`` over an existing report reuses the references, exits 0."""
    out, rep = quick
    assert cli.main(["bench", "--quick", "-o", str(out)]) == 0
    captured = capsys.readouterr()
    assert "reusing" in captured.err
    assert "PASS" in captured.out or "FAIL" in captured.out
    with open(out / "work_precision.csv", newline="") as fh:
        assert next(csv.reader(fh))[0] == "method"


def test_cli_rejects_bad_subsample(capsys):
    """A scipy subsample below two points is refused with one line and exit code 2."""
    assert cli.main(["bench", "--quick", "--scipy-points", "1"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--scipy-points" in err[0]


# ---------------------------------------------------------------------------------------------
# The logic, on synthetic curves
# ---------------------------------------------------------------------------------------------
def _curve(method, rtols, time_us, err, stages="stage1", points="full set"):
    c = Curve(method, stages, points, 10)
    c.rtol = list(rtols)
    c.time_us = list(time_us)
    c.failed = [0] * len(rtols)
    c.n_points = {"m_wall": [10] * len(rtols)}
    c.median = {"m_wall": list(err)}
    c.max = {"m_wall": [10 * e for e in err]}
    return c


def test_matched_ratio_of_a_scaled_curve():
    """A peer 100x slower at every error gives ratio 100 wherever the errors overlap."""
    err = [1e-4, 1e-6, 1e-8]
    m = report.matched_ratios(err, [1.0, 2.0, 4.0], err, [100.0, 200.0, 400.0])
    assert [round(x[3], 9) for x in m] == [100.0] * 3


def test_matched_ratio_interpolates_log_log_and_never_extrapolates():
    """Between two peer points the time is interpolated in log-log; outside, nothing is claimed."""
    m = report.matched_ratios([1e-5, 1e-9], [1.0, 1.0], [1e-4, 1e-6], [10.0, 1000.0])
    assert len(m) == 1
    assert math.isclose(m[0][2], 100.0, rel_tol=1e-12)  # halfway in log error: halfway in log time


def test_tolerance_target_on_ideal_and_bad_curves():
    """error = rtol passes; 1000x rtol fails as less accurate; 1e-3 rtol passes, with the note
    that it is more accurate than the band; above at one rtol and below at another fails."""
    rtols = [1e-4, 1e-6, 1e-8, 1e-10]
    ok = report.tolerance_target(_curve("ours", rtols, [1] * 4, rtols, "both"))
    assert ok[0].passed and ok[0].note == "" and ok[0].required and not ok[1].required
    bad = report.tolerance_target(_curve("ours", rtols, [1] * 4, [1e3 * r for r in rtols], "both"))
    assert bad[0].passed is False and "less accurate" in bad[0].detail and "by 10x" in bad[0].detail
    assert bad[0].missed and bad[0].line().startswith("FAIL: ")
    over = report.tolerance_target(_curve("ours", rtols, [1] * 4, [1e-5 * r for r in rtols], "both"))
    assert over[0].passed is True and not over[0].missed
    assert over[0].line().startswith("PASS (more accurate than the band): ")
    assert "m_wall at rtol 1e-04 by 1e+03x" in over[0].detail
    mixed = report.tolerance_target(_curve("ours", rtols, [1] * 4, [1e-5, 1e-4, 1e-12, 1e-10],
                                           "both"))
    assert mixed[0].passed is False and "less accurate" in mixed[0].detail
    assert "more accurate" in mixed[0].detail


def test_bench_more_accurate_than_the_band_is_no_failure(tmp_path, monkeypatch, capsys):
    """A full ``bench`` whose answers are 1000x more accurate than the band (error rtol/1e5)
    exits 0 and prints no FAIL line: better than asked is reported, not failed."""
    from types import SimpleNamespace

    rtols = [1e-4, 1e-6, 1e-8, 1e-10]
    targets = report.tolerance_target(_curve("ours", rtols, [1] * 4, [1e-5 * r for r in rtols],
                                             "both"))
    fake = SimpleNamespace(targets=targets, paths={"md": str(tmp_path / "r.md")})
    monkeypatch.setattr(workprecision, "run", lambda *a, **k: fake)
    assert cli.main(["bench", "-o", str(tmp_path / "r")]) == 0
    out, err = capsys.readouterr()
    assert "FAIL" not in out and "error" not in err
    assert "PASS (more accurate than the band): median error" in out


def test_speed_targets_say_by_how_much():
    """A peer only 100x slower fails the 300x RK45 target by 3x; numbalsoda absent is not measured."""
    rtols = [1e-4, 1e-6, 1e-8]
    err = [1e-5, 1e-7, 1e-9]
    ours = _curve("ours", rtols, [1.0, 2.0, 3.0], err, points="subsample")
    rk45 = _curve("scipy-RK45", rtols, [100.0, 200.0, 300.0], err, points="subsample")
    targets, table = report.speed_targets([report.Comparison(rk45, ours, rk45, ours)],
                                          "not installed")
    below_all, vs_rk45, vs_nbs = targets
    assert below_all.passed is True
    assert vs_rk45.passed is False and "3x short of 300x" in vs_rk45.detail
    assert vs_nbs.passed is None and "not installed" in vs_nbs.detail
    assert len(table) == 1 and "100x" in table[0]["solved"]


def test_two_stage_target_is_judged_within_its_range():
    """Ours faster than numbalsoda LSODA at every matched error from 1e-4 to 1e-10 passes, however
    much slower below 1e-10 (reported, not judged); slower at one error inside fails."""
    rtols = [1e-4, 1e-6, 1e-8, 1e-10, 1e-12]
    lsoda = _curve("numbalsoda-LSODA", rtols, [10.0, 20.0, 30.0, 40.0, 50.0],
                   [1e-5, 1e-7, 1e-9, 1e-11, 1e-13])
    ours = _curve("ours", rtols, [5.0, 10.0, 15.0, 200.0, 400.0],
                  [1e-5, 1e-7, 1e-9, 1e-11, 1e-13], "both")
    targets, _ = report.speed_targets([report.Comparison(lsoda, ours, lsoda, ours)], "-")
    vs_nbs = targets[2]
    assert vs_nbs.passed is True and "outside the range (not judged)" in vs_nbs.detail
    slow = _curve("ours", rtols, [5.0, 30.0, 15.0, 200.0, 400.0],
                  [1e-5, 1e-7, 1e-9, 1e-11, 1e-13], "both")
    targets, _ = report.speed_targets([report.Comparison(lsoda, slow, lsoda, slow)], "-")
    assert targets[2].passed is False and "at median error 1e-07" in targets[2].detail


def test_verdict_uses_the_points_the_peer_solved():
    """A peer that looks 1000x slower only because of capped failures is judged where it solved."""
    rtols = [1e-4, 1e-6, 1e-8]
    err = [1e-5, 1e-7, 1e-9]
    ours = _curve("ours", rtols, [1.0, 1.0, 1.0], err, points="subsample")
    capped = _curve("scipy-RK45", rtols, [1000.0] * 3, err, points="subsample")
    solved = _curve("scipy-RK45", rtols, [100.0] * 3, err, points="solved")
    ours_solved = _curve("ours", rtols, [1.0] * 3, err, points="solved")
    targets, _ = report.speed_targets([report.Comparison(capped, ours, solved, ours_solved)], "-")
    vs_rk45 = targets[1]
    assert vs_rk45.passed is False
    assert vs_rk45.detail.startswith("100x")
    assert "1e+03x" in vs_rk45.detail  # the capped comparison is still shown


def test_subsample_spans_eta():
    """The scipy subsample includes the stiffest and the least stiff point."""
    eta = np.array([3.0, 1e-6, 0.1, 10.0, 1e-3])
    pick = workprecision.subsample(eta, 3)
    assert 1 in pick and 3 in pick and pick.size == 3


def test_cache_key_follows_the_definition():
    """Same definition, same key; another seed or size, another key."""
    a = validation.SetSpec(size=12)
    assert a.key() == validation.SetSpec(size=12).key()
    assert a.key() != validation.SetSpec(size=12, seed=1).key()
    assert a.key() != validation.SetSpec(size=13).key()


def test_edge_stratum_edges_are_pinned():
    """Where the edge stratum's bisection lands, rounded to 6 digits as the set uses it.

    The set (and so every cached reference) follows these values; if this test fails, bump
    validation.GENERATOR_VERSION so that cached sets are rebuilt.
    """
    spec = validation.SetSpec()
    assert validation._edge_eta(1 / 3, 1.0, spec) == 3.30886
    assert validation._edge_eta(0.0, 1.0, spec) == 1.4434


# ---------------------------------------------------------------------------------------------
# Interrupted
# ---------------------------------------------------------------------------------------------
@pytest.mark.slow
def test_interrupted_bench_keeps_the_references_and_resumes(tmp_path, monkeypatch):
    """Ctrl-C while the references are computed: one line naming what is kept, exit 130, each
    finished reference in reference_cache.partial.npz, no report file; building the set again
    computes only the references still missing, then keeps the whole set and drops the partial
    file."""
    out = tmp_path / "bench"
    spec = workprecision.QUICK.spec
    proc = start_cli("bench", "--quick", "-o", out)
    wait_until(proc, lambda: validation.partial_count(spec, out) >= 2)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    lines = [ln for ln in err.strip().splitlines() if "error" in ln or "Traceback" in ln]
    kept = validation.partial_count(spec, out)
    partial = out / validation.PARTIAL_NAME
    assert lines == [f"cosserat-channel: error: interrupted; the references of {kept} candidate "
                     f"points are kept in {partial}: run the same command again to continue "
                     "from them"], err
    assert sorted(p.name for p in out.iterdir()) == [validation.PARTIAL_NAME]

    computed = []
    real = validation._reference_point

    def counting(p):
        computed.append(p)
        return real(p)

    monkeypatch.setattr(validation, "_reference_point", counting)
    said = []
    vs = validation.get(spec, out, said.append)
    assert any(f"resuming from {partial} ({kept} candidates done before)" in m for m in said)
    assert len(computed) == vs.counts["candidates"] - kept
    assert sorted(p.name for p in out.iterdir()) == [validation.CACHE_NAME]
    assert "the reference set is kept in" in workprecision.kept(out, quick=True)
    assert validation.load(spec, out / validation.CACHE_NAME).size == vs.size


@pytest.mark.slow
def test_kept_says_what_an_interrupted_run_left(tmp_path, quick):
    """Nothing, the references of some candidates, or the whole set (the quick report's)."""
    assert workprecision.kept(tmp_path, quick=True) == "no reference was finished, nothing is kept"
    assert "reference set is kept" in workprecision.kept(quick[0], quick=True)
    assert "no reference" in workprecision.kept(quick[0], quick=False)  # another set
