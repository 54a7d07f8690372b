"""Where the blocks run: the local pool of threads (the distributed path is tested with the
engine, tests/test_sweep_engine.py)."""

import threading
import time

import pytest

from cosserat_channel.sweep import block, schedulers


class Store:
    """Records the blocks started and stored."""

    def __init__(self):
        self.stored, self.started, self.lock = [], [], threading.Lock()

    def put(self, k, out):
        with self.lock:
            self.stored.append(k)


def test_a_failing_block_ends_the_run_after_the_blocks_in_flight_are_stored(monkeypatch):
    """The first block raises while the second is being solved: the error comes out only after
    the second is stored (nothing writes into the store while the caller cleans up), and the
    blocks not yet started are dropped."""
    store = Store()

    def fake_block(plan, k, args):
        with store.lock:
            store.started.append(k)
        if k == 0:
            time.sleep(0.05)
            raise RuntimeError("block 0 failed")
        time.sleep(0.3)
        return {"k": k}

    monkeypatch.setattr(block, "_block_task", fake_block)
    with pytest.raises(RuntimeError, match="block 0 failed"):
        schedulers._run_threads(None, list(range(40)), store, None, 2, lambda: None)
    with store.lock:
        started, stored = sorted(store.started), sorted(store.stored)
    assert 1 in started and len(started) < 40
    # every block that started (but the failing one) was stored before the error came out
    assert stored == [k for k in started if k != 0]
    assert not [t for t in threading.enumerate() if t.name.startswith("cc-solve")]
