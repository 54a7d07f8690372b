"""Whether the workers of a dask cluster run the package sources this process runs.

A worker started from another source tree (another checkout, an older installation, a
``PYTHONPATH`` of its own, another user's worker on a shared scheduler) imports its own
``cosserat_channel`` and computes blocks with it: the result would mix two solvers and look like
any other file. So every worker present when the client connects is asked for its
:func:`cosserat_channel.source_digest`, and every block carries the digest of the worker that
computed it (a worker may join later): a block from other sources is never stored.
"""

from __future__ import annotations

import re
from functools import lru_cache

_HEX = re.compile(r"[0-9a-f]{64}")
REMEDY = ("its blocks would differ silently; start every worker from this installation (the "
          "same sources), or use a scheduler of your own")


@lru_cache(maxsize=1)
def digest() -> str:
    """This process's :func:`cosserat_channel.source_digest`, computed once (a worker gives it
    with every block)."""
    from .. import source_digest

    return source_digest()


def foreign_workers(client) -> dict:
    """``{address: its digest, or why it gave none}`` of the cluster's workers whose sources
    differ from this process's (empty when all agree, or when there is no worker yet)."""
    from .. import source_digest

    # Pickled by reference: each worker runs the function of the package it imports, so it
    # answers with the digest of its own sources.
    theirs = client.run(source_digest, on_error="return")
    mine = digest()
    return {address: d if isinstance(d, str) else f"{type(d).__name__}: {d}"
            for address, d in theirs.items() if d != mine}


def refusal(foreign: dict) -> str:
    """One line naming the first of the workers ``foreign`` (:func:`foreign_workers`)."""
    address, theirs = sorted(foreign.items())[0]
    if isinstance(theirs, str) and _HEX.fullmatch(theirs):
        what = (f"worker {address} runs other cosserat_channel sources (sha256 {theirs[:12]}..., "
                f"this process {digest()[:12]}...)")
    else:
        what = (f"worker {address} does not show that it runs this process's cosserat_channel "
                f"sources ({' '.join(str(theirs).split())})")
    more = f" (and {len(foreign) - 1} other worker(s))" if len(foreign) > 1 else ""
    return f"{what}{more}: {REMEDY}"


def stamp(out: dict) -> dict:
    """``out`` (a block, on a worker) with this worker's digest, for :func:`foreign_block`."""
    out["sources"] = digest()
    return out


def foreign_block(out, address: str) -> str | None:
    """One line if the block ``out`` was not computed by this process's sources, else None."""
    theirs = out.get("sources") if isinstance(out, dict) else None
    if theirs == digest():
        return None
    return refusal({address: theirs if theirs is not None else "its block carries no digest"})
