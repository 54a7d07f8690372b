"""The record of a traced edge (:class:`Edge`) and the one bisection of a solvability edge
(:func:`bisect_edge`). Imports numpy only (and the regime codes)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..regime_codes import EDGE_NONE


@dataclass
class Edge:
    """The traced edge of solvability in ``eta = eps L`` at one ``(A, N)``.

    Attributes
    ----------
    eta_max : float
        Largest ``eta`` with status ok (bracketed to ``xtol`` relative), or at a tangential edge
        the node's ``eta`` (the zero of ``D(1)``; the status is noise within ``bands[-1]`` of it);
        for ``kind`` unbounded the upper end of the search range (a lower bound only); NaN for
        ``kind`` no_solution.
    kind : int
        ``EDGE_BOUNDED``, ``EDGE_UNBOUNDED`` or ``EDGE_NONE``.
    eta_min : float
        Smallest ``eta`` with status ok, bisected likewise; the lower end of the range when the
        smallest sample is already ok.
    status_above : int
        Status just above ``eta_max`` (bounded edges), else -1.
    transitions : ndarray
        Every ``eta`` where the coarse samples change feasibility, each bisected, or the node's
        ``eta`` where the edge is tangential. One entry (for a bounded edge with ok below) means
        feasibility is monotone on the samples.
    bands : ndarray
        Per transition, the relative distance from it within which the solver's status is not
        reliable (:attr:`Probe.band`; 0 where ``D(1)`` could not be probed).
    tangential : ndarray of bool
        Per transition, whether it is the node's ``eta`` (a tangential edge, :func:`trace_edge`).
    smooth : ndarray of bool
        Per transition, whether it is the zero of :func:`smooth_wall_D` (a transversal edge where
        the status is noise over more than ``SMOOTH_BAND``, :func:`trace_edge`).
    slopes : ndarray
        Per transition, ``d D(1) / d log eta`` there where the corrector measured it (NaN
        elsewhere): what a neighbour's corrector takes as its first slope.
    continued : bool
        Whether the edge was corrected from a prediction (:func:`continue_edge`) rather than
        traced afresh.
    """

    A: float
    N: float
    eta_max: float
    kind: int
    eta_min: float
    status_above: int
    transitions: np.ndarray
    bands: np.ndarray = None
    tangential: np.ndarray = None
    smooth: np.ndarray = None
    slopes: np.ndarray = None
    continued: bool = False

    def __post_init__(self):
        if self.bands is None:
            self.bands = np.zeros(self.transitions.size)
        if self.tangential is None:
            self.tangential = np.zeros(self.transitions.size, dtype=bool)
        if self.smooth is None:
            self.smooth = np.zeros(self.transitions.size, dtype=bool)
        if self.slopes is None:
            self.slopes = np.full(self.transitions.size, math.nan)

    @property
    def feasible_low(self) -> bool:
        """Feasibility at the low end of the searched range: solutions below the first
        transition, if any (the sides alternate from there)."""
        return self.kind != EDGE_NONE and not (self.transitions.size
                                               and self.eta_min == self.transitions[0])

    @property
    def monotone(self) -> bool:
        """Feasibility changes at most once over the sampled range."""
        return self.transitions.size <= 1


def bisect_edge(feasible, lo, hi, xtol, *, feasible_lo=True):
    """Narrow a bracket of a change of feasibility in ``eta`` by bisection in ``log eta``.

    The one bisection of the solvability edge: :func:`trace_edge`, the stability report's
    ``feasible_eta_max`` and the edge stratum of the work-precision validation set all call it,
    each with its own feasibility predicate. The validation set's points depend on where this
    stops (``measure/validation.py``): a change here that moves an edge by more than the rounding
    there needs a bump of its ``GENERATOR_VERSION``.

    Parameters
    ----------
    feasible : callable
        ``feasible(eta) -> bool``.
    lo, hi : float
        The bracket, ``0 < lo < hi``: ``feasible(lo) == feasible_lo`` and ``feasible(hi)`` is the
        opposite (the caller has evaluated both ends; they are not evaluated again).
    xtol : float
        Relative width at which to stop: ``hi / lo - 1 <= xtol``.
    feasible_lo : bool, optional
        Feasibility at ``lo``: True for an upper edge (feasible below), False for a lower edge.

    Returns
    -------
    lo, hi : float
        The narrowed bracket, with the feasibility of the input ends.

    Notes
    -----
    The midpoint is geometric: the bracket can span decades of ``eta`` (1e-3 to 50), and a
    geometric midpoint halves ``log(hi/lo)``, so the number of predicate calls is
    ``log2(log(hi/lo) / xtol)`` whatever the span. It stops early should round-off leave no
    float strictly inside the bracket.
    """
    while hi - lo > xtol * lo:
        mid = math.sqrt(lo * hi)
        if not lo < mid < hi:
            break
        if feasible(mid) == feasible_lo:
            lo = mid
        else:
            hi = mid
    return lo, hi
