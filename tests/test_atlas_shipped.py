"""The whole-plane atlas the package carries (``atlas/data``), against independent references:
fresh traces at random (A, N) over the whole plane and at the atlas's own nodes, direct status
solves for ``classify``, and the build command that made it (``make atlas``).

Building the whole plane takes minutes (``benchmarks/bench_atlas.py --plane`` measures it); these
tests check the shipped file where a fresh computation is cheap: one trace or one solve at a time.
"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import numpy as np
import pytest

from cosserat_channel import atlas as at
from cosserat_channel import regimes
from cosserat_channel import status as st
from cosserat_channel.physics import model
from cosserat_channel.solver.point import Workspace

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def shipped():
    path = at.shipped_path()
    assert path is not None, "the package carries no whole-plane atlas (make atlas)"
    return at.load_atlas(path)


def test_it_is_the_whole_plane_at_the_default_tolerance(shipped):
    """Box, tolerance and depth are the defaults of ``atlas``; every leaf is resolved and within
    tol or an envelope with its own stated error; the cost is recorded."""
    assert shipped.box == (*at.DEFAULT_A, *at.DEFAULT_N)
    assert shipped.tol == at.DEFAULT_TOL and shipped.max_depth == at.MAX_DEPTH
    assert (shipped.leaf_n >= 0).all()
    assert np.isfinite(shipped.leaf_error).all()
    assert 0 < shipped.attrs["solves_per_edge_point"] <= 6


def test_make_atlas_builds_it_with_the_defaults():
    """The Makefile's ``atlas`` target writes the shipped file with the box and tolerance read
    back above, and nothing else that changes the build (a rebuild gives the same file:
    ``test_atlas.test_threads_build_the_same_atlas``)."""
    text = (ROOT / "Makefile").read_text().replace("\\\n", " ")
    line = re.search(r"^atlas:.*\n\t(.*)$", text, flags=re.M).group(1)
    words = shlex.split(line)
    assert words[1] == "atlas"
    args = dict(w.split("=", 1) if "=" in w else (w, None) for w in words[2:] if w.startswith("-"))
    assert args["--A"] == "%g:%g" % at.DEFAULT_A and args["--N"] == "%g:%g" % at.DEFAULT_N
    assert float(words[words.index("--tol") + 1]) == at.DEFAULT_TOL
    out = words[words.index("-o") + 1]
    assert ROOT / out == Path(at.shipped_path())
    assert not {"--degree", "--max-depth", "--max-degree", "--eta-range"} & set(args)


def test_transitions_agree_with_fresh_traces_over_the_plane(shipped):
    """At random (A, N) over the whole plane (and next to A = -1, the wall line, the node/focus
    switch and N = 1), a fresh trace finds the atlas's transitions, each within
    SAFETY * max(tol, the leaf's stated error, its noise band)."""
    rng = np.random.default_rng(2026)
    A = np.r_[rng.uniform(-1, 5, 10), -1 + 10 ** rng.uniform(-3, -1, 2), rng.uniform(0, 1, 3)]
    N = np.r_[rng.uniform(0.3, 3, 10), rng.uniform(0.5, 2, 2), rng.uniform(0.9, 1.1, 3)]
    # Next to the wall line A = 1 - 2 N^2 and the node/focus switch N^2 = (5 + 3 A) / 2.
    A = np.r_[A, 1 - 2 * 0.8**2 + 1e-3, 0.5]
    N = np.r_[N, 0.8, np.sqrt((5 + 3 * 0.5) / 2) + 1e-3]
    keep = (A > -1) & (A > 1 - 2 * N**2 + 1e-9)
    A, N = A[keep], N[keep]
    leaf, _, eta, err = shipped.transitions(A, N)
    lo, hi = shipped.eta_range
    checked = 0
    for k in range(A.size):
        edge = regimes.trace_edge(A[k], N[k], eta_range=(lo / at.TRACE_WIDEN, hi * at.TRACE_WIDEN))
        mine = eta[k][np.isfinite(eta[k])]
        theirs = edge.transitions
        inside = (theirs >= lo) & (theirs <= hi)
        band = at.SAFETY * max(shipped.tol, float(np.nanmax(np.r_[err[k], 0.0])),
                               float(shipped.leaf_band[leaf[k]]))
        for t in theirs[inside]:
            assert np.min(np.abs(np.log(mine / t))) <= band, (A[k], N[k], mine, theirs)
            checked += 1
    assert checked >= 10


def test_the_paper_point_and_its_row_are_within_tol(shipped):
    """Along N = 1, where eta_min leaves the traced range, eta_max is interpolated, not an
    envelope: at the paper's A = 1/3 and across the row it is within SAFETY * tol of a fresh
    trace, and the atlas states no more than tol for it."""
    A = np.r_[1 / 3, np.linspace(-0.5, 2.5, 5)]
    got = shipped.boundary(A, [1.0])
    lo, hi = shipped.eta_range
    for k, a in enumerate(A):
        edge = regimes.trace_edge(a, 1.0, eta_range=(lo / at.TRACE_WIDEN, hi * at.TRACE_WIDEN))
        eta_max = float(got["eta_max"].values[k, 0])
        inside = edge.transitions[(edge.transitions > lo) & (edge.transitions < hi)]
        if not inside.size:  # eta_max beyond the range: the atlas says so
            assert eta_max == hi, (a, eta_max, edge.transitions)
            continue
        assert abs(np.log(eta_max / inside[-1])) <= at.SAFETY * shipped.tol, (a, eta_max)
        assert float(got["eta_error"].values[k, 0]) <= shipped.tol, a


def test_its_nodes_are_what_a_fresh_trace_gives(shipped):
    """At a few of the atlas's own nodes, spread over the plane, a fresh trace (no prediction)
    has the transitions the file keeps, to the tolerance it was traced at."""
    s = shipped.samples
    rng = np.random.default_rng(7)
    n_tr = np.asarray(s["n"])
    pick = rng.choice(np.flatnonzero(n_tr > 0), 8, replace=False)
    lo, hi = shipped.eta_range
    for k in pick:
        edge = regimes.trace_edge(float(s["A"][k]), float(s["N"][k]),
                                  eta_range=(lo / at.TRACE_WIDEN, hi * at.TRACE_WIDEN))
        kept = np.asarray(s["transitions"][k])
        kept = kept[np.isfinite(kept)]
        assert kept.size == edge.transitions.size, (s["A"][k], s["N"][k], kept, edge.transitions)
        bands = np.asarray(s["bands"][k])[: kept.size] if "bands" in s else np.zeros(kept.size)
        tol = at.SAFETY * np.fmax(shipped.tol, np.nan_to_num(bands))
        assert (np.abs(np.log(kept / edge.transitions)) <= tol).all(), (s["A"][k], s["N"][k])


def test_classify_without_an_atlas_uses_it_and_agrees_with_solves(shipped):
    """``classify`` with no atlas decides from the shipped one: over the whole plane, every
    decided point has the status a direct solve gives, and at most 1 % are undecided."""
    rng = np.random.default_rng(11)
    n = 300
    A, N = rng.uniform(-1, 5, n), rng.uniform(0.3, 3, n)
    L = 100.0
    eta = 10 ** rng.uniform(-3, 2, n)
    codes = at.classify(eta / L, L, 0.5, A, N)
    assert np.array_equal(codes, at.classify(eta / L, L, 0.5, A, N, atlas=shipped))
    ws = Workspace(max_steps_stage1=regimes.EDGE_MAX_STEPS)
    direct = []
    for e, a, b in zip(eta, A, N):
        code = model.classify(e, a, b)
        if code == st.OK and a != -1.0:
            code = ws.status(e, a, b, regimes.EDGE_RTOL, regimes.EDGE_ATOL)
        direct.append(code)
    direct = np.array(direct)
    decided = codes != at.UNDECIDED
    assert np.array_equal(codes[decided], direct[decided])
    assert decided.mean() >= 0.99


def test_threads_loading_it_at_once_share_one_load(monkeypatch):
    # The explorer and users' threads call classify() concurrently; HDF5 as the wheels build it
    # is not thread-safe, so the store reads an atlas once, under a lock, and every thread gets
    # that one object.
    import threading

    from cosserat_channel.atlas import store

    path = store.shipped_path()
    if path is None:
        pytest.skip("this copy of the package carries no atlas")
    monkeypatch.setattr(store, "_LOADED", {})
    loads = []
    real = store.load_atlas

    def counted(p):
        loads.append(p)
        return real(p)

    monkeypatch.setattr(store, "load_atlas", counted)
    got = [None] * 8
    start = threading.Barrier(len(got))

    def load(i):
        start.wait()
        got[i] = store._load_once(path)

    threads = [threading.Thread(target=load, args=(i,)) for i in range(len(got))]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert len(loads) == 1
    assert all(a is got[0] for a in got)
