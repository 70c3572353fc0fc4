"""Runs stepped together (twin.cosim.batch): each copy's rows bit for bit its run alone's; a
copy whose FMU fails is left to run alone and the others are not changed by it."""

from __future__ import annotations

import dataclasses
import threading
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from twin.config.load import load_scenario, scenarios_dir
from twin.config.spec import NS_PER_S, Event, Scenario
from twin.cosim import make_plan
from twin.cosim.batch import Batch, identities, run_batch, structure, unbatchable
from twin.cosim.master import Master
from twin.cosim.state import driven_every, driven_ticks
from twin.errormodel.config import evaluation_config
from twin.errormodel.evaluate import end_reach_s
from twin.errors import FMUError
from twin.fmu.pool import SlotPool
from twin.uncertainty.rooms import shaped, smooth_drift

PAPER = scenarios_dir() / "li2017-thermal-experiment.toml"


def _paper(minutes: int) -> Scenario:
    return dataclasses.replace(load_scenario(PAPER), duration_ns=minutes * 60 * NS_PER_S)


def _same(alone: object, batched: object) -> None:
    a, b = alone.table, batched.table  # type: ignore[attr-defined]
    assert a.time.tobytes() == b.time.tobytes()
    assert a.names() == b.names()
    for name in a.names():
        assert a[name].tobytes() == b[name].tobytes(), name
    assert alone.macro_steps == batched.macro_steps  # type: ignore[attr-defined]
    assert alone.fmu_steps == batched.fmu_steps  # type: ignore[attr-defined]
    assert alone.end_ns == batched.end_ns  # type: ignore[attr-defined]


def test_copies_of_the_paper_replay_are_bit_for_bit_their_runs_alone() -> None:
    base = _paper(120)
    target = "thermal.t_room"
    # what a Monte Carlo sample changes: parameters, the noise seed, the room's driven profile
    scenarios = []
    for i in range(5):
        sample = base.with_seed(100 + i).with_parameters("mechanics", {"alpha_base": 11e-6 + 1e-7 * i})
        shape = ("exponential", "ramp", "s-curve")[i % 3]
        drift = smooth_drift(np.random.default_rng(i), 1.0)
        scenarios.append(sample.with_input(shaped(sample, target, shape, drift, "test: a room per copy")))
    plans = [make_plan(s) for s in scenarios]
    assert len({structure(p) for p in plans}) == 1 and unbatchable(plans[0]) is None
    keep = {c.meta.name for c in plans[0].columns}
    batch = run_batch(plans, keep, SlotPool(per_key=5))
    assert batch.alone == [] and sorted(batch.results) == list(range(5))
    for i, plan in enumerate(plans):
        _same(Master(plan).run(), batch.results[i])
    # the copies differ (the check above can fail): other seeds, rooms and parameters
    probes = [batch.results[i].table["sensors.probe_meas"] for i in range(5)]
    assert len({p.tobytes() for p in probes}) == 5


def test_kept_columns_only_and_the_same_values() -> None:
    plan = make_plan(_paper(30))
    keep = {"sensors.probe_meas", "thermal.t_base"}
    batch = run_batch([plan, plan], keep)
    alone = Master(plan).run().table
    for i in (0, 1):
        table = batch.results[i].table
        assert sorted(table.names()) == sorted(keep)
        for name in keep:
            assert table[name].tobytes() == alone[name].tobytes()


def test_rows_kept_near_the_ends_only_are_those_of_every_row() -> None:
    # a Monte Carlo's samples record the rows their figures read: those near either end
    plans = []
    for i in range(3):
        plans.append(make_plan(_paper(120).with_seed(40 + i)))
    keep = {"sensors.probe_meas", "sensors.t_base_meas", "thermal.t_base"}
    whole = run_batch(plans, keep)
    ends_s = 5 * 60.0 + 0.5  # the rows from 0 to 300 s and from 6900 to 7200 s
    ends = run_batch(plans, keep, ends_s=ends_s)
    assert whole.alone == ends.alone == []
    for i in range(3):
        a, b = whole.results[i].table, ends.results[i].table
        near = (a.time <= a.time[0] + ends_s) | (a.time >= a.time[-1] - ends_s)
        assert 0 < near.sum() < len(a.time) // 10  # most rows were not recorded
        assert b.time.tobytes() == a.time[near].tobytes()
        for name in keep:
            assert b[name].tobytes() == a[name][near].tobytes(), name
        # every tick was stepped all the same: the FMUs' own counts, and the run's end
        assert whole.results[i].macro_steps == ends.results[i].macro_steps
        assert whole.results[i].end_ns == ends.results[i].end_ns
    # ends that meet keep every row
    met = run_batch(plans[:1], keep, ends_s=3600.0)
    assert met.results[0].table.time.tobytes() == whole.results[0].table.time.tobytes()


