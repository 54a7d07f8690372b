"""The stability report: `cosserat-channel stability --quick`, its table and figure.

Timings are not checked (the machine is shared); files, table columns, statuses, paths, the
verdict and the figure's artists are.
"""

import json
import math
import signal

import pytest

from cosserat_channel import cli
from cosserat_channel.measure import stability
from cosserat_channel.plot.stability import stability_figure
from support import start_cli, wait_until, without_heartbeat

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def report_dir(tmp_path_factory):
    """`cosserat-channel stability --quick -o DIR` run once, in process."""
    out = tmp_path_factory.mktemp("stab") / "report"
    code = cli.main(["stability", "--quick", "-o", str(out)])
    assert code == 0
    return out


@pytest.fixture(scope="module")
def quick_report():
    """The quick report as data (no files)."""
    return stability.build_report(quick=True, repeats=1)


def _table(md):
    lines = [ln for ln in md.splitlines() if ln.startswith("|")]
    header = [c.strip() for c in lines[0].strip("|").split("|")]
    rows = [dict(zip(header, (c.strip() for c in ln.strip("|").split("|")))) for ln in lines[2:]]
    return header, rows


def test_cli_writes_markdown_and_png(report_dir):
    """Both files exist; the PNG is a PNG; the markdown has the table and a verdict."""
    md = (report_dir / "stability.md").read_text()
    assert (report_dir / "stability.png").read_bytes()[:8] == PNG_SIGNATURE
    header, rows = _table(md)
    assert tuple(header) == stability.COLUMNS
    assert len(rows) >= 5
    assert "## Verdict" in md and "cost at eta = 1e-06 / cost at eta = 0.3" in md
    etas = [float(r["eta"]) for r in rows if r["case"] == "sweep"]
    assert min(etas) == pytest.approx(1e-8)
    # Every row says which path stage 1 took (none for A = -1 and regimes without a solution).
    assert {r["path"] for r in rows} <= {"explicit", "stiff", "none"}
    assert {"explicit", "stiff"} <= {r["path"] for r in rows}
    assert not any("(ref:" in r["status"] for r in rows)


def test_cli_leaves_no_temporary_files(report_dir):
    """The markdown and the figure are written atomically, with nothing left beside them."""
    assert sorted(p.name for p in report_dir.iterdir()) == ["stability.md", "stability.png"]


def test_report_rows_and_verdict(quick_report):
    """Small eta takes the stiff path, eta = 0.3 the explicit one; the acceptance ratios hold."""
    rows = {(r["case"], r["eta"]): r for r in quick_report.rows}
    assert rows[("sweep", 1e-8)]["path"] == "stiff"
    assert rows[("sweep", 0.3)]["path"] == "explicit"
    for r in quick_report.rows:
        if r["case"] == "sweep":
            assert r["status"] == "ok"
            # Away from the edges: within 30 rtol of the reference (measured <= ~20 rtol).
            assert r["err_Delta"] < 30 * stability.RTOL and r["err_m_wall"] < 30 * stability.RTOL
    edge = [r for r in quick_report.rows if r["case"].startswith("eps_too_large_path")]
    assert edge and edge[0]["status"] == "eps_too_large_path"
    am1 = [r for r in quick_report.rows if r["A"] == -1.0]
    assert am1 and am1[0]["ref"] == "closed form" and am1[0]["err_Delta"] < 1e-6
    v = quick_report.verdict["series"][(1 / 3, 1.0)]
    # Steps are deterministic; the cost ratio is a timing, so it is only checked to be sane here.
    assert v["flat_pass"] and abs(v["stiff_slope"]) < 0.1
    assert 0 < v["cost_ratio"] < 1000


def test_feasible_eta_max_brackets_the_edge():
    """The bisected edge is ok just below and not ok just above."""
    from cosserat_channel.solver import point as sv

    eta_max, beyond = stability.feasible_eta_max(1 / 3, 1.0)
    ws = sv.Workspace()
    assert ws.run(eta_max, 1 / 3, 1.0, 1e-8, 1e-12) == 0
    assert ws.run(eta_max * (1 + 1e-9), 1 / 3, 1.0, 1e-8, 1e-12) != 0
    assert beyond == "eps_too_large_path"
    assert 3.2 < eta_max < 3.4  # paper: no solution at eps = 0.33 with L = 10 (we find 0.3309)
    assert stability.feasible_eta_max(2.0, 3.0)[1] is None  # A > 1: feasible up to the cap


def test_figure_artists(quick_report):
    """Three log-log panels with labelled axes, one line per series, path legend and rtol line."""
    fig = stability_figure(quick_report)
    ax_s, ax_t, ax_e = fig.axes[:3]
    for ax in (ax_s, ax_t, ax_e):
        assert ax.get_xscale() == "log" and ax.get_yscale() == "log"
        assert r"\varepsilon L" in ax.get_xlabel()
        assert ax.get_ylabel()
    assert len(ax_s.get_lines()) == 2  # stage 1 and stage 2 steps of the one quick series
    labels_t = [t.get_text() for t in ax_t.get_legend().get_texts()]
    assert any("stiff path" in t for t in labels_t) and any("explicit path" in t for t in labels_t)
    labels_e = [t.get_text() for t in ax_e.get_legend().get_texts()]
    assert any("rtol" in t for t in labels_e)
    assert "L$ = 10" in fig._suptitle.get_text() and "rtol" in fig._suptitle.get_text()


