"""The fit command: its result is the API's, bad data and outputs are refused in one line with
exit code 2 before anything is written, and warnings are one line each."""

import json
import pathlib

import pytest

import cosserat_channel
from cosserat_channel import cli
from cosserat_channel.calibrate import fit

EXAMPLES = pathlib.Path(cosserat_channel.__file__).parent / "examples"
PROFILE = str(EXAMPLES / "fit_profile.csv")
ARGS = ["fit", PROFILE, "--free", "L,K", "--fixed", "A=1/3,N=1"]
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def test_fit_writes_the_api_result(tmp_path, capsys):
    """-o holds the API's estimates and errors to the bit, --plot a PNG; the table names them."""
    out, png = tmp_path / "fit.json", tmp_path / "fit.png"
    code = cli.main([*ARGS, "-o", str(out), "--plot", str(png)])
    stdout, stderr = capsys.readouterr()
    assert code == 0, stderr
    assert "error" not in stderr and "warning" not in stderr  # (a first run's progress may show)
    api = fit(PROFILE, "L,K", {"A": 1 / 3, "N": 1})
    data = json.loads(out.read_text())
    assert data["estimates"] == api.params
    assert data["std_errors"] == api.errors
    assert data["dof"] == 18 and len(data["rows"]) == 20
    assert png.read_bytes().startswith(PNG_SIGNATURE)
    assert stdout.splitlines()[1].split()[:2] == ["L", f"{api.params['L']:.8g}"]
    assert cli.main([*ARGS, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["estimates"] == api.params


def test_bad_data_is_one_line_and_writes_nothing(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("quantity,value,std_error,xi,eps\nu_over_u0,0.9,0.01,0.5,1/30\n"
                   "u_over_u0,0.8,0,0.9,1/30\n")
    out = tmp_path / "fit.json"
    code = cli.main(["fit", str(bad), "--free", "L,K", "--fixed", "A=1/3,N=1", "-o", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("cosserat-channel: error: ")
    assert "row 2 (line 3), column 'std_error'" in err
    assert not out.exists()


@pytest.mark.parametrize("extra,expected", [
    (["--fixed", "A"], "--fixed: expected NAME=VALUE"),
    (["--bounds", "L=1"], "--bounds L: expected LO:HI"),
    (["--start", "L=x"], "--start L: not a number"),
    (["--bounds", "Q=1:2"], "bounds: 'Q' is not a free input"),
])
def test_bad_options(capsys, extra, expected):
    code = cli.main([*ARGS, *extra])
    err = capsys.readouterr().err
    assert code == 2 and expected in err and err.count("\n") == 1


def test_outputs_are_checked_before_the_fit(tmp_path, capsys):
    """An existing -o is kept without --overwrite, and -o or --plot naming the input is refused."""
    out = tmp_path / "fit.json"
    out.write_text("keep")
    assert cli.main([*ARGS, "-o", str(out)]) == 2
    assert "exists" in capsys.readouterr().err
    assert out.read_text() == "keep"
    assert cli.main([*ARGS, "-o", str(out), "--overwrite"]) == 0
    assert json.loads(out.read_text())["free"] == ["L", "K"]
    copy = tmp_path / "data.csv"
    copy.write_text(pathlib.Path(PROFILE).read_text())
    for option in ("-o", "--plot"):
        code = cli.main(["fit", str(copy), "--free", "L,K", "--fixed", "A=1/3,N=1", option,
                         str(copy), "--overwrite"])
        assert code == 2
        assert "is this command's input" in capsys.readouterr().err
    assert copy.read_text() == pathlib.Path(PROFILE).read_text()


def test_warnings_are_lines_of_their_own(capsys):
    code = cli.main([*ARGS, "--bounds", "L=1:8"])
    err = capsys.readouterr().err
    assert code == 0
    assert err.startswith("cosserat-channel: warning: L = 8 is at its upper bound 8")
    assert err.count("\n") == 1


def test_help_shows_the_csv_format(capsys):
    assert cli.main(["fit", "--help"]) == 0
    out = capsys.readouterr().out
    assert "quantity,value,std_error,xi,eps" in out
    assert "u_over_u0" in out and "sigma_xx_wall_Pa" in out and "delta_w" in out


def test_output_to_a_device_streams_and_keeps_it(tmp_path, capsys):
    """-o naming a character device (a private null device) receives the JSON as a stream and
    stays a device; nothing is created beside it."""
    import os
    import stat

    if os.geteuid() != 0:
        pytest.skip("mknod needs root")
    dev = tmp_path / "null"
    os.mknod(dev, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
    assert cli.main([*ARGS, "-o", str(dev)]) == 0
    assert stat.S_ISCHR(os.stat(dev).st_mode)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["null"]
