"""The telerobot's world on contact physics (MuJoCo): the arm, its gripper and the cell as bodies.

The executor drives it one servo period at a time (``servo``): the period's joint target and
velocity go to the joint servo (a PD law with velocity feed-forward, gravity compensated, run by
MuJoCo at every physics step), the world steps ``timestep`` at a time to the end of the period,
and then reports what its sensors read: the joint angles, the wrist force/torque sensor, the
fingers' opening, the objects' poses. Nothing here decides an outcome: a peg sticks, jams, wedges
or slips out of the fingers when the contact forces make it.

Seeded differences from the console's model (``WorldSettings``): each static object that carries a
hole is placed up to ``object_offset`` off its modelled place (what stands in its holes moves with
it), the wrist sensor is noisy, the peg settles in the fingers tilted by ``grasp_tilt`` once it is
clear of the hole it was grasped in (a grasp that slipped), and friction and clearance can be set.

A world at rest costs nothing: while the arm holds still, nothing is in flight and no setpoint
changes, ``servo`` moves the clock on without stepping (the state of a settled world is a fixed
point of the step, to within ``REST_SPEED``); the first change of setpoint wakes it. A part of it
at rest costs little: MuJoCo's sleeping (``SLEEP``) stops integrating and colliding an object that
rests (a peg in its hole) while the arm moves elsewhere, until something awake touches it, and the
world then reads its pose and hole as they were.
"""

from __future__ import annotations

import copy
import logging
import math
from dataclasses import dataclass

import numpy as np

from robot_sim.physics.mjcf import ModelLayout, build_mjcf
from shared.cells.physics import PhysicsParams
from robot_sim.settings import WorldSettings
from robot_sim.world import Contact, Hole, PegState, perceived_poses
from shared.cells.cell import Cell
from shared.errors import FileFormatError, TeleprogError
from shared.robots.model import Robot
from shared.spatial import invert
from shared.wire.messages import ObjectPose

log = logging.getLogger(__name__)
_NO_CONTACTS = (np.zeros(0, dtype=int), np.zeros(0, dtype=int))
_IDENTITY = np.eye(4)
_NO_NOISE = np.zeros(6)
_NO_NOISE.flags.writeable = False

GRAVITY = 9.81
REST_SPEED = 1e-4
"""Joint and object speeds (rad/s, m/s) under which a world with unchanged setpoints is at rest."""
NOISE_TABLE = 1 << 15
"""Servo periods of sensor noise drawn per world (at 100 Hz, 5.5 minutes before it repeats)."""
BRAKE_GAIN = 8.0
"""How much the servo's damping rises while it brakes to a stop."""
BRAKE_TIME = 0.05
"""How long it brakes (s)."""
MONITOR_PERIOD = 0.002
"""The force monitor's period (s): the setpoint moves and the wrist is read this often."""
CLOSE_FORCE = 0.25
"""The fingers close with this share of the grip force until both pads touch one object."""
HOLD_TOLERANCE = 0.002
"""How much narrower than the held object the fingers may close before it counts as lost (m)."""


def _mujoco_warning(text: str) -> None:
    log.warning("MuJoCo: %s", text.strip())


def _route_warnings() -> None:
    """MuJoCo's warnings to the log (it would write MUJOCO_LOG.TXT into the working folder)."""
    import mujoco

    if mujoco.get_mju_user_warning() is not _mujoco_warning:
        mujoco.set_mju_user_warning(_mujoco_warning)


class PhysicsUnstable(TeleprogError):
    """The simulation diverged (NaN or a blow-up): the robot stops and reports it."""


@dataclass(frozen=True)
class HoleGeometry:
    """A hole as the physics world has it: mouth, measured width in x and y, depth (m)."""

    name: str
    world_T_hole: np.ndarray
    width: np.ndarray  # (2,) along the hole frame's x and y
    depth: float


_COMPILED: dict[tuple, tuple[object, ModelLayout, dict[str, HoleGeometry]]] = {}
"""Compiled models by (cell file, physics parameters, object sizes): a world copies one."""


def _halves_key(halves: dict[str, np.ndarray]) -> tuple:
    return tuple((name, tuple(float(v) for v in h)) for name, h in sorted(halves.items()))


