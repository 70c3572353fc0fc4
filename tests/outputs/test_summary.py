"""summary.json: valid JSON, NaN/Inf as null, numpy converted, written atomically."""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from twin.outputs.summary import to_jsonable, write_summary


def _strict_load(path: Path) -> object:
    def refuse(token: str) -> None:
        raise AssertionError(f"non-standard JSON token {token}")

    return json.loads(path.read_text(encoding="utf-8"), parse_constant=refuse)


@dataclass
class Timing:
    wall_s: float
    steps: int


def test_nan_and_inf_become_null_and_numpy_is_converted(tmp_path: Path) -> None:
    data = {
        "seed": np.int64(42),
        "drift_um": np.float64(3.25),
        "residual_um": float("nan"),
        "cpi": np.float32("inf"),
        "ok": np.bool_(True),
        "series": np.array([1.5, np.nan, -np.inf]),
        "matrix": np.arange(4).reshape(2, 2),
        "nested": {"parts": [np.float64(1e-6), None, (1, "a")]},
        "timing": Timing(wall_s=1.5, steps=10),
        "file": Path("scenarios/paper.toml"),
        "unit": "µm",
    }
    path = write_summary(tmp_path / "summary.json", data)
    loaded = _strict_load(path)
    assert loaded == {
        "seed": 42,
        "drift_um": 3.25,
        "residual_um": None,
        "cpi": None,
        "ok": True,
        "series": [1.5, None, None],
        "matrix": [[0, 1], [2, 3]],
        "nested": {"parts": [1e-6, None, [1, "a"]]},
        "timing": {"wall_s": 1.5, "steps": 10},
        "file": "scenarios/paper.toml",
        "unit": "µm",
    }
    text = path.read_text(encoding="utf-8")
    assert "NaN" not in text and "Infinity" not in text
    assert text.endswith("}\n")
    assert '\n  "seed": 42,' in text  # indent 2


def test_keys_keep_insertion_order(tmp_path: Path) -> None:
    path = write_summary(tmp_path / "summary.json", {"z": 1, "a": 2, "m": {"y": 1, "b": 2}})
    assert list(_strict_load(path)) == ["z", "a", "m"]
    assert list(_strict_load(path)["m"]) == ["y", "b"]


def test_replaces_atomically_and_leaves_no_temporary_files(tmp_path: Path) -> None:
    path = tmp_path / "summary.json"
    write_summary(path, {"run": 1})
    write_summary(path, {"run": 2})
    assert _strict_load(path) == {"run": 2}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def test_failed_write_keeps_the_old_file(tmp_path: Path) -> None:
    path = write_summary(tmp_path / "summary.json", {"run": 1})
    with pytest.raises(TypeError, match=r"\$\.bad\.obj: cannot write a object"):
        write_summary(path, {"run": 2, "bad": {"obj": object()}})
    assert _strict_load(path) == {"run": 1}
    assert sorted(p.name for p in tmp_path.iterdir()) == ["summary.json"]


def test_non_string_keys_are_refused() -> None:
    with pytest.raises(TypeError, match="JSON keys must be str"):
        to_jsonable({"a": {1: "x"}})
