"""The MBS error model: zero errors, one-to-one dz, first order vs full product, vectorisation."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from twin.errormodel import model as model_mod
from twin.errormodel.model import ERROR_KEYS, BranchModel, ErrorModel, Joint
from twin.errormodel.tester import load_tester_spec, tester_model
from twin.errormodel.topology import Body, Topology
from twin.errormodel.transforms import rotation_y, rotation_z, translation
from twin.errors import ConfigError

BRANCH_1 = ("bearing_block", "testing_spindle", "spherical_plain_bearing", "t_plate")
BRANCH_2 = ("detecting_frame", "displacement_sensor", "contacting_clamp", "long_pole")


@pytest.fixture(scope="module")
def tester() -> ErrorModel:
    return tester_model()


def random_errors(rng: np.random.Generator, eps: float, n: int | None = None, length: float = 0.5) -> dict:
    """All twelve parameters of every tester body: translations ~ eps * length, rotations ~ eps."""
    size = () if n is None else (n,)
    errs = {}
    for body in BRANCH_1 + BRANCH_2:
        errs[body] = {
            key: eps * (length if key[2] == "d" else 1.0) * rng.uniform(-1, 1, size) for key in ERROR_KEYS
        }
    return errs


def scale(errors: dict, factor: float) -> dict:
    return {b: {k: factor * v for k, v in p.items()} for b, p in errors.items()}


# -- all errors zero --------------------------------------------------------------------------------


def test_zero_errors_give_zero_exactly(tester: ErrorModel) -> None:
    angles = np.random.default_rng(10).uniform(-np.pi, np.pi, 200)
    zeros = {body: dict.fromkeys(ERROR_KEYS, np.zeros(200)) for body in BRANCH_1 + BRANCH_2}
    for errors in (zeros, {}, None):
        motion = {"angle": angles}
        assert np.array_equal(tester.e_z(errors, motion), np.zeros(200))
        assert np.array_equal(tester.e_z_full(errors, motion), np.zeros(200))
        assert np.array_equal(tester.e_z_full(errors, motion, exact=True), np.zeros(200))
        for branch in tester.branches:
            assert np.array_equal(branch.position_error(errors, motion), np.zeros((200, 3)))


@given(angle=st.floats(-np.pi, np.pi), n=st.integers(1, 5))
@settings(max_examples=30, deadline=None)
def test_zero_errors_zero_for_any_angle(angle: float, n: int) -> None:
    m = tester_model()
    zeros = {b: dict.fromkeys(ERROR_KEYS, 0.0) for b in BRANCH_1 + BRANCH_2}
    angles = np.full(n, angle)
    assert np.array_equal(m.e_z(zeros, {"angle": angles}), np.zeros(n))
    assert np.array_equal(m.e_z_full(zeros, {"angle": angles}), np.zeros(n))
    assert m.e_z_full(zeros, {"angle": angle}) == 0.0


# -- one body's dz goes one-to-one into e_z ---------------------------------------------------------


@pytest.mark.parametrize(("body", "sign"), [(b, 1.0) for b in BRANCH_1] + [(b, -1.0) for b in BRANCH_2])
@pytest.mark.parametrize("key", ["p_dz", "s_dz"])
def test_single_dz_one_to_one(tester: ErrorModel, body: str, sign: float, key: str) -> None:
    dz = np.array([-2e-5, 1e-6, 3.7e-5])
    errors = {body: {key: dz}}
    np.testing.assert_allclose(tester.e_z(errors), sign * dz, rtol=1e-12, atol=1e-20)
    # the full product subtracts ideal from actual positions ~0.5 m: rounding ~1e-16 m remains
    for e in (tester.e_z_full(errors), tester.e_z_full(errors, exact=True)):
        np.testing.assert_allclose(e, sign * dz, rtol=0, atol=1e-15)
    parts = tester.e_z_by_body(errors)
    np.testing.assert_allclose(parts[body], sign * dz, rtol=1e-12)
    assert all(not np.any(v) for k, v in parts.items() if k != body)


def test_dz_and_dx_rotate_with_the_spindle_when_it_swings(tester: ErrorModel) -> None:
    # a kinematic error of the spindle lives in the swinging spindle frame: at 90 deg its dx points along Z
    errors = {"testing_spindle": {"s_dx": 1e-5}}
    # rotation_y(+pi/2) turns +X into -Z
    np.testing.assert_allclose(tester.e_z(errors, {"angle": np.pi / 2}), -1e-5, rtol=1e-12)
    np.testing.assert_allclose(tester.e_z(errors, {"angle": 0.0}), 0.0, atol=1e-21)
    # while a positioning error of the block does not swing
    np.testing.assert_allclose(
        tester.e_z({"bearing_block": {"p_dz": 1e-5}}, {"angle": 1.0}), 1e-5, rtol=1e-12
    )


# -- first order vs full product --------------------------------------------------------------------


@pytest.mark.parametrize("exact", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_first_order_matches_full_product_to_second_order(tester: ErrorModel, exact: bool, seed: int) -> None:
    rng = np.random.default_rng(seed)
    n = 64
    base_errors = random_errors(rng, 1.0, n)
    motion = {"angle": rng.uniform(-np.pi / 3, np.pi / 3, n)}
    residuals = []
    for eps in (1e-3, 5e-4, 2.5e-4):
        errors = scale(base_errors, eps)
        first, full = tester.e_z(errors, motion), tester.e_z_full(errors, motion, exact=exact)
        residual = np.abs(full - first).max()
        # twelve parameters on eight bodies, lever arms ~0.5 m: the squared terms stay below 20 eps^2 m
        assert residual <= 20.0 * eps**2
        assert np.abs(first).max() > 10 * residual  # the first-order part is not negligible
        residuals.append(residual)
    ratios = np.array(residuals[:-1]) / np.array(residuals[1:])
    np.testing.assert_allclose(ratios, 4.0, rtol=0.1)  # halving eps quarters the dropped terms


@given(seed=st.integers(0, 2**32 - 1), eps=st.floats(1e-5, 1e-3))
@settings(max_examples=25, deadline=None)
def test_first_order_branch_error_vector_second_order(seed: int, eps: float) -> None:
    m = tester_model()
    rng = np.random.default_rng(seed)
    errors = random_errors(rng, eps)
    angle = float(rng.uniform(-np.pi, np.pi))
    for branch in m.branches:
        full = branch.position_error(errors, {"angle": angle}, exact=True)
        first = branch.first_order_error(errors, {"angle": angle})
        assert full.shape == first.shape == (3,)
        assert np.abs(full - first).max() <= 20.0 * eps**2


def test_first_order_is_linear_in_the_coefficients(tester: ErrorModel) -> None:
    rng = np.random.default_rng(4)
    errors = random_errors(rng, 1e-4)
    coef = tester.e_z_coefficients({"angle": 0.3})
    by_hand = sum(coef[(body, key)] * errors[body][key] for body in errors for key in ERROR_KEYS)
    np.testing.assert_allclose(tester.e_z(errors, {"angle": 0.3}), by_hand, rtol=1e-12)


def test_by_body_sums_to_total(tester: ErrorModel) -> None:
    rng = np.random.default_rng(5)
    errors = random_errors(rng, 1e-4, 100)
    motion = {"angle": rng.uniform(-1, 1, 100)}
    parts = tester.e_z_by_body(errors, motion)
    assert tuple(parts) == BRANCH_1 + BRANCH_2
    np.testing.assert_allclose(sum(parts.values()), tester.e_z(errors, motion), rtol=1e-12, atol=1e-18)


# -- vectorisation: chunks, per-sample vs constant paths --------------------------------------------


def test_per_sample_path_agrees_with_scalar_evaluations(tester: ErrorModel) -> None:
    rng = np.random.default_rng(6)
    n = 2 * model_mod.CHUNK + 37  # several chunks and a ragged last one
    errors = random_errors(rng, 1e-4, n)
    motion = {"angle": rng.uniform(-np.pi, np.pi, n)}
    first, full = tester.e_z(errors, motion), tester.e_z_full(errors, motion)
    assert first.shape == full.shape == (n,)
    for i in (0, model_mod.CHUNK - 1, model_mod.CHUNK, n - 1):
        errors_i = {b: {k: v[i] for k, v in p.items()} for b, p in errors.items()}
        assert tester.e_z(errors_i, {"angle": motion["angle"][i]}) == pytest.approx(
            first[i], rel=1e-12, abs=1e-20
        )
        assert tester.e_z_full(errors_i, {"angle": motion["angle"][i]}) == pytest.approx(full[i], rel=1e-12)


def test_constant_and_per_sample_angles_agree(tester: ErrorModel) -> None:
    rng = np.random.default_rng(7)
    errors = random_errors(rng, 1e-4, 50)
    constant = tester.e_z(errors, {"angle": 0.4})
    per_sample = tester.e_z(errors, {"angle": np.full(50, 0.4)})
    np.testing.assert_allclose(constant, per_sample, rtol=1e-12, atol=1e-20)
    coef = tester.e_z_coefficients({"angle": np.full(50, 0.4)})
    assert coef[("bearing_block", "p_dz")].shape == (50,)


def test_coefficients_computed_once_for_constant_ideal_matrices(monkeypatch: pytest.MonkeyPatch) -> None:
    tester = load_tester_spec().model()  # its own: the shared model keeps what others made
    calls = []
    original = BranchModel._coefficients

    def counting(self: BranchModel, kins: list, *args: object, **kwargs: object) -> dict:
        calls.append(max(k.ndim for k in kins))
        return original(self, kins, *args, **kwargs)

    monkeypatch.setattr(BranchModel, "_coefficients", counting)
    n = 100_000
    tester.e_z({"detecting_frame": {"p_dz": np.linspace(0, 4e-5, n)}})
    assert calls == [2, 2]  # once per branch, from constant 4x4 matrices
    calls.clear()
    tester.e_z({"detecting_frame": {"p_dz": np.linspace(0, 4e-5, 7)}})
    assert calls == []  # kept for the next evaluation (a Monte Carlo's next sample)
    tester.e_z({"detecting_frame": {"p_dz": np.zeros(n)}}, {"angle": np.zeros(n)})
    chunks = -(-n // model_mod.CHUNK)
    assert len(calls) == 2 * chunks  # swinging spindle: per chunk of samples
    assert calls[::2] == [3] * chunks  # branch 1 per sample; branch 2 has no motion, constant per chunk


def test_kinematic_stack_equals_callable() -> None:
    topo = Topology([Body(1, "base"), Body(2, "arm", 1), Body(3, "probe", 2), Body(4, "post", 1)])
    angles = np.linspace(-1, 1, 9)
    common = {3: Joint(translation(0.3, 0.0, 0.1)), 4: Joint(translation(0.3, 0.0, 0.1))}
    by_callable = ErrorModel(
        topo, {2: Joint(kinematic=lambda m: rotation_z(m["a"])), **common}, ends=("probe", "post")
    )
    by_stack = ErrorModel(topo, {2: Joint(kinematic=rotation_z(angles)), **common}, ends=("probe", "post"))
    errors = {"arm": {"p_ey": 1e-4, "s_dz": 2e-5}, "probe": {"p_ex": np.full(9, 3e-5)}}
    np.testing.assert_allclose(by_callable.e_z(errors, {"a": angles}), by_stack.e_z(errors), rtol=1e-12)
    np.testing.assert_allclose(
        by_callable.e_z_full(errors, {"a": angles}), by_stack.e_z_full(errors), rtol=1e-12
    )
    # an arm of 0.3 m turned by ey lowers the probe by... nothing along Z: ey turns X into -Z
    coef = by_stack.e_z_coefficients()[("arm", "p_ey")]
    np.testing.assert_allclose(coef, -0.3 * np.cos(angles), rtol=1e-12)


def test_shared_bodies_cancel() -> None:
    # both ends on the same lower body: its translation errors move both and cancel in e_z
    topo = Topology([Body(1, "base"), Body(2, "column", 1), Body(3, "left", 2), Body(4, "right", 2)])
    joints = {2: Joint(rotation_y(0.2) @ translation(0, 0, -1.0)), 3: Joint(translation(0.1, 0, 0))}
    m = ErrorModel(topo, joints, ends=("left", "right"))
    assert m.bodies == ("column", "left", "right")
    np.testing.assert_allclose(m.e_z({"column": {"p_dz": 1e-3, "p_dx": 2e-3}}), 0.0, atol=1e-18)
    np.testing.assert_allclose(m.e_z({"right": {"p_dz": 1e-3}}), -1e-3 * np.cos(0.2), rtol=1e-12)


# -- input validation --------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("errors", "motion", "match"),
    [
        ({"nope": {"p_dz": 1.0}}, None, "unknown body 'nope'"),
        ({"base": {"p_dz": 1.0}}, None, "base"),
        ({"t_plate": {"dz": 1.0}}, None, "unknown error parameter 'dz'"),
        ({"t_plate": {"p_dz": np.zeros(3)}}, {"angle": np.zeros(4)}, "inconsistent sample counts"),
        ({"t_plate": {"p_dz": np.zeros((2, 2))}}, None, r"shape \(2, 2\)"),
        ({"t_plate": {"p_dz": "x"}}, None, "not numeric"),
    ],
)
def test_bad_inputs_raise_config_error(
    tester: ErrorModel, errors: dict, motion: dict | None, match: str
) -> None:
    with pytest.raises(ConfigError, match=match):
        tester.e_z(errors, motion)


def test_bad_joint_matrices_raise_config_error() -> None:
    topo = Topology([Body(1, "base"), Body(2, "a", 1)])
    with pytest.raises(ConfigError, match="shape must be"):
        ErrorModel(topo, {2: Joint(np.eye(3))}, ends=("a", "a"))
    with pytest.raises(ConfigError, match="last row"):
        ErrorModel(topo, {2: Joint(2 * np.eye(4))}, ends=("a", "a"))
    with pytest.raises(ConfigError, match="base"):
        ErrorModel(topo, {1: Joint()}, ends=("a", "a"))


def test_branch_sensitivities_agree_with_e_z_coefficients(tester: ErrorModel) -> None:
    angles = np.array([0.0, 0.7, -1.2])
    b1, b2 = tester.branches
    s1, s2 = b1.sensitivities({"angle": angles}), b2.sensitivities({"angle": angles})
    assert s1.shape == (3, 4, 2, 3, 6)
    assert b2.sensitivities().shape == (4, 2, 3, 6)  # no motion on branch 2: constant
    coef = tester.e_z_coefficients({"angle": angles})
    for j, body in enumerate(BRANCH_1):
        np.testing.assert_allclose(coef[(body, "s_ey")], s1[:, j, 1, 2, 4], atol=1e-15)
    for j, body in enumerate(BRANCH_2):
        np.testing.assert_allclose(coef[(body, "p_ex")], -s2[:, j, 0, 2, 3], atol=1e-15)


def test_branch_first_order_per_sample_path(tester: ErrorModel) -> None:
    rng = np.random.default_rng(8)
    n = model_mod.CHUNK + 5
    errors = random_errors(rng, 1e-5, n)
    motion = {"angle": rng.uniform(-np.pi, np.pi, n)}
    branch = tester.branches[0]
    first = branch.first_order_error(errors, motion)
    full = branch.position_error(errors, motion)
    assert first.shape == full.shape == (n, 3)
    assert np.abs(first - full).max() <= 20 * 1e-5**2
    assert np.abs(first).max() > 1e-7


def test_bad_kinematic_callable_output() -> None:
    topo = Topology([Body(1, "base"), Body(2, "arm", 1)])
    wrong_count = ErrorModel(
        topo, {2: Joint(kinematic=lambda m: rotation_z(m["a"][:-1]))}, ends=("arm", "arm")
    )
    with pytest.raises(ConfigError, match="kinematic matrix of body 'arm': 2 samples for 3 motion samples"):
        wrong_count.e_z({"arm": {"p_dz": 1.0}}, {"a": np.zeros(3)})
    not_4x4 = ErrorModel(topo, {2: Joint(kinematic=lambda m: np.eye(3))}, ends=("arm", "arm"))
    with pytest.raises(ConfigError, match="shape must be"):
        not_4x4.e_z(None, {"a": 0.0})


def test_kept_coefficients_give_the_numbers_of_fresh_ones() -> None:
    """The coefficients of constant ideal matrices are kept per motion: an evaluation after
    others (other slots, another swing angle) gives the same doubles as a fresh model's."""
    rng = np.random.default_rng(11)
    used = load_tester_spec().model()
    cases = [
        (random_errors(rng, 1e-4, 40), {"angle": 0.3}),
        ({"t_plate": {"p_dz": rng.normal(size=40)}}, {"angle": 0.3}),
        (random_errors(rng, 1e-4, 40), {"angle": -1.1}),
        (random_errors(rng, 1e-4, 40), None),
    ]
    for _ in range(2):
        for errors, motion in cases:
            fresh = load_tester_spec().model()
            kept, new = used.e_z_by_body(errors, motion), fresh.e_z_by_body(errors, motion)
            assert all(np.array_equal(kept[b], new[b]) for b in new)
    assert len(used.branches[0]._constant) == 4  # three angles (one the default), at 0.3 two slot sets


