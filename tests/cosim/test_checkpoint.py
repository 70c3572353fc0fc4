"""Checkpoints, events and the clock: a resumed run continues byte for byte."""

from __future__ import annotations

import pickle
from typing import Any

import numpy as np
import pytest

from twin.config.load import load_scenario
from twin.config.spec import NS_PER_S
from twin.cosim import Master, RunControls, make_plan
from twin.errors import ConfigError, RunError

from .test_master import LOOP_SYSTEM, scenario

# noise on (the FMU state must come back), a delayed loop, a slow and a fast instance, and
# events before, at and between the checkpoint times (every 60 s)
BODY = (
    LOOP_SYSTEM
    + """
[input.thermal.q_hydraulic]
profile = "sine"
mean = 200.0
amplitude = 50.0
period = "90 s"
[[event]]
at = "30 s"
action = "set"
target = "thermal.q_hydraulic"
value = 150.0
[[event]]
at = "60 s"
action = "ramp"
target = "thermal.q_hydraulic"
value = 400.0
duration = "100 s"
[[event]]
at = "90 s"
action = "bias"
target = "sensors.t_room_meas"
value = 0.5
[[event]]
at = "180 s"
action = "set"
target = "thermal.q_hydraulic"
value = 50.0
"""
)
EVERY_NS = 60 * NS_PER_S


@pytest.fixture(scope="module")
def sc(tmp_path_factory: pytest.TempPathFactory) -> Any:
    return load_scenario(scenario(tmp_path_factory.mktemp("ckpt"), BODY, duration="5 min"))


@pytest.mark.parametrize("loop", ["fast", "python"])
def test_resuming_from_any_checkpoint_gives_the_same_signals(sc: Any, loop: str) -> None:
    snaps: list[dict[str, Any]] = []
    full = Master(
        make_plan(sc),
        controls=RunControls(checkpoint_every_ns=EVERY_NS, on_checkpoint=snaps.append),
        loop=loop,
    ).run()
    assert full.status == "completed"
    assert [s["tick"] for s in snaps] == [60, 120, 180, 240]
    for snap in snaps:
        saved = pickle.loads(pickle.dumps(snap, protocol=5))  # as the pipeline keeps it
        rest = Master(make_plan(sc), loop=loop, resume=saved).run()
        assert rest.status == "completed"
        assert (rest.macro_steps, rest.fmu_steps, rest.end_ns) == (
            full.macro_steps,
            full.fmu_steps,
            full.end_ns,
        )
        k = int(np.searchsorted(full.table.time, snap["tick"]))
        assert rest.table.time.tobytes() == full.table.time[k:].tobytes()
        for name in full.table.names():
            assert rest.table[name].tobytes() == full.table[name][k:].tobytes(), (snap["tick"], name)


def test_a_snapshot_holds_the_whole_master(sc: Any) -> None:
    snaps: list[dict[str, Any]] = []
    Master(
        make_plan(sc), controls=RunControls(checkpoint_every_ns=EVERY_NS, on_checkpoint=snaps.append)
    ).run()
    snap = snaps[1]  # 120 s: after the set, the ramp and the bias
    assert set(snap) == {"tick", "macro_steps", "fmu_steps", "events_applied", "driven", "instances"}
    assert (snap["tick"], snap["macro_steps"], snap["fmu_steps"]) == (120, 120, 12 + 120)
    assert snap["events_applied"] == 3
    assert ["ramp", 150.0, 400.0, 60.0, 100.0] in snap["driven"]  # the ramp starts where the set left it
    thermal, sensors = snap["instances"]
    assert set(thermal) == {
        "name",
        "state",
        "in_val",
        "delay_buf",
        "raw",
        "cur",
        "bias",
        "pending",
        "pending_at",
    }
    # both stepped before 120 s (thermal at 110 s, sensors at 119 s): their outputs become visible at 120 s
    assert (thermal["name"], thermal["pending_at"], sensors["pending_at"]) == ("thermal", 120, 120)
    assert isinstance(sensors["state"], bytes) and sensors["bias"].max() == 0.5


def test_a_checkpoint_of_another_scenario_is_refused(sc: Any) -> None:
    snaps: list[dict[str, Any]] = []
    Master(
        make_plan(sc), controls=RunControls(checkpoint_every_ns=EVERY_NS, on_checkpoint=snaps.append)
    ).run()
    snaps[0]["instances"][0]["name"] = "other"
    with pytest.raises(RunError, match="checkpoint holds instance 'other'"):
        Master(make_plan(sc), resume=snaps[0]).run()
    del snaps[0]["driven"][0]
    with pytest.raises(RunError, match="driven inputs"):
        Master(make_plan(sc), resume=snaps[0]).run()


def test_progress_is_reported_a_hundred_times_up_to_the_end(sc: Any) -> None:
    seen: list[tuple[int, int]] = []
    Master(make_plan(sc), controls=RunControls(progress=lambda now, total: seen.append((now, total)))).run()
    assert len(seen) == 100
    assert [now for now, _ in seen] == sorted({now for now, _ in seen})
    assert seen[-1] == (sc.duration_ns, sc.duration_ns)


def test_stop_ends_the_run_between_batches_with_its_rows(sc: Any) -> None:
    polls: list[int] = []

    def stop() -> str | None:
        polls.append(1)
        return "SIGTERM" if len(polls) == 10 else None

    result = Master(make_plan(sc), controls=RunControls(stop=stop)).run()
    assert result.status == "interrupted" and result.info == {"interrupted_by": "SIGTERM"}
    end_s = result.end_ns / NS_PER_S
    assert 0 < end_s < 300 and result.macro_steps == result.end_ns // sc.step_ns
    # every tick done was recorded (1 s output interval): rows up to the last one before the stop
    assert result.table.time[-1] == end_s - 1.0


def test_unknown_loop_names_are_refused(sc: Any) -> None:
    with pytest.raises(ConfigError, match="unknown master loop 'reference'"):
        Master(make_plan(sc), loop="reference")  # type: ignore[arg-type]
