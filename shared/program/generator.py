"""Automatic program generation: the virtual robot's motion becomes action statements online.

Thesis section 4.2.2 splits generation into *trajectory segmentation* and *action matching*;
section 4.3.5 gives the matching rules. This module implements both as a push-driven state
machine: the console feeds it the virtual robot's states as they happen (``feed``), and it hands
back statements as soon as a segment closes, so in the free-motion zone they can stream to the
robot while the operator is still moving.

Segmentation (4.2.2). The thesis assumes the operator's path is piecewise linear with roughly
constant velocity in each piece, and ends the current segment when the current velocity ``V_i``
departs from the segment's mean velocity ``V_m`` by ``||V_i - V_m|| >= eps``; otherwise ``V_m`` is
updated and the segment grows. Practical additions, each there to keep jitter or the operator's
uneven hand from making statements:

* velocities are finite differences over a short window (``velocity_window``), not one sample
  step: their noise is about ``sqrt(2) * jitter / window`` whatever the sample rate;
* a segment also closes when the robot stops (every velocity part at or below its *noise
  floor*), and motion only opens a segment when some part rises above it;
* by default only the part of ``V_i - V_m`` across the mean direction counts, plus a reversal:
  statements carry no speed, so a stroke that speeds up or slows down along one line stays one
  statement (``split_on_speed_change=True`` applies the thesis's test literally);
* the departure is seen only once the window has taken in part of the new motion, so the split
  point is placed where a two-piece least-squares fit of the window (velocity before, velocity
  after, vectorised over the candidate samples) puts it, not at the sample where the test fired;
  the same fit times a stop and finds the turning point of a reversal;
* a tool-mode segment is cut once it has turned ``max_segment_rotation`` (150 deg), so a
  ROTATE/MOVES target is never half a turn or more away.

In tool mode the velocity has a linear part (m/s) and an angular part (rad/s), tested separately
against their own thresholds because their units do not mix; in joint mode the joint-velocity
vector (rad/s) is one part. A relative term (``relative_departure * ||V_m||``) is added to each
absolute threshold, so a fast stroke is not cut by noise that is small relative to its speed.

Matching (4.3.5). Each segment is compared with the *program's* state at its start (the ideal end
of the previous generated statement, which is where the real robot will be; this is the thesis's
action continuity): in joint mode one changed joint gives DRIVE, two or more give MOVE; in tool
mode a position change only gives DRAW, an orientation change only ROTATE, both MOVES. "Changed"
means beyond ``min_joint_change``, ``min_translation`` or ``min_rotation``, so a segment made of
jitter, or too small to be worth a statement, yields nothing and its change is carried into the
next one. Components that did not change keep the program's values (DRIVE and MOVE keep the
unchanged joints, DRAW keeps the orientation, ROTATE the position), so no jitter leaks into
targets. The thesis assumes the jog mode (joint or tool) does not change within a statement: a mode
change closes the open segment.

Continuations. A statement generated right after another of the same kind, in the same frame,
that goes on the same way is marked as continuing it (``Generated.continues``): a DRIVE of the
same joint, a DRAW whose path is the same straight line onward (the previous target within
``merge_tolerance`` of the line from the previous start to the new target), a ROTATE about the
same axis onward (``merge_angle``), a MOVES that does both, a MOVE along the same joint-space
line. The program then replaces the previous statement's target with the new one instead of
adding a statement (``merged``): one straight stroke cut by a pause or a change of pace is one
statement, and action continuity holds since the replaced statement started where the previous
one did. ``feed``/``flush``/``generate`` keep giving every segment's statement.

Cartesian targets are expressed in a named frame (``settings.frame``, BASE by default; the
console follows the frame the operator jogs in, ``set_frame``); samples may carry the tool pose
in the base or the world frame, and the caller passes ``world_T_base`` / ``world_T_work`` when a
conversion between frames is needed.
"""

from __future__ import annotations

import logging
import dataclasses
import math
from collections import deque
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from shared.errors import InputError
from shared.language.statements import Draw, Drive, Frame, Move, Moves, Rotate, Statement
from shared.language.units import TextUnit, to_si
from shared.spatial import invert, log_so3, matrix_to_rpy

log = logging.getLogger(__name__)


class JogMode(str, Enum):
    """What the operator is driving (thesis 4.3.4): one joint at a time, or the tool.

    Not the arm's control mode (position or force: ``MODE`` statements, and
    ``shared.wire.messages.ControlMode`` in telemetry), which is the one ``ControlMode``.
    """

    JOINT = "joint"
    TOOL = "tool"


