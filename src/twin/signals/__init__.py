"""The signal table the master records: time plus named SI columns."""

from twin.signals.table import Signal, SignalTable

__all__ = ["Signal", "SignalTable"]
