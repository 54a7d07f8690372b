"""The one set of Numba compile options of the package's kernels.

``error_model="numpy"``: a division by zero gives inf/NaN, which the integrators handle as a
non-finite trial step, instead of a branch and a Python exception around every division.
``JIT_INLINE`` adds Numba-IR inlining: kernels that receive ``fun``/``jac``/``event`` stay
cacheable that way (see :mod:`cosserat_channel.integrate.rk45`), and small helpers that pass arrays
avoid the reference-count updates of a call (see :mod:`cosserat_channel.solver.stress_path`). An
inlined kernel is compiled with the error model of the caller it is inlined into.
``cache`` is off only where no directory keyed on the sources is writable (see
:func:`cosserat_channel._numba_cache_enabled`).
"""

from . import _numba_cache_enabled

JIT = dict(nogil=True, cache=_numba_cache_enabled(), error_model="numpy")
JIT_INLINE = dict(JIT, inline="always")
