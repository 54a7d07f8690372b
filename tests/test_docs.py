"""The documentation site's sources: the API reference lists every name the package exports,
the command-line reference covers every command, and CITATION.cff cites the paper as its
manuscript names it, and the site builds from scratch with warnings as errors (as ``make docs``
does, with the notebooks' execution left to ``test_notebooks.py``)."""

import importlib
import importlib.util
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import cosserat_channel
from cosserat_channel import cli

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"


def _autosummary_entries(text):
    """The entries of each ``.. autosummary::`` block of an RST text, in order, per block."""
    blocks = re.findall(r"^\.\. autosummary::\n((?:   .*\n|\n)+)", text, flags=re.M)
    return [[ln.strip().lstrip("~") for ln in b.splitlines()
             if ln.strip() and not ln.strip().startswith(":")] for b in blocks]


def test_api_reference_lists_every_exported_name():
    """The reference's first table is cosserat_channel.__all__, each name at its home module,
    and every entry is the very object ``cosserat_channel.<name>`` gives."""
    namespace, modules = _autosummary_entries((DOCS / "api.rst").read_text())
    expected = [f"cosserat_channel.{cosserat_channel._API[n]}.{n}" if n in cosserat_channel._API
                else f"cosserat_channel.{n}" for n in cosserat_channel.__all__]
    assert namespace == expected
    for name, entry in zip(cosserat_channel.__all__, namespace):
        module, _, attr = entry.rpartition(".")
        assert getattr(importlib.import_module(module), attr) is getattr(cosserat_channel, name)
    assert modules == ["cosserat_channel"]  # and every module below it, recursively


def test_cli_reference_has_every_command(tmp_path, monkeypatch):
    """The generated command-line page has a section with the --help of every command."""
    spec = importlib.util.spec_from_file_location("docs_conf", DOCS / "conf.py")
    conf = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(conf)
    monkeypatch.setattr(conf, "GENERATED", tmp_path)
    conf.write_cli_reference()
    text = (tmp_path / "cli.md").read_text()
    for name in cli.COMMANDS:
        section = text.split(f"## `cosserat-channel {name}`", 1)
        assert len(section) == 2, name
        assert f"usage: cosserat-channel {name}" in section[1].split("## ", 1)[0], name


def test_citation_names_the_paper_and_the_software():
    """CITATION.cff: the software, and the paper with its title and authors as the .tex has them."""
    text = (ROOT / "CITATION.cff").read_text()
    assert text.startswith("cff-version: 1.2.0\n")
    assert "title: cosserat-channel\n" in text and f"version: {_version()}\n" in text
    assert ("title: A frictional Cosserat model for the flow of granular materials through a "
            "vertical channel\n") in text
    for given, family in (("L. Srinivasa", "Mohan"), ("Prabhu R.", "Nott"), ("K. Kesava", "Rao")):
        assert f"- given-names: {given}\n      family-names: {family}\n" in text


def _version():
    import tomllib

    return tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]


def test_every_module_imports_without_running_anything(monkeypatch):
    """The API reference's recursive autosummary imports every module of the package, private
    ones and ``__main__`` included, with sphinx-build's own command line in ``sys.argv``: a
    module that runs a command on import (a ``__main__.py`` without its ``__name__`` guard)
    would stop the build."""
    import pkgutil
    import sys

    monkeypatch.setattr(sys, "argv", ["sphinx-build", "--keep-going", "docs", "docs/_build"])
    names = [m.name for m in pkgutil.walk_packages(cosserat_channel.__path__, "cosserat_channel.")]
    assert "cosserat_channel.cli.__main__" in names
    for name in names:
        try:
            importlib.import_module(name)
        except SystemExit as exc:
            raise AssertionError(f"importing {name} ran a command (exit {exc.code})") from None


@pytest.mark.slow
def test_site_builds_from_scratch_with_warnings_as_errors(tmp_path):
    """``make docs``'s Sphinx build, warnings as errors, from nothing: a copy of ``docs/`` without
    ``_build`` or ``_generated`` and a fresh environment (``-E``), so that no page a previous
    build read is skipped (an incremental build hides the warnings of pages it does not read
    again). Two of ``make docs``'s steps are replaced by cheaper ones of the same shape: the
    notebooks are rendered as committed, without outputs (``tests/test_notebooks.py`` runs
    them), and the paper's page holds table 1 alone (the figures are ``test_paper.py``'s)."""
    pytest.importorskip("sphinx")
    docs = tmp_path / "docs"
    shutil.copytree(DOCS, docs, ignore=shutil.ignore_patterns("_build", "_generated"))
    notebooks = docs / "_generated" / "notebooks"
    notebooks.mkdir(parents=True)
    for nb in sorted((ROOT / "notebooks").glob("*.ipynb")):
        shutil.copy(nb, notebooks / nb.name)
    from cosserat_channel import paper

    paper.write_paper_figures(docs / "_generated" / "paper", keys=("table1",))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(Path(cosserat_channel.__file__).resolve().parents[1]),
         *filter(None, [os.environ.get("PYTHONPATH")])]))
    proc = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-E", "-q", "-b", "html",
         "-d", str(tmp_path / "doctrees"), str(docs), str(tmp_path / "html")],
        capture_output=True, text=True, env=env, timeout=1200)
    assert proc.returncode == 0, proc.stderr[-5000:]
    html = tmp_path / "html"
    for page in ("index", "getting-started", "api", "_generated/cli", "_generated/paper",
                 "_generated/notebooks/01_quickstart"):
        assert (html / f"{page}.html").is_file(), page
    assert "Not generated in this build" not in (html / "_generated" / "paper.html").read_text()


def test_zstd_cost_stated_as_measured():
    """What README and getting-started say of Zstandard's CPU beside zlib's is the ratio that
    docs/performance.md measured (its one-thread timings of the same chunks), not a number typed
    by hand that drifts from it."""
    perf = (DOCS / "performance.md").read_text()
    found = re.search(r"zstd -1 ([\d.]+) s, zlib 1 \+ shuffle ([\d.]+) s", perf)
    assert found, "performance.md's compression timings"
    zstd, zlib = map(float, found.groups())
    words = {2: "half", 3: "third", 4: "quarter", 5: "fifth", 6: "sixth", 7: "seventh",
             8: "eighth", 9: "ninth", 10: "tenth"}
    word = words[round(zlib / zstd)]
    assert f"about a {word} of zlib's CPU" in " ".join((ROOT / "README.md").read_text().split())
    assert f"takes about a {word} of its CPU" in " ".join(
        (DOCS / "getting-started.md").read_text().split())
