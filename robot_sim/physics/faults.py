"""Faults put into the physics world, and what the physics says really happened (ground truth).

A fault campaign (``server.trials.faults``) changes the real cell while the telerobot works in it,
the way the world surprises a real robot: an object moved or gone, a hole elsewhere, the peg
slipping in the fingers, an obstacle nobody modelled, a heavier object, friction far off, a jammed
hole, a joint that drags, a wrist sensor that is biased or drops out. Each change is made on the
MuJoCo model and data of one :class:`PhysicsWorld` (a heavier object and friction far off the
model are the world's from the start: ``WorldSettings``); none tells the robot anything: it learns of
the fault through its sensors or not at all.

The same module reads the physics' own truth for the judge: the contact load on the robot and what
it carries (:func:`contact_load`), whether anything touches the unmodelled geom, where the tool is.

A fault wakes every body MuJoCo has put to sleep and turns its sleeping off for the rest of the run
(a sleeping peg would not notice being moved).
"""

from __future__ import annotations

import math

import numpy as np

from robot_sim.physics.mjcf import STATIC_BIT, UNMODELLED_GEOM
from robot_sim.physics.world import PhysicsWorld


def _static_moved(world: PhysicsWorld) -> None:
    """A geom of the static cell moved: MuJoCo's mid-phase keeps the compiled bounding-volume tree
    of the world's geoms, so it is switched off for this world (every pair then goes to the
    narrow phase by bounding spheres; the cell has a few dozen geoms)."""
    world.model.opt.disableflags |= int(world.mj.mjtDisableBit.mjDSBL_MIDPHASE)


def wake(world: PhysicsWorld) -> None:
    """Every body awake and integrated from now on (MuJoCo's sleeping off for this world)."""
    mujoco = world.mj
    sleep = getattr(mujoco.mjtEnableBit, "mjENBL_SLEEP", None)
    if sleep is not None:
        world.model.opt.enableflags &= ~int(sleep)
    world._dof_tree = None
    world._read.clear()
    world._asleep = False


def _forward(world: PhysicsWorld) -> None:
    world.mj.mj_forward(world.model, world.data)
    world._contact_pairs = None
    world._read.clear()
    world._after_step()


def unmodelled_geom(world: PhysicsWorld) -> int:
    return world.mj.mj_name2id(world.model, world.mj.mjtObj.mjOBJ_GEOM, UNMODELLED_GEOM)


def place_unmodelled(world: PhysicsWorld, world_p_centre: np.ndarray, half: np.ndarray) -> None:
    """Put a box of half extents ``half`` (m) at ``world_p_centre``: an obstacle, or a block in a
    hole. It is static, as heavy as the cell, and collides with the arm, the fingers and objects."""
    wake(world)
    g = unmodelled_geom(world)
    m = world.model
    half = np.asarray(half, dtype=float)
    m.geom_size[g] = half
    m.geom_rbound[g] = float(np.linalg.norm(half))
    m.geom_aabb[g] = np.concatenate([np.zeros(3), half])
    m.geom_pos[g] = np.asarray(world_p_centre, dtype=float)
    m.geom_contype[g] = STATIC_BIT
    m.geom_conaffinity[g] = 0
    _static_moved(world)
    _forward(world)


def retract_unmodelled(world: PhysicsWorld) -> None:
    """Take the unmodelled box out of the cell again (it collides with nothing)."""
    g = unmodelled_geom(world)
    world.model.geom_pos[g] = [0.0, 0.0, -100.0]
    world.model.geom_contype[g] = 0
    _forward(world)


def move_object(world: PhysicsWorld, name: str, world_T_object: np.ndarray) -> None:
    """Put movable object ``name`` at ``world_T_object``, at rest."""
    wake(world)
    mujoco = world.mj
    a = world._object_qadr[name]
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(world_T_object[:3, :3]).ravel())
    world.data.qpos[a:a + 3] = world_T_object[:3, 3]
    world.data.qpos[a + 3:a + 7] = quat
    b = world._bodies[name]
    dof = world.model.body_dofadr[b]
    world.data.qvel[dof:dof + 6] = 0.0
    _forward(world)


def remove_object(world: PhysicsWorld, name: str) -> None:
    """Object ``name`` is gone: it no longer collides, floats (gravity compensated) far from the
    cell, and its pose reads as where it went."""
    wake(world)
    m = world.model
    b = world._bodies[name]
    geoms = np.flatnonzero(np.asarray(m.geom_bodyid) == b)
    m.geom_contype[geoms] = 0
    m.geom_conaffinity[geoms] = 0
    m.body_gravcomp[b] = 1.0
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.0, -50.0]
    move_object(world, name, T)


