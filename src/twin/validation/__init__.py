"""Validation of the error model beyond one nominal tester.

- :mod:`twin.validation.draws`: testers as built drawn from the spreads file
  (``scenarios/validation/testers-as-built.toml``, facts.md section 6) and room curves;
- :mod:`twin.validation.heldout`: ``twin heldout``, identify each drawn tester on the
  calibration experiments, then compensate operating scenarios the identification never saw,
  beside the group's MLR + AR baseline (:mod:`twin.errormodel.baselines`);
- :mod:`twin.validation.replay`: the paper replay's uncertainty (a Monte Carlo over its
  uncertain inputs, nominal, sigma and 90 % interval in the run's summary.json).

Everything runs on Dask through :mod:`twin.sweep`'s client, executor, shipping and results
modules.
"""
