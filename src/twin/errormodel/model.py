"""The comprehensive error model: branches of characteristic matrices and the error e_z.

Each body ``j`` with lower body ``i`` carries four 4x4 matrices (the paper's Tables 2 and 3):

- ``T_ijp`` ideal positioning characteristic matrix (constant),
- ``dT_ijp`` positioning error matrix from six parameters ``p_dx .. p_ez``,
- ``T_ijs`` ideal kinematic characteristic matrix (constant, per sample, or a function of the motion),
- ``dT_ijs`` kinematic error matrix from six parameters ``s_dx .. s_ez``.

A point ``p_n`` given in the frame of a branch's end body ``n`` lies in the base frame at
``p_1n = prod over the chain base->n of (T_ijp dT_ijp T_ijs dT_ijs) @ p_n``. Its error is the actual
position minus the ideal one (all error matrices = I). Dropping the higher-order terms leaves a sum,
over every error matrix, of ``[ideal prefix] (dT - I) [ideal suffix] p_n``, linear in the error
parameters: a fixed sensitivity coefficient per parameter when the ideal matrices are constant.

The comprehensive error is ``e_z = (error of branch-1 end)_z - (error of branch-2 end)_z``, both ends in
the base frame. Lengths in metres, angles in radians; ``e_z`` has the unit of the lengths.

Errors are given as ``{body: {"p_dz": values, "s_ex": values, ...}}``; ``body`` is a name or index,
values are scalars or arrays of shape ``(N,)`` (one per sample). Motion variables (e.g. the spindle
swing angle) are given as ``{"angle": values}`` and passed to callable kinematic matrices.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from twin.errormodel.topology import Body, Topology
from twin.errormodel.transforms import ERROR_PARAMETERS, apply, error_matrix
from twin.errors import ConfigError

__all__ = [
    "ERROR_KEYS",
    "KINDS",
    "BranchModel",
    "ErrorModel",
    "Errors",
    "Joint",
    "Kinematic",
    "Motion",
]

#: The two error matrices of a joint: ``p`` = positioning (dT_ijp), ``s`` = kinematic (dT_ijs).
KINDS: tuple[str, ...] = ("p", "s")
#: Accepted keys of one body's error parameters: ``p_dx .. p_ez`` and ``s_dx .. s_ez``.
ERROR_KEYS: tuple[str, ...] = tuple(f"{k}_{q}" for k in KINDS for q in ERROR_PARAMETERS)

Array = NDArray[np.float64]
Motion = Mapping[str, ArrayLike]
# keyed by body name or by body index (two mapping types: Mapping keys are invariant for type checkers)
Errors = Mapping[str, Mapping[str, ArrayLike]] | Mapping[int, Mapping[str, ArrayLike]]
#: An ideal kinematic matrix: ``None`` (identity), a ``(4, 4)`` or ``(N, 4, 4)`` array, or a function
#: of the motion variables (a mapping of name -> array of shape ``()`` or ``(m,)``) returning either.
Kinematic = None | ArrayLike | Callable[[Mapping[str, Array]], ArrayLike]

# Samples per chunk on the per-sample paths: bounds memory (a (m, 4, 4) stack is 1 MB at 8192)
# while keeping the Python overhead per chunk negligible.
CHUNK = 8192


@dataclass(frozen=True)
class Joint:
    """Ideal characteristic matrices of a body relative to its lower body.

    ``positioning`` is ``T_ijp`` (constant 4x4); ``kinematic`` is ``T_ijs`` (see :data:`Kinematic`).
    """

    positioning: ArrayLike = field(default_factory=lambda: np.eye(4))
    kinematic: Kinematic = None


#: Joints keyed by body name or by body index; bodies left out get identity matrices.
Joints = Mapping[str, Joint] | Mapping[int, Joint]


def _check_matrix(value: Any, what: str, *, stack: bool) -> Array:
    try:
        m = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{what}: not a numeric 4x4 matrix ({exc})") from None
    if m.shape[-2:] != (4, 4) or m.ndim not in ((2, 3) if stack else (2,)):
        allowed = "(4, 4) or (N, 4, 4)" if stack else "(4, 4)"
        raise ConfigError(f"{what}: shape must be {allowed}, got {m.shape}")
    # max-abs rather than allclose: this runs on every chunk of a callable's output
    if m.size and np.abs(m[..., 3, :] - [0.0, 0.0, 0.0, 1.0]).max() > 1e-12:
        raise ConfigError(f"{what}: last row must be [0, 0, 0, 1]")
    return m


@dataclass(frozen=True)
class _Chunk:
    """A slice of the samples: its motion values and error parameters, already sliced."""

    sl: slice
    m: int | None  # samples in the chunk; None when everything is scalar
    motion: dict[str, Array]
    errors: dict[int, list[tuple[int, int, Array]]]  # body -> [(kind, parameter, values)]


@dataclass(frozen=True)
class _Inputs:
    n: int | None
    motion: dict[str, Array]
    errors: dict[int, list[tuple[int, int, Array]]]

    def chunks(self, size: int | None) -> Iterator[_Chunk]:
        """The whole input at once (``size=None`` or scalar input), else slices of ``size`` samples."""
        if self.n is None or size is None or size >= self.n:
            yield _Chunk(slice(None), self.n, self.motion, self.errors)
            return
        for start in range(0, self.n, size):
            sl = slice(start, min(start + size, self.n))
            cut = lambda a, sl=sl: a[sl] if a.ndim else a  # noqa: E731
            yield _Chunk(
                sl,
                sl.stop - sl.start,
                {k: cut(v) for k, v in self.motion.items()},
                {b: [(k, q, cut(v)) for k, q, v in e] for b, e in self.errors.items()},
            )


def _as_samples(value: ArrayLike, what: str) -> Array:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{what}: not numeric ({exc})") from None
    if a.ndim > 1:
        raise ConfigError(f"{what}: must be a scalar or an array of shape (N,), got shape {a.shape}")
    return a


def _run(
    inputs: _Inputs, size: int | None, tail: tuple[int, ...], compute: Callable[[_Chunk], dict[Any, Array]]
) -> dict[Any, Array]:
    """Apply ``compute`` chunk by chunk and assemble the outputs, each of shape ``(N, *tail)``.

    A chunk's output is either per sample, ``(m, *tail)``, or constant, ``tail`` (then broadcast), so
    a model with constant ideal matrices computes its coefficients once and never per sample.
    With scalar input (``N`` is ``None``) the outputs have shape ``tail``.
    """
    n = inputs.n
    if n is None:
        return compute(next(inputs.chunks(None)))
    out: dict[Any, Array] = {}
    for chunk in inputs.chunks(size):
        for key, value in compute(chunk).items():
            if key not in out:
                out[key] = np.empty((n, *tail))
            out[key][chunk.sl] = value  # broadcasts a constant over the chunk
    return out


def _add_cm(a: Array, b: Array | float) -> Array:
    """``a + b`` for component-major arrays ``(rows,)`` or ``(rows, m)``: the sample axis is last."""
    a, b = np.asarray(a), np.asarray(b)
    if 0 < a.ndim < b.ndim:
        a = a[..., None]
    elif 0 < b.ndim < a.ndim:
        b = b[..., None]
    return a + b


#: the sets of kept terms a model holds at most (:meth:`ErrorModel._constant_terms`): a Monte
#: Carlo needs one; a long record evaluated in chunks of scalar motion would add one a chunk
_TERMS_KEPT = 64


class BranchModel:
    """One branch: the chain of joints from the base to an end body and a point on that body.

    Build it through :class:`ErrorModel` or directly from a topology and joints.
    """

    def __init__(
        self,
        topology: Topology,
        joints: Joints,
        end: str | int,
        point: ArrayLike = (0.0, 0.0, 0.0),
        *,
        motion_defaults: Mapping[str, float] | None = None,
    ) -> None:
        self.topology = topology
        self.chain: tuple[int, ...] = topology.branch(end)
        self.end = topology.body(end).name
        known = _normalise_joints(topology, joints)
        self._positioning = [known[k][0] for k in self.chain[1:]]
        self._kinematic = [known[k][1] for k in self.chain[1:]]
        p = np.asarray(point, dtype=np.float64)
        if p.shape not in ((3,), (4,)):
            raise ConfigError(f"branch end point must have 3 or 4 coordinates, got shape {p.shape}")
        self.point: Array = np.append(p, 1.0) if p.shape == (3,) else p
        self.motion_defaults = dict(motion_defaults or {})
        # the coefficients of constant ideal matrices, by (rows, slots, scalar motion): the same
        # for every evaluation of a model (a Monte Carlo evaluates one per sample)
        self._constant: dict[tuple[Any, ...], dict[int, Array]] = {}

    @property
    def bodies(self) -> tuple[str, ...]:
        """Names of the bodies with a joint on this branch (base excluded), base side first."""
        return tuple(self.topology.body(k).name for k in self.chain[1:])

    # -- inputs -----------------------------------------------------------------------------------

    def _time_varying(self, motion: Mapping[str, Array]) -> bool:
        any_array_motion = any(v.ndim for v in motion.values())
        return any(
            (callable(k) and any_array_motion) or (isinstance(k, np.ndarray) and k.ndim == 3)
            for k in self._kinematic
        )

    def _stack_length(self) -> int | None:
        lengths = {k.shape[0] for k in self._kinematic if isinstance(k, np.ndarray) and k.ndim == 3}
        return lengths.pop() if lengths else None

    def _kinematics(self, chunk: _Chunk) -> list[Array]:
        mats = []
        for body, k in zip(self.chain[1:], self._kinematic, strict=True):
            if callable(k):
                what = f"kinematic matrix of body '{self.topology.body(body).name}'"
                m = _check_matrix(k(chunk.motion), what, stack=True)
                if m.ndim == 3 and m.shape[0] != chunk.m:
                    raise ConfigError(f"{what}: {m.shape[0]} samples for {chunk.m} motion samples")
            else:
                m = k[chunk.sl] if k.ndim == 3 else k
            mats.append(m)
        return mats

    # -- the three evaluations, on one chunk --------------------------------------------------------

    def _ideal(self, kins: list[Array]) -> Array:
        v = self.point
        for tp, ts in zip(reversed(self._positioning), reversed(kins), strict=True):
            v = apply(tp, apply(ts, v))
        return v

    def _actual(
        self, kins: list[Array], errors: Mapping[int, list[tuple[int, int, Array]]], exact: bool
    ) -> Array:
        v = self.point
        for j in reversed(range(len(self.chain) - 1)):
            params: list[list[Array | float]] = [[0.0] * 6, [0.0] * 6]
            given = [False, False]
            for kind, q, x in errors.get(self.chain[j + 1], ()):
                params[kind][q] = x
                given[kind] = True
            if given[1]:
                v = apply(error_matrix(params[1], exact=exact), v)
            v = apply(kins[j], v)
            if given[0]:
                v = apply(error_matrix(params[0], exact=exact), v)
            v = apply(self._positioning[j], v)
        return v

    def _coefficients(
        self, kins: list[Array], rows: tuple[int, ...] = (0, 1, 2), slots: set[int] | None = None
    ) -> dict[int, Array]:
        """First-order sensitivities ``d p_1n[row] / d parameter`` per error slot.

        Slot ``2 * joint + kind`` (kind 0 = p, 1 = s) maps to an array ``(len(rows), 6, *batch)``:
        base-frame components ``rows`` of x, y, z, the six parameters, then the sample axis if the ideal
        matrices vary per sample (component-major, so every operation below runs on contiguous
        per-sample vectors). ``slots=None`` computes all of them.

        The error matrix of slot ``m`` sits after the ideal matrices ``M_0 .. M_m``; its first-order
        term is ``R @ G_q @ v``, with ``R`` the rotation block of ``M_0 .. M_m`` (``G_q v`` has no
        homogeneous part) and ``v = M_{m+1} .. M_last @ p``. For a row ``r`` of ``R``, a translation
        ``q`` gives ``r[q] * w`` and a small rotation about axis ``q`` gives ``r . (e_q x v) = (v x r)[q]``.
        So only rows of ``R`` and the point are propagated, skipping pure translations' rotations.
        """
        mats: list[Array] = []
        for tp, ts in zip(self._positioning, kins, strict=True):
            mats += [tp, ts]
        # per-sample stacks (m, 4, 4) -> component-major (4, 4, m)
        mats = [m if m.ndim == 2 else np.ascontiguousarray(np.moveaxis(m, 0, -1)) for m in mats]
        eye = np.eye(3)
        r: Array = eye[list(rows)]  # (rows, 3, *batch)
        prefix_rows: list[Array] = []
        for m in mats:
            rot = m[:3, :3]
            if rot.ndim == 2 and r.ndim == 2:
                r = r @ rot
            elif rot.ndim > 2 or not np.array_equal(rot, eye):
                r = np.einsum("ri...,ij...->rj...", r, rot)
            prefix_rows.append(r)
        v: Array = self.point  # (4, *batch)
        points: list[Array] = [v]
        for m in reversed(mats[1:]):
            if m.ndim == 2 and np.array_equal(m[:3, :3], eye):
                # a pure translation: three scaled additions instead of a matrix product
                t = m[:3, 3].reshape(3, *([1] * (v.ndim - 1)))
                v = np.concatenate([v[:3] + t * v[3], v[3:]]) if t.any() else v
            else:
                v = np.einsum("ij...,j...->i...", m, v)
            points.append(v)
        points.reverse()
        out: dict[int, Array] = {}
        for slot, (r, v) in enumerate(zip(prefix_rows, points, strict=True)):
            if slots is not None and slot not in slots:
                continue
            batch = np.broadcast_shapes(r.shape[2:], v.shape[1:])
            c = np.empty((len(rows), 6, *batch))
            if r.ndim == 2 and v.ndim == 2:
                r = r[..., None]  # constant rows against per-sample points: add the sample axis
            x, y, z, w = v
            rx, ry, rz = r[:, 0], r[:, 1], r[:, 2]
            c[:, 0], c[:, 1], c[:, 2] = rx * w, ry * w, rz * w
            c[:, 3], c[:, 4], c[:, 5] = y * rz - z * ry, z * rx - x * rz, x * ry - y * rx
            out[slot] = c
        return out

    def _chunk_coefficients(self, c: _Chunk, rows: tuple[int, ...], slots: set[int]) -> dict[int, Array]:
        """:meth:`_coefficients` on the chunk ``c``; those of constant ideal matrices (no
        per-sample stack, every motion variable a scalar) made once per motion and kept,
        read-only (the kinematic matrices are functions of the motion alone)."""
        if self._time_varying(c.motion) or any(v.ndim for v in c.motion.values()):
            return self._coefficients(self._kinematics(c), rows=rows, slots=slots)
        key = (rows, frozenset(slots), tuple(sorted((k, float(v)) for k, v in c.motion.items())))
        known = self._constant.get(key)
        if known is None:
            known = self._coefficients(self._kinematics(c), rows=rows, slots=slots)
            for value in known.values():
                value.setflags(write=False)
            self._constant[key] = known
        return known

    def _error_slots(self, errors: Mapping[int, list[tuple[int, int, Array]]]) -> set[int]:
        """The slots (``2 * joint + kind``) that carry at least one given error parameter."""
        return {2 * j + kind for j, body in enumerate(self.chain[1:]) for kind, _, _ in errors.get(body, ())}

    def _first_order(
        self, coef: Mapping[int, Array], errors: Mapping[int, list[tuple[int, int, Array]]]
    ) -> dict[int, Array]:
        """Per-body first-order contribution ``sum_q coef[:, q] * x_q``, shape ``(rows, *batch)``."""
        n_rows = next(iter(coef.values())).shape[0] if coef else 1
        out: dict[int, Array] = {}
        for j, body in enumerate(self.chain[1:]):
            total: Array = np.zeros(n_rows)
            for kind, q, x in errors.get(body, ()):
                c = coef[2 * j + kind][:, q]
                # constant (rows,) coefficients times per-sample x: the sample axis goes last
                total = _add_cm(total, c[:, None] * x if c.ndim == 1 and x.ndim == 1 else c * x)
            out[body] = total
        return out

    # -- public evaluations -------------------------------------------------------------------------

    def _inputs(self, errors: Errors | None, motion: Motion | None) -> _Inputs:
        return _prepare(self.topology, [self], errors, motion, self.motion_defaults)

    def ideal_position(self, motion: Motion | None = None) -> Array:
        """Ideal position of the end point in the base frame, shape ``(..., 3)``."""
        inputs = self._inputs(None, motion)
        res = _run(inputs, CHUNK, (3,), lambda c: {"p": self._ideal(self._kinematics(c))[..., :3]})
        return res["p"]

    def actual_position(
        self, errors: Errors | None, motion: Motion | None = None, *, exact: bool = False
    ) -> Array:
        """Actual position (full 4x4 product), shape ``(..., 3)``.

        ``exact=False`` uses the first-order error matrices (the paper's), ``True`` full rotations.
        """
        inputs = self._inputs(errors, motion)

        def compute(c: _Chunk) -> dict[str, Array]:
            return {"p": self._actual(self._kinematics(c), c.errors, exact)[..., :3]}

        return _run(inputs, CHUNK, (3,), compute)["p"]

    def position_error(
        self, errors: Errors | None, motion: Motion | None = None, *, exact: bool = False
    ) -> Array:
        """Actual minus ideal position of the end point (full product), shape ``(..., 3)``."""
        inputs = self._inputs(errors, motion)

        def compute(c: _Chunk) -> dict[str, Array]:
            kins = self._kinematics(c)
            return {"e": (self._actual(kins, c.errors, exact) - self._ideal(kins))[..., :3]}

        return _run(inputs, CHUNK, (3,), compute)["e"]

    def first_order_error(self, errors: Errors | None, motion: Motion | None = None) -> Array:
        """Position error with higher-order terms dropped (linear in the parameters), ``(..., 3)``."""
        inputs = self._inputs(errors, motion)
        size = CHUNK if self._time_varying(inputs.motion) else None

        def compute(c: _Chunk) -> dict[str, Array]:
            coef = self._coefficients(self._kinematics(c), slots=self._error_slots(c.errors))
            total: Array = np.zeros(3)
            for part in self._first_order(coef, c.errors).values():
                total = _add_cm(total, part)
            return {"e": np.moveaxis(total, 0, -1)}

        return _run(inputs, size, (3,), compute)["e"]

    def sensitivities(self, motion: Motion | None = None) -> Array:
        """First-order sensitivities of the end point, shape ``(..., K, 2, 3, 6)``.

        ``[..., j, kind, axis, q]`` is ``d p_1n[axis] / d (kind, parameter q)`` of the ``j``-th body of
        :attr:`bodies`. Constant (no sample axis) when the ideal matrices are constant.
        """
        inputs = self._inputs(None, motion)
        size = CHUNK if self._time_varying(inputs.motion) else None
        k = len(self.chain) - 1

        def compute(c: _Chunk) -> dict[str, Array]:
            coef = self._coefficients(self._kinematics(c))
            full = np.stack(np.broadcast_arrays(*(coef[s] for s in range(2 * k))))  # (2K, 3, 6, *batch)
            return {
                "c": np.moveaxis(full.reshape(k, 2, 3, 6, *full.shape[3:]), (0, 1, 2, 3), (-4, -3, -2, -1))
            }

        return _run(inputs, size, (k, 2, 3, 6), compute)["c"]


def _normalise_joints(topology: Topology, joints: Joints) -> dict[int, tuple[Array, Any]]:
    out: dict[int, tuple[Array, Any]] = {
        b.index: (np.eye(4), np.eye(4)) for b in topology.bodies if b.lower is not None
    }
    for key, joint in joints.items():
        body = topology.body(key)
        if body.lower is None:
            raise ConfigError(f"body '{body.name}' is the base: it has no joint")
        what = f"body '{body.name}'"
        tp = _check_matrix(joint.positioning, f"{what}: positioning matrix", stack=False)
        kin = joint.kinematic
        if kin is None:
            ks: Any = np.eye(4)
        elif callable(kin):
            ks = kin
        else:
            ks = _check_matrix(kin, f"{what}: kinematic matrix", stack=True)
        out[body.index] = (tp, ks)
    return out


def _prepare(
    topology: Topology,
    branches: Sequence[BranchModel],
    errors: Errors | None,
    motion: Motion | None,
    defaults: Mapping[str, float],
) -> _Inputs:
    """Validate errors and motion and find the sample count ``N`` (``None`` if all scalar).

    Every per-sample input (a motion variable, an error parameter, a stack of ideal kinematic
    characteristic matrices) must have the same ``N``; the first of each length is named.
    """
    lengths: dict[int, str] = {}
    mot = {
        name: _samples(value, f"motion variable '{name}'", lengths)
        for name, value in {**defaults, **(motion or {})}.items()
    }
    errs: dict[int, list[tuple[int, int, Array]]] = {}
    for key, params in (errors or {}).items():
        body = topology.body(key)
        if body.index in errs:
            raise ConfigError(f"errors of body '{body.name}' given twice")
        errs[body.index] = _body_errors(body, params, lengths)
    for b in branches:
        n_stack = b._stack_length()
        if n_stack is not None:
            lengths.setdefault(n_stack, "a kinematic matrix stack")
    if len(lengths) > 1:
        detail = ", ".join(f"{who}: {n}" for n, who in lengths.items())
        raise ConfigError(f"inconsistent sample counts ({detail})")
    return _Inputs(next(iter(lengths), None), mot, errs)


def _samples(value: ArrayLike, what: str, lengths: dict[int, str]) -> Array:
    """:func:`_as_samples`, noting the length of a per-sample array (and who has it first)."""
    x = _as_samples(value, what)
    if x.ndim:
        lengths.setdefault(x.shape[0], what)
    return x


def _body_errors(body: Body, params: Any, lengths: dict[int, str]) -> list[tuple[int, int, Array]]:
    """One body's error parameters as ``(kind, parameter, values)``: kind 0 is its positioning
    error matrix dT_ijp (``p_*``), 1 its kinematic error matrix dT_ijs (``s_*``)."""
    if body.lower is None:
        raise ConfigError(f"body '{body.name}' is the base (the reference): it takes no errors")
    if not isinstance(params, Mapping):
        raise ConfigError(f"errors of body '{body.name}' must map parameter names to values")
    entries = []
    for pkey, value in params.items():
        if pkey not in ERROR_KEYS:
            raise ConfigError(
                f"body '{body.name}': unknown error parameter {pkey!r} (expected p_dx..p_ez or s_dx..s_ez)"
            )
        kind, q = pkey.split("_")
        x = _samples(value, f"body '{body.name}' {pkey}", lengths)
        entries.append((KINDS.index(kind), ERROR_PARAMETERS.index(q), x))
    return entries


class ErrorModel:
    """The comprehensive error model of a two-branch MBS (the paper's eq. 9).

    ``ends`` are the end bodies of branch 1 and branch 2; ``points`` the points on them (default:
    their frame origins). ``e_z = (error of branch-1 end)_z - (error of branch-2 end)_z``.
    ``motion_defaults`` gives values for motion variables not passed to an evaluation.
    """

    def __init__(
        self,
        topology: Topology,
        joints: Joints,
        ends: tuple[str | int, str | int],
        points: tuple[ArrayLike, ArrayLike] = ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
        *,
        motion_defaults: Mapping[str, float] | None = None,
    ) -> None:
        if len(ends) != 2 or len(points) != 2:
            raise ConfigError("the comprehensive error needs exactly two branch ends and two points")
        self.topology = topology
        self.motion_defaults = dict(motion_defaults or {})
        self.branches: tuple[BranchModel, BranchModel] = (
            BranchModel(topology, joints, ends[0], points[0], motion_defaults=self.motion_defaults),
            BranchModel(topology, joints, ends[1], points[1], motion_defaults=self.motion_defaults),
        )
        # Bodies on either branch, branch 1 first; a body shared by both branches appears once.
        self.bodies: tuple[str, ...] = tuple(dict.fromkeys(self.branches[0].bodies + self.branches[1].bodies))
        self._terms: dict[tuple[Any, ...], list[tuple[float, str, int, list[tuple[Any, int]]]]] = {}

    def _inputs(self, errors: Errors | None, motion: Motion | None) -> _Inputs:
        return _prepare(self.topology, self.branches, errors, motion, self.motion_defaults)

    def _size(self, inputs: _Inputs) -> int | None:
        return CHUNK if any(b._time_varying(inputs.motion) for b in self.branches) else None

    def _parts(self, c: _Chunk) -> dict[str, Array]:
        """First-order e_z per body on one chunk: +branch-1 contribution - branch-2 contribution."""
        terms = self._constant_terms(c)
        parts: dict[str, Any] = {}
        if terms is not None:
            # the same operations as below in the same order, the coefficients looked up once
            for sign, name, body, each in terms:
                entries = c.errors.get(body, ())
                total: Any = np.float64(0.0)
                for i, (coefficient, position) in enumerate(each):
                    x = coefficient * entries[position][2]
                    total = 0.0 + x if i == 0 else total + x
                parts[name] = parts.get(name, 0.0) + sign * total
            return {k: np.asarray(v) for k, v in parts.items()}
        for sign, branch in zip((1.0, -1.0), self.branches, strict=True):
            coef = branch._chunk_coefficients(c, (2,), branch._error_slots(c.errors))
            for body, value in branch._first_order(coef, c.errors).items():
                name = self.topology.body(body).name
                parts[name] = parts.get(name, 0.0) + sign * value[0]
        return {k: np.asarray(v) for k, v in parts.items()}

    def _constant_terms(self, c: _Chunk) -> list[tuple[float, str, int, list[tuple[Any, int]]]] | None:
        """For ideal matrices constant over the chunk ``c`` (None otherwise): per body of each
        branch in turn, the branch's sign, the body's name and index, and per error parameter
        of ``c`` its coefficient in e_z and its place among the body's parameters.

        A model evaluated again and again with the same parameters (a Monte Carlo's samples)
        finds its coefficients here instead of walking the branches and the slots anew; kept
        per scalar motion and per set of parameters given."""
        if any(v.ndim for v in c.motion.values()) or any(b._time_varying(c.motion) for b in self.branches):
            return None
        given = tuple((body, tuple((kind, q) for kind, q, _ in e)) for body, e in c.errors.items())
        key = (tuple(sorted((k, float(v)) for k, v in c.motion.items())), given)
        terms = self._terms.get(key)
        if terms is None:
            terms = []
            for sign, branch in zip((1.0, -1.0), self.branches, strict=True):
                coef = branch._chunk_coefficients(c, (2,), branch._error_slots(c.errors))
                for j, body in enumerate(branch.chain[1:]):
                    each = [
                        (coef[2 * j + kind][0, q], i) for i, (kind, q, _) in enumerate(c.errors.get(body, ()))
                    ]
                    terms.append((sign, self.topology.body(body).name, body, each))
            if len(self._terms) >= _TERMS_KEPT:  # a long record's chunks, each its own motion
                self._terms.clear()
            self._terms[key] = terms
        return terms

    def e_z(self, errors: Errors | None, motion: Motion | None = None) -> Array:
        """First-order comprehensive error along Z, shape ``()`` or ``(N,)``."""
        inputs = self._inputs(errors, motion)
        return _run(
            inputs, self._size(inputs), (), lambda c: {"e": np.asarray(sum(self._parts(c).values()))}
        )["e"]

    def e_z_by_body(self, errors: Errors | None, motion: Motion | None = None) -> dict[str, Array]:
        """First-order ``e_z`` split by body (each body's own parameters); sums to :meth:`e_z`.

        Keys are :attr:`bodies` in order; a body without errors contributes zeros.
        """
        inputs = self._inputs(errors, motion)
        return _run(inputs, self._size(inputs), (), self._parts)

    def e_z_full(self, errors: Errors | None, motion: Motion | None = None, *, exact: bool = False) -> Array:
        """``e_z`` from the full 4x4 products (no terms dropped), shape ``()`` or ``(N,)``.

        ``exact=True`` also replaces the first-order error matrices by full rotations.
        """
        inputs = self._inputs(errors, motion)

        def compute(c: _Chunk) -> dict[str, Array]:
            e = []
            for b in self.branches:
                kins = b._kinematics(c)
                e.append(b._actual(kins, c.errors, exact)[..., 2] - b._ideal(kins)[..., 2])
            return {"e": e[0] - e[1]}

        return _run(inputs, CHUNK, (), compute)["e"]

    def e_z_coefficients(self, motion: Motion | None = None) -> dict[tuple[str, str], Array]:
        """Sensitivity of ``e_z`` to every error parameter: ``{(body, "p_dz"): d e_z / d p_dz, ...}``.

        Constant values when the ideal matrices are constant, else one per sample.
        """
        inputs = self._inputs(None, motion)

        def compute(c: _Chunk) -> dict[tuple[str, str], Array]:
            out: dict[tuple[str, str], Array] = {}
            for sign, branch in zip((1.0, -1.0), self.branches, strict=True):
                coef = branch._coefficients(branch._kinematics(c), rows=(2,))  # slot -> (1, 6, *batch)
                for j, body in enumerate(branch.bodies):
                    for kind in range(2):
                        for q in range(6):
                            key = (body, f"{KINDS[kind]}_{ERROR_PARAMETERS[q]}")
                            out[key] = out.get(key, 0.0) + sign * coef[2 * j + kind][0, q]
            return out

        return _run(inputs, self._size(inputs), (), compute)

    def ideal_gap(self, motion: Motion | None = None) -> Array:
        """Ideal branch-1 end minus ideal branch-2 end, shape ``(..., 3)``: zero for a closed geometry."""
        return self.branches[0].ideal_position(motion) - self.branches[1].ideal_position(motion)
