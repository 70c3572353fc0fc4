"""Designs: deterministic from the sweep seed, SALib's meaning of bounds and distributions."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from tests.sweep.helpers import write_spec
from twin.sweep.design import fingerprint, make_design, point_seed
from twin.sweep.spec import Spec, load_spec

PROBLEM = """[problem]
names = ["input.thermal.t_room.rise", "fmu.sensors.parameters.probe_zero_drift",
         "fmu.thermal.parameters.g_base_room"]
bounds = [[2.0, 6.0], [1e-7, 2e-7], [2.5, 0.3]]
dists = ["unif", "norm", "lognorm"]
"""


@pytest.fixture(scope="module")
def base_spec(tmp_path_factory: pytest.TempPathFactory) -> Spec:
    path = tmp_path_factory.mktemp("design") / "d.toml"
    return load_spec(write_spec(path, f'design = "lhs"\nsamples = 4096\nseed = 9\n{PROBLEM}'))


def with_(spec: Spec, **changes: object) -> Spec:
    return dataclasses.replace(spec, **changes)


def test_lhs_is_stratified_and_maps_through_salibs_distributions(base_spec: Spec) -> None:
    x = np.array(make_design(base_spec).rows)
    n = len(x)
    # Latin hypercube: one point in each of the n equal slices of the uniform input
    assert sorted(np.floor((x[:, 0] - 2.0) / 4.0 * n).astype(int)) == list(range(n))
    assert x[:, 1].mean() == pytest.approx(1e-7, abs=1e-10) and x[:, 1].std() == pytest.approx(2e-7, rel=0.02)
    assert np.median(x[:, 2]) == pytest.approx(np.exp(2.5), rel=0.01)  # lognorm: ln-space mean and sd
    assert np.log(x[:, 2]).std() == pytest.approx(0.3, rel=0.02)


@pytest.mark.parametrize("design", ["random", "montecarlo", "lhs", "sobol-sequence", "saltelli", "morris"])
def test_designs_are_reproducible_and_depend_on_the_seed(base_spec: Spec, design: str) -> None:
    spec = with_(base_spec, design=design, samples=16)
    a, b = make_design(spec), make_design(spec)
    assert a.rows == b.rows and a.seeds == b.seeds and fingerprint(a) == fingerprint(b)
    other = make_design(with_(spec, seed=10))
    assert other.rows != a.rows and fingerprint(other) != fingerprint(a)
    expected = {"saltelli": 16 * (3 + 2), "morris": 16 * (3 + 1)}.get(design, 16)
    assert len(a) == expected


def test_point_seeds_depend_only_on_the_sweep_seed_and_the_index() -> None:
    seeds = [point_seed(7, i) for i in range(1000)]
    assert len(set(seeds)) == 1000 and all(0 <= s < 2**31 for s in seeds)
    assert point_seed(7, 500) == seeds[500]  # no state: any order, any worker
    assert point_seed(8, 500) != seeds[500]


def test_a_point_carries_its_values_and_seed(base_spec: Spec) -> None:
    design = make_design(with_(base_spec, samples=4))
    values = design.values(2)
    assert list(values) == [*base_spec.names, "scenario.seed"]
    assert values["input.thermal.t_room.rise"] == design.rows[2][0]
    assert values["scenario.seed"] == point_seed(9, 2)
    point = design.point(base_spec.scenario, 2)  # the base scenario with those values set
    assert point.profile("thermal.t_room").params["rise"] == design.rows[2][0]
    assert point.fmu("sensors").parameters["probe_zero_drift"].value == design.rows[2][1]
    assert point.seed == point_seed(9, 2) and base_spec.scenario.seed == 2017
    fixed = make_design(with_(base_spec, samples=4, vary_seed=False))
    assert set(fixed.seeds) == {2017}  # the paper scenario's own seed: common random numbers


def test_grid_is_every_combination_in_order(tmp_path: Path) -> None:
    spec = load_spec(
        write_spec(
            tmp_path / "g.toml",
            'design = "grid"\n[grid]\n"input.thermal.t_room.rise" = [1.0, 2.0, 3.0]\n'
            '"fmu.sensors.parameters.probe_zero_drift" = [0.0, 1e-7]\n',
        )
    )
    design = make_design(spec)
    assert design.rows == [(1.0, 0.0), (1.0, 1e-7), (2.0, 0.0), (2.0, 1e-7), (3.0, 0.0), (3.0, 1e-7)]
    assert len(set(design.seeds)) == 6


@pytest.mark.parametrize(
    ("design", "samples", "extra"),
    [
        ("lhs", 6, ""),
        ("saltelli", 4, ""),
        ("saltelli", 4, "second_order = true\n"),
        ("morris", 3, ""),
        ("saltelli", 4, "GROUPS"),
        ("morris", 3, "GROUPS"),
    ],
)
def test_the_point_count_checked_before_a_design_is_made_is_its_size(
    design: str, samples: int, extra: str, tmp_path: Path
) -> None:
    # the limit on a sweep's points is checked from this count, before the design exists
    from twin.sweep.spec import point_count

    groups = 'groups = ["a", "a", "b"]\n' if extra == "GROUPS" else ""
    body = (
        f'design = "{design}"\nsamples = {samples}\n{extra if extra != "GROUPS" else ""}'
        '[problem]\nnames = ["input.thermal.t_room.rise", "fmu.thermal.parameters.g_base_room", '
        '"fmu.thermal.parameters.g_oil_room"]\nbounds = [[0.0, 1.0], [10.0, 20.0], [10.0, 20.0]]\n' + groups
    )
    spec = load_spec(write_spec(tmp_path / "s.toml", body))
    size = len(make_design(spec))
    assert point_count(spec.design, spec.samples, spec.problem, spec.levels, spec.second_order) == size