def _compiled(cell: Cell, params: PhysicsParams, halves: tuple) -> tuple[object, ModelLayout, dict[str, HoleGeometry]]:
    """The cell's model as its file places everything (no seeded offsets), compiled once per
    process, with its holes measured by rays against the static geometry."""
    key = (cell.source, cell.name, params, halves)
    if key in _COMPILED:
        return _COMPILED[key]
    import mujoco

    poses = {}
    for obj in cell.objects:
        if obj.movable:
            T = obj.world_T_object.copy()
            T[2, 3] += 2e-5  # let it settle onto what it stands on
            poses[obj.name] = T
    layout = build_mjcf(cell, params, poses, {name: np.array(h) for name, h in halves})
    model = mujoco.MjModel.from_xml_string(layout.xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    holes: dict[str, HoleGeometry] = {}
    groups = np.array([1, 0, 0, 0, 0, 0], dtype=np.uint8)  # the static cell only
    geomid = np.zeros(1, dtype=np.int32)
    for feat in cell.features.values():
        if feat.kind != "hole":
            continue
        T = feat.world_T_feature.copy()
        axis = T[:3, 2]
        start = T[:3, 3] + 1e-4 * axis
        depth = mujoco.mj_ray(model, data, start, -axis, groups, 1, -1, geomid)
        depth = float(depth - 1e-4) if depth >= 0 else 0.0
        middle = T[:3, 3] - 0.5 * depth * axis
        width = np.zeros(2)
        for k in range(2):
            d = T[:3, k]
            a = mujoco.mj_ray(model, data, middle, d, groups, 1, -1, geomid)
            b = mujoco.mj_ray(model, data, middle, -d, groups, 1, -1, geomid)
            width[k] = (a + b) if a >= 0 and b >= 0 else np.inf
        holes[feat.name] = HoleGeometry(feat.name, T, width, depth)
    if len(_COMPILED) > 16:
        _COMPILED.clear()
    _COMPILED[key] = (model, layout, holes)
    return _COMPILED[key]


class PhysicsWorld:
    """The real cell around the telerobot, simulated by MuJoCo."""

    engine = "mujoco"
    physical = True
    SLEEP = True
    """Let MuJoCo put resting bodies to sleep (benchmarks switch it off to show it changes no outcome)."""

    def __init__(self, cell: Cell, robot: Robot, settings: WorldSettings | None = None,
                 q0: np.ndarray | None = None, servo_period: float = 0.01) -> None:
        import mujoco

        _route_warnings()
        self._mj = mujoco
        self.cell = cell
        self.robot = robot
        self.settings = settings or WorldSettings()
        s = self.settings
        where = f"{cell.source} (world settings)"
        self.params: PhysicsParams = cell.physics.with_overrides(
            friction=s.friction, clearance=None if s.clearance is None else s.clearance, where=where)
        self.servo_period = servo_period
        self.substeps = max(1, int(round(servo_period / self.params.timestep)))
        self._rng = np.random.default_rng(s.seed)
        self._noise_table: np.ndarray | None = None
        self.sensor_fault: np.ndarray | None = None
        """A fault of the wrist sensor (``robot_sim.physics.faults``): added to every reading, world
        frame (a bias), or NaN (a dropout: the sensor flags its readings invalid). Never in the
        clean wrench, which is the physics' own (ground truth)."""
        self._plan_world(where)
        self._build()
        self.gripper_closed = False
        self._soft_close = False
        self._held: str | None = None
        self._grasp_name: str | None = None
        self._tilt_pending = 0.0
        self._payload = 0.0
        self.time = 0.0
        self.steps = 0
        self.skipped_steps = 0
        self._asleep = False
        q = np.array(cell.q_home if q0 is None else q0, dtype=float)
        self.data.qpos[self._qadr] = q
        self._set_target(q, np.zeros_like(q))
        self.mj.mj_forward(self.model, self.data)
        self._contact_pairs = None
        self._last_good = self.data.qpos.copy()
        w = mujoco.mjtWarning
        self._bad_warnings = [int(w.mjWARN_BADQACC), int(w.mjWARN_BADQVEL), int(w.mjWARN_BADQPOS)]
        self._bad_count = 0
        for _ in range(max(1, int(round(0.3 / servo_period)))):  # settle; once at rest, time passes unstepped
            self.advance(servo_period)
        self._noise = np.zeros(6)
        self._sense()

    @property
    def mj(self):
        return self._mj

    # -- building ---------------------------------------------------------------------------------
    def _plan_world(self, where: str) -> None:
        """Seeded placement of the hole carriers and the objects, and each object's size."""
        cell, s = self.cell, self.settings
        off = s.object_offset
        holes = {f.name: f for f in cell.features.values() if f.kind == "hole"}
        self._carrier_shift: dict[str, np.ndarray] = {}
        hole_shift: dict[str, np.ndarray] = {}
        for obj in cell.objects:
            if obj.movable:
                continue
            carried = [h for h in holes.values() if _contains(obj, h.world_T_feature[:3, 3])]
            if not carried:
                continue
            shift = np.array([*self._rng.uniform(-off, off, 2), 0.0]) if off > 0 else np.zeros(3)
            self._carrier_shift[obj.name] = shift
            for h in carried:
                hole_shift[h.name] = shift
        self.object_poses: dict[str, np.ndarray] = {}
        self.start_hole: dict[str, str | None] = {}
        self.object_half: dict[str, np.ndarray] = {}
        for obj in cell.objects:
            if not obj.movable:
                continue
            T = obj.world_T_object.copy()
            half = np.asarray(obj.shapes[0].size, dtype=float) / 2.0 if obj.shapes[0].kind == "box" else np.zeros(3)
            inside = None
            for h in holes.values():
                mouth = h.world_T_feature[:3, 3]
                if np.linalg.norm(T[:2, 3] - mouth[:2]) < 1e-6 and T[2, 3] - half[2] < mouth[2]:
                    inside = h.name
            if inside is not None:
                T[:3, 3] += hole_shift.get(inside, 0.0)
                T[2, 3] += 2e-5  # let it settle onto the hole's floor
            elif off > 0:
                T[:3, 3] += np.array([*self._rng.uniform(-off, off, 2), 0.0])
            self.object_poses[obj.name] = T
            self.start_hole[obj.name] = inside
            self.object_half[obj.name] = half
        self._hole_shift = hole_shift
        self._where = where

    def _build(self) -> None:
        """The compiled model of the cell as the file has it (built once per process and cell,
        ``_compiled``), copied, with this world's seeded placement applied to the copy: each hole
        carrier's geoms moved, the objects put where they stand."""
        mujoco = self.mj
        template, layout, holes = _compiled(self.cell, self.params, _halves_key(self.object_half))
        self._set_holes(holes)
        if self._fit_objects():
            template, layout, _ = _compiled(self.cell, self.params, _halves_key(self.object_half))
        model = copy.deepcopy(template)
        for obj_name, shift in self._carrier_shift.items():
            for g in range(model.ngeom):
                name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
                if name.startswith(f"{obj_name}/"):
                    model.geom_pos[g] += shift
        data = mujoco.MjData(model)
        self._modelled_mass = {name: float(model.body_subtreemass[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)])
                               for name in layout.objects}
        factor = self.settings.object_mass_factor
        if factor != 1.0:  # heavier (or lighter) than modelled: the physics gets the true mass
            for name in layout.objects:
                b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
                model.body_mass[b] *= factor
                model.body_inertia[b] *= factor
            mujoco.mj_setConst(model, data)
        for name in layout.objects:
            b = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name)
            a = model.jnt_qposadr[model.body_jntadr[b]]
            T = self.object_poses[name]
            quat = np.zeros(4)
            mujoco.mju_mat2Quat(quat, np.ascontiguousarray(T[:3, :3]).ravel())
            data.qpos[a:a + 3] = T[:3, 3]
            data.qpos[a + 3:a + 7] = quat
        self.layout: ModelLayout = layout
        self.model, self.data = model, data
        dof = self.robot.dof
        jid = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"j{i}") for i in range(1, dof + 1)]
        self._qadr = np.array([model.jnt_qposadr[j] for j in jid])
        self._vadr = np.array([model.jnt_dofadr[j] for j in jid])
        self._servo = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"servo{i}")
                                for i in range(1, dof + 1)])
        self._ff = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, f"feedforward{i}")
                             for i in range(1, dof + 1)])
        self._grip = [g for g in (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_ACTUATOR, "grip0"),) if g >= 0]
        fingers = [j for j in (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"finger{k}") for k in range(2)) if j >= 0]
        self._finger_q = [model.jnt_qposadr[j] for j in fingers]
        self._finger_geoms = {mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"finger{k}/pad")
                              for k in range(len(fingers))}
        self._gripper_body = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "wrist")
        self._tcp_site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "tcp")
        self._wrist_site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, "wrist")
        self._tool_mass = float(model.body_subtreemass[self._gripper_body])
        self._bodies = {name: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, name) for name in layout.objects}
        self._object_qadr = {name: model.jnt_qposadr[model.body_jntadr[b]] for name, b in self._bodies.items()}
        self._geom_body = np.asarray(model.geom_bodyid)
        self._static_geom = np.asarray(model.geom_group) == 0
        self._arm_geom = np.asarray(model.geom_contype) == 2
        self._tool_geom = self._subtree(self._gripper_body)[self._geom_body]  # the gripper's geoms
        self._pad_geom = np.zeros(model.ngeom, dtype=bool)
        self._pad_geom[list(self._finger_geoms)] = True
        self._arm_only_geom = self._arm_geom & ~self._tool_geom
        self._touching = ""
        self._tune_servo()
        # MuJoCo's own sleeping (4.0 on): a tree at rest (a peg standing in its hole, on the
        # table) is no longer integrated or collided until something awake touches it; the arm,
        # driven by its servo, stays awake
        self._dof_tree: np.ndarray | None = None
        sleep = getattr(mujoco.mjtEnableBit, "mjENBL_SLEEP", None)
        if self.SLEEP and sleep is not None:
            model.opt.enableflags |= int(sleep)
            self._dof_tree = np.asarray(model.dof_treeid)
        self._object_tree = {name: int(model.body_treeid[b]) for name, b in self._bodies.items()}
        self._read: set[str] = set()  # objects whose pose has been read since the last forward
        self.pegs: dict[str, PegState] = {
            name: PegState(world_T_peg=self.object_poses[name].copy(), half_size=self.object_half[name].copy(),
                           in_hole=self.start_hole[name])
            for name in layout.objects
        }

    def _set_holes(self, measured: dict[str, HoleGeometry]) -> None:
        """The holes as measured on the file's geometry, moved with their carriers."""
        self.holes: dict[str, Hole] = {}
        self.hole_geometry: dict[str, HoleGeometry] = {}
        for name, geo in measured.items():
            T = geo.world_T_hole.copy()
            T[:3, 3] += self._hole_shift.get(name, 0.0)
            self.holes[name] = Hole(name, T, depth=geo.depth)
            self.hole_geometry[name] = HoleGeometry(name, T, geo.width.copy(), geo.depth)
        self._hole_T_world = {name: invert(h.world_T_hole) for name, h in self.holes.items()}
        # the same as floats, for ``_hole_of``: hole_R_world, hole_p, half-width + 1 mm
        self._hole_frames = [(n, (T[:3, :3].tolist(), T[:3, 3].tolist(), (self.hole_geometry[n].width / 2.0 + 1e-3).tolist()))
                             for n, T in self._hole_T_world.items()]

    def _fit_objects(self) -> bool:
        """Check each object that starts in a hole fits it; narrow it to the asked clearance."""
        changed = False
        for name, hole_name in self.start_hole.items():
            if hole_name is None:
                continue
            hole = self.hole_geometry[hole_name]
            half = self.object_half[name]
            if not np.all(np.isfinite(hole.width)):
                continue
            wide = 2.0 * half[:2]
            if np.any(wide > hole.width + 1e-9):
                raise FileFormatError(self.cell.source, (
                    f"object {name!r} ({wide[0] * 1e3:.3f} x {wide[1] * 1e3:.3f} mm) is wider than its hole "
                    f"{hole_name} ({hole.width[0] * 1e3:.3f} x {hole.width[1] * 1e3:.3f} mm)"))
            if self.params.clearance is not None:
                new = hole.width / 2.0 - self.params.clearance / 2.0
                if np.any(new <= 0.0):
                    raise FileFormatError(self._where, f"a clearance of {self.params.clearance * 1e3:g} mm leaves "
                                                       f"no peg in {hole_name}")
                self.object_half[name] = np.array([new[0], new[1], half[2]])
                changed = True
        return changed

    def clearance(self, name: str) -> float | None:
        """The fit (m) of an object in the hole it started in: hole width minus object width."""
        hole = self.start_hole.get(name)
        if hole is None:
            return None
        return float(np.min(self.hole_geometry[hole].width - 2.0 * self.object_half[name][:2]))

    def _tune_servo(self) -> None:
        """Joint servo gains from the arm's inertia at its home pose: each joint a critically
        damped second-order system of ``joint_bandwidth`` (its diagonal of the mass matrix)."""
        mujoco = self.mj
        m, d = self.model, self.data
        d.qpos[self._qadr] = self.cell.q_home
        mujoco.mj_forward(m, d)
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        inertia = np.diag(M)[self._vadr]
        w = 2.0 * math.pi * self.params.joint_bandwidth
        kp = inertia * w * w
        kv = 2.0 * self.params.joint_damping_ratio * inertia * w
        m.actuator_gainprm[self._servo, 0] = kp
        m.actuator_biasprm[self._servo, 1] = -kp
        m.actuator_biasprm[self._servo, 2] = -kv
        m.actuator_gear[self._ff, 0] = kv  # velocity feed-forward: kv * qd_target
        self.kp, self.kv = kp, kv
        self._brake_until: float | None = None

    # -- the servo --------------------------------------------------------------------------------
    def _set_target(self, q: np.ndarray, qd: np.ndarray) -> None:
        self._target = np.asarray(q, dtype=float).copy()
        self._target_qd = np.asarray(qd, dtype=float).copy()
        self.data.ctrl[self._servo] = self._target
        self.data.ctrl[self._ff] = self._target_qd

    def _end_brake(self) -> None:
        """The servo's own gains again (the brake's time is over, or a new motion starts)."""
        m = self.model
        m.actuator_gainprm[self._servo, 0] = self.kp
        m.actuator_biasprm[self._servo, 1] = -self.kp
        m.actuator_biasprm[self._servo, 2] = -self.kv
        self._brake_until = None

    @property
    def target(self) -> np.ndarray:
        """The joint servo's present setpoint."""
        return self._target.copy()

    def servo(self, q: np.ndarray, qd: np.ndarray | None = None, stop_force: float | None = None,
              guarded: bool = False) -> bool:
        """One servo period towards joint target ``q`` (velocity ``qd``, feed-forward).

        The setpoint moves from the last one to ``q`` in ``MONITOR_PERIOD`` slices. With
        ``stop_force``, the force monitor reads the wrist after each slice and, once the force
        beyond the held object's weight passes it, holds the arm where it is for the rest of the
        period (a guarded move stops within a millisecond, not a servo period). True if it did."""
        qd = np.zeros_like(q) if qd is None else qd
        if (q == self._target).all() and (qd == self._target_qd).all():  # (array_equal's checks cost more than the step's sums)
            self.advance(self.servo_period)
            return False
        self._asleep = False
        if self._brake_until is not None:
            self._end_brake()
        start = self._target
        # the force monitor slices the period where a force can build up: a guarded motion, or
        # the tool already touching something; in free space the servo reads it once a period
        slices = max(1, int(round(self.servo_period / MONITOR_PERIOD))) if stop_force is not None and (
            guarded or self._touching) else 1
        for k in range(1, slices + 1):
            self._set_target(start + (q - start) * (k / slices), qd)
            self.advance(self.servo_period / slices, sense=k == slices)
            if stop_force is not None and self._force_beyond_payload() > stop_force:
                self.hold()
                if k < slices:
                    self.advance(self.servo_period * (slices - k) / slices)
                else:
                    self._after_step()
                return True
        return False

    def _force_beyond_payload(self) -> float:
        """The wrist force's magnitude beyond the tool's and the held object's weight (N), read
        straight from the sensor (the force monitor's fast path: no contact scan, no noise)."""
        # |R f - w z| = |f - w R^T z|: in the sensor's frame, where R^T z is R's last row (floats:
        # this runs every 2 ms while pressing)
        d = self.data
        fx, fy, fz = d.sensordata[0:3].tolist()
        zx, zy, zz = d.site_xmat[self._wrist_site, 6:9].tolist()
        w = GRAVITY * (self._tool_mass + self._payload)
        if self.sensor_fault is not None:  # the fault, turned into the sensor's frame (F_world = -R f)
            R = d.site_xmat[self._wrist_site].reshape(3, 3)
            fx, fy, fz = (np.array([fx, fy, fz]) - R.T @ self.sensor_fault[:3]).tolist()
        return math.sqrt((fx - w * zx) ** 2 + (fy - w * zy) ** 2 + (fz - w * zz) ** 2)

    def hold(self) -> None:
        """Hold the arm where it is now (a stop): the setpoint becomes the measured pose, at rest,
        and the servo brakes (``BRAKE_GAIN`` times its damping for ``BRAKE_TIME``, its stiffness
        kept, gravity compensated) so the arm halts within a servo period instead of coasting
        through the servo's own settling and back, and a torque from outside (a joint that drags,
        a contact pushing back) cannot carry it off while it brakes."""
        self._set_target(self.q.copy(), np.zeros(self.robot.dof))
        m = self.model
        m.actuator_gainprm[self._servo, 0] = self.kp  # braking: the stop point held stiffly, heavily damped
        m.actuator_biasprm[self._servo, 1] = -self.kp
        m.actuator_biasprm[self._servo, 2] = -BRAKE_GAIN * self.kv
        self._brake_until = self.time + BRAKE_TIME
        self._asleep = False

    def hold_at(self, q: np.ndarray) -> None:
        """Hold the joint setpoint ``q`` (at rest), with the servo's own gains."""
        if self._brake_until is not None:
            self._end_brake()
        self._set_target(np.asarray(q, dtype=float), np.zeros(self.robot.dof))
        self._asleep = False

    def set_gripper(self, closed: bool) -> None:
        """Close or open the fingers. They close softly (``CLOSE_FORCE`` of the grip force) until
        both pads touch one object, and squeeze with the full grip force only then
        (:meth:`_firm_grip`): a finger that meets something held fast pushes it gently instead
        of striking it with the whole grip."""
        self.gripper_closed = closed
        force = self.params.grip_force * (CLOSE_FORCE if closed else 1.0)
        for g in self._grip:
            self.data.ctrl[g] = self.layout.finger_travel if closed else 0.0
            self.model.actuator_forcerange[g] = (-force, force)
        self._soft_close = closed and bool(self._grip)
        self._asleep = False

    def _firm_grip(self) -> None:
        """Both pads on one object: the full grip force."""
        if self._soft_close and self.held_by_fingers() is not None:
            for g in self._grip:
                self.model.actuator_forcerange[g] = (-self.params.grip_force, self.params.grip_force)
            self._soft_close = False

    def advance(self, seconds: float, sense: bool = True) -> None:
        """Let ``seconds`` pass with the present setpoints (no steps while the world is at rest)."""
        n = max(1, int(round(seconds / self.params.timestep)))
        if self._asleep:  # nothing moves: only the sensor's noise changes
            self.time += n * self.params.timestep
            self.skipped_steps += n
            self.wrench = self.wrench_clean + self._noise_at(self.time)
            if self.sensor_fault is not None:
                self.wrench = self.wrench + self.sensor_fault
            return
        self.mj.mj_step(self.model, self.data, nstep=n)
        self._contact_pairs = None
        self.steps += n
        self.time += n * self.params.timestep
        if self._brake_until is not None and self.time >= self._brake_until:
            self._end_brake()
            self._set_target(self.q, np.zeros(self.robot.dof))  # hold where the brake stopped it
        if sense:
            d = self.data
            speed = float(np.abs(d.qvel).max())
            if not speed < 1e3 or self._diverged():  # NaN fails the first; MuJoCo resets a diverged state itself
                self._restore_last_good()
                raise PhysicsUnstable(f"the physics simulation became unstable at t = {self.time:.3f} s "
                                      f"(speeds over 1000 or not finite); the world is back at its last "
                                      f"stable state, at rest, and the arm holds there")
            self._last_good = d.qpos.copy()
            self._after_step()
            self._asleep = speed < REST_SPEED and self._settled()

    def _settled(self) -> bool:
        """No awake degree of freedom accelerates (a tree MuJoCo put to sleep keeps the
        acceleration it had when it fell asleep, but does not move)."""
        d = self.data
        if self._dof_tree is None:
            return float(np.max(np.abs(d.qacc))) < 100 * REST_SPEED
        awake = np.asarray(d.tree_awake, dtype=bool)[self._dof_tree]
        return not (np.abs(d.qacc[awake]) >= 100 * REST_SPEED).any()

    def _diverged(self) -> bool:
        """MuJoCo met a NaN, an infinity or a huge value since the last look (it then resets the
        state to the model's initial pose, which the robot must never take for the real arm)."""
        number = self.data.warning.number
        count = int(number[self._bad_warnings[0]]) + int(number[self._bad_warnings[1]]) + int(number[self._bad_warnings[2]])
        diverged = count > self._bad_count
        self._bad_count = count
        return diverged

    def _restore_last_good(self) -> None:
        """Back to the last state that sensed finite and sane, every speed zero."""
        d = self.data
        d.qpos[:] = self._last_good
        d.qvel[:] = 0.0
        d.act[:] = 0.0 if d.act.size else d.act
        self.mj.mj_forward(self.model, d)
        self._contact_pairs = None
        self._read.clear()
        self._set_target(self.q, np.zeros(self.robot.dof))

    def settle(self, seconds: float) -> None:
        """Let the world come to rest (building it, after a grasp)."""
        self.advance(seconds)

    @property
    def asleep(self) -> bool:
        return self._asleep

    # -- sensing ----------------------------------------------------------------------------------
    @property
    def q(self) -> np.ndarray:
        return self.data.qpos[self._qadr]  # fancy indexing: a copy

    @property
    def qd(self) -> np.ndarray:
        return self.data.qvel[self._vadr]

    def wrist_position(self) -> np.ndarray:
        """Where the wrist sensor is (world, m): the point its torques are about."""
        return np.array(self.data.site_xpos[self._wrist_site])

    def world_T_tcp(self, q: np.ndarray | None = None) -> np.ndarray:
        if q is not None:
            return self.cell.world_T_base @ self.robot.fk(q) @ self.cell.flange_T_tcp
        T = _IDENTITY.copy()
        T[:3, :3] = self.data.site_xmat[self._tcp_site].reshape(3, 3)
        T[:3, 3] = self.data.site_xpos[self._tcp_site]
        return T

    def _object_pose(self, name: str) -> np.ndarray:
        b = self._bodies[name]
        T = _IDENTITY.copy()
        T[:3, :3] = self.data.xmat[b].reshape(3, 3)
        T[:3, 3] = self.data.xpos[b]
        return T

    def _after_step(self) -> None:
        # an object MuJoCo has put to sleep has not moved since it was last read: its pose and
        # its hole stay as they were (it is never the held one: the fingers on it keep it awake)
        awake = self.data.tree_awake if self._dof_tree is not None else None
        moved = [name for name in self.pegs
                 if awake is None or awake[self._object_tree[name]] or name == self._held
                 or self.pegs[name].held or name not in self._read]
        for name in moved:
            self.pegs[name].world_T_peg = self._object_pose(name)
        if (self._held is not None and self._tilt_pending and self._hole_of(self._held) is None
                and not self._touching_static(self._held)):
            self._apply_tilt(self._held, self._tilt_pending)
            self._tilt_pending = 0.0
        for name in moved:
            peg = self.pegs[name]
            peg.in_hole = self._hole_of(name)
            peg.held = name == self._held
            peg.tool_T_peg = invert(self.world_T_tcp()) @ peg.world_T_peg if peg.held else None
            self._read.add(name)
        self._touching = self._touching_what()
        if self._soft_close:
            self._firm_grip()
        self._sense()

    def _sense(self) -> None:
        """The wrist sensor: force and torque on the tool in the world frame, the gripper's own
        weight taken off (a tared sensor), with noise."""
        d = self.data
        R = d.site_xmat[self._wrist_site].reshape(3, 3)
        # the sensor reads what the arm exerts on the gripper; the world exerts the opposite:
        # force and torque (the rows) turned into the world frame at once
        wrench = (d.sensordata[0:6].reshape(2, 3) @ -R.T).reshape(6)
        w = GRAVITY * self._tool_mass  # the tool's weight, (0, 0, -w)
        com, wrist = d.subtree_com[self._gripper_body], d.site_xpos[self._wrist_site]
        wrench[2] += w
        wrench[3] -= (com[1] - wrist[1]) * w  # lever x (0, 0, -w), taken off
        wrench[4] += (com[0] - wrist[0]) * w
        self.wrench_clean = wrench
        self.wrench = wrench + self._noise_at(self.time)
        if self.sensor_fault is not None:
            self.wrench = self.wrench + self.sensor_fault

    def _noise_at(self, t: float) -> np.ndarray:
        """The sensor's noise at time ``t``: a function of the seed and the servo period's index
        only, so letting time pass at rest without reading draws the same noise afterwards."""
        sigma = self.settings.force_noise
        if sigma <= 0:
            return _NO_NOISE
        if self._noise_table is None:  # one seeded table, read by period index (repeats after 5.5 min)
            self._noise_table = np.random.default_rng((self.settings.seed & 0xFFFFFFFF, 7)).normal(0.0, sigma, (NOISE_TABLE, 6))
        return self._noise_table[int(round(t / self.servo_period)) % NOISE_TABLE]

    def contact(self, q: np.ndarray | None = None, noise: bool = True) -> Contact:
        """What the force sensor feels now beyond the held object's weight (N, world frame).
        ``q`` is ignored: a physical sensor reads the present, not a pose asked about."""
        w = self.wrench if noise else self.wrench_clean
        force = w[:3] - np.array([0.0, 0.0, -GRAVITY * self._payload])
        return Contact(force, touching=bool(self._touching), what=self._touching)

    def _contacts(self) -> tuple[np.ndarray, np.ndarray]:
        """The geom pairs in contact now (read once per state: several sensors ask each period)."""
        if self._contact_pairs is None:
            d = self.data
            n = d.ncon
            if n == 0:
                self._contact_pairs = _NO_CONTACTS
            else:
                contact = d.contact
                g = contact.geom[contact.dist < 1e-5]
                self._contact_pairs = (g[:, 0], g[:, 1])
        return self._contact_pairs

    def _touching_static(self, name: str) -> bool:
        g1, g2 = self._contacts()
        b = self._bodies[name]
        mine = (self._geom_body[g1] == b) & self._static_geom[g2] | (self._geom_body[g2] == b) & self._static_geom[g1]
        return bool(np.any(mine))

    def _touching_what(self) -> str:
        """What the tool (the gripper, the fingers, a held object) touches in the cell, or ''."""
        g1, g2 = self._contacts()
        if g1.size == 0:
            return ""
        tool = self._tool_geom if self._held is None else self._tool_geom | (self._geom_body == self._bodies[self._held])
        mask_tool1 = tool[g1]
        mask_tool2 = tool[g2]
        hits = (mask_tool1 & ~mask_tool2) | (mask_tool2 & ~mask_tool1)
        if not hits.any():
            return ""
        k = int(np.flatnonzero(hits)[0])
        other = g2[k] if mask_tool1[k] else g1[k]
        return self._geom_label(int(other))

    def arm_contact(self) -> str:
        """A link of the arm (not the gripper) touching the cell or an object, or ''."""
        g1, g2 = self._contacts()
        if g1.size == 0:
            return ""
        arm1 = self._arm_only_geom[g1]
        arm2 = self._arm_only_geom[g2]
        hits = np.flatnonzero(arm1 | arm2)
        if hits.size == 0:
            return ""
        k = int(hits[0])
        a, b = (g1[k], g2[k]) if arm1[k] else (g2[k], g1[k])
        return f"{self._geom_label(int(a))} touches {self._geom_label(int(b))}"

    def _subtree(self, root: int) -> np.ndarray:
        parents = np.asarray(self.model.body_parentid)
        inside = np.zeros(self.model.nbody, dtype=bool)
        inside[root] = True
        for b in range(root + 1, self.model.nbody):
            inside[b] = inside[parents[b]]
        return inside

    def _geom_label(self, geom: int) -> str:
        name = self.mj.mj_id2name(self.model, self.mj.mjtObj.mjOBJ_GEOM, geom) or f"geom {geom}"
        return name.split("/")[0]

    def _hole_of(self, name: str) -> str | None:
        """The hole an object's foot is inside (below the mouth, within the hole's width)."""
        peg = self.pegs[name]
        T = peg.world_T_peg
        h = float(peg.half_size[2])
        x, y, z = T[0, 3] - T[0, 2] * h, T[1, 3] - T[1, 2] * h, T[2, 3] - T[2, 2] * h  # its foot
        for hole, (r, p, reach) in self._hole_frames:  # a few holes: plain floats beat numpy here
            lz = r[2][0] * x + r[2][1] * y + r[2][2] * z + p[2]
            if lz >= 0.0:
                continue
            lx = r[0][0] * x + r[0][1] * y + r[0][2] * z + p[0]
            ly = r[1][0] * x + r[1][1] * y + r[1][2] * z + p[1]
            if abs(lx) <= reach[0] and abs(ly) <= reach[1]:
                return hole
        return None

    # -- the gripper ------------------------------------------------------------------------------
    def finger_opening(self) -> float:
        """Gap between the finger pads (m)."""
        closed = sum(float(self.data.qpos[a]) for a in self._finger_q)
        return self.layout.finger_open_gap - closed

    def held_by_fingers(self) -> str | None:
        """The object both pads touch, if any."""
        g1, g2 = self._contacts()
        if g1.size == 0 or len(self._finger_geoms) < 2:
            return None
        pad = np.concatenate([g1, g2])
        other = np.concatenate([self._geom_body[g2], self._geom_body[g1]])
        on_pad = self._pad_geom[pad]
        for name, b in self._bodies.items():
            if np.unique(pad[on_pad & (other == b)]).size == 2:
                return name
        return None

    def close_gripper(self, name: str | None) -> None:
        self.set_gripper(True)
        self._grasp_name = name

    def grasp_result(self) -> tuple[bool, str]:
        """After the fingers closed: whether they hold an object, and a sentence for the report."""
        holding = self.held_by_fingers()
        opening = self.finger_opening()
        if holding is None or (self._grasp_name is not None and holding != self._grasp_name):
            what = f"the fingers closed to {opening * 1e3:.1f} mm on nothing"
            if holding is not None:
                what = f"the fingers closed on {holding}, not {self._grasp_name}"
            return False, f"gripper closed: {what}"
        self._held = holding
        self._payload = self.object_mass(holding)
        self._tilt_pending = self.settings.grasp_tilt
        self._after_step()
        peg = self.pegs[holding]
        axis_offset = np.linalg.norm((invert(peg.world_T_peg) @ self.world_T_tcp())[:2, 3])
        return True, f"holding {holding} ({axis_offset * 1e3:.2f} mm off its axis, fingers {opening * 1e3:.2f} mm apart)"

    def open_gripper(self) -> None:
        self.set_gripper(False)

    def release_result(self) -> str:
        name = self._held
        self._held = None
        self._payload = 0.0
        self._after_step()
        if name is None:
            return "gripper opened, holding nothing"
        where = self.pegs[name].in_hole
        return f"released {name} in {where}" if where else f"released {name}"

    def lost(self) -> str | None:
        """Why the held object is no longer held (fingers closed past it, or off it), or None."""
        if self._held is None or not self.gripper_closed:
            return None
        name = self._held
        width = 2.0 * float(np.min(self.object_half[name][:2]))
        if self.finger_opening() < width - HOLD_TOLERANCE or self.held_by_fingers() != name:
            self._held = None
            self._payload = 0.0
            self._after_step()
            return f"{name} lost from the gripper (fingers {self.finger_opening() * 1e3:.1f} mm apart)"
        return None

    def held_peg(self) -> tuple[str, PegState] | None:
        if self._held is None:
            return None
        return self._held, self.pegs[self._held]

    def object_mass(self, name: str) -> float:
        """The object's mass as the model has it (what the robot tares its wrist for)."""
        return self._modelled_mass[name]

    def _apply_tilt(self, name: str, tilt: float) -> None:
        """The object turns in the fingers by ``tilt`` about the line through both pads."""
        mujoco = self.mj
        world_T_tcp = self.world_T_tcp()
        axis = world_T_tcp[:3, 0]  # the fingers close along the tool's x
        c, s = math.cos(tilt), math.sin(tilt)
        K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
        R = np.eye(3) + s * K + (1 - c) * K @ K
        T = self._object_pose(name)
        pivot = world_T_tcp[:3, 3]
        T[:3, :3] = R @ T[:3, :3]
        T[:3, 3] = pivot + R @ (T[:3, 3] - pivot)
        a = self._object_qadr[name]
        self.data.qpos[a:a + 3] = T[:3, 3]
        quat = np.zeros(4)
        mujoco.mju_mat2Quat(quat, T[:3, :3].ravel())
        self.data.qpos[a + 3:a + 7] = quat
        mujoco.mj_forward(self.model, self.data)
        self._contact_pairs = None
        self.pegs[name].world_T_peg = T

    # -- the executor's queries (kinematic-world interface) -----------------------------------------
    def follow(self, q: np.ndarray) -> None:  # noqa: ARG002 - the physics carries the objects
        return None

    def perceived_objects(self) -> tuple[ObjectPose, ...]:
        return perceived_poses(self.pegs, self.cell.world_T_base)


def _contains(obj, point: np.ndarray, tol: float = 1e-6) -> bool:
    """Whether ``point`` lies in the object's bounding box (in its own frame, all shapes
    together): a hole's mouth lies in the box of the plate it is cut into."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for s in obj.shapes:
        if s.kind == "box":
            half = np.asarray(s.size) / 2.0
        elif s.kind in ("cylinder", "capsule"):
            half = np.array([s.radius, s.radius, s.length / 2.0 + (s.radius if s.kind == "capsule" else 0.0)])
        elif s.kind == "sphere":
            half = np.full(3, s.radius)
        else:
            continue
        extent = np.abs(s.link_T_shape[:3, :3]) @ half
        lo = np.minimum(lo, s.link_T_shape[:3, 3] - extent)
        hi = np.maximum(hi, s.link_T_shape[:3, 3] + extent)
    if not np.all(np.isfinite(lo)):
        return False
    local = (invert(obj.world_T_object) @ np.array([*point, 1.0]))[:3]
    return bool(np.all(local >= lo - tol) and np.all(local <= hi + tol))
