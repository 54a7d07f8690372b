"""Where the physics meets the integrators: the two stages of one point, and the point API.

Layer: above :mod:`cosserat_channel.integrate` and :mod:`cosserat_channel.physics`, the only
package that imports both. Numba kernels over batches of points, cut by stage:

- :mod:`.stage1`: the stresses, marched from the axis series to the wall (or to ``D = 0``);
- :mod:`.stress_path`: reading stage 1's solution where stage 2 and the profiles need it;
- :mod:`.stage2`: the velocities, a nested quadrature from the wall towards the axis;
- :mod:`.plug_edge`: the root of eq:13 per ``eps K``;
- :mod:`.batch`: both stages for one ``(eta, A, N)`` and batches of them (the entry kernels),
  and the counters they fill (:func:`~.batch.new_statistics`, :func:`~.batch.accepted_steps`:
  callers never index the integrators' statistics slots themselves);
- :mod:`.wall`: stage 1's scalars at the wall, for the regimes' edge location;
- :mod:`.layout`: the slots of the kernels' result vectors (plain constants);
- :mod:`.point`: :func:`~cosserat_channel.solver.point.solve_point` and its result, the Python API.

May import: :mod:`cosserat_channel.integrate`, :mod:`cosserat_channel.physics` and the
vocabulary modules (parameters, status, outputs). Never sweeps, dask, plotting or files. No
other part of the package imports an integrator.
"""
