"""What is not known of a tester, drawn reproducibly: the spreads of its parameters, the testers
as built, the room's curve.

- :mod:`~twin.uncertainty.spreads`: a ``[spread]`` table (spreads around a scenario's own
  values) as SALib rows, and the standard errors of calibrated parameters;
- :mod:`~twin.uncertainty.testers`: testers as built, drawn from a spreads file, and a
  scenario changed to one of them;
- :mod:`~twin.uncertainty.rooms`: room curves of a rise whose shape the paper does not give,
  and a slow random drift.

Used by a run's Monte Carlo (:mod:`twin.pipeline.montecarlo`), sweeps (``[spread]``), the
held-out validation and the thermal calibration.
"""
