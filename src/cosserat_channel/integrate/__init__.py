"""Generic ODE numerics for Numba: integrators, their shared step policy, dense output, roots.

Layer: the lowest one with kernels. Dormand-Prince 5(4) (:mod:`.rk45`), DOP853 (:mod:`.dop853`)
and RODAS4P2 (:mod:`.rosenbrock`) march any ``fun(t, y, args, out)``; :mod:`.stepping` holds what
their drivers share (outcome codes, statistics slots, error norm, first step, stiffness test);
:mod:`.dense` evaluates and searches their dense output; :mod:`.roots` finds roots of scalar
functions; :mod:`.panels` integrates on Chebyshev panels.

May import: numpy, numba, math and :mod:`cosserat_channel._jit`. Never the physics, the solver,
sweeps or files: nothing here knows what is being integrated.
"""
