"""The solve set of a sweep: which integrations, which ``eps K`` values each, in which blocks.

model.md's similarity: both stages depend on ``(eta = eps L, A, N)`` only, and ``eps``, ``K``
enter afterwards. A grid over ``(eps, L, K, A, N)`` therefore needs one integration per distinct
*triple* ``(eta, A, N)``; that triple's run of ``eps K`` values (one per grid point it serves)
goes into :func:`batch.solve_batch`'s ``offsets``. Without the reduction every grid point is its
own triple with one ``eps K``. Both use the same ``eta = eps * L`` product, so the integrations,
and with them every value, are bit-identical.

Triples are numbered so that per-triple arrays reshape onto the grid:

* reduced: ``t = (u * nA + a) * nN + n`` with ``u`` the index of ``eta`` among the sorted distinct
  products ``eps[i] * L[j]``; its entries are the ``(eps, L)`` pairs with that product (in pair
  order) times every ``K``;
* unreduced: ``t`` is the C-order flat index of the grid point.

Blocks are dealt so that every block costs about the same (see :func:`block_plan`). The blocks
are a function of the grid, the reduction, the block size and the tile shape of the result file
alone; only the *default* block size looks at the number of workers, and a resumed run takes its
block size from its store, so it finds the same blocks whatever ``--workers`` it is given.

*Groups*: with a tile shape (the boxes the result file is written in, :class:`.writer.Tiles`),
the tiles are joined into groups such that every triple's grid points lie in one group, and
each block holds triples of one group only. A group's tiles can then be written as soon as its
own blocks are done, while the other blocks are still being solved. A triple's points span its
``(eps, L)`` pairs times every ``K`` times its ``(A, N)``: the groups are the tiles' ``(A, N)``
boxes times the classes of ``(eps, L)`` boxes linked by a shared ``eta`` (reduced, and only when
a tile spans the whole ``K`` axis; otherwise one group holds every tile); unreduced, every tile
is a group.
"""

from __future__ import annotations

import hashlib
import math
import dataclasses
from dataclasses import dataclass

import numpy as np

from ..physics import analytic
from .. import status as st

# Default plan: at least this many blocks, BLOCKS_PER_WORKER per worker on more than 8 workers
# (fewer when there are fewer triples), each at most MAX_BLOCK_TRIPLES integrations and about
# MAX_BLOCK_ENTRIES eps K values (bounded memory per task). Enough blocks for balance and a live
# progress bar, few enough that the per-block overhead (a task, an .npz file) stays below 1 %.
DEFAULT_BLOCKS = 128
BLOCKS_PER_WORKER = 16
MAX_BLOCK_TRIPLES = 20_000
MAX_BLOCK_ENTRIES = 2_000_000

# Expected cost of a triple in microseconds (measured with solve_batch at rtol = 1e-8): a fixed
# part plus stage-1 steps that grow like 1/eta for small eta, a near-free classify rejection, and
# the root search of eq:13 per eps K value. Only the ordering matters: blocks are dealt from it.
COST_FIXED = 30.0
COST_PER_INV_ETA = 1.2
COST_REJECTED = 0.5
COST_PER_ENTRY = 0.75
# Triples per slice when the plan computes per-triple values (costs, groups): its temporaries
# then follow the slice, not the grid, and only the results are grid-sized.
SLICE = 1 << 20
# Bytes a plan takes at its peak per triple (costs, groups, the ranking, the blocks) and per
# (eps, L) pair of a reduced plan (the products, their sorting, the pair arrays kept): 74 per
# triple measured (tracemalloc) with one pair per triple, 2 x 10^7 of them.
PLAN_BYTES_PER_TRIPLE = 48
PLAN_BYTES_PER_PAIR = 40
# (eps, L) pairs up to which the distinct products are counted exactly before planning.
COUNT_PAIRS = 1 << 22


