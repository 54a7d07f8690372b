"""Every output a command writes under a name the user gives (figures of ``--plot`` and of
``plot``/``phase-plane``, ``query -o`` in each format, ``boundary -o``, ``example -o``) is
published without replacing: a file that appears at that name while the command works (after
it checked the name was free) is kept as it is, the new output is kept beside it
(``NAME.new.EXT``), one line, exit 1; with ``--overwrite`` it is replaced as asked."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from cosserat_channel import cli, files
from test_faults_publish import FIT_DATA, SWEEP

THEIRS = b"someone else's file"


def _appears(monkeypatch, target: Path) -> None:
    """Make ``target`` appear (someone else's file) just as the command starts writing it."""
    real = files.temp_path

    def temp(directory, path):
        if os.path.abspath(path) == os.path.abspath(target) and not target.exists():
            target.write_bytes(THEIRS)
        return real(directory, path)

    monkeypatch.setattr(files, "temp_path", temp)


def _check_kept(capsys, target: Path, code: int) -> None:
    assert code == 1
    err = [line for line in capsys.readouterr().err.splitlines() if "error:" in line]
    beside = target.with_name(target.stem + ".new" + target.suffix)
    assert len(err) == 1 and "appeared while" in err[0] and str(beside) in err[0], err
    assert target.read_bytes() == THEIRS
    assert beside.stat().st_size > 0 and beside.read_bytes() != THEIRS


@pytest.fixture
def result(tmp_path):
    sweep = tmp_path / "s.toml"
    sweep.write_text(SWEEP)
    out = tmp_path / "r.nc"
    assert cli.main(["run", str(sweep), "-o", str(out), "--workers", "1"]) == 0
    return out


POINT = ["--eps", "1/30", "--L", "10", "--K", "0.5", "--A", "1/3", "--N", "1"]


@pytest.mark.parametrize("name, argv", [
    ("p.png", lambda out, r: ["point", *POINT, "--plot", out]),
    ("pp.png", lambda out, r: ["phase-plane", "--eps", "1/30", "--L", "10", "--A", "1/3",
                               "--N", "1", "-o", out]),
    ("b.nc", lambda out, r: ["boundary", "--A", "0.3333", "--N", "2", "-o", out]),
    ("b.png", lambda out, r: ["boundary", "--A", "0.3,0.4", "--N", "2", "--plot", out]),
    ("q.csv", lambda out, r: ["query", r, "--format", "csv", "-o", out]),
    ("q.json", lambda out, r: ["query", r, "--format", "json", "-o", out]),
    ("q.nc", lambda out, r: ["query", r, "--format", "netcdf", "-o", out]),
    ("m.png", lambda out, r: ["plot", r, "--x", "eps", "--y", "Delta", "--at", "L=5", "-o",
                             out]),
    ("e.toml", lambda out, r: ["example", "quickstart", "-o", out]),
])
def test_an_output_appearing_meanwhile_is_kept(tmp_path, monkeypatch, capsys, result, name,
                                               argv):
    target = tmp_path / name
    args = argv(str(target), str(result))
    _appears(monkeypatch, target)
    _check_kept(capsys, target, cli.main(args))
    # Asked to replace it, the command does.
    monkeypatch.undo()
    assert cli.main([*args, "--overwrite"]) == 0
    assert target.read_bytes() != THEIRS


def test_a_fit_figure_appearing_meanwhile_is_kept(tmp_path, monkeypatch, capsys):
    from cosserat_channel import solve_point

    d = [solve_point(e, 10.0, 5.0, 1 / 3, 1.0).Delta for e in (0.01, 0.02, 0.05)]
    data = tmp_path / "data.csv"
    data.write_text(FIT_DATA.format(d1=d[0], d2=d[1], d3=d[2]))
    target = tmp_path / "fit.png"
    _appears(monkeypatch, target)
    code = cli.main(["fit", str(data), "--free", "L", "--fixed", "K=5,A=1/3,N=1",
                     "--plot", str(target)])
    _check_kept(capsys, target, code)
