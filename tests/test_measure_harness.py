"""measure/harness.py: best-of timing, verdict wording, the header and the JSON record."""

import json
import math
import os
import stat

import numpy as np
import pytest

from cosserat_channel.measure import harness, machine


class FakeClock:
    """A clock that only the timed calls move forward."""

    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_best_of_keeps_the_fastest_repeat_per_call():
    """Repeats of 3, 1 and 2 s (two calls each): 0.5 s per call, every repeat listed, and the
    result is what the last call returned."""
    clock = FakeClock()
    costs = iter([1.5, 1.5, 0.5, 0.5, 1.0, 1.0])
    calls = []

    def call():
        clock.now += next(costs)
        calls.append(1)
        return len(calls)

    t = harness.best_of(call, 3, inner=2, clock=clock)
    assert t.seconds == 0.5 and t.times == (1.5, 0.5, 1.0) and t.result == 6


def test_best_of_sets_inner_from_a_first_call():
    """A call of 1 ms with min_seconds 10 ms: one untimed call, then 10 calls per timing (capped
    by max_inner)."""
    clock = FakeClock()
    n = [0]

    def call():
        clock.now += 1e-3
        n[0] += 1

    t = harness.best_of(call, 2, min_seconds=10e-3, clock=clock)
    assert n[0] == 1 + 2 * 10 and math.isclose(t.seconds, 1e-3)
    n[0] = 0
    harness.best_of(call, 2, min_seconds=10e-3, max_inner=4, clock=clock)
    assert n[0] == 1 + 2 * 4


def test_verdict_words_notes_and_requirement():
    """PASS/FAIL/NOT MEASURED; a note qualifies a PASS without changing it; an informative
    target is never missed."""
    assert [harness.word(p) for p in (True, False, None, np.bool_(True))] == \
        ["PASS", "FAIL", "NOT MEASURED", "PASS"]
    v = harness.Verdict("error <= 100 rtol", True, "ratio 1e-5", note="more accurate than the band")
    assert v.line() == "PASS (more accurate than the band): error <= 100 rtol: ratio 1e-5"
    assert v.line(bold=True).startswith("**PASS (more accurate than the band)**: ")
    assert harness.Verdict("x", False).missed
    assert not harness.Verdict("x", False, required=False).missed
    assert not harness.Verdict("x", None).missed


def test_record_writes_header_numbers_and_verdicts_as_json(tmp_path, capsys):
    """The JSON holds the machine header (the same CPU, cores and commit as machine.py says),
    the numbers (numpy made plain, NaN as null) and each verdict."""
    path = tmp_path / "out.json"
    rec = harness.Record("bench_x", str(path), argv=["bench_x.py", "--json", str(path)],
                         dask="9.9")
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith("command:  ") and printed[0].endswith(f"bench_x.py --json {path}")
    assert printed[2] == f"machine:  {machine.machine()}"
    assert printed[3].startswith("versions: cosserat-channel ") and printed[3].endswith(", dask 9.9")
    rec.add("us_per_point", np.float64(12.5))
    rec.row("rows", eta=0.3, err=math.nan, steps=np.int64(7))
    rec.row("rows", eta=np.array([1.0, 2.0]), err=1e-9, steps=3)
    v = rec.check("peak RSS < 1 GiB", np.bool_(False), "1.2 GiB")
    assert v.word == "FAIL" and rec.finish() == 0
    d = json.loads(path.read_text())
    assert d["benchmark"] == "bench_x"
    h = d["header"]
    assert h["machine"] == {"cpu": machine.cpu_model(), "cores": os.cpu_count(),
                            "os": machine.os_name()}
    assert h["commit"] == machine.git_revision() == h["versions"]["git"]
    assert h["versions"]["dask"] == "9.9" and h["versions"]["numpy"] == np.__version__
    assert d["results"] == {"us_per_point": 12.5,
                            "rows": [{"eta": 0.3, "err": None, "steps": 7},
                                     {"eta": [1.0, 2.0], "err": 1e-9, "steps": 3}]}
    assert d["verdicts"] == [{"target": "peak RSS < 1 GiB", "verdict": "FAIL", "passed": False,
                              "required": True, "note": "", "detail": "1.2 GiB"}]
    assert [p.name for p in tmp_path.iterdir()] == ["out.json"]  # written atomically


def test_record_without_json_writes_nothing(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rec = harness.Record("bench_x", None, echo=False)
    rec.add("x", 1.0)
    assert rec.finish() == 0 and not list(tmp_path.iterdir())


def test_json_path_is_checked_before_any_work(tmp_path, capsys):
    """A missing directory and a directory are refused; an existing file is kept unless
    --overwrite; a FIFO and a device node take the JSON as a stream (never renamed over)."""
    ap = harness.parser("A benchmark.\n\nMore text.")
    assert ap.description == "A benchmark."
    new = tmp_path / "new.json"
    assert ap.parse_args(["--json", str(new)]).json == str(new)
    existing = tmp_path / "old.json"
    existing.write_text("{}")
    for bad in ([str(tmp_path / "no" / "x.json")], [str(tmp_path)], [str(existing)]):
        with pytest.raises(SystemExit) as exit_:
            ap.parse_args(["--json", *bad])
        assert exit_.value.code == 2
        assert "--json: " in capsys.readouterr().err
    assert ap.parse_args(["--json", str(existing), "--overwrite"]).overwrite
    assert existing.read_text() == "{}"
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    assert ap.parse_args(["--json", str(fifo)]).json == str(fifo)
    assert fifo.is_fifo()


def test_json_into_a_device_is_a_stream(tmp_path):
    """The record goes into a character device; the node stays a node."""
    node = tmp_path / "null"
    try:
        os.mknod(node, 0o600 | stat.S_IFCHR, os.makedev(1, 3))  # a private /dev/null
    except PermissionError:
        pytest.skip("making a device node needs root")
    assert harness.json_problem(str(node)) is None
    rec = harness.Record("bench_x", str(node), echo=False)
    rec.add("x", 1.0)
    assert rec.finish() == 0
    assert node.is_char_device() and [p.name for p in tmp_path.iterdir()] == ["null"]
