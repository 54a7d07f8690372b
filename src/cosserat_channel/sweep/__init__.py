"""Parameter sweeps: sweep file -> validated spec (:mod:`.spec`) -> solved grid -> labelled Dataset.

``run_sweep`` is imported on first use, so that parsing a sweep file (:mod:`.spec`) never loads
the kernels.
"""

__all__ = ["run_sweep"]


def __getattr__(name):
    if name == "run_sweep":
        from .engine import run_sweep

        return run_sweep
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
