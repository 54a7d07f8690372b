"""Which source gives the edge of solvability on a grid of ``(A, N)``: an atlas, or a trace.

:func:`edge_source` is the one rule, for ``boundary``, ``plot --regime`` and any other caller:

* ``trace=True``: trace, whatever atlas there is;
* an atlas file given: it answers, for its own ``eta`` range (a different one asked is an
  error), drawn where it covers the grid (NaN elsewhere, with a note);
* else the default atlas (:func:`~.store.default_atlas`: the cached one, then the shipped one)
  answers where it covers the whole grid, its ``eta`` range is the one asked (default: the
  search range, ``regime_codes.ETA_SEARCH_MIN`` to ``ETA_SEARCH_MAX``), and on every pair it
  decides with a stated error within ``tol`` (default: its own tolerance; a figure, which marks
  where the stated error exceeds the atlas's tolerance, accepts any). Otherwise the caller
  traces.

Imports numpy and xarray, never numba.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import numpy as np

from ..parameters import ParameterError
from ..regime_codes import ETA_SEARCH_MAX, ETA_SEARCH_MIN
from .store import default_atlas, describe, load_atlas


class SourceError(ParameterError):
    """An edge source that cannot answer as asked; ``parameter`` names the argument at fault
    (``"atlas"``, ``"eta_range"`` or ``"trace"``)."""

    def __init__(self, parameter: str, message: str):
        super().__init__(message)
        self.parameter = parameter


@dataclass(frozen=True)
class EdgeSource:
    """The answer of :func:`edge_source`.

    Attributes
    ----------
    boundary : xarray.Dataset or None
        The edge on the grid drawn from the atlas (:meth:`~.interpolant.Atlas.boundary`, its
        ``attrs["atlas"]`` naming the atlas by its file's name); None: the caller traces.
    atlas : Atlas or None
    path, which : str or None
        The atlas's file, and ``"cached"``, ``"shipped"`` or None (a file the caller gave).
    """

    boundary: object = None
    atlas: object = None
    path: str | None = None
    which: str | None = None

    @property
    def traced(self) -> bool:
        return self.boundary is None

    def describe(self) -> str:
        """One line naming the atlas that answers (:func:`~.store.describe`)."""
        return describe(self.atlas, self.path, self.which)


def above_tolerance(ds, tol) -> int:
    """How many ``(A, N)`` pairs of a boundary Dataset drawn from an atlas it leaves undecided
    or answers with a stated error above ``tol``."""
    with np.errstate(invalid="ignore"):
        rough = ds["eta_error"].values > tol * (1.0 + 1e-9)
    return int(np.sum(rough | ~ds["resolved"].values))


def edge_source(A, N, *, atlas=None, trace=False, eta_range=None, tol=None, note=None):
    """Which source gives the edge on the grid ``A x N`` (the module's rule), as an
    :class:`EdgeSource`.

    Parameters
    ----------
    A, N : sequence of float
        The grid.
    atlas : str, optional
        An atlas file to draw from (else the default atlas, where it may answer).
    trace : bool
        Trace, whatever atlas there is (with ``atlas``: a :class:`SourceError`).
    eta_range : (float, float), optional
        The ``eta`` range asked: a given atlas must answer for this one; the default atlas
        answers only for it (default: a given atlas's own, else the search range).
    tol : float, optional
        The largest stated error the default atlas may answer with (default: its tolerance).
    note : callable, optional
        ``note(text)`` is told why the default atlas does not answer, or where a given one does
        not cover the grid.

    Raises
    ------
    SourceError
        ``atlas`` with ``trace``; an ``atlas`` that cannot be read, or whose ``eta`` range is not
        ``eta_range``.
    """
    note = note or (lambda text: None)
    span = ((float(np.min(A)), float(np.max(A))), (float(np.min(N)), float(np.max(N))))
    if atlas is not None and trace:
        raise SourceError("trace", "atlas and trace are two sources of the same edge: give one")
    if trace:
        return EdgeSource()
    if atlas is not None:
        path, which = atlas, None
        try:
            found = load_atlas(path)
        except ParameterError as exc:
            raise SourceError("atlas", str(exc)) from None
        if eta_range is not None and tuple(eta_range) != found.eta_range:
            lo, hi = eta_range
            raise SourceError("eta_range", f"{lo:g}:{hi:g} differs from the atlas's "
                              f"{found.eta_range[0]:g}:{found.eta_range[1]:g}; give that or none")
        if not found.covers(*span):
            a0, a1, n0, n1 = found.box
            note(f"{path} covers A in [{a0:g}, {a1:g}], N in [{n0:g}, {n1:g}]; outside it the "
                 "edge is not drawn (eta_max is NaN)")
    else:
        found, path, which = default_atlas(*span, note=note)
        asked = (ETA_SEARCH_MIN, ETA_SEARCH_MAX) if eta_range is None else tuple(eta_range)
        if found is None or found.eta_range != asked:
            return EdgeSource()
    ds = found.boundary(A, N)
    if atlas is None:
        limit = found.tol if tol is None else tol
        rough = above_tolerance(ds, limit) if limit < math.inf else 0
        if rough:
            # The default atlas answers only where it holds the error asked; a cell that could
            # not reach it (an envelope next to a singular curve) is traced instead.
            note(f"the {which} atlas states an error above {limit:g} at {rough} of the (A, N) "
                 "pairs; tracing instead")
            return EdgeSource()
    # The file's name, not its path: a path of this machine means nothing elsewhere.
    ds.attrs["atlas"] = describe(found, os.path.basename(path), which)
    return EdgeSource(ds, found, path, which)
