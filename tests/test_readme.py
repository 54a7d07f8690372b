"""Every command of README.md's code blocks runs, as written, in a scratch copy of the repository.

The ``sh`` blocks are run line by line (backslash continuations joined) from the scratch copy's
root, where ``.venv/bin/cosserat-channel`` is a shim for this Python's package, so the commands
are the README's own text (run in this process through ``cli.main``, see the test). Each must
exit 0, write every file it names (``-o``, ``--plot``), and, all together, leave nothing outside
``demo/`` (which git ignores). Only the set-up lines (``make ...``, which build a venv: CI runs
``make test`` itself; ``make notebooks`` is checked with ``make -n`` below) are skipped, and the
report commands that take minutes (``bench``, ``stability``, ``paper``) run with ``--quick``
(``--coarse``): the same code on a smaller set. The cluster commands are checked, not run:
``dask scheduler`` and ``dask worker`` serve until stopped and need the other nodes, so each
runs with ``--help`` (the command exists in the venv and takes those options), and
``run ... --scheduler ADDRESS`` is parsed by the command line's own parser (the cluster itself
is tested in ``test_sweep_engine.py``), and so is ``explore``, which serves until stopped. The
``python`` blocks run with this interpreter in the same directory.
"""

from __future__ import annotations

import os
import pathlib
import re
import shlex
import shutil
import stat
import subprocess
import sys

import pytest

from cosserat_channel import cli

ROOT = pathlib.Path(__file__).resolve().parent.parent
README = ROOT / "README.md"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# Minutes in full: the README test runs them on their smaller set (the same code).
QUICK = {"bench": "--quick", "stability": "--quick", "paper": "--coarse"}
OUTPUT_FLAGS = ("-o", "--output", "--output-dir", "--plot")


def blocks(lang: str) -> list[str]:
    """The fenced code blocks of README.md in language ``lang``."""
    return re.findall(rf"^```{lang}\n(.*?)^```", README.read_text(), flags=re.S | re.M)


def commands() -> list[str]:
    """Every command line of the sh blocks, continuations joined, comments and blanks dropped."""
    out = []
    for block in blocks("sh"):
        for line in block.replace("\\\n", " ").splitlines():
            words = shlex.split(line, comments=True)
            if words:
                out.append(line)
    return out


def outputs(words: list[str]) -> list[str]:
    """The files or directories a command names as its outputs."""
    found = [words[i + 1] for i, w in enumerate(words[:-1]) if w in OUTPUT_FLAGS]
    found += [w.split("=", 1)[1] for w in words
              if "=" in w and w.split("=", 1)[0] in OUTPUT_FLAGS[1:]]
    return found


@pytest.fixture(scope="module")
def scratch(tmp_path_factory):
    """A copy of the repository's tracked inputs with a ``.venv/bin`` whose commands are shims."""
    root = tmp_path_factory.mktemp("readme")
    for name in ("sweeps", "notebooks", "docs"):
        shutil.copytree(ROOT / name, root / name)
    for name in ("README.md", "pyproject.toml", "Makefile"):
        shutil.copy(ROOT / name, root / name)
    bin_dir = root / ".venv" / "bin"
    bin_dir.mkdir(parents=True)
    src = ROOT / "src"
    shim = bin_dir / "cosserat-channel"
    shim.write_text(f"#!/bin/sh\nPYTHONPATH={shlex.quote(str(src))}${{PYTHONPATH:+:$PYTHONPATH}} "
                    f"exec {shlex.quote(sys.executable)} -m cosserat_channel.cli \"$@\"\n")
    shim.chmod(shim.stat().st_mode | stat.S_IXUSR)
    (bin_dir / "python").symlink_to(sys.executable)
    dask = pathlib.Path(sys.executable).parent / "dask"
    if dask.exists():
        (bin_dir / "dask").symlink_to(dask)
    return root


def serving_command(words: list[str]) -> bool:
    """``explore`` serves its page until stopped: parsed here, not run (its page is tested in
    test_explore.py, in a browser)."""
    return words[0] == ".venv/bin/cosserat-channel" and len(words) > 1 and words[1] == "explore"


def cluster_command(words: list[str]) -> bool:
    """A command of the cluster block: checked, not run (module docstring)."""
    return words[0].endswith("/dask") or "--scheduler" in words


