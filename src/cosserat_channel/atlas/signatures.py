"""The transitions of a cell's nodes as one signature: nodes aligned across a transition that
leaves the traced range (:func:`_unify`), the predictions that follow from such an alignment
(:func:`_variants`), and what a deepest cell keeps where its nodes do not agree: the envelope of
their transitions (:func:`_envelope`, :func:`_cluster_columns`). Imports numpy only."""

from __future__ import annotations

import math

import numpy as np

from .settings import SAFETY, TOL_MIN


def _envelope(traces, lo, hi):
    """A mixed cell that may not be split again, as a leaf with its reached error.

    ``traces``: its nodes' ``(low, transitions)``. Every gap between the nodes' transitions
    (in ``log eta``) where the nodes agree on feasibility is decided; runs of gaps where they do
    not, with the transitions around them, form clusters, each widened by half its width for
    what lies between the nodes (at least ``TOL_MIN``). A cluster across which feasibility
    changes becomes one transition at its centre, one across which it does not two; the error
    of each is its cluster's half-width (over ``SAFETY``, which :func:`classify` applies).
    Returns ``(low, log_transitions, errors)``, an error per transition.
    """
    logs = np.unique(np.concatenate([np.log(t) for _, t in traces] + [np.empty(0)]))
    edges = np.r_[math.log(lo), logs, math.log(hi)]
    mids = 0.5 * (edges[:-1] + edges[1:])
    agree = []
    for x in mids:
        s = {bool(low) ^ (int(np.sum(np.log(t) < x)) % 2 == 1) for low, t in traces}
        agree.append(s.pop() if len(s) == 1 else None)
    decided = [k for k, a in enumerate(agree) if a is not None]
    if not decided:
        half = 0.75 * (edges[-1] - edges[0])
        return False, np.full(2, 0.5 * (edges[0] + edges[-1])), np.full(2, half / SAFETY)
    clusters = []  # (log start, log end, feasible below, feasible above; None: the range's end)
    first, last = decided[0], decided[-1]
    if first > 0:
        clusters.append((edges[0], edges[first], None, agree[first]))
    for k1, k2 in zip(decided, decided[1:]):
        if agree[k1] != agree[k2] or k2 > k1 + 1:
            clusters.append((edges[k1 + 1], edges[k2], agree[k1], agree[k2]))
    if last < len(agree) - 1:
        clusters.append((edges[last + 1], edges[-1], agree[last], None))
    low = agree[0] if first == 0 else not agree[first]
    centres, errs = [], []
    for c0, c1, below, above in clusters:
        flips = below is None or above is None or below != above
        centres.extend([0.5 * (c0 + c1)] * (1 if flips else 2))
        errs.extend([max(0.75 * (c1 - c0), TOL_MIN) / SAFETY] * (1 if flips else 2))
    return bool(low), np.array(centres), np.array(errs)


def _unify(traces, trace_range):
    """One signature for nodes whose signatures differ only by transitions beyond the traced range.

    ``traces``: the nodes' ``(low, transitions)``. Where a transition leaves the traced ``eta``
    range across a cell (``eta_min`` below it, ``eta_max`` above it), the nodes beyond the
    crossing lack it: their feasibility at that end of the range differs from the others'. Such a
    node gets the transition at the end of the range (the function clamped there), which keeps the
    cell's other transitions aligned, so they are interpolated as in any cell; the clamped one
    stays outside the answered range (:data:`TRACE_WIDEN`), where :func:`_answered` leaves it out
    of the estimate wherever its interpolant keeps off that range. Nodes that differ otherwise (a
    window of feasibility closing: two transitions meeting) are not unified.

    Returns ``(low, log_transitions, clamped)``: the transitions ``(node, k)`` in ``log eta``
    ascending and, for each of the ``k``, where some node has it clamped (0 nowhere, 1 at the
    low end, 2 at the high end); or ``None`` where no feasibility at the two ends makes the
    numbers of transitions agree.
    """
    lows = [bool(low) for low, _ in traces]
    ns = [int(t.size) for _, t in traces]
    tops = [low ^ (n % 2 == 1) for low, n in zip(lows, ns)]
    options = []
    for bottom in (False, True):
        for top in (False, True):
            counts = {n + (low != bottom) + (tp != top) for low, n, tp in zip(lows, ns, tops)}
            if len(counts) == 1:
                options.append((counts.pop(), bottom, top))
    if not options:
        return None
    k, bottom, top = min(options)  # the fewest transitions: none added where all agree
    lo, hi = math.log(trace_range[0]), math.log(trace_range[1])
    logt = np.empty((len(traces), k))
    clamped = np.zeros(k, dtype=np.int8)
    for row, ((_, t), low, tp) in zip(logt, zip(traces, lows, tops)):
        row[:] = np.r_[[lo] * (low != bottom), np.log(t), [hi] * (tp != top)]
        clamped[:1] |= 1 if low != bottom else 0
        clamped[k - 1:] |= 2 if tp != top else 0
    return bottom, logt, clamped


def _cluster_columns(coef, errs, logt, hard):
    """A deepest cell's interpolant, each transition in ``hard`` (clamped by :func:`_unify` and
    reaching into the answered range) and each whose nodes' envelope states a smaller error than
    its own estimate replaced by that envelope: the centre of its nodes' values, with three
    quarters of their spread as its error (over ``SAFETY``), as :func:`_envelope` states a
    cluster. The other transitions keep their interpolants and estimates. ``None`` where an
    envelope overlaps the nodes' values of a neighbouring transition (the order of the
    transitions would not hold over the cell)."""
    coef, errs = coef.copy(), errs.copy()
    for k in range(coef.shape[0]):
        c0, c1 = float(logt[..., k].min()), float(logt[..., k].max())
        width = max(0.75 * (c1 - c0), TOL_MIN) / SAFETY
        if k not in hard and width >= errs[k]:
            continue
        if (k > 0 and logt[..., k - 1].max() >= c0 - 0.25 * (c1 - c0)) or \
                (k + 1 < coef.shape[0] and logt[..., k + 1].min() <= c1 + 0.25 * (c1 - c0)):
            return None
        coef[k] = 0.0
        coef[k, 0, 0] = 0.5 * (c0 + c1)
        errs[k] = width
    return coef, errs


def _variants(lt, spread, clamped, log_trace):
    """The transitions an interpolant's prediction ``lt`` keeps, most likely first: a list of
    ``(mask, flip)``, ``flip`` whether feasibility at the low end differs from the
    interpolant's (its low transition dropped).

    A transition that :func:`_unify` clamped at an end of the traced range (``clamped``) may be
    beyond that end at the predicted point: absent from its trace. It is taken as absent first
    where it is predicted within its ``spread`` of the end, as present first elsewhere, and the
    other way next (the corrector rejects the wrong one in a few solves, where a fresh trace
    would cost dozens).
    """
    first = np.ones(lt.size, dtype=bool)
    ends = []
    if lt.size and clamped[0] & 1:
        ends.append(0)
        first[0] = lt[0] - log_trace[0] > spread[0]
    if lt.size and clamped[-1] & 2 and not (lt.size == 1 and ends):
        ends.append(lt.size - 1)
        first[-1] = log_trace[1] - lt[-1] > spread[-1]
    bottom = bool(ends) and ends[0] == 0 and bool(clamped[0] & 1)
    out = [first]
    for k in ends:
        other = first.copy()
        other[k] = not other[k]
        out.append(other)
    return [(m, bottom and not m[0]) for m in out]
