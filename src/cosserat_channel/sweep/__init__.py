"""Parameter sweeps: sweep file -> validated spec (:mod:`.spec`) -> solved grid -> labelled Dataset."""

from .engine import run_sweep  # noqa: E402  (the engine's public entry point)
