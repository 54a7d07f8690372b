"""How a cell's nodes become one signature (``atlas.signatures``): alignment across a transition
that leaves the traced range, the predictions that follow, and the envelopes a deepest cell
keeps, on hand-made nodes whose answers are known."""

import math

import numpy as np
import pytest

from cosserat_channel import atlas as at
from cosserat_channel.atlas import chebyshev, signatures


def test_unify_aligns_nodes_that_differ_by_a_transition_beyond_the_range():
    """eta_min below the range at some nodes, eta_max above it at others: the missing ones are
    clamped at the range's ends and marked; a window that closes is not unified."""
    lo, hi = 5e-4, 200.0
    traces = [(False, np.array([0.01, 2.0])), (True, np.array([2.05])),
              (False, np.array([0.02]))]  # eta_min below the range; eta_max above it
    low, logt, clamped = signatures._unify(traces, (lo, hi))
    assert low is False and logt.shape == (3, 2) and clamped.tolist() == [1, 2]  # low, high end
    np.testing.assert_allclose(np.exp(logt), [[0.01, 2.0], [lo, 2.05], [0.02, hi]])
    # one signature: nothing is added
    low, logt, clamped = signatures._unify(traces[:1] * 2, (lo, hi))
    assert logt.shape == (2, 2) and not clamped.any()
    # a window of solutions closing (two transitions meet): not one signature
    assert signatures._unify([(False, np.array([0.01, 0.02])), (False, np.empty(0))], (lo, hi)) is None


def test_variants_predict_a_clamped_transition_absent_next_to_the_range_end():
    """A transition clamped at the low end is predicted absent first where the interpolant puts
    it within its spread of that end (feasibility at the low end then flips), present first
    elsewhere; one clamped at the high end likewise (no flip); the other way comes next."""
    ends = (math.log(5e-4), math.log(200.0))
    lt = np.log([6e-4, 2.0])
    got = signatures._variants(lt, np.array([0.5, 1e-6]), np.array([1, 0]), ends)
    assert [(m.tolist(), f) for m, f in got] == [([False, True], True), ([True, True], False)]
    got = signatures._variants(np.log([0.01, 2.0]), np.array([0.05, 1e-6]), np.array([1, 0]), ends)
    assert [(m.tolist(), f) for m, f in got] == [([True, True], False), ([False, True], True)]
    got = signatures._variants(np.log([0.01, 190.0]), np.array([1e-6, 0.1]), np.array([0, 2]), ends)
    assert [(m.tolist(), f) for m, f in got] == [([True, False], False), ([True, True], False)]
    got = signatures._variants(np.log([0.01, 2.0]), np.array([1e-6, 1e-6]), np.array([0, 0]), ends)
    assert [(m.tolist(), f) for m, f in got] == [([True, True], False)]


def test_cluster_columns_keeps_interpolants_and_envelopes_the_clamped_one():
    """A deepest cell keeps each transition's interpolant unless it is clamped and answered, or
    its nodes' envelope states less than its estimate; an envelope that overlaps its neighbour's
    values is refused."""
    logt = np.log(np.array([[[5e-4, 2.0], [0.002, 2.01]], [[0.003, 2.02], [0.004, 2.03]]]))
    coef = chebyshev._coefficients(np.moveaxis(logt, -1, 0), 1, 1)
    errs = np.array([0.3, 1e-9])
    got, got_errs = signatures._cluster_columns(coef, errs, logt, [0])
    assert np.array_equal(got[1], coef[1]) and got_errs[1] == 1e-9
    assert np.count_nonzero(got[0]) == 1
    c0, c1 = math.log(5e-4), math.log(0.004)
    assert got[0, 0, 0] == pytest.approx(0.5 * (c0 + c1))
    assert got_errs[0] == pytest.approx(0.75 * (c1 - c0) / at.SAFETY)
    # a large estimate of eta_max is replaced by its (smaller) envelope
    _, e2 = signatures._cluster_columns(coef, np.array([0.3, 0.5]), logt, [0])
    assert e2[1] == pytest.approx(0.75 * math.log(2.03 / 2.0) / at.SAFETY)
    # eta_min's envelope reaching eta_max's values: refused
    close = logt.copy()
    close[..., 0] = np.log([[5e-4, 1.9], [0.003, 0.004]])
    assert signatures._cluster_columns(coef, errs, close, [0]) is None


def test_envelope_leaf_decides_where_its_nodes_agree():
    """A cell mixed at the deepest level becomes a leaf that decides where every node agrees
    (here: below the lowest and above the highest transition of any node) and leaves the
    cluster of transitions between undecided, with its width as the error."""
    traces = [(False, np.array([0.01, 2.0])), (False, np.array([0.012, 2.1])),
              (True, np.array([2.05]))]  # eta_min left the range at the third node
    low, logt, err = signatures._envelope(traces, 5e-4, 200.0)
    assert logt.size == 2 and (err > 0).all()
    # the cluster at the low end (5e-4 .. 0.012) and the one at 2.0 .. 2.1
    assert math.log(5e-4) <= logt[0] <= math.log(0.012)
    assert math.log(2.0) <= logt[1] <= math.log(2.1)
    assert at.SAFETY * err[0] >= 0.5 * (math.log(0.012) - math.log(5e-4))
    assert at.SAFETY * err[1] >= 0.5 * (math.log(2.1) - math.log(2.0)) and err[1] < err[0]
    # above 2.1 nobody has a solution, between 0.012 and 2.0 everybody has
    status = lambda x: bool(low) ^ (int(np.sum(logt < math.log(x))) % 2 == 1)  # noqa: E731
    assert status(0.5) and not status(50.0)
