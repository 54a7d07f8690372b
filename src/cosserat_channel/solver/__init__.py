"""Where the physics meets the integrators: the two stages of one point, and the point API.

Layer: above :mod:`cosserat_channel.integrate` and :mod:`cosserat_channel.physics`, the only
package that imports both. :mod:`.stages` marches stage 1 (stresses, axis to wall) and stage 2
(velocities, wall to axis) and finds the plug edge, in Numba kernels over batches of points;
:mod:`.point` is :func:`~cosserat_channel.solver.point.solve_point` and its result.

May import: :mod:`cosserat_channel.integrate`, :mod:`cosserat_channel.physics` and the
vocabulary modules (parameters, status, outputs). Never sweeps, dask, plotting or files.
"""
