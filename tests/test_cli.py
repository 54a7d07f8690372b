"""The command line: output formats, exit codes and one-line errors (in-process, one subprocess)."""

import json
import math
import os
import shutil
import subprocess
import sys

import pytest

from cosserat_channel import cli
from cosserat_channel.solve import solve_point

# Paper figure 2: eps = 1/30, L = 10, K = 0.5, A = 1/3, N = 1. str() of a float round-trips, so
# the command line sees exactly the floats the API call below gets.
FIG2 = (1 / 30, 10.0, 0.5, 1 / 3, 1.0)
FIG2_ARGS = ["--eps", str(1 / 30), "--L", "10", "--K", "0.5", "--A", str(1 / 3), "--N", "1"]
MATERIAL_ARGS = ["--d-p", "0.002", "--rho-p", "2940", "--phi", "25"]
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def _point_args(**override):
    """``point`` arguments for figure 2 with some options replaced (value None drops it)."""
    values = dict(zip(["--eps", "--L", "--K", "--A", "--N"], FIG2_ARGS[1::2]))
    values.update(override)
    args = ["point"]
    for flag, value in values.items():
        if value is not None:
            args += [flag, value]
    return args


@pytest.fixture(scope="module")
def fig2_result():
    """The API's answer for figure 2, to compare the command line against."""
    return solve_point(*FIG2)


def test_json_output_matches_api(capsys, fig2_result):
    """--json prints one JSON object with status ok and the API's Delta."""
    code = cli.main(["point", *FIG2_ARGS, "--json"])
    out, err = capsys.readouterr()
    assert code == 0
    assert err == ""
    data = json.loads(out)
    assert data["status"] == "ok"
    assert data["message"] == fig2_result.status.message
    assert math.isclose(data["Delta"], fig2_result.Delta, rel_tol=1e-9)
    assert out.count("\n") == 1  # exactly one line, one object


def test_table_output_has_status_and_delta(capsys, fig2_result):
    """The table names the status and shows Delta with its unit; no NaN rows for an ok point."""
    code = cli.main(["point", *FIG2_ARGS])
    out, _ = capsys.readouterr()
    assert code == 0
    assert "ok: " + fig2_result.status.message in out
    delta_line = next(line for line in out.splitlines() if line.split()[:1] == ["Delta"])
    assert f"{fig2_result.Delta:.10g}" in delta_line
    assert "particle diameters" in delta_line
    assert "xi_stop" not in out  # NaN for an ok point: skipped
    assert "nan" not in out.lower()
    assert "stage1_accepted=" in out.splitlines()[-1]


def test_material_adds_solids_fraction(capsys):
    """With --d-p --rho-p --phi the JSON carries nu near the paper's 0.6 and stresses in Pa."""
    code = cli.main(["point", *FIG2_ARGS, *MATERIAL_ARGS, "--json"])
    data = json.loads(capsys.readouterr().out)
    assert code == 0
    assert 0.59 <= data["nu"] <= 0.61
    assert data["sigma_xx_wall_Pa"] > 0  # compressive positive


def test_material_table_has_dimensional_units(capsys):
    """The table shows nu and the wall couple stress in Pa m when a material is given."""
    cli.main(["point", *FIG2_ARGS, *MATERIAL_ARGS])
    out = capsys.readouterr().out
    rows = {line.split()[0]: line for line in out.splitlines() if line.startswith("  ")}
    assert "nu" in rows
    assert "Pa m" in rows["m_wall_Pa_m"]
    assert " Pa " in rows["sigma_xx_wall_Pa"]


def test_point_without_solution_is_an_answer(capsys):
    """A point with no solution exits 0, names its status, and reports Delta as null."""
    code = cli.main(_point_args(**{"--eps": "0.4"}) + ["--json"])
    out, err = capsys.readouterr()
    assert code == 0
    assert err == ""
    data = json.loads(out)
    assert data["status"] == "eps_too_large_axis"
    assert data["Delta"] is None


def test_table_skips_nan_outputs_for_non_ok_point(capsys):
    """The table of a point without solution lists no output rows and no NaN."""
    code = cli.main(_point_args(**{"--eps": "0.4"}))
    out = capsys.readouterr().out
    assert code == 0
    assert "eps_too_large_axis" in out
    assert "Delta" not in out
    assert "nan" not in out.lower()


