"""Every seed of the twin, derived in one place.

Two kinds of stream, and nothing else draws random numbers:

- an FMU instance's noise (its ``seed`` parameter) comes from the scenario's seed and the
  instance's position: :func:`instance_seed`. Its formula is part of every recorded signal
  (the sensors' noise), so it never changes;
- a study's draws (a sweep's design and points, the testers as built, room curves, the
  Monte Carlo's samples) come from ``numpy.random.SeedSequence(seed, spawn_key=key)``:
  :func:`sequence`, and a scenario seed for one of its runs from :func:`scenario_seed`. The
  first number of each key says what the draw is for (:class:`Key`), so two studies with the
  same seed never share a stream, and a draw depends only on its seed and its key: the same
  whatever the number of workers or the order results come back in.
"""

from __future__ import annotations

from enum import IntEnum

import numpy as np

__all__ = ["Key", "generator", "instance_seed", "scenario_seed", "sequence"]

#: a scenario's seed is a 31-bit number (what every FMU's seed parameter takes)
SEED_LIMIT = 2**31


class Key(IntEnum):
    """What a draw is for: the first number of its spawn key."""

    DESIGN = 0  # a sweep's design matrix
    POINT = 1  # a sweep point's scenario seed
    TESTER = 2  # a tester as built
    ROOM = 3  # a held-out scenario's slow room drift
    RUN = 4  # a held-out or calibration run's scenario seed
    SAMPLE = 7  # a run's Monte Carlo sample (its room drift and scenario seed)
    UPDATE = 8  # twin update: its walkers' start, its sampler and its prior draws


def sequence(seed: int, *key: int) -> np.random.SeedSequence:
    """The seed sequence of one draw: ``seed`` and its spawn key (first :class:`Key`)."""
    return np.random.SeedSequence(seed, spawn_key=key)


def generator(seed: int, *key: int) -> np.random.Generator:
    """A random generator of one draw (:func:`sequence`)."""
    return np.random.default_rng(sequence(seed, *key))


def scenario_seed(seed: int, *key: int) -> int:
    """A scenario seed in [0, 2^31) for one run, from ``seed`` and the run's key."""
    return int(sequence(seed, *key).generate_state(1, np.uint32)[0] % SEED_LIMIT)


def instance_seed(scenario_seed: int, index: int) -> int:
    """The noise seed of the scenario's FMU instance number ``index``: distinct, reproducible
    streams per instance from the one scenario seed."""
    return (scenario_seed * 1_000_003 + 7919 * (index + 1)) % (SEED_LIMIT - 1)
