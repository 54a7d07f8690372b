"""Parameter sweeps: sweep file -> validated spec (:mod:`.spec`) -> solved grid -> labelled Dataset.

The pipeline is :mod:`.engine`; it plans the blocks (:mod:`.plan`), checks the disk and memory
they need (:mod:`.budget`), solves them (:mod:`.block`) on threads or a cluster
(:mod:`.schedulers`), keeps each in the working store (:mod:`~cosserat_channel.sweep.store`)
and writes the file tile by tile (:mod:`.writer`, :mod:`.dataset`). :mod:`.arrays` solves
arrays of points in memory the same way, without a file.

``run_sweep`` is imported on first use, so that parsing a sweep file (:mod:`.spec`) never loads
the kernels.

Layer: above :mod:`cosserat_channel.solver` (its batch kernel and slot layout) and the
vocabulary modules (parameters, outputs, status, files, netcdf_policy); beside the results
reader (:mod:`cosserat_channel.results`, whose flags the Dataset writes);
:mod:`~cosserat_channel.physics.analytic` tells the plan which triples cost nothing. Below the
paper's figures, the measurements and the command line; the file's chunks are encoded by
:mod:`cosserat_channel.chunk_filters`. Never imports plotting, the regimes, the atlas, an
integrator or numba (the kernels are the solver's and the chunk filters').
"""

__all__ = ["run_sweep"]


def __getattr__(name):
    if name == "run_sweep":
        from .engine import run_sweep

        return run_sweep
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