def test_the_kept_terms_give_the_doubles_of_the_walk_over_the_branches(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """An evaluation on constant ideal matrices takes each body's terms kept from the one
    before (a Monte Carlo's samples): the same operations in the same order as walking the
    branches and slots, so the same doubles, signed zeros included, for every mix of
    parameters (arrays, scalars, zeros of either sign, a body on both branches)."""
    rng = np.random.default_rng(17)
    thermal = {b: {"p_dz": rng.normal(0, 1e-5, 50)} for b in BRANCH_1 + BRANCH_2}
    cases: list[tuple[ErrorModel, dict, dict | None]] = [
        (tester_model(), random_errors(rng, 1e-4, 50), None),
        (tester_model(), random_errors(rng, 1e-4, None), {"angle": 0.4}),
        (tester_model(), thermal, None),
        (
            tester_model(),
            {"displacement_sensor": {"p_dz": -np.zeros(50)}, "contacting_clamp": {"p_ey": 0.0}},
            None,
        ),
        (
            tester_model(),
            {"t_plate": {"p_dz": rng.choice([0.0, -0.0, 1e-6], 50), "s_ez": -0.0}},
            {"angle": 0.0},
        ),
    ]
    topo = Topology([Body(1, "base"), Body(2, "column", 1), Body(3, "left", 2), Body(4, "right", 2)])
    joints = {2: Joint(rotation_y(0.2) @ translation(0, 0, -1.0)), 3: Joint(translation(0.1, 0, 0))}
    shared = ErrorModel(topo, joints, ends=("left", "right"))
    cases.append(
        (shared, {"column": {"p_dz": rng.normal(size=50), "p_ex": -0.0}, "right": {"p_dz": 1e-3}}, None)
    )
    kept = [(model.e_z_by_body(e, m), model.e_z(e, m)) for model, e, m in cases]
    kept_again = [(model.e_z_by_body(e, m), model.e_z(e, m)) for model, e, m in cases]
    assert all(model._terms for model, _, _ in cases)  # the short way was taken
    monkeypatch.setattr(ErrorModel, "_constant_terms", lambda self, c: None)
    for (model, e, m), *got in zip(cases, kept, kept_again, strict=True):
        walked_by_body, walked = model.e_z_by_body(e, m), model.e_z(e, m)
        for by_body, total in got:
            assert list(by_body) == list(walked_by_body)
            assert all(by_body[b].tobytes() == walked_by_body[b].tobytes() for b in by_body)
            assert total.shape == walked.shape and total.tobytes() == walked.tobytes()