def test_the_rows_an_end_figure_reads_are_kept_when_the_run_ends_between_two_rows() -> None:
    # 7205 s at a row every 10 s: the last row (7200 s) comes 5 s before the run's end, which
    # is where the kept stretches are measured from; end_reach_s's extra row covers it
    paper = _paper(120)
    plan = make_plan(dataclasses.replace(paper, duration_ns=paper.duration_ns + 5 * NS_PER_S))
    evaluation = evaluation_config(paper)  # the paper's: no loading factor, ends only
    interval = plan.scenario.output_interval_ns / NS_PER_S
    ends_s = end_reach_s(evaluation, interval)
    assert ends_s == evaluation.window_s + (evaluation.filter_reach + 1) * interval
    t = run_batch([plan], {"sensors.probe_meas"}, ends_s=ends_s).results[0].table.time
    assert t[-1] == 7200.0
    # every row a drift line or the robust filter reads: within the window and the filter's
    # reach (in rows) of the first and the last row
    reach = evaluation.window_s + evaluation.filter_reach * interval
    every = np.arange(0.0, 7200.0 + interval / 2, interval)
    needed = every[(every <= t[0] + reach) | (every >= t[-1] - reach)]
    assert set(needed) <= set(t.tolist())
    with pytest.raises(ValueError, match="ends_s"):
        run_batch([plan], {"sensors.probe_meas"}, ends_s=-1.0)


def _placed(plans: list, pool: SlotPool) -> tuple[dict[int, dict[str, int]], dict[int, object], int]:
    """Run ``plans`` as one batch: per copy the instances it borrowed (name -> the copy that ran
    it), its results, and the instances the batch opened (after its retries)."""
    with Batch(plans, {c.meta.name for c in plans[0].columns}, pool) as batch:
        batch.open().step()
        names = [i.name for i in plans[0].instances]
        borrowed = {c.index: {names[i]: o.index for i, o in c.borrowed.items()} for c in batch.copies}
        opened = sum(len(c.slots) for c in batch.copies)
        done = batch.results()
    return borrowed, {**done.results, **dict.fromkeys(done.alone)}, opened


def test_an_instance_the_same_in_two_copies_runs_once_and_every_copy_is_its_run_alone() -> None:
    base = _paper(60)
    room = "thermal.t_room"
    own = base.with_seed(100).with_input(
        shaped(base, room, "ramp", smooth_drift(np.random.default_rng(1), 1.0), "test: a sample's room")
    )
    c_base = own.fmu("thermal").parameters["c_base"].value
    scenarios = [
        own,
        own.with_parameters("mechanics", {"alpha_base": 12e-6}),  # the thermal network's run the same
        own.with_parameters("thermal", {"c_base": c_base * (1 + 1e-9)}),  # a heat capacity a little apart
        own,  # the same throughout
        own.with_seed(101),  # another noise seed: the sensors' only
        own.with_input(  # another room: the thermal network's input, so all three differ
            shaped(base, room, "s-curve", smooth_drift(np.random.default_rng(1), 1.0), "test: another room")
        ),
    ]
    plans = [make_plan(s) for s in scenarios]
    borrowed, results, opened = _placed(plans, SlotPool(per_key=6))
    assert borrowed == {
        0: {},
        1: {"thermal": 0},
        2: {},
        3: {"thermal": 0, "mechanics": 0, "sensors": 0},
        4: {"thermal": 0, "mechanics": 0},
        5: {},
    }
    assert opened == 6 * 3 - 6
    for i, plan in enumerate(plans):
        _same(Master(plan).run(), results[i])
    # what was shared is what the copies do have in common (the check above can fail)
    probe = [results[i].table["sensors.probe_meas"].tobytes() for i in range(6)]
    base_t = [results[i].table["thermal.t_base"].tobytes() for i in range(6)]
    assert probe[0] == probe[3] and len({probe[i] for i in (0, 1, 4, 5)}) == 4
    # another heat capacity: another temperature of the base (the probe's quantized reading may not see it)
    assert base_t[0] == base_t[1] == base_t[4] and base_t[2] != base_t[0] and base_t[5] != base_t[0]


