"""A run's Monte Carlo in process (its samples' FMUs stepped together) and on Dask give the same
samples, byte for byte: where a sample runs is a matter of time, never of its figures."""

from __future__ import annotations

import importlib
import os
from collections import Counter
from pathlib import Path

import pytest

from twin.cli import main

#: the module (twin.pipeline re-exports its function ``run`` under the same name)
run_module = importlib.import_module("twin.pipeline.run")
ARGS = [
    "run",
    "li2017-thermal-experiment",
    "--uncertainty",
    "30",
    "--set",
    'scenario.duration="30 min"',
]


def test_in_process_and_on_dask_the_samples_are_the_same(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    assert main([*ARGS, "--out", str(tmp_path / "here")]) == 0
    # a cluster that costs nothing to start pays at once: judged on the first batch finished
    # in process (3 samples each: a tenth), when STEPPED_AHEAD more are started (2: the
    # third batch), the other 21 go to Dask
    monkeypatch.setattr(run_module, "CLUSTER_START_S", 0.0)
    monkeypatch.setattr(run_module, "ON_DASK", 0.0)  # and whose samples cost nothing there
    capfd.readouterr()
    assert main([*ARGS, "--out", str(tmp_path / "dask")]) == 0
    said = capfd.readouterr()
    on_dask = 30 - 3 * (run_module.STEPPED_AHEAD + 1)
    assert f"uncertainty: the other {on_dask} samples on Dask" in said.out + said.err
    here = (tmp_path / "here" / "uncertainty.csv").read_bytes()
    dask = (tmp_path / "dask" / "uncertainty.csv").read_bytes()
    assert here.count(b"\n") == 1 + 30
    # the samples in process recorded the rows near their ends only, those on Dask every row:
    # the figures read off the ends are the same bits, the others are not reported
    assert here == dask
    assert b",failed," not in here
    header = here.split(b"\n", 1)[0].decode().split(",")
    figures = {c.split(".")[0] for c in header if "." in c and not c.startswith(("fmu.", "room."))}
    assert figures == {"drift_mm", "thermal_parts_mm", "temperature_rise_C", "error_parts_mm", "wear_mm"}


def test_a_cluster_pays_when_its_workers_save_more_than_its_start() -> None:
    pays = run_module._cluster_pays
    start, on_dask = run_module.CLUSTER_START_S, run_module.ON_DASK
    # two cores, in process already two threads (the ticks beside the evaluation): 9 ms a
    # sample in 13 ms of CPU; on two workers 13 x 1.3 / 2 = 8.5 ms: nothing worth a cluster
    assert not pays(100_000 // 100, 0.009, 0.013, cores=2)
    # in process without the overlap (wall = CPU): 1000 samples save 1000 x 13 x (1 - 0.65) ms
    assert pays(1000, 0.013, 0.013, cores=2) == (1000 * 0.013 * (1 - on_dask / 2) > start)
    # sixteen cores: the cluster pays from a few hundred samples of that size
    assert pays(400, 0.009, 0.013, cores=16) and not pays(100, 0.009, 0.013, cores=16)
    assert not pays(10_000, 1.0, 1.0, cores=1)  # one core: on a worker it only costs more
    # a loaded machine: other work kept 1.5 of two cores busy and stretched the samples in
    # process (wall twice the CPU's share of two threads); its workers would get one core
    assert pays(1000, 0.013, 0.013, cores=2) and not pays(1000, 0.013, 0.013, cores=2, others=1.5)
    assert not pays(1000, 0.0134, 0.013, cores=16, others=15.5)  # sixteen cores, all but half busy


def test_the_cores_other_work_keeps_busy_are_the_machine_s_busy_time_less_the_run_s() -> None:
    busy = run_module._machine_busy_s()
    if busy is None:  # not Linux: the run counts every core as free
        assert run_module._others(None, None, 1.0, 1.0) == 0.0
        return
    assert busy > 0
    # over 2 s the machine ran 5 CPU seconds, 2 of them this process's: 1.5 cores of others
    assert run_module._others(10.0, 15.0, 2.0, 2.0) == pytest.approx(1.5)
    assert run_module._others(10.0, 11.0, 2.0, 2.0) == 0.0  # never below none
    assert run_module._others(None, 15.0, 2.0, 2.0) == 0.0


def test_what_lives_before_the_samples_is_frozen_for_them_and_thawed_after(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The collector's full passes skip the modules and the nominal run while the samples
    come and go; nothing stays frozen after the Monte Carlo, even one that fails."""
    import gc

    real, frozen = run_module._in_process, []

    def watched(*args: object) -> list[int]:
        frozen.append(gc.get_freeze_count())
        return real(*args)

    monkeypatch.setattr(run_module, "_in_process", watched)
    small = [*ARGS[:3], "4", *ARGS[4:]]
    assert main([*small, "--out", str(tmp_path / "a")]) == 0
    assert frozen and frozen[0] > 10_000 and gc.get_freeze_count() == 0

    def fails(*args: object) -> list[int]:
        raise RuntimeError("a sample's bug")

    monkeypatch.setattr(run_module, "_in_process", fails)
    with pytest.raises(RuntimeError, match="a sample's bug"):
        main([*small, "--out", str(tmp_path / "b")])
    assert gc.get_freeze_count() == 0


def test_prior_and_updated_sample_i_share_their_thermal_network_and_every_sample_is_as_alone(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The default run's Monte Carlo (the shipped updated tester: prior and posterior samples)
    pairs prior sample i with updated sample i in a batch, where their thermal network, which
    the posterior does not touch, runs once; its samples are those of batches of one sample
    each (every sample its run alone), byte for byte."""
    import twin.cosim.batch as batch_module

    opened: list[str] = []
    real_open = batch_module.open_slots

    def counted(plan: object, *args: object, **kwargs: object) -> object:
        slots = real_open(plan, *args, **kwargs)
        opened.extend(slot.name for slot in slots)
        return slots

    monkeypatch.setattr(batch_module, "open_slots", counted)
    monkeypatch.setattr(run_module, "CLUSTER_START_S", 1e9)  # in process however loaded the machine
    small = ["run", "--uncertainty", "20", "--set", 'scenario.duration="30 min"']
    assert main([*small, "--out", str(tmp_path / "paired")]) == 0
    assert sorted(Counter(opened).items()) == [("mechanics", 40), ("sensors", 40), ("thermal", 20)]
    opened.clear()
    monkeypatch.setattr(run_module, "IN_PROCESS_BATCH", 1)
    assert main([*small, "--out", str(tmp_path / "alone")]) == 0
    assert Counter(opened)["thermal"] == 40
    paired = (tmp_path / "paired" / "uncertainty.csv").read_bytes()
    assert paired.count(b"\n") == 1 + 40 and b",failed," not in paired
    assert paired == (tmp_path / "alone" / "uncertainty.csv").read_bytes()


@pytest.mark.parametrize(("prior", "updated"), [(200, 200), (200, 13), (30, 12), (30, 0), (4, 4), (0, 0)])
def test_batches_hold_every_sample_once_and_prior_and_updated_sample_i_together(
    prior: int, updated: int
) -> None:
    batches = run_module._batches(prior, updated)
    size = max(1, min(run_module.IN_PROCESS_BATCH, (prior + updated) // 10))
    assert sorted(i for b in batches for i in b) == list(range(prior + updated))
    assert all(0 < len(b) <= size for b in batches)
    if size > 1:  # a batch of one sample cannot hold two
        where = {i: n for n, b in enumerate(batches) for i in b}
        assert all(where[i] == where[prior + i] for i in range(updated))


def test_the_choice_of_a_cluster_weighs_every_batch_so_far_not_the_last_one() -> None:
    """One batch that other work stretched (a burst on a loaded machine) does not send the
    samples left to a cluster; batches that keep being slow with cores to spare do."""
    pace = run_module._Pace()
    assert not pace.cluster_pays(300)  # nothing measured yet
    for _ in range(8):  # 20 samples a batch, two threads: 9 ms a sample for 13 ms of CPU
        pace.add(20, 0.26, 0.18, 0.27)
    assert not pace.cluster_pays(300)
    burst = run_module._Pace(pace.samples, pace.cpu_s, pace.wall_s, pace.busy_s)
    burst.add(20, 0.26, 1.2, 0.27)  # one batch stretched five-fold, the machine otherwise idle
    alone = run_module._Pace()
    alone.add(20, 0.26, 1.2, 0.27)
    cores = os.cpu_count() or 1
    if cores >= 2:  # the same batch judged alone would have gone to a cluster
        assert alone.cluster_pays(300)
    assert not burst.cluster_pays(300)
    steady = run_module._Pace()
    for _ in range(8):
        steady.add(20, 0.26, 1.2, 0.27)
    assert steady.cluster_pays(300) == alone.cluster_pays(300)
    unknown = run_module._Pace()
    unknown.add(20, 0.26, 0.18, None)  # no /proc/stat: every core counted free
    assert unknown.busy_s is None and not unknown.cluster_pays(10)
