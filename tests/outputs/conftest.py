"""Fixtures of the output tests."""

from __future__ import annotations

import pytest

from twin.signals.table import SignalTable

from .sample import make_table


@pytest.fixture
def table() -> SignalTable:
    """A fresh two-hour sample table (tests may modify it)."""
    return make_table()