def test_unwritable_directory_is_one_line_exit_2(tmp_path, capsys):
    """-o under a regular file: one error line, exit 2, no work done."""
    blocker = tmp_path / "file"
    blocker.write_text("x")
    code = cli.main(["stability", "--quick", "-o", str(blocker / "sub")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("cosserat-channel: error: -o/--output")
    code = cli.main(["stability", "--quick", "-o", str(blocker)])
    assert code == 2 and "not a directory" in capsys.readouterr().err


def test_markdown_formats_nan_as_dash():
    """Rows without a solution print '-' for errors and D_wall, not 'nan'."""
    row = {c: math.nan for c in stability.COLUMNS}
    row.update(case="x", A=0.5, N=1.0, eta=1.0, status="eps_too_large_axis", path="none",
               s1_acc=0, s1_rej=0, s2_acc=0, s2_rej=0, fev=0, us=1.0, ref="-")
    rep = stability.Report(rows=[row], verdict=stability.verdict([row]))
    md = stability.markdown(rep)
    assert "nan" not in md.split("## Verdict")[0]


def _partial_rows(path):
    try:
        return len(json.loads(path.read_text())["rows"])
    except (OSError, ValueError):
        return 0


@pytest.mark.slow
@pytest.mark.parametrize("sig, code, word", [(signal.SIGINT, 130, "interrupted"),
                                             (signal.SIGTERM, 143, "terminated")],
                         ids=["SIGINT", "SIGTERM"])
def test_interrupted_report_keeps_its_rows_and_resumes(tmp_path, monkeypatch, capsys, sig, code,
                                                       word):
    """Ctrl-C or SIGTERM after two rows: one line naming what is kept, exit 130 or 143, the rows
    in stability.partial.json; the same command again measures only the rows still missing,
    writes the report and removes the partial file."""
    out = tmp_path / "report"
    partial = out / stability.PARTIAL_NAME
    proc = start_cli("stability", "--quick", "-o", out)
    wait_until(proc, lambda: _partial_rows(partial) >= 2)
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == code, err
    lines = without_heartbeat(err.strip(), "stability")  # past a minute (a cold cache): its beat
    assert len(lines) == 1 and "Traceback" not in err, err
    kept = _partial_rows(partial)
    assert lines[0] == (f"cosserat-channel: error: {word}; the {kept} rows measured so far are kept "
                        f"in {partial}: run the same command again to continue from them")
    assert sorted(p.name for p in out.iterdir()) == [stability.PARTIAL_NAME]

    measured = []
    real = stability.measure

    def counting(case, *args, **kw):
        measured.append(case)
        return real(case, *args, **kw)

    monkeypatch.setattr(stability, "measure", counting)
    assert cli.main(["stability", "--quick", "-o", str(out)]) == 0
    md = (out / "stability.md").read_text()
    rows = _table(md)[1]
    assert len(measured) == len(rows) - kept
    assert f"{kept} of the {len(rows)} rows were measured by an interrupted run" in md
    assert sorted(p.name for p in out.iterdir()) == ["stability.md", "stability.png"]


def test_partial_rows_of_other_settings_are_not_taken(tmp_path):
    """Rows kept by a run with other settings (or other sources) are measured again."""
    path = tmp_path / stability.PARTIAL_NAME
    row = {c: 1.0 for c in stability.COLUMNS}
    row.update(case="sweep", eta=1e-8, A=1 / 3, N=1.0)
    key = stability._run_key(True, 1)
    path.write_text(json.dumps({"key": key, "rows": [row]}))
    assert stability.kept(tmp_path, True, 1) == 1
    assert stability.kept(tmp_path, True, 5) == 0
    assert stability.kept(tmp_path, False, 1) == 0
    path.write_text(json.dumps({"key": dict(key, sources="0" * 12), "rows": [row]}))
    assert stability.kept(tmp_path, True, 1) == 0
    path.write_text("not json")
    assert stability.kept(tmp_path, True, 1) == 0


def test_stiff_set_at_rtol_1e_6_within_100_rtol():
    """The stiff rows of the quick report solved at rtol 1e-6 (``rtol=``): every ok row away from
    the path edge within 100 rtol of its reference in Delta and m_wall (was 350 and 80 rtol at
    eta = 1e-6 before the stiff path's turn onto the wall was marched again)."""
    rep = stability.build_report(quick=True, repeats=1, rtol=1e-6)
    assert rep.rtol == 1e-6
    stiff = [r for r in rep.rows if r["case"] == "sweep" and r["eta"] <= 1e-6]
    assert {r["eta"] for r in stiff} == {1e-8, 1e-6} and all(r["path"] == "stiff" for r in stiff)
    for r in stiff:
        assert r["err_Delta"] < 100 * 1e-6 and r["err_m_wall"] < 100 * 1e-6, r
    assert rep.verdict["max_err_over_rtol"] < 100
