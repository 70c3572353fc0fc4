"""Topology: Huston's lower-body array, branches, validation errors."""

from __future__ import annotations

import numpy as np
import pytest

from twin.errormodel.tester import tester_model
from twin.errormodel.topology import Body, Topology
from twin.errors import ConfigError, ConfigErrors

# Table 1 of the paper, derived by hand from the two branches 1-2-3-4-5 and 1-6-7-8-9:
# row n holds L^n(k) for k = 1..9; L^0(k) = k, L^n(1) = 1, and the table ends when all entries are 1.
TESTER_LOWER_BODY_ARRAY = [
    [1, 2, 3, 4, 5, 6, 7, 8, 9],
    [1, 1, 2, 3, 4, 1, 6, 7, 8],
    [1, 1, 1, 2, 3, 1, 1, 6, 7],
    [1, 1, 1, 1, 2, 1, 1, 1, 6],
    [1, 1, 1, 1, 1, 1, 1, 1, 1],
]


def chain(*lowers: int | None) -> list[Body]:
    """Bodies 1..n with the given lower bodies."""
    return [Body(i + 1, f"b{i + 1}", low) for i, low in enumerate(lowers)]


def test_tester_lower_body_array_matches_hand_table() -> None:
    topo = tester_model().topology
    assert topo.indices == tuple(range(1, 10))
    np.testing.assert_array_equal(topo.lower_body_array(), TESTER_LOWER_BODY_ARRAY)


def test_lower_operator_definition() -> None:
    topo = tester_model().topology
    for k in topo.indices:
        assert topo.lower(k, 0) == k
        assert topo.lower(1, k) == 1
        for n in range(1, 6):
            assert topo.lower(k, n) == topo.lower(topo.lower(k, n - 1), 1)


def test_branches_and_lookup() -> None:
    topo = tester_model().topology
    assert topo.branch(5) == (1, 2, 3, 4, 5)
    assert topo.branch("long_pole") == (1, 6, 7, 8, 9)
    assert topo.branch("base") == (1,)
    assert topo.depth("t_plate") == 4
    assert topo.body("detecting_frame").index == 6
    assert topo.base.name == "base"


def test_unordered_input_is_sorted_by_index() -> None:
    topo = Topology([Body(3, "c", 2), Body(1, "a"), Body(2, "b", 1)])
    assert topo.indices == (1, 2, 3)
    np.testing.assert_array_equal(topo.lower_body_array(), [[1, 2, 3], [1, 1, 2], [1, 1, 1]])


def one_line_error(bodies: list[Body]) -> str:
    with pytest.raises(ConfigError) as info:
        Topology(bodies)
    assert not isinstance(info.value, ConfigErrors)
    message = str(info.value)
    assert "\n" not in message
    return message


def test_cycle_is_a_config_error() -> None:
    message = one_line_error(chain(None, 3, 4, 2))
    assert message == "cycle in lower bodies: 2 -> 3 -> 4 -> 2"


def test_self_lower_is_a_cycle() -> None:
    assert "cycle" in one_line_error(chain(None, 2))


def test_unknown_lower_body() -> None:
    assert one_line_error(chain(None, 1, 7)) == "body 3 ('b3'): unknown lower body 7"


def test_duplicate_index() -> None:
    assert "duplicate body index 2" in one_line_error([Body(1, "a"), Body(2, "b", 1), Body(2, "c", 1)])


def test_no_base() -> None:
    assert "no base body" in one_line_error([Body(1, "a", 2), Body(2, "b", 1)])


def test_base_must_be_body_1() -> None:
    assert "index 1" in one_line_error([Body(2, "a"), Body(3, "b", 2)])


def test_several_problems_are_reported_together() -> None:
    with pytest.raises(ConfigErrors) as info:
        Topology([Body(1, "a"), Body(2, "b", 8), Body(3, "c", 9)])
    lines = str(info.value).splitlines()
    assert lines == ["body 2 ('b'): unknown lower body 8", "body 3 ('c'): unknown lower body 9"]


def test_unknown_body_lookup() -> None:
    with pytest.raises(ConfigError, match="unknown body 'nope'"):
        tester_model().topology.body("nope")