def count_triples(axes: dict, reduce: bool = True) -> int:
    """The number of integrations of a grid, before any plan is made: exact, or for a reduced
    grid of more than :data:`COUNT_PAIRS` ``(eps, L)`` pairs an upper bound (every product
    distinct), so that what depends on it is checked without grid-sized work."""
    n = {d: np.size(axes[d]) for d in ("eps", "L", "K", "A", "N")}
    if not reduce:
        return math.prod(n.values())
    pairs = n["eps"] * n["L"]
    if pairs <= COUNT_PAIRS:
        eps = np.asarray(axes["eps"], dtype=np.float64)
        L = np.asarray(axes["L"], dtype=np.float64)
        pairs = np.unique(eps[:, None] * L[None, :]).size
    return pairs * n["A"] * n["N"]


def plan_memory(shape, n_triples: int, reduce: bool = True) -> int:
    """Bytes a :class:`Plan` of ``n_triples`` integrations over ``shape`` takes at its peak."""
    pairs = shape[0] * shape[1] if reduce else 0
    return PLAN_BYTES_PER_TRIPLE * n_triples + PLAN_BYTES_PER_PAIR * pairs


def triple_costs(eta, A, N, entries) -> np.ndarray:
    """Expected cost of triples ``(eta, A, N)`` serving ``entries`` ``eps K`` values each
    (arbitrary units; see the ``COST_*`` constants)."""
    code = analytic.classify_points(eta, A, N)  # rejected triples cost next to nothing
    with np.errstate(over="ignore", divide="ignore"):  # only the order matters (inf is fine)
        cost = np.where(code == st.OK, COST_FIXED + COST_PER_INV_ETA / eta, COST_REJECTED)
    return cost + COST_PER_ENTRY * entries


@dataclass(frozen=True, eq=False)
class BlockInputs:
    """Arguments of one :func:`batch.solve_batch` call and where its ``eps K`` entries land.

    ``flat[j]`` is the C-order grid index of entry ``j``; ``owner[j]`` the position (within the
    block) of the triple that entry belongs to.
    """

    eta: np.ndarray
    A: np.ndarray
    N: np.ndarray
    eps_K: np.ndarray
    offsets: np.ndarray
    flat: np.ndarray

    def unpack(self) -> "BlockInputs":
        """These inputs (as :meth:`PackedInputs.unpack`)."""
        return self


@dataclass(frozen=True, eq=False)
class PackedInputs:
    """A reduced block's :class:`BlockInputs` without its ``eps K`` entries, to be sent where the
    block is solved: each triple's ``eps`` values (one per ``(eps, L)`` pair of its ``eta``, in
    pair order; ``pairs[i]`` of them for triple ``i``) and the ``K`` axis. A thousandth of the
    bytes of the entries, which :meth:`unpack` makes there (without ``flat``, the grid indices
    only the writing process needs).
    """

    eta: np.ndarray
    A: np.ndarray
    N: np.ndarray
    pair_eps: np.ndarray
    pairs: np.ndarray
    K: np.ndarray

    def unpack(self) -> BlockInputs:
        """The block's :class:`BlockInputs` (``flat`` empty): the entries are the products
        ``eps * K``, pair after pair, ``K`` fastest (:meth:`Plan.inputs` makes them here too)."""
        eps_K = (self.pair_eps[:, None] * self.K[None, :]).ravel()
        offsets = np.concatenate(([0], np.cumsum(self.pairs * self.K.size))).astype(np.int64)
        return BlockInputs(self.eta, self.A, self.N, eps_K, offsets, np.empty(0, dtype=np.int64))