def test_readme_has_the_commands_it_should():
    """The parser finds the README's commands (a broken fence would silently test nothing)."""
    cmds = commands()
    assert len(cmds) >= 12
    assert all(c.startswith((".venv/bin/", "make ", "mkdir ")) for c in cmds), cmds
    assert any(" plot " in c and "--hue" in c for c in cmds)
    assert sum(cluster_command(shlex.split(c, comments=True)) for c in cmds) == 3
    assert blocks("python")


@pytest.mark.slow
def test_every_readme_command_runs_as_written(scratch, monkeypatch, capsys):
    """Each command exits 0 and writes what it names; nothing lands outside demo/.

    ``.venv/bin/cosserat-channel ARGS`` runs as ``cli.main(ARGS)`` in this process, which is
    what the shim execs (one process keeps the suite fast: kernels load once); the shim itself
    runs once, for ``--help``, and other commands (``mkdir``) run as they are.
    """
    before = {p.name for p in scratch.iterdir()}
    shim = subprocess.run([".venv/bin/cosserat-channel", "--help"], cwd=scratch,
                          capture_output=True, text=True, timeout=120)
    assert shim.returncode == 0 and "examples:" in shim.stdout, shim.stderr
    monkeypatch.chdir(scratch)
    ran = 0
    for line in commands():
        words = shlex.split(line, comments=True)
        if words[0] == "make":
            continue
        if serving_command(words):
            cli.build_parser("explore").parse_args(words[1:])  # raises CliError if wrong
            continue
        if cluster_command(words):
            if words[0] == ".venv/bin/cosserat-channel":
                args = cli.build_parser().parse_args(words[1:])  # raises CliError if wrong
                assert args.scheduler and os.path.exists(args.sweep), line
            elif not (scratch / words[0]).exists():
                pytest.fail(f"{line}: {words[0]} is not in the venv")
            else:
                proc = subprocess.run([words[0], words[1], "--help"], capture_output=True,
                                      text=True, timeout=120)
                assert proc.returncode == 0 and all(
                    w in proc.stdout for w in words[2:] if w.startswith("--")), proc.stderr
            continue
        if words[0] == ".venv/bin/cosserat-channel":
            if words[1] in QUICK and QUICK[words[1]] not in words:
                words.append(QUICK[words[1]])
            code = cli.main(words[1:])
            err = capsys.readouterr().err
        else:
            proc = subprocess.run(words, capture_output=True, text=True, timeout=120)
            code, err = proc.returncode, proc.stderr
        assert code == 0, f"{line}\nexit {code}\n{err[-3000:]}"
        for name in outputs(words):
            path = scratch / name
            assert path.exists(), f"{line}: did not write {name}"
            if path.suffix == ".png":
                assert path.read_bytes()[:8] == PNG_SIGNATURE, name
        ran += 1
    assert ran >= 12
    after = {p.name for p in scratch.iterdir()}
    assert after - before == {"demo"}, f"left outside demo/: {sorted(after - before - {'demo'})}"


def test_readme_python_blocks_run(scratch):
    """The Python examples run (after the shell commands, in the same scratch directory)."""
    for code in blocks("python"):
        proc = subprocess.run([sys.executable, "-c", code], cwd=scratch, capture_output=True,
                              text=True, timeout=600,
                              env=dict(os.environ, PYTHONPATH=str(ROOT / "src")))
        assert proc.returncode == 0, f"{code}\n{proc.stderr[-3000:]}"


def test_make_notebooks_allows_root_only_as_root(tmp_path):
    """Jupyter refuses root without --allow-root: ``make notebooks`` passes it as root, only then.

    ``make -n`` prints the recipe without running it, in a copy of the Makefile, with the venv
    stamp taken as made (``-o``): nothing is installed.
    """
    if shutil.which("make") is None:
        pytest.skip("make is not installed")
    for name in ("Makefile", "pyproject.toml"):
        shutil.copy(ROOT / name, tmp_path / name)
    proc = subprocess.run(["make", "-n", "-o", ".venv/.installed", "notebooks"], cwd=tmp_path,
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 0, proc.stderr
    line = next(w for w in proc.stdout.splitlines() if "jupyter lab" in w)
    assert ("--allow-root" in line) == (os.geteuid() == 0), line
