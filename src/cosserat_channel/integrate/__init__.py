"""Generic ODE numerics for Numba: integrators, their shared step policy, dense output, roots.

Layer: the lowest one with kernels. Dormand-Prince 5(4) (:mod:`.rk45`), DOP853 (:mod:`.dop853`)
and RODAS4P2 (:mod:`.rosenbrock`) march any ``fun(t, y, args, out)``; the two explicit pairs run
in one driver loop (:mod:`.explicit`); :mod:`.stepping` holds what all three drivers share
(outcome codes and messages, statistics slots, error norm, first step, stiffness test, the
too-small and non-finite policy); :mod:`.dense` evaluates and searches their dense output;
:mod:`.roots` finds roots of scalar functions; :mod:`.panels` integrates on Chebyshev panels.

May import: numpy, numba, math and :mod:`cosserat_channel._jit`. Never the physics, the solver,
sweeps or files: nothing here knows what is being integrated.
"""
