"""The signal table the master records: time plus named SI columns."""

from twin.signals.table import Block, Signal, SignalTable

__all__ = ["Block", "Signal", "SignalTable"]
