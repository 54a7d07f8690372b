"""Numbers and homes at the edges: a fraction beyond every double, a read-only cache home.

Each ends in the right answer or one line naming what is wrong, exit 2 (or 1 where the
environment, not the input, is at fault), nothing written.
"""

from __future__ import annotations

import math
import os
import tracemalloc

import pytest

from cosserat_channel import cli
from cosserat_channel.parameters import parse_number


@pytest.mark.parametrize("text, value", [
    ("1e400/1", math.inf), ("-1e400/1", -math.inf), ("1/1e-400", math.inf),
    ("1e-400/1", 0.0), ("1e99999999/1e99999999", 1.0), ("-3e99999999/1e99999999", -3.0),
    ("1e-99999999/1", 0.0), ("1/30", 1 / 30), ("2e308/2e308", 1.0),
])
def test_fractions_beyond_every_double_are_rounded_not_raised(text, value):
    assert parse_number(text) == value
    assert _peak_bytes(lambda: parse_number(text)) < NEVER_BUILT


# 10**99999999 is an int of 41 MB (and its gcd with another takes hours): the parser never
# builds it, which its peak allocation shows on any machine however slow or loaded (a bound of
# time did not).
NEVER_BUILT = 1 << 20


def _peak_bytes(f) -> int:
    """The peak of Python's allocations while ``f()`` runs (once before, so that what it
    imports or caches on a first call is not counted)."""
    f()
    tracemalloc.start()
    try:
        f()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


@pytest.mark.parametrize("text", ["1/0", "0/0", "1e400/0", "nan/1", "1/1e99999999x", "snan/1"])
def test_fractions_without_a_value_are_refused(text):
    with pytest.raises(ValueError):
        parse_number(text)


@pytest.mark.parametrize("argv, words", [
    (["point", "--eps", "1e400/1", "--L", "10", "--K", "5", "--A", "1/3", "--N", "1"], "eps"),
    (["point", "--eps", "1e99999999/1e99999998", "--L", "10", "--K", "5", "--A", "1/3",
      "--N", "1"], "eps"),
])
def test_overflowing_fractions_on_the_command_line_are_one_line(argv, words, capsys):
    assert cli.main(argv) == 2
    err = capsys.readouterr().err.splitlines()
    assert len(err) == 1 and words in err[0] and "Traceback" not in err[0], err


def test_overflowing_fractions_in_fit_data_are_one_line(tmp_path, capsys):
    data = tmp_path / "d.csv"
    data.write_text("quantity,value,std_error,eps\nDelta,1e400/1,0.05,0.01\nDelta,12,0.05,0.02\n")
    code = cli.main(["fit", str(data), "--free", "L", "--fixed", "K=5,A=1/3,N=1"])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and "row 1" in err[0] and "value" in err[0], err


def test_a_fraction_of_huge_exponents_in_fit_data_is_read_at_once(tmp_path):
    from cosserat_channel.calibrate.data import read_data

    data = tmp_path / "d.csv"
    data.write_text("quantity,value,std_error,eps\nDelta,1e99999999/1e99999999,0.05,0.01\n")
    assert read_data(data).value.tolist() == [1.0]
    assert _peak_bytes(lambda: read_data(data)) < NEVER_BUILT


@pytest.mark.parametrize("option", ["--fixed", "--start", "--bounds"])
def test_overflowing_fractions_in_fit_options_are_one_line(tmp_path, capsys, option):
    data = tmp_path / "d.csv"
    data.write_text("quantity,value,std_error,eps\nDelta,17,0.05,0.01\nDelta,12,0.05,0.02\n")
    value = {"--fixed": "K=1e400/1,A=1/3,N=1", "--start": "L=1e400/1",
             "--bounds": "L=1e400/1:1e401/1"}[option]
    argv = ["fit", str(data), "--free", "L", option, value]
    if option != "--fixed":
        argv += ["--fixed", "K=5,A=1/3,N=1"]
    code = cli.main(argv)
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and "Traceback" not in err[0], err


@pytest.mark.skipif(hasattr(os, "geteuid") and os.geteuid() == 0,
                    reason="root writes into read-only directories")
def test_atlas_cache_in_a_read_only_home_is_one_line(tmp_path, monkeypatch, capsys):
    home = tmp_path / "home"
    home.mkdir()
    home.chmod(0o500)
    monkeypatch.setenv("XDG_CACHE_HOME", str(home))
    try:
        code = cli.main(["atlas", "--cache", "--A=0.3:0.4", "--N=1:1.1", "--tol", "1e-3"])
    finally:
        home.chmod(0o700)
    err = capsys.readouterr().err.splitlines()
    assert code == 1 and len(err) == 1 and "XDG_CACHE_HOME" in err[0], err
    assert list(home.iterdir()) == []


def test_atlas_cache_where_a_file_blocks_the_directory_is_one_line(tmp_path, monkeypatch,
                                                                     capsys):
    """A regular file where the cache directory should be (what a read-only home does for
    root as well): one line, nothing touched."""
    home = tmp_path / "home"
    home.mkdir()
    (home / "cosserat-channel").write_text("a file of the user's")
    monkeypatch.setenv("XDG_CACHE_HOME", str(home))
    code = cli.main(["atlas", "--cache", "--A=0.3:0.4", "--N=1:1.1", "--tol", "1e-3"])
    err = capsys.readouterr().err.splitlines()
    assert code == 1 and len(err) == 1 and "XDG_CACHE_HOME" in err[0], err
    assert (home / "cosserat-channel").read_text() == "a file of the user's"


def test_a_csv_cell_beyond_the_field_limit_is_one_line(tmp_path, capsys):
    data = tmp_path / "d.csv"
    data.write_text("quantity,value,std_error,eps\nDelta,17,0.05,0.01\n"
                    f"Delta,{'1' * 200_000},0.05,0.02\n")
    code = cli.main(["fit", str(data), "--free", "L", "--fixed", "K=5,A=1/3,N=1"])
    err = capsys.readouterr().err.splitlines()
    assert code == 2 and len(err) == 1 and "line 3" in err[0], err
