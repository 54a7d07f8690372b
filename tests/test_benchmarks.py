"""benchmarks/: every script takes --json, the index lists the whole suite, each calibration probe
names constants that exist, and one benchmark writes its JSON record end to end."""

import ast
import json
import pathlib
import re
import runpy
import sys

import pytest

from cosserat_channel.solver import stage1

BENCHMARKS = pathlib.Path(__file__).resolve().parent.parent / "benchmarks"
# Every script but fingerprint.py, which uses public entry points only (it must run unchanged
# on either side of a restructuring).
SCRIPTS = sorted(p for p in BENCHMARKS.glob("*.py") if p.name != "fingerprint.py")
PROBES = sorted((BENCHMARKS / "probes").glob("probe_*.py"))


def _main(path):
    """The script's ``main``, loaded without running it."""
    return runpy.run_path(str(path), run_name="benchmark_under_test")["main"]


def test_the_suite_is_there():
    assert len(SCRIPTS) >= 8 and len(PROBES) >= 2
    assert not list(BENCHMARKS.glob("probe_*.py"))  # probes live apart from the benchmarks


@pytest.mark.parametrize("path", SCRIPTS, ids=lambda p: p.name)
def test_every_benchmark_offers_json(path, monkeypatch, capsys):
    """``--help`` answers (exit 0) and offers ``--json PATH``."""
    main = _main(path)
    monkeypatch.setattr(sys, "argv", [str(path), "--help"])
    with pytest.raises(SystemExit) as exit_:
        main()
    assert exit_.value.code == 0
    assert "--json PATH" in capsys.readouterr().out


def test_the_index_lists_every_benchmark_and_probe():
    text = (BENCHMARKS / "README.md").read_text()
    for path in SCRIPTS:
        assert f"`{path.name}`" in text, path.name
    for path in PROBES:
        assert f"| `probes/{path.name}` |" in text, path.name


@pytest.mark.parametrize("path", PROBES, ids=lambda p: p.name)
def test_each_probe_names_the_constants_it_calibrates(path):
    """The docstring's ``Calibrates:`` paragraph names constants of solver.stage1 that exist."""
    doc = ast.get_docstring(ast.parse(path.read_text()))
    para = re.search(r"^Calibrates: (.*?)(?:\n\n|\Z)", doc, re.M | re.S)
    assert para, f"{path.name}: no 'Calibrates:' paragraph"
    names = re.findall(r"``(?:cosserat_channel\.solver\.stage1\.)?([A-Z][A-Z0-9_]+)``", para.group(1))
    assert names, para.group(1)
    for name in names:
        assert isinstance(getattr(stage1, name), (int, float)), name


def test_plug_edge_benchmark_writes_its_json_record(tmp_path, monkeypatch, capsys):
    """A small run of bench_plug_edge: the printed header and a JSON record with the three cases,
    each a cost per root, and the target's verdict."""
    out = tmp_path / "plug.json"
    main = _main(BENCHMARKS / "bench_plug_edge.py")
    monkeypatch.setattr(sys, "argv", ["bench_plug_edge.py", "--values", "2000", "--repeat", "1",
                                      "--json", str(out)])
    assert main() == 0
    printed = capsys.readouterr().out
    assert printed.startswith("command:  ") and "\nmachine:  " in printed
    d = json.loads(out.read_text())
    assert d["benchmark"] == "bench_plug_edge"
    assert {"command", "date", "machine", "commit", "versions"} <= set(d["header"])
    cases = d["results"]["cases"]
    assert [(c["eta"], c["A"], c["N"]) for c in cases] == [(1 / 3, 1 / 3, 1.0), (0.01, 1 / 3, 1.0),
                                                           (3.0, 2.0, 2.0)]
    assert all(c["values"] == 2000 and isinstance(c["us_per_root"], float) for c in cases)
    (v,) = d["verdicts"]
    assert v["verdict"] in ("PASS", "FAIL") and v["target"].startswith("plug-edge root")
    assert v["verdict"] in printed


def test_the_atlas_check_finds_a_transition_moved_beyond_its_stated_error():
    """bench_atlas's independent check of the shipped atlas at the paper's point: eta_max within
    1e-8 of a scipy bisection, every gap decided as scipy decides it; the same transition moved
    by 1e-6 is reported beyond tol and beyond the atlas's stated uncertainty, and the gap it
    opens decided wrongly against both references; next to A = -1, where the atlas states its
    eta_max no closer than a factor e, it is within that statement."""
    import numpy as np

    from cosserat_channel import atlas as at

    check = runpy.run_path(str(BENCHMARKS / "bench_atlas.py"),
                           run_name="benchmark_under_test")["_independent_point"]
    atlas = at.default_atlas()[0]
    lo, hi = atlas.eta_range

    def work(a, n, shift=1.0):
        leaf, low, eta, _ = atlas.transitions(np.array([a]), np.array([n]))
        k = max(int(leaf[0]), 0)
        return (a, n, int(low[0]), eta[0] * shift, atlas.leaf_transition_error[k],
                atlas.undecided_band(leaf)[0])

    lines, rels, within, counts, _ = check(work(1 / 3, 1.0), lo, hi, 1e-8)
    assert len(rels) == 1 and rels[0] <= 1e-8 and within == [] and lines == []
    assert counts == {"fresh": 0, "scipy": 0, "missing": 0, "coarse": 0, "timeout": 0}
    lines, rels, within, counts, _ = check(work(1 / 3, 1.0, 1 + 1e-6), lo, hi, 1e-8)
    assert abs(rels[0] - 1e-6) < 1e-8 and within == [False]
    assert any("beyond tol" in line for line in lines)
    assert counts["fresh"] == counts["scipy"] == 1  # the gap between it and the true edge
    lines, rels, within, counts, _ = check(work(-0.999, 2.2), lo, hi, 1e-8)
    assert counts["coarse"] == 1 and rels[0] > 1 and within == [True]
