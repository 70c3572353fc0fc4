"""What one evaluation of the error model is set to: which columns hold what, what is known of
the tester (its coefficients) and which of the five factors are on.

Made from an ``[errormodel]`` table by :mod:`twin.errormodel.config` (a scenario's, a lab's),
or in code by a fit (:mod:`twin.errormodel.identify`); read by the factors
(:mod:`twin.errormodel.factors`) and the evaluation (:mod:`twin.errormodel.evaluate`).
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass

from twin.errormodel.sources import Columns, MechanicalCoefficients, ThermalCoefficients

__all__ = ["EvaluationConfig"]


@dataclass(frozen=True, kw_only=True)
class EvaluationConfig(Columns):
    """Which columns hold what (the fields of :class:`~twin.errormodel.sources.Columns`), what
    is known of the tester, and the evaluation's settings."""

    thermal: ThermalCoefficients
    mechanics: MechanicalCoefficients | None = None
    window_s: float = 300.0
    spike_half_window: int = 10
    spike_sigmas: float = 5.0
    spike_min: float = 1e-6
    ra_window_s: float = 1800.0
    #: the factors the model evaluates (None: all five); the paper's thermal experiment leaves
    #: out loading and fluctuating (no load, no motion: its Eq. 10), so their sensors' noise
    #: does not enter
    factors: Collection[str] | None = None
    #: whether the run evaluates the model at all: a scenario that is not the tester (one FMU
    #: alone, ``twin run X.fmu``) says ``[errormodel] evaluate = false``
    evaluate: bool = True
    #: whether a run with a true wear computes the credibility indexes (the Frechet distance's
    #: O(n^2) recursion is half a replay's evaluation): a Monte Carlo's samples report only the
    #: drift and its parts, so they leave them out
    credibility: bool = True

    @property
    def filter_reach(self) -> int:
        """The rows either side of a reading that its cleaned value depends on: the robust
        filter takes a moving median of the deviations from a moving median, two half windows."""
        return 2 * self.spike_half_window

    def factor_on(self, name: str) -> bool:
        """Whether the factor ``name`` is evaluated (else it contributes zero)."""
        return self.factors is None or name in self.factors
