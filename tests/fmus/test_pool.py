"""FMU instances reused across runs (twin.fmu.pool): the signals of a reused, reset instance are
bit for bit those of a fresh one, whatever ran on it before; failed runs give nothing back."""

from __future__ import annotations

from pathlib import Path

import pytest

from twin.config.load import load_scenario, load_scenario_data, read_scenario_data, scenarios_dir
from twin.config.spec import Scenario
from twin.cosim import Master, RunResult, make_plan
from twin.fmu.pool import SlotPool, sweep_pool

SHORT = ['scenario.duration="2 min"']


def scenario(name: str, *overrides: str) -> Scenario:
    return load_scenario(scenarios_dir() / f"{name}.toml", [*SHORT, *overrides])


def run(sc: Scenario, pool: SlotPool | None = None) -> RunResult:
    return Master(make_plan(sc), pool=pool).run()


def same_signals(a: RunResult, b: RunResult) -> None:
    assert a.table is not None and b.table is not None
    assert a.table.names() == b.table.names()
    assert a.table.time.tobytes() == b.table.time.tobytes()
    for name in a.table.names():
        assert a.table[name].tobytes() == b.table[name].tobytes(), name


def test_a_reused_instance_gives_a_fresh_ones_signals() -> None:
    # every FMU of the tester, its states (wear, creep, hysteresis, filters, noise generators,
    # swing phase) driven away from their start by another tester and seed in between
    first = scenario("sine-load")
    other = scenario(
        "trapezoid-load",
        "scenario.seed=99",
        "fmu.mechanics.parameters.liner_modulus=2.5e9",
        "fmu.thermal.parameters.g_base_room=3.0",
    )
    fresh = run(first)
    pool = SlotPool()
    run(other, pool)
    assert len(pool) == 5 and pool.created == 5
    again = run(first, pool)
    assert pool.reused == 5 and pool.created == 5  # every instance of the second run was reused
    assert fresh.status == again.status == "completed"
    same_signals(fresh, again)


def test_a_failed_run_gives_its_instances_back_to_nobody(tmp_path: Path) -> None:
    data = read_scenario_data(scenarios_dir() / "constant-load.toml")
    data["event"] = [{"at": "1 min", "action": "fault", "target": "mechanics", "fault": "error"}]
    data["scenario"]["duration"] = "2 min"
    failing = load_scenario_data(data, "failing.toml", scenarios_dir())
    pool = SlotPool()
    result = run(failing, pool)
    assert result.status == "failed" and "fmi2DoStep" in str(result.error)
    assert len(pool) == 0  # freed, not kept
    # the next run makes new instances and runs as a fresh one does
    ok = run(scenario("constant-load"), pool)
    assert ok.status == "completed" and pool.created == 10 and pool.reused == 0
    same_signals(ok, run(scenario("constant-load")))


def test_the_pool_keeps_one_of_each_and_frees_the_rest() -> None:
    pool = SlotPool(per_key=1)
    sc = scenario("constant-load")
    a, b = Master(make_plan(sc), pool=pool), Master(make_plan(sc), pool=pool)
    # two runs at once in one process (a worker with two threads): two sets of instances
    a._create(), b._create()
    assert pool.created == 10
    a.close(reuse=True)
    b.close(reuse=True)
    assert len(pool) == 5
    pool.clear()
    assert len(pool) == 0


@pytest.mark.slow
def test_sweep_points_reuse_the_workers_instances() -> None:
    from twin.pipeline import prepare_scenario
    from twin.pipeline.point import point_task

    pool = sweep_pool()
    sc = prepare_scenario(scenario("constant-load"))
    first = point_task({"index": 0, "run": sc})["figures"]  # as a worker runs it: its pool
    reused = pool.reused
    assert (
        point_task({"index": 0, "run": sc})["figures"] == first
    )  # same scenario, same seed: the same figures
    assert pool.reused == reused + 5


def test_an_fmu_rebuilt_at_the_same_path_is_not_given_the_old_ones_instances(tmp_path: Path) -> None:
    """The pool resolves an FMU's path once; its size and time are read at every open."""
    import os
    import shutil

    from twin.fmu import catalog
    from twin.fmu.slot import FMUSlot, file_key

    fmu = tmp_path / "sensors.fmu"
    shutil.copyfile(catalog.fmu("SensorsDAQ"), fmu)
    pool = SlotPool()
    first = pool.open(fmu, "sensors", lambda: FMUSlot(fmu, "sensors"))
    assert first.pool_key == (file_key(fmu), "sensors")
    pool.release(first)
    again = pool.open(fmu, "sensors", lambda: FMUSlot(fmu, "sensors"))
    assert again is first and pool.reused == 1
    pool.release(again)
    st = os.stat(fmu)
    os.utime(fmu, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))  # as a rebuild leaves it
    rebuilt = pool.open(fmu, "sensors", lambda: FMUSlot(fmu, "sensors"))
    assert rebuilt is not first and pool.created == 2 and rebuilt.pool_key == (file_key(fmu), "sensors")
    pool.release(rebuilt)
    pool.clear()