class Plan:
    """The reduced (or unreduced) solve set of a grid and its division into blocks.

    Parameters
    ----------
    axes : dict
        ``{"eps": ..., "L": ..., "K": ..., "A": ..., "N": ...}``, 1-D float64 arrays.
    reduce : bool
        One integration per distinct ``(eps L, A, N)`` (True) or per grid point (False).
    block_size : int, optional
        Integrations per block; default from :data:`DEFAULT_BLOCKS` and the size bounds.
    workers : int
        Only sets the default block size (a resumed run takes the block size from its store).
    tile : tuple of int, optional
        Shape of the tiles the result is written in: blocks are dealt group by group (see the
        module docstring). Default: one group, the whole grid.

    Attributes
    ----------
    groups : list of ndarray
        Tile indices (C order of the tile grid) of each group.
    block_group : ndarray
        The group of each block; blocks are numbered group after group, the costliest groups
        first (the cheap ones finish the run, so little is left to write after the solve).
    """

    def __init__(self, axes: dict, reduce: bool = True, block_size: int | None = None,
                 workers: int = 1, tile=None):
        self.eps, self.L, self.K, self.A, self.N = (
            np.ascontiguousarray(axes[d], dtype=np.float64) for d in ("eps", "L", "K", "A", "N")
        )
        self.shape = (self.eps.size, self.L.size, self.K.size, self.A.size, self.N.size)
        self.size = math.prod(self.shape)
        self.reduce = bool(reduce)
        nE, nL, nK, nA, nN = self.shape
        if self.reduce:
            pair_eta = (self.eps[:, None] * self.L[None, :]).ravel()
            # Exact float equality: a shared product is the very same float in solve_point too.
            self.eta_u, self.inv = np.unique(pair_eta, return_inverse=True)
            del pair_eta
            self.inv = self.inv.ravel()
            self.pair_order = np.argsort(self.inv, kind="stable")
            counts = np.bincount(self.inv, minlength=self.eta_u.size)
            self.pair_start = np.concatenate(([0], np.cumsum(counts)))
            self.n_triples = self.eta_u.size * nA * nN
        else:
            self.n_triples = self.size
        if block_size is not None and (int(block_size) != block_size or block_size < 1):
            raise ValueError(f"block_size must be a positive integer; got {block_size!r}")
        if block_size is None:
            block_size = self._default_block_size(max(DEFAULT_BLOCKS, BLOCKS_PER_WORKER * workers))
        self.block_size = int(block_size)
        self.tile = self.shape if tile is None else tuple(min(int(t), n) for t, n in
                                                         zip(tile, self.shape))
        self.tile_grid = tuple(-(-n // t) for n, t in zip(self.shape, self.tile))
        triple_group, self.groups = self._groups()
        self.blocks, self.block_group = grouped_block_plan(self.costs(), triple_group,
                                                           self.block_size)

    # -- triples ------------------------------------------------------------------------------
    def triple_params(self, t: np.ndarray):
        """``(eta, A, N)`` of triples ``t`` (int64 array)."""
        nE, nL, nK, nA, nN = self.shape
        if self.reduce:
            u, a, n = t // (nA * nN), (t // nN) % nA, t % nN
            return self.eta_u[u], self.A[a], self.N[n]
        e, l, _, a, n = np.unravel_index(t, self.shape)
        return self.eps[e] * self.L[l], self.A[a], self.N[n]

    def entries_per_triple(self, t: np.ndarray) -> np.ndarray:
        """How many grid points (``eps K`` values) each triple serves."""
        if not self.reduce:
            return np.ones(t.size, dtype=np.int64)
        u = t // (self.shape[3] * self.shape[4])
        return (self.pair_start[u + 1] - self.pair_start[u]) * self.shape[2]

    def costs(self) -> np.ndarray:
        """Expected cost of every triple (arbitrary units; see the ``COST_*`` constants)."""
        out = np.empty(self.n_triples)
        for lo in range(0, self.n_triples, SLICE):
            t = np.arange(lo, min(self.n_triples, lo + SLICE), dtype=np.int64)
            out[lo:lo + t.size] = triple_costs(*self.triple_params(t), self.entries_per_triple(t))
        return out

    def _groups(self):
        """``(group of every triple, tile indices of every group)``; see the module docstring."""
        nE, nL, nK, nA, nN = self.shape
        te, tl, tk, ta, tn = self.tile
        ge, gl, gk, ga, gn = self.tile_grid
        all_tiles = np.arange(math.prod(self.tile_grid), dtype=np.int64).reshape(self.tile_grid)
        if not self.reduce:
            # Every triple is a grid point: its tile is its group.
            tile = np.empty(self.size, dtype=np.int64)
            for lo in range(0, self.size, SLICE):
                t = np.arange(lo, min(self.size, lo + SLICE), dtype=np.int64)
                e, l, k, a, n = np.unravel_index(t, self.shape)
                tile[lo:lo + t.size] = np.ravel_multi_index(
                    (e // te, l // tl, k // tk, a // ta, n // tn), self.tile_grid)
            return tile, [np.array([i]) for i in range(all_tiles.size)]
        if gk != 1:
            return np.zeros(self.n_triples, dtype=np.int64), [all_tiles.ravel()]
        # Classes of (eps, L) boxes: union-find over the boxes of the pairs sharing an eta.
        box = ((np.arange(nE)[:, None] // te) * gl + np.arange(nL)[None, :] // tl).ravel()
        parent = np.arange(ge * gl)

        def root(i):
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        pair_box = box[self.pair_order]
        shared = np.flatnonzero(np.diff(self.inv[self.pair_order]) == 0)
        for j in shared[pair_box[shared] != pair_box[shared + 1]]:
            parent[root(pair_box[j])] = root(pair_box[j + 1])
        roots = np.array([root(i) for i in range(ge * gl)])
        _, cls = np.unique(roots, return_inverse=True)
        n_cls = int(cls.max()) + 1
        # eta u's class: that of its first pair (all its pairs are in one class).
        u_cls = cls[box[self.pair_order[self.pair_start[:-1]]]]
        group = np.empty(self.n_triples, dtype=np.int64)
        for lo in range(0, self.n_triples, SLICE):
            t = np.arange(lo, min(self.n_triples, lo + SLICE), dtype=np.int64)
            u, a, n = t // (nA * nN), (t // nN) % nA, t % nN
            group[lo:lo + t.size] = (u_cls[u] * ga + a // ta) * gn + n // tn
        tiles_el = all_tiles[:, :, 0].reshape(ge * gl, ga, gn)
        groups = [tiles_el[cls == c, i, j].ravel() for c in range(n_cls)
                  for i in range(ga) for j in range(gn)]
        return group, groups

    def _default_block_size(self, n_blocks: int) -> int:
        n = self.n_triples
        entries_per = max(1.0, self.size / n)
        size = math.ceil(n / n_blocks)
        return max(1, min(size, MAX_BLOCK_TRIPLES, int(MAX_BLOCK_ENTRIES // entries_per)))

    def digest(self) -> str:
        """sha256 of the block plan: the same digest means the same blocks in the same order."""
        h = hashlib.sha256()
        h.update(np.asarray(self.shape, dtype=np.int64).tobytes())
        h.update(b"reduced" if self.reduce else b"unreduced")
        for b in self.blocks:
            h.update(np.int64(b.size).tobytes())
            h.update(b.tobytes())
        if len(self.groups) > 1:  # one group: the digest of the plan before groups existed
            h.update(np.asarray(self.tile, dtype=np.int64).tobytes())
            h.update(self.block_group.tobytes())
        return h.hexdigest()

    # -- blocks -------------------------------------------------------------------------------
    def inputs(self, k: int) -> BlockInputs:
        """Kernel inputs of block ``k``, with the grid index of every entry (``flat``)."""
        t = self.blocks[k]
        nE, nL, nK, nA, nN = self.shape
        if not self.reduce:
            eta, A, N = self.triple_params(t)
            e, _, kk, _, _ = np.unravel_index(t, self.shape)
            eps_K = self.eps[e] * self.K[kk]
            offsets = np.arange(t.size + 1, dtype=np.int64)
            return BlockInputs(eta, A, N, eps_K, offsets, t.copy())
        # The entries come in runs of nK (one triple, one (eps, L) pair, every K): the grid index
        # of a run's first entry, then K's stride in the grid.
        pair, a, n = self._runs(t)
        first = (pair * nK * nA + a) * nN + n
        flat = (first[:, None] + (nA * nN) * np.arange(nK, dtype=np.int64)).ravel()
        return dataclasses.replace(self.packed_inputs(k).unpack(), flat=flat)

    def solve_inputs(self, k: int) -> BlockInputs:
        """Block ``k``'s inputs as the solve takes them: :meth:`inputs` without ``flat`` (the
        grid indices only the writing process needs), made as a worker makes them."""
        return self.packed_inputs(k).unpack()

    def packed_inputs(self, k: int):
        """Block ``k``'s inputs to send to a worker: :class:`PackedInputs` (reduced), or its
        :class:`BlockInputs` without ``flat`` (unreduced: one entry per triple, nothing to pack)."""
        if not self.reduce:
            return dataclasses.replace(self.inputs(k), flat=np.empty(0, dtype=np.int64))
        t = self.blocks[k]
        eta, A, N = self.triple_params(t)
        u = t // (self.shape[3] * self.shape[4])
        pairs = self.pair_start[u + 1] - self.pair_start[u]
        pair, _, _ = self._runs(t)
        return PackedInputs(eta, A, N, self.eps[pair // self.shape[1]], pairs, self.K)

    def _runs(self, t: np.ndarray):
        """``(pair, a, n)`` of every run of a reduced block of triples ``t``: a run is one triple
        and one ``(eps, L)`` pair of its ``eta`` (the pair's C-order index), in pair order, triple
        after triple; its ``nK`` entries follow each other, ``K`` fastest."""
        nA, nN = self.shape[3:]
        u, a, n = t // (nA * nN), (t // nN) % nA, t % nN
        pairs = self.pair_start[u + 1] - self.pair_start[u]
        owner = np.repeat(np.arange(t.size), pairs)
        first = np.concatenate(([0], np.cumsum(pairs)))[:-1]
        pair = self.pair_order[self.pair_start[u[owner]] + np.arange(owner.size) - first[owner]]
        return pair, a[owner], n[owner]

    @property
    def runs_along_K(self) -> bool:
        """Whether each block's entries come in runs along the whole ``K`` axis of a tile
        (:meth:`tile_runs`): reduced, with tiles that span ``K``."""
        return self.reduce and self.tile[2] == self.shape[2]

    def tile_runs(self, k: int):
        """``(tile, local, stride)`` of each run of block ``k``'s entries (see :meth:`_runs`): its
        tile (C order of the tile grid), the C-order index inside that tile (edge tiles are
        smaller) of its first entry and the stride of ``K`` there; or None where this does not
        apply (not :attr:`runs_along_K`). Entry ``j`` of a run lies at ``local + j * stride``."""
        nE, nL, nK, nA, nN = self.shape
        te, tl, tk, ta, tn = self.tile
        if not self.runs_along_K:
            return None
        pair, a, n = self._runs(self.blocks[k])
        e, l = pair // nL, pair % nL
        ge, gl, _, ga, gn = self.tile_grid
        tile = (((e // te) * gl + l // tl) * ga + a // ta) * gn + n // tn
        ext_l = np.minimum(tl, nL - (l // tl) * tl)
        ext_a = np.minimum(ta, nA - (a // ta) * ta)
        ext_n = np.minimum(tn, nN - (n // tn) * tn)
        stride = ext_a * ext_n  # of K inside the tile
        local = ((e % te) * ext_l + l % tl) * nK * stride + (a % ta) * ext_n + n % tn
        return tile, local, stride

    def tile_local(self, k: int):
        """``(tile, local)`` of block ``k``'s entries, in :meth:`inputs` order: each entry's tile
        and C-order index inside it (:meth:`tile_runs` spread over the runs' entries), or None
        where :meth:`tile_runs` is."""
        runs = self.tile_runs(k)
        if runs is None:
            return None
        tile, local, stride = runs
        nK = self.shape[2]
        kk = np.arange(nK, dtype=np.int64)
        return np.repeat(tile, nK), (local[:, None] + stride[:, None] * kk).ravel()

    def to_grid(self, per_triple: np.ndarray, spread: bool = True) -> np.ndarray:
        """Spread per-triple values (leading axis ``n_triples``) onto the grid (a new array);
        see :meth:`Region.to_grid` for ``spread``."""
        return self.region().to_grid(per_triple, spread)

    def region(self, slices=None) -> "Region":
        """The box of the grid given by one slice per axis (default: the whole grid)."""
        return Region(self, slices)


class Region:
    """A box of a plan's grid, one ``slice`` per axis: its axis values, and per-triple values
    spread onto it, so that a result can be built (and written) one box at a time.

    Attributes ``eps``, ``L``, ``K``, ``A``, ``N`` (the box's axis values), ``shape`` and
    ``reduce`` mirror :class:`Plan`'s, so the functions of :mod:`.dataset` take either.
    """

    def __init__(self, plan: Plan, slices=None):
        self.plan = plan
        self.slices = tuple(slices) if slices is not None else (slice(None),) * 5
        self.eps, self.L, self.K, self.A, self.N = (
            axis[s] for axis, s in zip((plan.eps, plan.L, plan.K, plan.A, plan.N), self.slices))
        self.shape = (self.eps.size, self.L.size, self.K.size, self.A.size, self.N.size)
        self.reduce = plan.reduce

    def to_grid(self, per_triple: np.ndarray, spread: bool = True) -> np.ndarray:
        """Spread per-triple values (leading axis ``n_triples``) onto the box (a new array).

        ``spread=False``: reduced, the values do not depend on ``K``, so the ``K`` axis is left
        at length 1 (broadcastable onto the box, a ``K``-th of the memory and of the work of
        anything computed from it); unreduced, the box as with ``spread=True``.
        """
        p = self.plan
        trailing = per_triple.shape[1:]
        se, sl, sk, sa, sn = self.slices
        if not p.reduce:
            return per_triple.reshape(p.shape + trailing)[se, sl, sk, sa, sn].copy()
        nE, nL, nK, nA, nN = p.shape
        by_u = per_triple.reshape((p.eta_u.size, nA, nN) + trailing)[:, sa, sn]
        by_pair = by_u[p.inv.reshape(nE, nL)[se, sl]]  # (box eps, box L, box A, box N, ...)
        if not spread:
            return by_pair[:, :, None]
        out = np.empty(self.shape + trailing, dtype=per_triple.dtype)
        out[...] = by_pair[:, :, None]
        return out


def grouped_block_plan(cost: np.ndarray, group: np.ndarray, block_size: int):
    """``(blocks, block_group)``: the triples of each group dealt into blocks by :func:`block_plan`,
    groups in order of falling total cost (empty groups get no block)."""
    n_groups = int(group.max()) + 1 if group.size else 0
    total = np.bincount(group, weights=cost, minlength=n_groups)
    # Triples by group, ascending within each; one group (the common case) needs no sorting.
    order = np.argsort(group, kind="stable") if n_groups > 1 else np.arange(group.size)
    bounds = np.concatenate(([0], np.cumsum(np.bincount(group, minlength=n_groups))))
    blocks, block_group = [], []
    for g in np.argsort(-total, kind="stable"):
        members = order[bounds[g]:bounds[g + 1]]
        if members.size:
            for b in block_plan(cost[members], block_size):
                blocks.append(members[b])
                block_group.append(g)
    return blocks, np.asarray(block_group, dtype=np.int64)


def block_plan(cost: np.ndarray, block_size: int) -> list[np.ndarray]:
    """Deal triples into ``ceil(n / block_size)`` blocks of near-equal expected cost.

    Triples sorted by falling cost are dealt like cards in a snake (0, 1, ..., B-1, B-1, ..., 0,
    0, 1, ...): every block gets one triple from each band of the ranking, so blocks cost about
    the same even where cost varies by orders of magnitude (small eta), and no worker is left
    with the expensive corner of the grid. Each block's triples come back sorted by index.
    """
    n = cost.size
    n_blocks = max(1, math.ceil(n / block_size))
    rank = np.argsort(-cost, kind="stable")
    # Block k takes the ranks k and 2B - 1 - k of every round of 2B (B blocks): the snake read
    # off directly, so that no other grid-sized array is made.
    period = 2 * n_blocks
    return [np.sort(np.concatenate((rank[k::period], rank[period - 1 - k::period])))
            .astype(np.int64) for k in range(n_blocks)]