def test_identities_tell_apart_what_is_equal_but_not_the_same_bits() -> None:
    plan = make_plan(_paper(10))
    thermal = [i.name for i in plan.instances].index("thermal")

    def share(value: float) -> object:  # the base's share of the friction heat (none)
        return make_plan(plan.scenario.with_parameters("thermal", {"fric_share_base": value}))

    ulp = float(np.nextafter(0.0, 1.0))
    same = identities([share(0.0), share(0.0), share(-0.0), share(ulp)])
    assert same[0] == same[1] and same[0][thermal] != same[2][thermal] != same[3][thermal]
    # what feeds an instance counts: the mechanics are fed by the thermal network
    assert same[0][1:] == same[1][1:] and same[0][1:] != same[2][1:]


def _heated(
    tmp_path: Path,
    name: str,
    watts: float,
    offset: float = 0.0,
    clock: tuple[str, ...] = ("10 s", "10 s", "10 s"),
) -> Path:
    """A thermal network heated by ``watts`` (a constant, or a ramp up to them) feeding the
    mechanics; ``clock``: the master's step, the thermal network's and the mechanics' periods,
    and when they differ the output interval (5 s), a ramp, and a load the mechanics read."""
    step, thermal, mechanics = clock
    even = len(set(clock)) == 1
    heat = (
        f'profile = "constant"\nvalue = {watts}'
        if even
        else f'profile = "ramp"\nstart = 0.0\nend = {watts}\nduration = "7 min"'
    )
    load = (
        ""
        if even
        else (
            '[input.mechanics.radial_load]\nprofile = "sine"\nmean = 1000.0\namplitude = 500.0\nperiod = "77 s"\n'
            'source = "test: a load the mechanics read at their own exchanges"\n'
        )
    )
    path = tmp_path / f"{name}.toml"
    path.write_text(f"""
[scenario]
name = "{name}"
duration = "{"2 h" if even else "10 min"}"
step = "{step}"
output_interval = "{"10 s" if even else "5 s"}"
seed = 3
[fmu.thermal]
model = "ThermalNetwork"
period = "{thermal}"
parameters = {{ solver_step = {10.0 if even else 1.0} }}
unconnected = "a test system: the inputs nothing feeds keep their start values"
[fmu.mechanics]
model = "FixtureMechanics"
period = "{mechanics}"
unconnected = "a test system: the inputs nothing feeds keep their start values"
[connections]
"thermal.t_oil" = {{ to = "mechanics.t_base", offset = {offset} }}
[input.thermal.q_hydraulic]
{heat}
source = "test: a heat input (all into the oil by default); a megawatt takes the oil past what the mechanics accept (473 K)"
{load}""")
    return path


def test_a_copy_that_fails_runs_alone_and_the_others_are_unchanged(tmp_path: Path) -> None:
    watts = [300.0, 1e6, 500.0, 400.0]  # the second heats the oil past 473 K within the run
    scenarios = [load_scenario(_heated(tmp_path, f"c{i}", w)) for i, w in enumerate(watts)]
    # the fourth is refused in its set-up: heat shares that do not sum to one (the model checks)
    scenarios[3] = scenarios[3].with_parameters("thermal", {"hyd_share_oil": 0.5})
    plans = [make_plan(s) for s in scenarios]
    batch = run_batch(plans, {c.meta.name for c in plans[0].columns}, SlotPool(per_key=4))
    assert batch.alone == [1, 3]
    assert sorted(batch.results) == [0, 2]
    refused = Master(plans[3]).run
    with pytest.raises(FMUError, match="share"):
        refused()
    for i in (0, 2):
        _same(Master(plans[i]).run(), batch.results[i])
    # the same with the first attempt in a thread of its own (the Monte Carlo's way), the
    # retry without the failed copy in the pool's thread
    with Batch(plans, {c.meta.name for c in plans[0].columns}, SlotPool(per_key=4)) as threaded:
        thread = threading.Thread(target=threaded.open().attempt)
        thread.start()
        thread.join()
        threaded.step()
        again = threaded.results()
    assert again.alone == [1, 3] and sorted(again.results) == [0, 2]
    for i in (0, 2):
        _same(batch.results[i], again.results[i])
    failed = Master(plans[1]).run()  # what its run alone says
    assert failed.status == "failed" and "fmi2SetReal" in str(failed.error), failed.error
    assert 0 < failed.macro_steps < 720  # mid-run: after the set-up, before the end


