"""The paper's figures 2-12, table 1 and Appendix A's ``eps = 0.33``, computed beside what the
paper prints.

Each function solves what one figure (or the table) of Mohan, Nott & Rao shows, with the
parameters of its caption, and returns a :class:`PaperFigure`: the data to draw
(:mod:`cosserat_channel.plot.paper` draws it and never solves) and the paper's stated numbers
next to ours, each with a sentence where they differ. :func:`paper_figures` computes them all;
``cosserat-channel paper -o DIR`` (or ``python -m cosserat_channel.cli paper -o DIR``) writes every
figure as a PNG and the comparison as Markdown, without a notebook.

The paper's figure numbers are used (its ``\\label``s differ: ``fig:new`` is figure 9,
``fig:9`` figure 10, ``fig:10`` figure 11 and ``fig:11`` figure 12). Stresses are drawn divided
by ``nu`` (the package's scaled variables; the paper's bars are ``nu`` times them).

Layer: above the solver, the regimes and the sweeps, whose public functions it calls; below the
command line. May import those, the physics, :mod:`cosserat_channel.plot` (to save the
figures) and the vocabulary modules; never an integrator, the atlas or the command line.
"""
from __future__ import annotations

import os

import numpy as np

from .figures import (figure2, figure3, figure4, figure5, figure6, figure7, figure8, figure9,
                      figure10, figure11, figure12)
from .record import PaperFigure, Row
from .tables import appendix_a, printed_march, table1

__all__ = ["PaperFigure", "Row", "KEYS", "paper_figures", "write_paper_figures", "table1",
           "appendix_a", "printed_march", "figure2", "figure3", "figure4", "figure5", "figure6",
           "figure7", "figure8", "figure9", "figure10", "figure11", "figure12"]


# ---------------------------------------------------------------------------------------------
# All of them
# ---------------------------------------------------------------------------------------------
KEYS = tuple(f"figure{n}" for n in range(2, 13)) + ("table1", "appendix_a")


def paper_figures(coarse: bool = False, keys=KEYS, progress=None) -> dict[str, PaperFigure]:
    """Every figure of :data:`KEYS` (``coarse``: small grids, the same code paths);
    ``progress(done, total, text)`` (the package's progress protocol), if given, is called
    before each, ``text`` naming it."""
    return dict(_each_figure(coarse, keys, progress))


def _each_figure(coarse, keys, progress):
    """``(key, PaperFigure)`` for each of ``keys``, computed one by one (see :func:`paper_figures`)."""
    n_xi = 101 if coarse else 401
    done = {}
    for i, key in enumerate(keys):
        if progress is not None:
            progress(i, len(keys), key)
        if key == "figure2":
            pf = figure2(n_xi)
        elif key == "figure3":
            pf = figure3(n_xi, done.get("figure2"))
        elif key in ("figure4", "figure5", "figure6", "figure10", "figure11"):
            pf = globals()[key](n_xi)
        elif key == "figure7":
            pf = figure7(15 if coarse else 120)
        elif key == "figure8":
            pf = figure8(12 if coarse else 117)
        elif key == "figure9":
            pf = figure9(301 if coarse else 3001)
        elif key == "figure12":
            pf = figure12(*((61, 81) if coarse else (301, 401)))
        elif key == "table1":
            pf = table1()
        elif key == "appendix_a":
            pf = (appendix_a(np.r_[1 / 30, 0.2, 0.31, 0.32, 0.33, 0.332],
                             np.array([1e-8, 1e-11, 1e-13])) if coarse else appendix_a())
        else:
            raise ValueError(f"unknown paper figure {key!r}; have {', '.join(KEYS)}")
        if key == "figure2":
            done[key] = pf
        yield key, pf


def write_paper_figures(directory, *, coarse=False, overwrite=False, keys=KEYS,
                        progress=None, written=None) -> list[str]:
    """Compute and draw every figure into ``directory`` (created if missing): ``<key>.png`` and
    ``comparison.md``. Existing files are kept (ValueError before any work) unless
    ``overwrite``. Returns the paths written.

    Each figure is saved as soon as it is computed, and its path appended to ``written`` (a
    list, if given): what a run stopped early (Ctrl-C) has finished stays on disk, and the
    caller can say which files those are.
    """
    from ..files import output_problem, write_text
    from ..plot import paper as plot_paper
    from ..plot import save_figure

    directory = os.fspath(directory)
    if os.path.lexists(directory) and not os.path.isdir(directory):
        raise ValueError(f"{directory}: exists and is not a directory")
    targets = [os.path.join(directory, n) for n in [f"{k}.png" for k in keys] + ["comparison.md"]]
    for t in targets:
        if os.path.lexists(t) and not (overwrite and os.path.isfile(t) and not os.path.islink(t)):
            what = "exists" if os.path.isfile(t) else "exists and is not a regular file"
            raise ValueError(f"{t} {what}; kept" + (": give --overwrite or another directory"
                                                    if os.path.isfile(t) else ""))
    if not os.path.isdir(directory):
        parent = os.path.dirname(os.path.abspath(directory))
        if not os.path.isdir(parent):
            raise ValueError(f"cannot create {directory!r}: directory {parent!r} does not exist")
        os.mkdir(directory)  # one level, as -o FILE needs its directory to exist
    for t in targets:
        problem = output_problem(t, overwrite=overwrite)
        if problem:
            raise ValueError(problem)
    written = [] if written is None else written
    figures = {}
    for key, pf in _each_figure(coarse, keys, progress):
        figures[key] = pf
        path = os.path.join(directory, f"{key}.png")
        save_figure(plot_paper.draw(pf), path)
        written.append(path)
    text = ["# The paper's figures and table 1 beside ours", ""]
    for pf in figures.values():
        text += [f"## {pf.title}", "", f"![{pf.key}]({pf.key}.png)", "", pf.rows_markdown(), ""]
    path = os.path.join(directory, "comparison.md")
    write_text(path, "\n".join(text))
    written.append(path)
    return written