@pytest.mark.parametrize(
    "args, named",
    [
        (_point_args(**{"--eps": "0"}), "eps"),  # eps in (0, 1]
        (_point_args(**{"--eps": "-1"}), "eps"),
        (_point_args(**{"--eps": "nan"}), "eps"),  # must reach check_point, not slip through
        (_point_args(**{"--eps": "inf"}), "eps"),
        (_point_args(**{"--L": "0"}), "L ="),
        (_point_args(**{"--K": "-1"}), "K ="),
        (_point_args(**{"--N": "0"}), "N ="),
        (_point_args() + ["--rtol", "2"], "rtol"),  # rtol in [1e-13, 1)
        (_point_args() + ["--rtol", "0"], "rtol"),
        (_point_args(**{"--eps": "abc"}), "--eps"),  # argparse: not a float
        (_point_args(**{"--A": None}), "--A"),  # argparse: required option missing
        (_point_args() + ["--d-p", "0.002"], "--rho-p, --phi"),  # partial material
        (_point_args() + ["--plot", "/nonexistent/dir/x.png"], "--plot"),  # checked before solving
        (_point_args() + ["--bogus"], "--bogus"),  # unknown option
        ([], "COMMAND"),  # no subcommand
    ],
)
def test_bad_input_is_one_line_exit_2(capsys, args, named):
    """Rejected input exits 2 with one stderr line naming the parameter, and nothing on stdout."""
    code = cli.main(args)
    out, err = capsys.readouterr()
    assert code == 2
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("cosserat-channel: error: ")
    assert named in lines[0]


def test_help_returns_zero(capsys):
    """--help prints the subcommand's usage and returns 0 instead of raising SystemExit."""
    code = cli.main(["point", "--help"])
    out = capsys.readouterr().out
    assert code == 0
    assert "--eps" in out and "--plot" in out


def test_plot_writes_png_atomically(capsys, tmp_path, fig2_result):
    """--plot writes a PNG, leaves no temporary file, and still prints the JSON."""
    target = tmp_path / "fig2.png"
    code = cli.main(["point", *FIG2_ARGS, "--json", "--plot", str(target)])
    out, err = capsys.readouterr()
    assert code == 0
    assert err == ""
    assert target.read_bytes()[:8] == PNG_SIGNATURE
    assert os.listdir(tmp_path) == ["fig2.png"]
    assert math.isclose(json.loads(out)["Delta"], fig2_result.Delta, rel_tol=1e-9)


def test_plot_of_non_ok_point_writes_nothing(capsys, tmp_path):
    """For a point without solution --plot writes no file, notes why on stderr, and exits 0."""
    target = tmp_path / "none.png"
    code = cli.main(_point_args(**{"--eps": "0.4"}) + ["--plot", str(target)])
    _, err = capsys.readouterr()
    assert code == 0
    assert os.listdir(tmp_path) == []
    assert len(err.splitlines()) == 1
    assert "no profile to plot" in err


def test_plot_unknown_file_type_is_rejected(capsys, tmp_path):
    """A --plot suffix matplotlib cannot write is an input error before any solving."""
    code = cli.main(_point_args() + ["--plot", str(tmp_path / "x.nosuchformat")])
    err = capsys.readouterr().err
    assert code == 2
    assert len(err.splitlines()) == 1 and ".nosuchformat" in err
    assert os.listdir(tmp_path) == []


def test_cli_import_is_light():
    """Importing cli pulls in neither numba nor matplotlib (heavy modules load lazily)."""
    code = (
        "import sys, cosserat_channel.cli; "
        "print(sorted(m for m in ('numba', 'matplotlib') if m in sys.modules))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    out = proc.stdout
    assert out.strip() == "[]"


def test_installed_executable_error_is_one_line():
    """The installed console script exits 2 with a single stderr line for --eps nan."""
    exe = shutil.which("cosserat-channel", path=os.path.join(sys.prefix, "bin")) or shutil.which(
        "cosserat-channel"
    )
    assert exe is not None, "cosserat-channel is not installed in this environment"
    proc = subprocess.run(
        [exe, *_point_args(**{"--eps": "nan"})], capture_output=True, text=True, timeout=120
    )
    assert proc.returncode == 2
    assert proc.stdout == ""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("cosserat-channel: error: eps = nan")