def test_a_copy_that_borrowed_the_failed_copy_s_instance_then_runs_its_own(tmp_path: Path) -> None:
    """The first copy's thermal network runs for the others; its mechanics, fed 100 K more,
    go past what they accept (473 K) mid-run: the others are run again without it, the second
    copy with a thermal network of its own, and each is still its run alone."""
    offsets = [100.0, 0.0, 0.0]
    plans = [make_plan(load_scenario(_heated(tmp_path, f"s{i}", 3000.0, o))) for i, o in enumerate(offsets)]
    assert identities(plans)[0][0] == identities(plans)[1][0]  # one thermal network for all three
    borrowed, results, opened = _placed(plans, SlotPool(per_key=3))
    assert borrowed == {1: {}, 2: {"thermal": 1, "mechanics": 1}} and opened == 2
    assert results[0] is None  # left to run alone
    failed = Master(plans[0]).run()
    assert failed.status == "failed" and "t_base" in str(failed.error) and 0 < failed.macro_steps < 720
    for i in (1, 2):
        _same(Master(plans[i]).run(), results[i])
    # the instance that fails shared too: the second copy runs the first's mechanics, fails
    # alone as well on its own, and the third, which shares only their thermal network, is run
    twice = [plans[0], make_plan(load_scenario(_heated(tmp_path, "t", 3000.0, 100.0))), plans[1]]
    ids = identities(twice)
    assert ids[0] == ids[1] and ids[2][0] == ids[0][0] and ids[2][1] != ids[0][1]
    borrowed, results, opened = _placed(twice, SlotPool(per_key=3))
    assert borrowed == {2: {}} and opened == 2
    assert results[0] is None and results[1] is None
    _same(Master(twice[2]).run(), results[2])


def test_plans_of_another_structure_or_with_events_are_refused(tmp_path: Path) -> None:
    paper = make_plan(_paper(10))
    other = make_plan(load_scenario(_heated(tmp_path, "o", 300.0)))
    with pytest.raises(ValueError, match="another structure"):
        run_batch([paper, other], set())
    path = _heated(tmp_path, "e", 300.0)
    path.write_text(
        path.read_text()
        + '[[event]]\nat = "5 min"\naction = "bias"\ntarget = "mechanics.probe_true"\nvalue = 1e-6\n'
    )
    evented = make_plan(load_scenario(path))
    assert "events" in (unbatchable(evented) or "")
    with pytest.raises(ValueError, match="events"):
        run_batch([evented], set())


def _uneven(tmp_path: Path, watts: float) -> Scenario:
    """Instances whose periods (4 s, 6 s) and output interval (5 s) share no tick pattern with
    the master's 1 s: most ticks do nothing, the driven inputs are read every second tick."""
    return load_scenario(_heated(tmp_path, f"uneven-{watts}", watts, clock=("1 s", "4 s", "6 s")))


