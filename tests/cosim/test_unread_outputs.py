"""An instance no connection reads (the tester's DAQ) has its outputs fetched only where a row
or Python between two batches can see them (native/stepper.c, fetch_needed), and the DAQ takes
its last sample only when it is read (SensorsDAQ: the wrapper's deferred outputs). Neither may
change a value: against the Python loop, which reads every output after every step, and across
a resume from a checkpoint, every column is byte for byte the same."""

from __future__ import annotations

import pickle
from typing import Any

import numpy as np
import pytest

from twin.config.load import load_scenario, scenarios_dir
from twin.config.spec import NS_PER_S
from twin.cosim import Master, RunControls, make_plan
from twin.cosim.master import run_scenario

#: the DAQ at a period the rows' interval is not a multiple of, so some of its steps are read
#: and most are not; an event biases one of its outputs between two batches
OVERRIDES = [
    'scenario.duration="4 min"',
    'scenario.output_interval="0.7 s"',
    'fmu.sensors.period="0.3 s"',
    'event=[{at = "61.2 s", action = "bias", target = "sensors.probe_meas", value = 1e-5}]',
]


@pytest.fixture(scope="module")
def sc() -> Any:
    return load_scenario(scenarios_dir() / "base" / "tester-system.toml", OVERRIDES)


def _same(a: Any, b: Any, k: int = 0) -> None:
    assert a.table.names() == b.table.names()
    assert a.table.time.tobytes() == b.table.time[k:].tobytes()
    for name in a.table.names():
        assert a.table[name].tobytes() == b.table[name][k:].tobytes(), name


def test_the_daq_is_read_by_no_connection(sc: Any) -> None:
    plan = make_plan(sc)
    daq = next(i.index for i in plan.instances if i.name == "sensors")
    assert all(i.src != daq for inst in plan.instances for i in inst.inputs if i.kind != 2)


def test_fast_loop_gives_the_python_loops_bytes(sc: Any) -> None:
    fast, py = run_scenario(sc, loop="fast"), run_scenario(sc, loop="python")
    assert fast.status == py.status == "completed"
    _same(fast, py)
    # the DAQ's noise is in the rows: they are its samples, not constants
    assert len(np.unique(fast.table["sensors.t_bearing_meas"])) > 5


def test_a_resumed_run_continues_byte_for_byte(sc: Any) -> None:
    snaps: list[dict[str, Any]] = []
    every = 50 * NS_PER_S  # not a multiple of the rows' interval nor of the DAQ's period
    full = Master(
        make_plan(sc), controls=RunControls(checkpoint_every_ns=every, on_checkpoint=snaps.append)
    ).run()
    assert full.status == "completed" and len(snaps) == 4
    for snap in snaps:
        rest = Master(make_plan(sc), resume=pickle.loads(pickle.dumps(snap, protocol=5))).run()
        assert rest.status == "completed"
        _same(rest, full, int(np.searchsorted(full.table.time, snap["tick"] * sc.step_ns / NS_PER_S)))


def test_the_checkpoints_hold_what_the_python_loops_hold(sc: Any) -> None:
    """Between two batches (a checkpoint, an event) the exchange buffers of the unread DAQ are
    those of a loop that reads every step: the stepper fetches the last two steps before a
    batch's end."""
    every = 50 * NS_PER_S
    snaps: dict[str, list[dict[str, Any]]] = {"fast": [], "python": []}
    for loop, kept in snaps.items():
        controls = RunControls(checkpoint_every_ns=every, on_checkpoint=kept.append)
        assert Master(make_plan(sc), controls=controls, loop=loop).run().status == "completed"
    assert len(snaps["fast"]) == len(snaps["python"]) == 4
    for fast, py in zip(snaps["fast"], snaps["python"], strict=True):
        for a, b in zip(fast["instances"], py["instances"], strict=True):
            for key in ("raw", "cur", "pending", "in_val", "state"):
                if key in a:
                    assert np.asarray(a[key]).tobytes() == np.asarray(b[key]).tobytes(), (a["name"], key)
            assert a["pending_at"] == b["pending_at"]
