"""The model's equations and what is known of them in closed form.

Layer: above :mod:`cosserat_channel.integrate`'s level, beside it. :mod:`.model` holds the
right-hand sides of both stages, the axis series and the wall forms; :mod:`.closure` the
critical-state closure; :mod:`.analytic` the regimes decided without integrating;
:mod:`.asymptotics` closed forms and asymptotic solutions; :mod:`.reference` an independent
scipy solution at tight tolerance, for validation only.

May import: numpy, numba, scipy (reference only), :mod:`cosserat_channel._jit`,
:mod:`cosserat_channel.parameters` and :mod:`cosserat_channel.status`. Never an integrator of
this package, a sweep, dask or a file.
"""
