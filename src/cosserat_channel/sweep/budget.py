"""What a sweep will take before it starts: disk for the file and the working store, and memory.

A run is refused before any large allocation when the machine lacks either (see
:func:`.engine.run_sweep`).
"""

from __future__ import annotations

import logging
import os


from .. import outputs as out_
from ..solver import layout
from ..files import format_size
from . import writer as writer_
from .plan import DEFAULT_BLOCKS, MAX_BLOCK_ENTRIES, plan_memory
from .spec import SweepSpec
from .store import partial_dir
from .writer import BUCKET

log = logging.getLogger("cosserat_channel.sweep")


def disk_needed(spec: SweepSpec, n_triples: int, xi, output: str) -> int:
    """Bytes the run will still put on disk at its peak: the result file uncompressed (an upper
    bound), the working store's blocks, the tile buckets and the writer's mapped arrays
    (:mod:`.writer`), less what an earlier run of the same output already left in the store.
    ``n_triples``: the integrations (:func:`.plan.count_triples`, an upper bound will do)."""
    n_xi = 0 if xi is None else xi.size
    plug_edge = out_.needs_plug_edge(spec.variables)
    result = spec.size * _bytes_per_point(spec, n_xi)
    store = n_triples * (8 * layout.N_R + 16 + 8 + 8 * layout.N_PROF * n_xi)
    if plug_edge:
        store += spec.size * (8 + BUCKET.itemsize)
    held = n_triples * writer_.bytes_per_triple(n_xi)
    if held > writer_.WRITER_MEMORY:
        store += held
    have = 0
    for root, _, files in os.walk(partial_dir(output)):
        have += sum(os.lstat(os.path.join(root, f)).st_size for f in files)
    return max(0, result + store - have)


def _bytes_per_point(spec: SweepSpec, n_xi: int) -> int:
    """Bytes of one grid point in the result: its variables (float64 outputs, int32 counters),
    status, and the profiles' four float64 rows."""
    return 1 + sum(8 if v in out_.OUTPUTS else 4 for v in spec.variables) + 4 * 8 * n_xi


# What a run holds besides its plan and the writer's per-integration arrays: the tiles being
# derived and encoded (.writer, .encode: a dozen tile-sized temporaries, near 200 MB, one per
# worker at once and one more being placed or written), the plug-edge values of the group being
# written (.writer.GROUP_POINTS at most) and, per worker, the block being solved and stored (its
# eps K entries with their grid indices, owners and plug-edge values).
TILE_MEMORY = 200 << 20
BLOCK_BYTES_PER_ENTRY = 64


def memory_needed(spec: SweepSpec, n_triples: int, xi, output, reduce: bool,
                  workers: int) -> int:
    """Bytes a run holds at its peak, from the grid's counts alone (``n_triples`` from
    :func:`.plan.count_triples`): the plan, the per-integration arrays the writer (or, without
    a file, the in-memory result) keeps, the tiles in flight and the blocks being solved."""
    n_xi = 0 if xi is None else xi.size
    need = plan_memory(spec.shape, n_triples, reduce)
    held = n_triples * writer_.bytes_per_triple(n_xi)
    if output is None:  # everything in memory, the grid-sized result twice while it is built
        need += held + 2 * spec.size * _bytes_per_point(spec, n_xi)
    else:  # beyond WRITER_MEMORY the writer maps its arrays onto the disk
        need += (held if held <= writer_.WRITER_MEMORY else 0) + (workers + 1) * TILE_MEMORY
        if out_.needs_plug_edge(spec.variables):  # a group's plug-edge values, regrouped
            need += 8 * min(spec.size, writer_.GROUP_POINTS)
    # A block holds whole integrations, about 1/DEFAULT_BLOCKS of the grid up to
    # MAX_BLOCK_ENTRIES entries (.plan), and at least one integration's entries.
    per_triple = -(-spec.size // max(1, n_triples))
    entries = min(spec.size, max(per_triple, min(MAX_BLOCK_ENTRIES,
                                                 -(-spec.size // DEFAULT_BLOCKS))))
    return need + workers * entries * BLOCK_BYTES_PER_ENTRY


def available_memory() -> int | None:
    """Bytes this process may still take: the system's MemAvailable, or the memory left under
    the cgroup's limit (a batch job's, a container's) when that is less; None when unknown."""
    found = []
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    found.append(int(line.split()[1]) * 1024)
    except (OSError, ValueError, IndexError):
        pass
    try:
        with open("/sys/fs/cgroup/memory.max") as f:
            limit = f.read().strip()
        with open("/sys/fs/cgroup/memory.current") as f:
            current = int(f.read().strip())
        if limit != "max":
            found.append(max(0, int(limit) - current))
    except (OSError, ValueError):
        pass
    return min(found) if found else None


def memory_problem(need: int) -> str | None:
    """Why ``need`` bytes will not fit in memory (one line), or None when they will (or when the
    system cannot say)."""
    free = available_memory()
    if free is None or need <= free:
        return None
    return (f"grid: the run needs about {format_size(need)} of memory and {format_size(free)} "
            "is available; split the sweep into smaller ones (fewer distinct eps L, A and N "
            "values each), or run it where there is more")
