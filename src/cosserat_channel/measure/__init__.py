"""The measurement tools: how fast and how accurate the solver is, and on which machine.

- :mod:`.stability`: the stability report (``cosserat-channel stability``): steps, cost and
  error of one point from ``eps L = 1e-8`` to the edge of solvability;
- :mod:`.workprecision`: the work-precision report (``cosserat-channel bench``); it runs
  :mod:`.validation` (the validation set and its references), :mod:`.runners` (ours and the
  peers, timed) and :mod:`.report` (curves, matched-error ratios, targets, markdown and CSV);
- :mod:`.machine`: CPU model, git revision and versions, printed by every report and by the
  scripts in ``benchmarks/``;
- :mod:`.harness`: what the reports and the scripts in ``benchmarks/`` share: best-of timing,
  the header, PASS/FAIL verdicts and the JSON record of ``--json``;

Layer: above the solver, the regimes and the figures, which these modules use (and the
physics, for the peers' formulation and the scipy reference, and the vocabulary modules
parameters, status and files); never an integrator directly (the batch kernels count the
steps: :func:`cosserat_channel.solver.batch.new_statistics`). Nothing else in the package
imports them, except the command line (lazily, inside its ``stability`` and ``bench``
commands). The figures of the reports live
in :mod:`cosserat_channel.plot.stability` and :mod:`cosserat_channel.plot.workprecision` and take
the reports' data.
"""