def _as_pose(value: object, name: str, t: float) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (4, 4):
        raise InputError(f"sample at t={t:.3f} s: {name} must be a 4x4 transform, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"sample at t={t:.3f} s: {name} contains NaN or infinity")
    return arr


@dataclass(frozen=True)
class RobotSample:
    """One state of the virtual robot: time (s), joint vector (rad), jog mode, and the tool
    pose in the base frame or in the world frame (at least one of them in tool mode).

    The tool pose is whatever point the statements should target (the flange, or the gripper
    centre); the generator does not compute kinematics itself.
    """

    t: float
    q: np.ndarray
    mode: JogMode
    base_T_tool: np.ndarray | None = None
    world_T_tool: np.ndarray | None = None

    def __post_init__(self) -> None:
        t = float(self.t)
        if not math.isfinite(t):
            raise InputError(f"sample time must be a finite number of seconds, got {self.t!r}")
        object.__setattr__(self, "t", t)
        q = np.asarray(self.q, dtype=float).reshape(-1)
        if q.size == 0 or not np.all(np.isfinite(q)):
            raise InputError(f"sample at t={t:.3f} s: joint vector must be non-empty and finite")
        object.__setattr__(self, "q", q)
        try:
            object.__setattr__(self, "mode", JogMode(self.mode))
        except ValueError:
            raise InputError(
                f"sample at t={t:.3f} s: unknown control mode {self.mode!r} for jogging; valid: joint, tool"
            ) from None
        if self.base_T_tool is not None:
            object.__setattr__(self, "base_T_tool", _as_pose(self.base_T_tool, "base_T_tool", t))
        if self.world_T_tool is not None:
            object.__setattr__(self, "world_T_tool", _as_pose(self.world_T_tool, "world_T_tool", t))
        if self.mode is JogMode.TOOL and self.base_T_tool is None and self.world_T_tool is None:
            raise InputError(f"tool-mode sample at t={t:.3f} s has no tool pose (base_T_tool or world_T_tool)")


@dataclass(frozen=True)
class GeneratorSettings:
    """Thresholds of segmentation and matching (SI units).

    Defaults suit an operator jogging at 5 deg/s or 10 mm/s and faster, with jitter up to about
    0.05 mm and 0.02 deg per sample on every joint and axis. The noise of a windowed velocity is
    about ``sqrt(2) * jitter / velocity_window`` per component whatever the sample rate; the noise
    floors sit above its tail, the departure thresholds above the floors, and the minimum
    changes well above the jitter itself.
    """

    velocity_window: float = 0.1
    """s: span of the finite difference that estimates the current velocity."""
    joint_departure: float = math.radians(3.0)
    """rad/s: joint-mode departure threshold eps on ||V_i - V_m||."""
    linear_departure: float = 0.010
    """m/s: tool-mode departure threshold on the linear velocity."""
    angular_departure: float = math.radians(4.0)
    """rad/s: tool-mode departure threshold on the angular velocity."""
    relative_departure: float = 0.25
    """Fraction of ||V_m|| added to each absolute departure threshold."""
    joint_noise_floor: float = math.radians(2.0)
    """rad/s: a joint velocity norm at or below this is standing still."""
    linear_noise_floor: float = 0.005
    """m/s: a linear tool speed at or below this is standing still."""
    angular_noise_floor: float = math.radians(1.5)
    """rad/s: an angular tool speed at or below this is standing still."""
    min_joint_change: float = math.radians(0.2)
    """rad: a joint whose change over a segment is at or below this did not change."""
    min_translation: float = 0.001
    """m: a tool displacement at or below this is no position change."""
    min_rotation: float = math.radians(0.5)
    """rad: a tool rotation at or below this is no orientation change."""
    max_segment_rotation: float = math.radians(150.0)
    """rad: a tool-mode segment closes once the tool has turned this far from the statement's
    start, so every ROTATE/MOVES target is less than half a turn away and the robot's shortest
    way to it is the way the operator turned."""
    split_on_speed_change: bool = False
    """Apply the thesis's test literally: the whole of ``V_i - V_m`` counts, so a change of speed
    alone also ends a segment. Generated statements carry no speed, so such a split only cuts
    one straight stroke into collinear pieces (an operator accelerating smoothly gets several
    DRAWs); by default only the part of the departure across the mean direction (or a reversal)
    counts."""
    frame: Frame = Frame.BASE
    """Frame of the Cartesian targets of DRAW, ROTATE and MOVES."""
    mm_decimals: int = 1
    """Generated positions are rounded to this many decimals of a millimetre (0.1 mm: the
    resolution an operator controls with the number boxes, below the minimum change, and it
    keeps the IK's hundredths out of the text: a pure-x drag writes y 0, not 0.04); the text
    shows exactly these."""
    deg_decimals: int = 1
    """Generated angles (joint targets, roll-pitch-yaw) are rounded to this many decimals of a
    degree (0.1 deg, as the joint boxes take them)."""
    merge_tolerance: float = 0.002
    """m: a DRAW/MOVES continues the previous one when the previous target lies within this of
    the straight line from the previous start to the new target (and between them)."""
    merge_angle: float = math.radians(2.0)
    """rad: the same for orientations (ROTATE/MOVES: the previous orientation within this of the
    turn from the previous start to the new one) and for joint vectors (MOVE)."""

    def __post_init__(self) -> None:
        for name in (
            "velocity_window", "joint_departure", "linear_departure", "angular_departure",
            "joint_noise_floor", "linear_noise_floor", "angular_noise_floor",
            "min_joint_change", "min_translation", "min_rotation", "max_segment_rotation",
            "merge_tolerance", "merge_angle",
        ):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise InputError(f"generator setting {name} must be a positive number, got {value!r}")
        for name in ("mm_decimals", "deg_decimals"):
            value = getattr(self, name)
            if not (isinstance(value, int) and 0 <= value <= 6):
                raise InputError(f"generator setting {name} must be an integer 0..6, got {value!r}")
        if not (math.isfinite(self.relative_departure) and self.relative_departure >= 0):
            raise InputError(f"generator setting relative_departure must be >= 0, got {self.relative_departure!r}")
        try:
            frame = Frame(self.frame)
        except ValueError:
            raise InputError(f"generator setting frame {self.frame!r} unknown; valid: BASE, WORK, WORLD") from None
        if frame is Frame.TOOL:
            raise InputError(
                "generator setting frame TOOL is not supported: a tool-frame target depends on where "
                "the statement starts; generate in BASE, WORLD or WORK"
            )
        object.__setattr__(self, "frame", frame)


@dataclass(frozen=True)
class GeneratedSegment:
    """A closed segment: when it ran, in which mode, why it closed, and its statement (``None``
    when the change stayed within the minimum-change thresholds)."""

    t_start: float
    t_end: float
    mode: JogMode
    reason: str  # "departure", "stop", "rotation", "mode", "flush"
    statement: Statement | None


@dataclass(frozen=True)
class Generated:
    """A generated statement, and whether it continues the statement generated just before it
    (same kind and frame, the same line or joint onward): then it replaces that statement, whose
    start it shares, instead of following it."""

    statement: Statement
    continues: bool = False


def merged(generated: Iterable[Generated]) -> list[Statement]:
    """The program that generated statements make: a continuing statement replaces the one
    before it."""
    out: list[Statement] = []
    for g in generated:
        if g.continues and out:
            out[-1] = g.statement
        else:
            out.append(g.statement)
    return out


def _between_on_line(start: np.ndarray, middle: np.ndarray, end: np.ndarray, tolerance: float) -> bool:
    """``middle`` lies within ``tolerance`` of the straight segment from ``start`` to ``end``,
    strictly after ``start`` and before ``end`` along it (the motion went on the same way)."""
    d = end - start
    length = _norm(d)
    if length <= 0.0:
        return False
    u = d / length
    along = float((middle - start) @ u)
    if along <= 0.0 or along >= length:
        return False
    return _norm(middle - start - along * u) <= tolerance


@dataclass
class _State:
    """A sample reduced to what segmentation needs, in the output frame."""

    t: float
    q: np.ndarray
    p: np.ndarray | None = None  # F_p_tool
    r: np.ndarray | None = None  # F_R_tool


def _log_so3_batch(rotations: np.ndarray) -> np.ndarray:
    """Rotation vectors of ``(n, 3, 3)`` rotations, well away from pi (window-relative turns)."""
    w = np.stack(
        [rotations[:, 2, 1] - rotations[:, 1, 2], rotations[:, 0, 2] - rotations[:, 2, 0], rotations[:, 1, 0] - rotations[:, 0, 1]],
        axis=1,
    )
    cos = np.clip((np.trace(rotations, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
    angle = np.arccos(cos)
    sin = np.sin(angle)
    scale = np.where(sin > 1e-9, angle / np.maximum(2.0 * sin, 1e-300), 0.5)
    return w * scale[:, None]


def _norm(v: np.ndarray) -> float:
    """Euclidean norm of a short vector (cheaper than ``np.linalg.norm`` per call)."""
    return math.sqrt(float(np.dot(v, v)))


def _rotvec_of(rotation: np.ndarray) -> tuple[float, float, float]:
    """Rotation vector of one rotation well away from pi, in plain floats (the per-sample path)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = rotation.ravel().tolist()
    c = max(-1.0, min(1.0, (r00 + r11 + r22 - 1.0) / 2.0))
    angle = math.acos(c)
    sin = math.sin(angle)
    k = angle / (2.0 * sin) if sin > 1e-9 else 0.5
    return ((r21 - r12) * k, (r02 - r20) * k, (r10 - r01) * k)


def _angle(rotation: np.ndarray) -> float:
    """Angle (rad) of one rotation matrix."""
    c = (float(rotation[0, 0]) + float(rotation[1, 1]) + float(rotation[2, 2]) - 1.0) / 2.0
    return math.acos(max(-1.0, min(1.0, c)))


def _corner_index(ts: np.ndarray, xs: np.ndarray, v_before: np.ndarray, prior: float) -> int:
    """Index ``j`` (0..n-2) of the window sample where the velocity most plausibly changed.

    Model for each candidate ``j``: the samples on each side of ``j`` lie on a line through
    ``x_j`` at that side's own least-squares velocity; the earlier side's velocity leans on
    ``v_before`` with the weight of a sample ``prior`` seconds away (it may hold only a sample or
    two). The cost is the sum of squared residuals. ``xs`` is ``(n, d)`` in commensurate (scaled)
    units. Vectorised over the candidates.
    """
    n = len(ts)
    if n <= 2:
        return 0
    js = np.arange(n - 1)
    dt = ts[None, :] - ts[js, None]  # (J, n): t_m - t_j
    dx = xs[None, :, :] - xs[js, None, :]  # (J, n, d): x_m - x_j
    before = np.arange(n)[None, :] <= js[:, None]  # (J, n)
    w_b, w_a = before * dt, (~before) * dt
    lam = prior * prior
    v_b = (np.einsum("jm,jmd->jd", w_b, dx) + lam * v_before[None, :]) / (np.einsum("jm,jm->j", w_b, dt) + lam)[:, None]
    v_a = np.einsum("jm,jmd->jd", w_a, dx) / np.einsum("jm,jm->j", w_a, dt)[:, None]
    model = np.where(before[:, :, None], v_b[:, None, :], v_a[:, None, :]) * dt[:, :, None]
    r = dx - model
    return int(np.argmin(np.einsum("jmd,jmd->j", r, r)))


class ProgramGenerator:
    """Online segmentation of a stream of ``RobotSample`` into action statements.

    ``feed(sample)`` returns the statements of the segments that closed at this sample (usually
    none, at most two); ``flush()`` closes the open segment. Samples must come in increasing time.
    ``segments`` holds the last ``SEGMENT_HISTORY`` closed segments, with or without a statement,
    for display and diagnosis.

    A stop is seen only in samples taken while standing still, so the caller either keeps
    sampling at a steady rate while the operator holds the control, or calls ``flush()`` when
    the operator lets go; otherwise the last stroke stays open until the next sample.
    """

    SEGMENT_HISTORY = 1000

    def __init__(
        self,
        settings: GeneratorSettings | None = None,
        *,
        world_T_base: np.ndarray | None = None,
        world_T_work: np.ndarray | None = None,
    ) -> None:
        self.settings = settings or GeneratorSettings()
        self._world_T_base = None if world_T_base is None else _as_pose(world_T_base, "world_T_base", 0.0)
        self._world_T_work = None if world_T_work is None else _as_pose(world_T_work, "world_T_work", 0.0)
        self._out_T_world: np.ndarray | None = None
        self._out_T_base: np.ndarray | None = None
        self._prepare_frames()
        self.segments: deque[GeneratedSegment] = deque(maxlen=self.SEGMENT_HISTORY)
        self._dof: int | None = None
        self._last: _State | None = None
        self._mode: JogMode | None = None
        self._reset_motion()
        self._anchor_q: np.ndarray | None = None
        self._anchor_p: np.ndarray | None = None
        self._anchor_r: np.ndarray | None = None
        self._forget_previous()

    # -- frames --------------------------------------------------------------------------------
    def _prepare_frames(self) -> None:
        """Work out ``out_T_world`` and ``out_T_base`` where the given transforms allow it."""
        frame = self.settings.frame
        wb, ww = self._world_T_base, self._world_T_work
        if frame is Frame.WORLD:
            self._out_T_world = np.eye(4)
            self._out_T_base = wb
        elif frame is Frame.BASE:
            self._out_T_base = np.eye(4)
            self._out_T_world = None if wb is None else invert(wb)
        else:  # WORK
            self._out_T_world = None if ww is None else invert(ww)
            self._out_T_base = None if (ww is None or wb is None) else invert(ww) @ wb

    def set_frame(self, frame: Frame | str) -> list[Generated]:
        """Write the Cartesian targets of the next statements in ``frame`` (BASE, WORLD or WORK):
        the open segment closes first (its statement is in the old frame, and returned), and the
        program state is re-expressed in the new one. Needs ``world_T_base`` (and
        ``world_T_work`` for WORK)."""
        if frame is self.settings.frame:  # the usual case, once per tool jog: nothing to check
            return []
        settings = dataclasses.replace(self.settings, frame=frame)  # checks the name
        if settings.frame is self.settings.frame:
            return []
        old = (self.settings, self._out_T_world, self._out_T_base)
        self.settings = settings
        self._prepare_frames()
        last = self._last if self._last is not None and self._last.p is not None else None
        if (last is not None or self._anchor_p is not None) and (old[1] is None or self._out_T_world is None):
            self.settings, self._out_T_world, self._out_T_base = old
            raise InputError(f"cannot write generated targets in {settings.frame.value}: give the generator world_T_base and world_T_work")
        self.settings, self._out_T_world, self._out_T_base = old
        out = self.finish()  # in the old frame
        old_T_world = self._out_T_world
        self.settings = settings
        self._prepare_frames()
        if last is not None or self._anchor_p is not None:
            new_T_old = self._out_T_world @ invert(old_T_world)
            rot, shift = new_T_old[:3, :3], new_T_old[:3, 3]
            if last is not None:  # the window is dropped below; the last state stays for the next sample
                last.p, last.r = rot @ last.p + shift, rot @ last.r
            if self._anchor_p is not None:
                self._anchor_p, self._anchor_r = rot @ self._anchor_p + shift, rot @ self._anchor_r
        self._reset_motion()
        self._forget_previous()
        return out

    def _out_T_tool(self, sample: RobotSample) -> np.ndarray:
        if sample.base_T_tool is not None and self._out_T_base is not None:
            return self._out_T_base @ sample.base_T_tool
        if sample.world_T_tool is not None and self._out_T_world is not None:
            return self._out_T_world @ sample.world_T_tool
        have = "base_T_tool" if sample.base_T_tool is not None else "world_T_tool"
        need = {Frame.WORLD: "world_T_base", Frame.BASE: "world_T_base", Frame.WORK: "world_T_work (and world_T_base for base poses)"}
        raise InputError(
            f"sample at t={sample.t:.3f} s gives {have} but targets are in {self.settings.frame.value}: "
            f"give the generator {need[self.settings.frame]}"
        )

    # -- state -------------------------------------------------------------------------------
    def _reset_motion(self) -> None:
        self._window: deque[_State] = deque()
        self._active = False
        self._t_start = 0.0
        self._vm_sum: np.ndarray | None = None
        self._vm_count = 0
        # velocities that joined the segment, with the time of their window's end
        self._v_hist: deque[tuple[float, np.ndarray]] = deque(maxlen=64)

    def _state(self, sample: RobotSample) -> _State:
        if sample.mode is JogMode.JOINT:
            return _State(sample.t, sample.q)
        pose = self._out_T_tool(sample)
        return _State(sample.t, sample.q, pose[:3, 3].copy(), pose[:3, :3].copy())

    def _set_anchor(self, state: _State) -> None:
        self._anchor_q = state.q.copy()
        self._anchor_p = None if state.p is None else state.p.copy()
        self._anchor_r = None if state.r is None else state.r.copy()

    def reset(self, sample: RobotSample | None = None) -> None:
        """Drop the open segment and re-anchor the program state at ``sample`` (e.g. after the
        virtual robot was re-synced from telemetry, thesis 4.2.3); with no sample the next fed
        sample becomes the anchor."""
        self._reset_motion()
        self._last = None
        self._mode = None
        self._anchor_q = self._anchor_p = self._anchor_r = None
        self._forget_previous()
        if sample is not None:
            self.feed(sample)

    def _forget_previous(self) -> None:
        """The next statement continues nothing (a re-anchoring, a mode or frame change)."""
        self._previous: Statement | None = None
        self._previous_start: tuple[np.ndarray, np.ndarray | None, np.ndarray | None] | None = None

    # -- velocities ----------------------------------------------------------------------------
    def _velocity(self, old: _State, new: _State) -> np.ndarray:
        dt = new.t - old.t
        if self._mode is JogMode.JOINT:
            return (new.q - old.q) / dt
        out = np.empty(6)
        out[:3] = new.p - old.p
        out[3:] = _rotvec_of(new.r @ old.r.T)
        return out / dt

    def _parts(self) -> tuple[tuple[slice, float, float], ...]:
        """(slice of the velocity vector, departure threshold, noise floor) per velocity part."""
        s = self.settings
        if self._mode is JogMode.JOINT:
            return ((slice(0, None), s.joint_departure, s.joint_noise_floor),)
        return (
            (slice(0, 3), s.linear_departure, s.linear_noise_floor),
            (slice(3, 6), s.angular_departure, s.angular_noise_floor),
        )

    def _stop_point(self) -> tuple[_State, float]:
        """Where and when the segment ended, once the window's velocity fell to the noise floor.
        The state is the latest sample (the robot is at rest, or creeping to rest), unless the
        motion turned back inside the window; then it is the turning point, which lies further
        along the segment. The time is the fitted change point in both cases."""
        latest = self._window[-1]
        if self._vm_count == 0:
            return latest, latest.t
        ts, xs, scale = self._scaled_window()
        vb = self._velocity_before(self._window[0].t, self._vm_sum / self._vm_count) * scale
        j = _corner_index(ts, xs, vb, self.settings.velocity_window / 2.0)
        state = self._window[j] if float((xs[j] - xs[-1]) @ vb) > 0.0 else latest
        return state, float(ts[j])

    def _velocity_before(self, t: float, vm: np.ndarray) -> np.ndarray:
        """The segment's velocity measured over the window that ended at ``t`` (the start of
        the current window): wholly before the change that the current window has seen."""
        for t_v, v in reversed(self._v_hist):
            if t_v <= t + 1e-9:
                return v
        return vm

    def _departed(self, v: np.ndarray, vm: np.ndarray, parts) -> bool:
        """The departure test of thesis 4.2.2, per velocity part: ``||v - vm|| >= eps`` (plus the
        relative term). Unless ``split_on_speed_change``, only the part of ``v`` across ``vm``'s
        direction counts, and reversing counts; a part that was standing still departs as soon
        as it moves faster than the threshold."""
        literal = self.settings.split_on_speed_change
        for sl, eps, floor in parts:
            vp, mp = v[sl], vm[sl]
            norm_m = _norm(mp)
            limit = eps + self.settings.relative_departure * norm_m
            if literal or norm_m <= floor:
                if _norm(vp - mp) >= limit:
                    return True
                continue
            u = mp / norm_m
            along = float(vp @ u)
            # across the mean direction the relative term sets a turning angle, so it scales
            # with the slower of the two speeds (a fast stroke followed by a slow one turns too)
            across_limit = eps + self.settings.relative_departure * min(norm_m, _norm(vp))
            if _norm(vp - along * u) >= across_limit:
                return True
            if along < 0.0 and -along >= limit:
                return True
        return False

    def _scaled_window(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Times, positions in commensurate units, and the per-component scale (1/threshold)."""
        states = list(self._window)
        ts = np.array([s.t for s in states])
        if self._mode is JogMode.JOINT:
            xs = np.stack([s.q for s in states])
            scale = np.full(xs.shape[1], 1.0 / self.settings.joint_departure)
        else:
            ps = np.stack([s.p for s in states])
            rs = np.stack([s.r for s in states])
            rv = _log_so3_batch(rs @ rs[0].T)
            xs = np.concatenate([ps, rv], axis=1)
            scale = np.array([1.0 / self.settings.linear_departure] * 3 + [1.0 / self.settings.angular_departure] * 3)
        return ts, xs * scale, scale

    # -- the push API ----------------------------------------------------------------------------
    def feed(self, sample: RobotSample) -> list[Statement]:
        """Take the next state of the virtual robot; return statements of segments that closed."""
        return [g.statement for g in self.push(sample)]

    def push(self, sample: RobotSample) -> list[Generated]:
        """As :meth:`feed`, each statement with whether it continues the one before it."""
        if not isinstance(sample, RobotSample):
            raise InputError(f"feed() takes a RobotSample, got {type(sample).__name__}")
        if self._dof is None:
            self._dof = sample.q.size
        elif sample.q.size != self._dof:
            raise InputError(f"sample at t={sample.t:.3f} s has {sample.q.size} joints, the stream has {self._dof}")
        if self._last is not None and sample.t <= self._last.t:
            raise InputError(f"sample time {sample.t:.6f} s does not follow the previous one ({self._last.t:.6f} s)")
        out: list[Generated] = []
        if self._mode is not None and sample.mode is not self._mode:
            out.extend(self._close(self._last, "mode"))
            self._reset_motion()
            self._anchor_q = self._anchor_p = self._anchor_r = None
            self._forget_previous()
        self._mode = sample.mode
        state = self._state(sample)
        self._last = state
        if self._anchor_q is None:
            self._set_anchor(state)
        window = self._window
        window.append(state)
        span = self.settings.velocity_window
        while len(window) > 2 and state.t - window[1].t >= span:
            window.popleft()
        if len(window) < 2:
            return out
        v = self._velocity(window[0], state)
        parts = self._parts()
        moving = False
        for sl, _, floor in parts:
            if _norm(v[sl]) > floor:
                moving = True
                break
        if not self._active:
            if moving:
                self._start_segment(self._onset_index(), "onset")
            return out
        if not moving:
            end, t_end = self._stop_point()
            out.extend(self._close(end, "stop", t_end))
            self._active = False
            return out
        if state.r is not None and _angle(self._anchor_r.T @ state.r) > self.settings.max_segment_rotation:
            out.extend(self._close(state, "rotation"))
            self._start_segment(len(window) - 1, "rotation")
            return out
        if window[0].t < self._t_start:  # the window still reaches back before this segment
            return out
        if self._vm_count == 0:
            self._vm_sum = v.copy()
            self._vm_count = 1
            self._v_hist.append((state.t, v))
            return out
        vm = self._vm_sum / self._vm_count
        if not self._departed(v, vm, parts):
            self._vm_sum += v
            self._vm_count += 1
            self._v_hist.append((state.t, v))
            return out
        ts, xs, scale = self._scaled_window()
        j = _corner_index(ts, xs, self._velocity_before(window[0].t, vm) * scale, self.settings.velocity_window / 2.0)
        corner = window[j]
        out.extend(self._close(corner, "departure"))
        self._start_segment(j, "departure")
        return out

    def flush(self) -> list[Statement]:
        """Close the open segment at the last sample (and emit any change that built up while
        standing still); the generator stays anchored there and may be fed on."""
        return [g.statement for g in self.finish()]

    def finish(self) -> list[Generated]:
        """As :meth:`flush`, each statement with whether it continues the one before it (a
        later stroke may continue the last statement of an earlier one)."""
        if self._last is None:
            return []
        out = self._close(self._last, "flush")
        self._active = False
        self._vm_sum, self._vm_count = None, 0
        return out

    def generate(self, samples: Iterable[RobotSample]) -> list[Statement]:
        """Feed a whole recorded stream and flush: the offline form of the same algorithm."""
        out: list[Statement] = []
        for sample in samples:
            out.extend(self.feed(sample))
        out.extend(self.flush())
        return out

    def generate_merged(self, samples: Iterable[RobotSample]) -> list[Statement]:
        """As :meth:`generate`, with continuing statements merged into the one before (what the
        console's program gets)."""
        generated: list[Generated] = []
        for sample in samples:
            generated.extend(self.push(sample))
        generated.extend(self.finish())
        return merged(generated)

    # -- segments ----------------------------------------------------------------------------------
    def _onset_index(self) -> int:
        ts, xs, _ = self._scaled_window()
        return _corner_index(ts, xs, np.zeros(xs.shape[1]), self.settings.velocity_window)

    def _start_segment(self, index: int, why: str) -> None:
        self._active = True
        self._t_start = self._window[index].t
        self._vm_sum, self._vm_count = None, 0
        self._v_hist.clear()
        log.debug("segment starts at t=%.3f s (%s)", self._t_start, why)

    def _close(self, end: _State | None, reason: str, t_end: float | None = None) -> list[Generated]:
        """Close the open segment at state ``end`` (``t_end``: when the motion ended, if not
        at that state's time) and match it to a statement."""
        if end is None or self._anchor_q is None:
            return []
        t_end = end.t if t_end is None else t_end
        t_start = self._t_start if self._active else t_end
        start = (self._anchor_q.copy(), self._copy(self._anchor_p), self._copy(self._anchor_r))
        statement = self._match(end)
        if not self._active and statement is None:
            return []
        self.segments.append(GeneratedSegment(t_start, t_end, self._mode, reason, statement))
        if statement is None:
            return []
        continues = self._continues(statement, start)
        log.debug("segment %.3f-%.3f s closed (%s): %s%s", t_start, t_end, reason, statement.kind, " (continues)" if continues else "")
        if not continues:
            self._previous_start = start
        self._previous = statement
        return [Generated(statement, continues)]

    @staticmethod
    def _copy(value: np.ndarray | None) -> np.ndarray | None:
        return None if value is None else value.copy()

    def _continues(self, statement: Statement, middle: tuple[np.ndarray, np.ndarray | None, np.ndarray | None]) -> bool:
        """Does ``statement`` (just matched: the anchors are its end; ``middle`` is where it
        starts, the previous statement's end) go on the way the previous statement went from
        where that one started?"""
        prev, start = self._previous, self._previous_start
        if prev is None or start is None or prev.kind != statement.kind or getattr(prev, "frame", None) != getattr(statement, "frame", None):
            return False
        s = self.settings
        (q0, p0, r0), (q1, p1, r1) = start, middle
        if isinstance(statement, Drive):
            return statement.joint == prev.joint
        if isinstance(statement, Move):
            return _between_on_line(q0, q1, self._anchor_q, s.merge_angle)
        if p0 is None or p1 is None or r0 is None or r1 is None:
            return False
        if isinstance(statement, (Draw, Moves)) and not _between_on_line(p0, p1, self._anchor_p, s.merge_tolerance):
            return False
        if isinstance(statement, (Rotate, Moves)):
            total = log_so3(self._anchor_r @ r0.T)
            if _norm(total) > s.max_segment_rotation:
                return False
            return _between_on_line(np.zeros(3), log_so3(r1 @ r0.T), total, s.merge_angle)
        return True

    def _angle_text(self, value: float) -> float:
        """An angle (rad) rounded to the degrees the statement text shows (no negative zero)."""
        return to_si(f"{math.degrees(float(value)):.{self.settings.deg_decimals}f}", TextUnit.DEG) + 0.0

    def _match(self, end: _State) -> Statement | None:
        """The statement of thesis 4.3.5 for a segment from the program state to ``end``;
        updates the program state to the statement's ideal end."""
        s = self.settings
        if self._mode is JogMode.JOINT:
            changed = np.abs(end.q - self._anchor_q) > s.min_joint_change
            n = int(np.count_nonzero(changed))
            if n == 0:
                return None
            target = self._anchor_q.copy()
            target[changed] = end.q[changed]
            self._anchor_q = target
            if n == 1:
                k = int(np.flatnonzero(changed)[0])
                return Drive(joint=k + 1, target=self._angle_text(target[k]))
            return Move(joints=tuple(self._angle_text(x) for x in target))
        if self._anchor_p is None:  # first tool-mode state after a joint-mode run
            return None
        moved = _norm(end.p - self._anchor_p) > s.min_translation
        turned = _angle(self._anchor_r.T @ end.r) > s.min_rotation
        if moved:
            self._anchor_p = end.p.copy()
        if turned:
            self._anchor_r = end.r.copy()
        position = tuple(to_si(f"{x * 1e3:.{s.mm_decimals}f}", TextUnit.MM) + 0.0 for x in self._anchor_p)
        rpy = tuple(self._angle_text(x) for x in matrix_to_rpy(self._anchor_r))
        if moved and turned:
            return Moves(position=position, rpy=rpy, frame=s.frame)
        if moved:
            return Draw(position=position, frame=s.frame)
        if turned:
            return Rotate(rpy=rpy, frame=s.frame)
        return None


def generate_program(
    samples: Sequence[RobotSample] | Iterable[RobotSample],
    settings: GeneratorSettings | None = None,
    *,
    world_T_base: np.ndarray | None = None,
    world_T_work: np.ndarray | None = None,
    merge: bool = False,
) -> list[Statement]:
    """Statements for a whole recorded stream (a fresh generator, fed and flushed); with
    ``merge`` continuing statements replace the one before (``ProgramGenerator.generate_merged``)."""
    gen = ProgramGenerator(settings, world_T_base=world_T_base, world_T_work=world_T_work)
    return gen.generate_merged(samples) if merge else gen.generate(samples)