def test_ticks_where_nothing_happens_are_counted_not_changed(tmp_path: Path) -> None:
    """The stepper skips the ticks where no instance is due, no output commits and no row is
    recorded, and its driven matrix holds only the ticks that read it: each copy is bit for bit
    the Python loop's run of it alone, which visits every tick."""
    plans = [make_plan(_uneven(tmp_path, w)) for w in (200.0, 900.0, 3000.0)]
    keep = {c.meta.name for c in plans[0].columns}
    batch = run_batch(plans, keep, SlotPool(per_key=3))
    assert batch.alone == []
    for i, plan in enumerate(plans):
        _same(Master(plan, loop="python").run(), batch.results[i])
        _same(Master(plan, loop="fast").run(), batch.results[i])
    assert batch.results[0].macro_steps == 600
    temps = {batch.results[i].table["thermal.t_oil"].tobytes() for i in range(3)}
    assert len(temps) == 3  # the copies differ: the check above can fail
    # an event at an odd tick starts the master's next batch of ticks between two that read
    # the driven inputs: its matrix's first row is the next even tick's
    sc = _uneven(tmp_path, 900.0)
    event = Event(at_ns=13 * NS_PER_S, action="bias", target="thermal.t_oil", value=0.5)
    plan = make_plan(dataclasses.replace(sc, events=(event,)))
    _same(Master(plan, loop="python").run(), Master(plan, loop="fast").run())


@pytest.mark.parametrize("ends", [False, True])
@pytest.mark.parametrize("ahead_bytes", [None, 0, 1])
def test_driven_rows_are_computed_ahead_by_the_opening_thread_within_their_budget(
    monkeypatch: pytest.MonkeyPatch, ahead_bytes: int | None, ends: bool
) -> None:
    # the stepping thread of a Monte Carlo's batch computes no driven rows (their numpy calls
    # would wait for the interpreter's lock), but those beyond the budget; either way every
    # row is the run's alone, with every row kept or only those near the ends (the samples')
    import twin.cosim.batch as batch_module

    monkeypatch.setattr(batch_module, "BATCH_TICKS", 1000)  # the 2 h replay in 8 or more calls
    plans = [make_plan(_paper(120).with_seed(60 + i)) for i in range(2)]
    # two scenarios loaded apart (their profiles other objects, equal or not): each copy's
    # columns its own in the rows (checked below)
    every, columns = driven_every(plans[0]), len(plans[0].driven) * 2

    def size(k0: int, k1: int) -> int:
        return len(driven_ticks(k0, k1, every)) * columns * 8

    k0 = plans[0].start_tick
    # None: the shipped budget (every call's rows); 0: none; 1: the first call's rows
    budget = {None: batch_module.DRIVEN_AHEAD_BYTES, 0: 0, 1: size(k0, k0 + 1000)}[ahead_bytes]
    monkeypatch.setattr(batch_module, "DRIVEN_AHEAD_BYTES", budget)
    made: list[tuple[str, int, int]] = []
    original = batch_module._driven

    def driven(copies: list, placed: Any, k0: int, k1: int, every: int) -> np.ndarray:
        made.append((threading.current_thread().name, k0, k1))
        rows = original(copies, placed, k0, k1, every)
        assert rows.shape[1] == columns
        return rows

    monkeypatch.setattr(batch_module, "_driven", driven)
    keep = {c.meta.name for c in plans[0].columns}
    ends_s = 5 * 60.0 + 0.5 if ends else None
    with Batch(plans, keep, ends_s=ends_s) as batch:
        calls = [(k, k1) for k, k1, _ in batch_module._chunks(batch.stretches)]
        batch.open()
        thread = threading.Thread(target=batch.attempt, name="stepping")
        thread.start()
        thread.join()
        assert batch._ahead is None  # handed to the attempt, which freed them call by call
        batch.step()
        results = batch.results()
    assert len(calls) >= 8 and sorted((k, k1) for _, k, k1 in made) == sorted(calls)  # each once
    opener = threading.current_thread().name
    ahead = [(k, k1) for who, k, k1 in made if who == opener]
    assert sum(size(k, k1) for k, k1 in ahead) <= budget
    assert all(who in (opener, "stepping") for who, _, _ in made)
    if ahead_bytes is None:
        assert ahead == calls  # the paper replay's fit in the shipped budget
    elif ahead_bytes == 0:
        assert ahead == []
    else:
        assert ahead[0] == calls[0] and len(ahead) < len(calls)
    for i, plan in enumerate(plans):
        alone = Master(plan).run()
        if ends_s is None:
            _same(alone, results.results[i])
            continue
        a, b = alone.table, results.results[i].table
        near = (a.time <= a.time[0] + ends_s) | (a.time >= a.time[-1] - ends_s)
        assert 0 < near.sum() < len(a.time) and b.time.tobytes() == a.time[near].tobytes()
        for name in keep:
            assert b[name].tobytes() == a[name][near].tobytes(), name