def shift_carrier(world: PhysicsWorld, carrier: str, shift: np.ndarray) -> list[str]:
    """Move the static object ``carrier`` (a plate with holes) by ``shift`` (m), with what stands in
    its holes and is not held; the holes' true places move with it. Returns the objects moved."""
    wake(world)
    mujoco = world.mj
    m = world.model
    shift = np.asarray(shift, dtype=float)
    _static_moved(world)
    for g in range(m.ngeom):
        if (mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, g) or "").startswith(f"{carrier}/"):
            m.geom_pos[g] += shift
    moved = []
    carried_holes = {h for h, s in world._hole_shift.items() if s is world._carrier_shift.get(carrier)}
    for name, peg in world.pegs.items():
        if peg.in_hole in carried_holes and not peg.held:
            T = peg.world_T_peg.copy()
            T[:3, 3] += shift
            move_object(world, name, T)
            moved.append(name)
    world._carrier_shift[carrier] = world._carrier_shift.get(carrier, np.zeros(3)) + shift
    for h in carried_holes:
        world._hole_shift[h] = world._carrier_shift[carrier]
    world._set_holes({n: g for n, g in _file_holes(world).items()})
    _forward(world)
    return moved


def _file_holes(world: PhysicsWorld):
    from robot_sim.physics.world import _compiled, _halves_key

    return _compiled(world.cell, world.params, _halves_key(world.object_half))[2]


def slip(world: PhysicsWorld, name: str, friction: float) -> None:
    """The finger pads lose their grip on ``name``: the pads' and the object's friction drops to
    ``friction`` (MuJoCo takes the larger of a pair's), so what the fingers hold slides out."""
    wake(world)
    m = world.model
    geoms = np.flatnonzero((np.asarray(m.geom_bodyid) == world._bodies[name]) | world._pad_geom)
    m.geom_friction[geoms, 0] = friction
    m.geom_friction[geoms, 1] = min(float(m.geom_friction[geoms[0], 1]), friction * 0.01)
    _forward(world)


def drag_joint(world: PhysicsWorld, joint: int, torque: float) -> None:
    """A torque disturbance of ``torque`` (N m) on joint ``joint`` (0-based) from now on: a joint
    that drags, a cable that pulls."""
    wake(world)
    world.data.qfrc_applied[world._vadr[joint]] = torque


def sensor_bias(world: PhysicsWorld, force: np.ndarray, torque: np.ndarray | None = None) -> None:
    """The wrist sensor reads ``force`` (N, world frame) more than it feels, from now on."""
    world.sensor_fault = np.concatenate([np.asarray(force, dtype=float),
                                         np.zeros(3) if torque is None else np.asarray(torque, dtype=float)])
    world._asleep = False  # the robot's next servo period reads it (no idle period skipped over it)
    world._sense()


def sensor_dropout(world: PhysicsWorld) -> None:
    """The wrist sensor's readings are flagged invalid (NaN) from now on."""
    world.sensor_fault = np.full(6, math.nan)
    world._asleep = False
    world._sense()


# -- ground truth -----------------------------------------------------------------------------------
def contact_load(world: PhysicsWorld) -> tuple[float, str]:
    """The force (N) the robot exerts on the world now, and on what: through its tool (the wrist's
    noise-free force beyond what it holds, while the tool or what it holds touches something;
    braking alone is no contact), or through a link of the arm (the largest total normal
    force between the arm's links and any one other body, from MuJoCo's contact solution)."""
    tool = 0.0
    tool_on = world._touching
    if tool_on:
        tool = float(np.linalg.norm(world.contact(noise=False).force))
    arm, arm_on = _arm_load(world)
    return (tool, tool_on) if tool >= arm else (arm, arm_on)


def _arm_load(world: PhysicsWorld) -> tuple[float, str]:
    d = world.data
    n = d.ncon
    if n == 0:
        return 0.0, ""
    geom = d.contact.geom[:n]
    arm = world._arm_only_geom
    a, b = arm[geom[:, 0]], arm[geom[:, 1]]
    rows = np.flatnonzero(a ^ b)
    if rows.size == 0:
        return 0.0, ""
    body = world._geom_body
    totals: dict[int, float] = {}
    out = np.zeros(6)
    for k in rows.tolist():
        world.mj.mj_contactForce(world.model, d, k, out)
        other = int(geom[k, 1] if a[k] else geom[k, 0])
        key = int(body[other]) if body[other] != 0 else -other - 1  # the world body's geoms one by one
        totals[key] = totals.get(key, 0.0) + abs(float(out[0]))
    key, load = max(totals.items(), key=lambda kv: kv[1])
    if key < 0:
        return load, world._geom_label(-key - 1)
    return load, world.mj.mj_id2name(world.model, world.mj.mjtObj.mjOBJ_BODY, key) or f"body {key}"


def unmodelled_touched(world: PhysicsWorld) -> bool:
    """Whether anything touches the unmodelled geom now."""
    g1, g2 = world._contacts()
    if g1.size == 0:
        return False
    g = unmodelled_geom(world)
    return bool(np.any(g1 == g) or np.any(g2 == g))
