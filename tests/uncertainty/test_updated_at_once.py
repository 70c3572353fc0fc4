"""An updated sample made in one pass (the prior's values and the posterior's set together) is
the prior sample with the posterior set after it, the old way's two passes: the same scenario,
parameters in the same order, the same inputs; where one pass might differ it takes two."""

from __future__ import annotations

import pytest

from twin.cli import common
from twin.errors import ConfigError
from twin.pipeline import montecarlo
from twin.pipeline.prepare import RunOptions, prepare
from twin.uncertainty.testers import apply


@pytest.fixture(scope="module")
def paper() -> tuple[montecarlo.Maker, object]:
    prepared = prepare(None, options=RunOptions(tester=common.tester_path(None, True)))
    assert prepared.uncertainty is not None and prepared.tester is not None
    _, make = montecarlo.sampler(prepared.uncertainty, prepared.prior_scenario or prepared.scenario)
    return make, prepared.tester


def _two_passes(make: montecarlo.Maker, i: int, posterior: dict[str, object]) -> montecarlo.Draw:
    draw = make(i)
    return montecarlo.Draw(apply(draw.scenario, posterior), draw.room_shape, draw.inputs | posterior)


def _same(a: montecarlo.Draw, b: montecarlo.Draw) -> None:
    assert a.scenario == b.scenario
    for fa, fb in zip(a.scenario.fmus, b.scenario.fmus, strict=True):
        assert list(fa.parameters.items()) == list(fb.parameters.items()), fa.name  # order too
    assert list(a.inputs.items()) == list(b.inputs.items())
    assert a.room_shape == b.room_shape


def test_the_paper_runs_updated_samples_are_the_two_passes(paper: tuple) -> None:
    make, tester = paper
    for i in range(0, 200, 7):
        posterior = tester.draw(i)
        at_once = make(i, posterior)
        _same(_two_passes(make, i, posterior), at_once)
        # the check can fail: the posterior changed the prior sample
        assert at_once.scenario != make(i).scenario


def test_a_posterior_of_other_keys_or_refused_values_takes_two_passes(paper: tuple) -> None:
    make, tester = paper
    posterior = tester.draw(3)
    key = next(iter(posterior))
    # a value outside its range: refused as the two passes refuse it
    bad = posterior | {key: -1.0}
    with pytest.raises(ConfigError) as two:
        _two_passes(make, 3, bad)
    with pytest.raises(ConfigError) as one:
        make(3, bad)
    assert (one.value.key, one.value.message) == (two.value.key, two.value.message)
    # the seed among the posterior's keys: set after the prior sample's own, as two passes do
    seeded = posterior | {"scenario.seed": 12345}
    _same(_two_passes(make, 3, seeded), make(3, seeded))
    assert make(3, seeded).scenario.seed == 12345


def test_a_prior_value_the_posterior_replaces_is_still_checked(paper: tuple) -> None:
    """Two passes refuse a prior value outside its range even where the posterior replaces it:
    one pass then gives way to them."""
    make, tester = paper
    posterior = tester.draw(0)
    key = next(iter(posterior))
    scenario = make(0).scenario
    assert montecarlo._with_posterior(scenario, {key: -1.0}, posterior) is None
    assert montecarlo._with_posterior(scenario, {key: posterior[key]}, posterior) is not None