def test_copies_driven_by_the_same_profiles_share_their_driven_rows(monkeypatch: pytest.MonkeyPatch) -> None:
    # a Monte Carlo's updated sample is its prior sample with other parameters: the same room
    # (the very same profiles), whose rows are worked out once for both; another room's not
    import twin.cosim.batch as batch_module
    import twin.cosim.state as state_module

    base = _paper(120)
    target = "thermal.t_room"
    drift = smooth_drift(np.random.default_rng(7), 1.0)
    prior = base.with_input(shaped(base, target, "ramp", drift, "test: a room"))
    updated = prior.with_parameters("mechanics", {"alpha_base": 11.5e-6})
    other = base.with_input(shaped(base, target, "s-curve", drift, "test: another room"))
    assert updated.profiles is prior.profiles and other.profiles is not prior.profiles
    plans = [make_plan(s) for s in (prior, updated, other)]
    evaluated: list[int] = []
    original = state_module.Driven.at_ticks

    def at_ticks(self: state_module.Driven, ticks: np.ndarray, step_ns: int) -> np.ndarray:
        evaluated.append(id(self))
        return original(self, ticks, step_ns)

    # each column of the driven rows is one of a copy's own functions, evaluated once a call
    calls_of: list[int] = []

    def driven(copies: list, placed: Any, k0: int, k1: int, every: int) -> np.ndarray:
        calls_of.append(placed.width)
        return original_driven(copies, placed, k0, k1, every)

    original_driven = batch_module._driven
    monkeypatch.setattr(batch_module, "_driven", driven)
    monkeypatch.setattr(state_module.Driven, "at_ticks", at_ticks)
    keep = {c.meta.name for c in plans[0].columns}
    with Batch(plans, keep) as opened:
        opened.open()
        placed = batch_module._Columns(opened.copies)
        opened.step()
        batch = opened.results()
    n = len(plans[0].driven)
    room = [p.target for p in prior.profiles].index(target)
    column = [d for d, spec in enumerate(plans[0].driven) if spec == ("profile", room)]
    assert len(column) == 1 and placed.width == n + 1  # the prior's columns and the other's room
    assert placed.of[0] == placed.of[1] == list(range(n))
    assert [j for j in range(n) if placed.of[2][j] != j] == column and placed.of[2][column[0]] == n
    calls = len(list(batch_module._chunks(batch_module._stretches(plans[0], None))))
    assert calls >= 1 and calls_of == [n + 1] * calls and evaluated == []  # no copy's whole matrix
    monkeypatch.setattr(state_module.Driven, "at_ticks", original)
    for i, plan in enumerate(plans):
        _same(Master(plan).run(), batch.results[i])
    # the two rooms differ (the shared rows could not have served the third copy)
    rooms = [batch.results[i].table["thermal.t_room"] for i in (0, 1, 2)]
    assert rooms[0].tobytes() == rooms[1].tobytes() != rooms[2].tobytes()


def test_batches_that_share_a_files_dict_find_the_models_files_once(monkeypatch: pytest.MonkeyPatch) -> None:
    # a Monte Carlo's batches in process: the first finds each model's .fmu (its sources
    # hashed, its cache entry checked), the next ones take what it found
    import twin.cosim.batch as batch_module

    found: list[object] = []
    real = batch_module.fmu_files
    monkeypatch.setattr(batch_module, "fmu_files", lambda plan: found.append(plan) or real(plan))
    plan = make_plan(_paper(10))
    keep = {"sensors.probe_meas"}
    files: dict[str, Path] = {}
    pool = SlotPool(per_key=2)
    rows = []
    for _ in range(3):
        with Batch([plan], keep, pool, None, files) as batch:
            batch.open().step()
            rows.append(batch.results().results[0].table["sensors.probe_meas"].tobytes())
    assert len(found) == 1
    assert set(files) == {inst.model for inst in plan.instances}
    alone = Master(plan).run().table["sensors.probe_meas"].tobytes()
    assert rows == [alone] * 3
    # a plan with a model the batches before did not find: its files are found (and kept)
    missing = next(iter(files))
    del files[missing]
    with Batch([plan], keep, pool, None, files) as batch:
        batch.open()
    assert len(found) == 2 and missing in files
