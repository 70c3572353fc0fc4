"""A summary's figures: its results flattened, floats and dicts taken first, the same dict
(keys, order, values) as the checks of the abstract types in turn."""

from __future__ import annotations

import math
from collections.abc import Mapping
from types import MappingProxyType
from typing import Any

import numpy as np

from twin.pipeline import run_summary
from twin.pipeline.run_summary import RunSummary, Timing


def flatten_as_it_was(data: Mapping[str, Any], prefix: str, out: dict[str, float]) -> None:
    for key, value in data.items():
        if key in run_summary._NOT_FIGURES or isinstance(value, bool):
            continue
        if isinstance(value, Mapping):
            flatten_as_it_was(value, f"{prefix}{key}.", out)
        elif value is None or isinstance(value, (int, float)):
            out[prefix + key] = math.nan if value is None else float(value)


RESULTS = {
    "drift_mm": {
        "predicted": -0.018,
        "probe": np.float64(-0.0),
        "paper_measured": 0.02,
        "interval_90": [1.0, 2.0],
    },
    "temperature_rise_C": MappingProxyType({"room": 8.9, "base": -0.0}),
    "interference_spikes": 1,
    "sensors_used": {"load": False},
    "flag": True,
    "missing": None,
    "note": "text",
    "nested": {"a": {"b": {"c": float("nan"), "d": np.int64(3), "e": np.bool_(True)}}},
    "temperature_rise_C_paper": {"room": 8.9},
}


def test_the_figures_are_the_same_dict_as_the_checks_in_turn_gave() -> None:
    summary = RunSummary(
        "s", "s.toml", "completed", 1, 10.0, Timing(1.0, 0.1, 2.0, 10, 40, 5.0), results=RESULTS
    )
    expected = {"sim_end_s": 10.0}
    flatten_as_it_was(RESULTS, "", expected)
    flatten_as_it_was(
        {f.name: getattr(summary.timing, f.name) for f in run_summary.dataclasses.fields(Timing)},
        "timing.",
        expected,
    )
    got = summary.figures()
    assert list(got) == list(expected)
    assert [repr(v) for v in got.values()] == [repr(v) for v in expected.values()]
    assert all(type(v) is float for v in got.values())
    results_alone = {k: v for k, v in expected.items() if not k.startswith("timing.") and k != "sim_end_s"}
    assert [(k, repr(v)) for k, v in summary.figures(timings=False).items()] == [
        (k, repr(v)) for k, v in results_alone.items()
    ]
