"""The co-simulation master: integer-nanosecond clock, multi-rate Jacobi, simpy for events.

:class:`Master` composes the parts (see :mod:`twin.cosim.master`); :func:`make_plan` builds the
static plan of a scenario on its own (no FMU loaded).
"""

from twin.cosim.controls import RunControls
from twin.cosim.master import Master, RunResult
from twin.cosim.plan import Plan, make_plan

__all__ = ["Master", "Plan", "RunControls", "RunResult", "make_plan"]
