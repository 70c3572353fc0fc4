"""Validation of the twin beyond one nominal run.

- :mod:`twin.validation.heldout`: ``twin heldout``, identify each tester as built on the
  calibration experiments, then compensate operating scenarios the identification never saw,
  beside the group's MLR + AR baseline (:mod:`twin.errormodel.baselines`);
- :mod:`twin.validation.paper_report`: the paper's thermal experiment beside its replay
  (:func:`reports` is what ``twin run`` hands the pipeline).
"""

from twin.validation.paper_report import reports

__all__ = ["reports"]
