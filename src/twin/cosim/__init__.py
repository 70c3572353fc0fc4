"""The co-simulation master: simpy-scheduled, integer-nanosecond clock, multi-rate Jacobi."""

from twin.cosim.master import Master, RunResult

__all__ = ["Master", "RunResult"]
