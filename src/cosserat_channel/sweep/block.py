"""One block of a sweep: the batch kernel on a block's integrations, and the kernels' warm-up.

:func:`solve_block` is what a thread or a cluster worker runs; it returns the arrays the working
store keeps (:mod:`~cosserat_channel.sweep.store`).
"""

from __future__ import annotations

import logging

import numpy as np

from ..solver import batch, layout, stage1, stage2
from .. import status as st
from .plan import BlockInputs, Plan

log = logging.getLogger("cosserat_channel.sweep")


def solve_block(inp: BlockInputs, rtol: float, atol: float, xi=None, stage2=True,
                plug_edge=True) -> dict:
    """Run :func:`batch.solve_batch` on one block; returns the arrays the store keeps.

    ``stage2`` / ``plug_edge``: whether the sweep's variables need the velocity stage and the
    eq:13 root (:func:`outputs.needs_stage2`); what is not needed is not computed.
    """
    need = (stage2, plug_edge)
    n = inp.eta.size
    res = np.empty((n, layout.N_R))
    stats = batch.new_statistics(n, 2)
    one_minus = np.empty(inp.eps_K.size)
    xi_k = np.empty(0) if xi is None else xi
    prof = np.empty((n, layout.N_PROF, xi_k.size))
    try:
        _batch(inp, slice(0, n), rtol, atol, xi_k, res, stats, one_minus, prof, need)
    except ArithmeticError:
        # The kernel raised on some triple (a bug at a boundary of the domain, e.g. an axis
        # margin of exactly 0): redo the block triple by triple so that only that triple is lost,
        # reported as integration_failed, instead of the whole run.
        for i in range(n):
            try:
                _batch(inp, slice(i, i + 1), rtol, atol, xi_k, res, stats, one_minus, prof, need)
            except ArithmeticError as exc:
                log.warning("kernel raised %s at eta=%r, A=%r, N=%r; reported as "
                            "integration_failed", type(exc).__name__, float(inp.eta[i]),
                            float(inp.A[i]), float(inp.N[i]))
                res[i] = np.nan
                res[i, layout.R_STATUS] = st.INTEGRATION_FAILED
                stats[i] = 0
                one_minus[inp.offsets[i]:inp.offsets[i + 1]] = np.nan
                prof[i] = np.nan
    out = {
        "res": res,
        "steps": batch.accepted_steps(stats),
        "one_minus": one_minus,
    }
    if xi is not None:
        out["profiles"] = prof
    return out


def _batch(inp: BlockInputs, sl: slice, rtol, atol, xi_k, res, stats, one_minus, prof,
           need) -> None:
    """solve_batch on triples ``sl`` of the block (views: results land in the block's arrays)."""
    lo, hi = inp.offsets[sl.start], inp.offsets[sl.stop]
    offsets = inp.offsets[sl.start:sl.stop + 1] - lo
    batch.solve_batch(inp.eta[sl], inp.A[sl], inp.N[sl], inp.eps_K[lo:hi], offsets, rtol, atol,
                      stage1.MAX_STEPS_STAGE1, stage2.MAX_STEPS_STAGE2, res[sl], stats[sl],
                      one_minus[lo:hi], xi_k, prof[sl], need[0], need[1])


def _block_task(plan: Plan, k: int, args) -> dict:
    # Build the inputs inside the task: a block's eps K arrays exist only while it runs.
    out = solve_block(plan.solve_inputs(k), *args)
    out["triples"] = plan.blocks[k]
    return out


def warm_up() -> None:
    """Load (or compile) the kernels once, here, before threads or workers race to do it."""
    inp = BlockInputs(np.array([0.3]), np.array([1 / 3]), np.array([1.0]), np.array([0.05]),
                      np.array([0, 1]), np.array([0]))
    solve_block(inp, 1e-6, 1e-10, np.array([0.0, 1.0]))
    solve_block(inp, 1e-6, 1e-10, None)
