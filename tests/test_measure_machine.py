"""measure/machine.py: what every report and benchmark prints about where it ran."""

import re
import shutil
import subprocess

import pytest

from cosserat_channel.measure import machine


def test_cpu_model_and_machine_line():
    """A CPU model (never empty), and the machine line with the core count and the OS."""
    cpu = machine.cpu_model()
    assert cpu.strip()
    line = machine.machine()
    assert line.startswith(cpu + ", ") and re.search(r", \d+ cores, ", line)


def test_versions_name_the_solver_exactly():
    """Version, git revision and source digest of the package, then the libraries, extras last."""
    text = machine.versions(dask="9.9", numbalsoda="not installed")
    assert text.startswith("cosserat-channel ")
    assert re.search(r"package sources sha256 [0-9a-f]{12}\)", text)
    for lib in ("Python", "numba", "numpy", "scipy"):
        assert f", {lib} " in text
    assert text.endswith(", dask 9.9, numbalsoda not installed")
    assert re.fullmatch(r"[0-9a-f]{12}", machine.source_digest())


def _git(cwd, *args):
    return subprocess.run(["git", "-C", str(cwd), "-c", "user.name=t", "-c", "user.email=t@t",
                           *args], capture_output=True, text=True, check=True).stdout.strip()


@pytest.mark.skipif(shutil.which("git") is None, reason="needs git")
def test_git_revision_of_a_checkout(tmp_path, monkeypatch):
    """In a checkout: its HEAD's short hash, flagged once a tracked file changes; outside any
    checkout: "unknown"."""
    repo = tmp_path / "repo"
    (repo / "pkg").mkdir(parents=True)
    (repo / "pkg" / "m.py").write_text("x = 1\n")
    _git(repo, "init", "-q")
    _git(repo, "add", ".")
    _git(repo, "commit", "-q", "-m", "one")
    monkeypatch.setattr(machine, "PACKAGE_DIR", repo / "pkg")
    head = _git(repo, "rev-parse", "HEAD")
    rev = machine.git_revision()
    assert re.fullmatch(r"[0-9a-f]{7,}", rev) and head.startswith(rev)
    (repo / "pkg" / "m.py").write_text("x = 2\n")
    assert machine.git_revision() == rev + " (with uncommitted changes)"
    (repo / "untracked.py").write_text("")  # untracked files are not changes of the package
    (repo / "pkg" / "m.py").write_text("x = 1\n")
    assert machine.git_revision() == rev
    outside = tmp_path / "plain"
    outside.mkdir()
    monkeypatch.setattr(machine, "PACKAGE_DIR", outside)
    monkeypatch.setenv("GIT_CEILING_DIRECTORIES", str(tmp_path))  # no checkout above it counts
    assert machine.git_revision() == "unknown"
