"""The contact physics of a cell: the ``[physics]`` table of its file, checked, in SI units.

The telerobot's physics world (``robot_sim.physics``) runs on these; the console never reads
them (its model has no dynamics). The loader (``shared.cells.loader``) checks the table with the
rest of the file, so a wrong value is refused wherever the cell is loaded.

Every key has a default that runs, so a cell without the table gets the physics world too. The
table's keys carry their unit in their name (``timestep_ms``, ``grip_force_n``) because a person
types them; the loaded ``PhysicsParams`` is in SI units.

| key | default | what |
|---|---|---|
| ``timestep_ms`` | 1.0 | the physics step (the servo period is a whole number of them) |
| ``friction`` | 0.3 | sliding friction between the peg, the plate, the table and the arm (lightly oiled steel) |
| ``finger_friction`` | 1.0 | sliding friction of the finger pads |
| ``torsional_friction`` | 0.005 | torsional friction (m) of the finger pads on the peg |
| ``contact_timeconst_ms`` | 2.0 | time constant of the contact's spring-damper (at least two steps) |
| ``contact_dampratio`` | 1.0 | its damping ratio |
| ``object_density`` | 7850 | density of the movable objects (kg/m^3; steel) |
| ``link_density`` | 2700 | density of links without published inertias (kg/m^3; aluminium) |
| ``finger_mass`` | 0.05 | each finger's mass (kg) |
| ``grip_force_n`` | 120 | the force each finger squeezes with |
| ``chamfer_mm`` | 1.0 | 45-degree chamfer round the foot of a movable object |
| ``clearance_mm`` | (the file's geometry) | the fit of a peg in its hole; the peg is made that much narrower than the hole |
| ``joint_bandwidth_hz`` | 12 | the joint servo's natural frequency |
| ``joint_damping_ratio`` | 1.0 | the joint servo's damping ratio |
| ``max_joint_torque`` | 400 | each joint motor's torque limit (N m) |
| ``compliance_lateral_n_per_mm`` | 5 | the compliant wrist's sideways stiffness (0: rigid) |
| ``compliance_axial_n_per_mm`` | 20 | its stiffness along the tool axis (0: rigid) |
| ``compliance_angular_nm_per_deg`` | 0.35 | its tilting stiffness (0: rigid) |
| ``compliance_centre_mm`` | 60 | where it tilts about: this far along the tool axis past the tool point |
| ``compliance_travel_mm`` | 2.5 | how far it gives way, each way, sideways and along the axis |
| ``compliance_tilt_deg`` | 3 | how far it tilts, each way |
| ``damage_force_n`` | 100 | the contact load past which the arm, its tool, what it holds or the cell is harmed (the fault campaigns' judge; the robot never reads it) |

The gripper hangs from the wrist sensor on a passive compliant wrist (a remote-centre compliance
device): a rigid arm holding a peg in a hole with 0.03 mm of clearance wedges it at the first
hundredth of a millimetre of tracking error, as a real PUMA would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace

from shared.errors import FileFormatError

# (key in the file, field, scale to SI, lower bound, strict)
_KEYS: tuple[tuple[str, str, float, float, bool], ...] = (
    ("timestep_ms", "timestep", 1e-3, 0.0, True),
    ("friction", "friction", 1.0, 0.0, False),
    ("finger_friction", "finger_friction", 1.0, 0.0, False),
    ("torsional_friction", "torsional_friction", 1.0, 0.0, False),
    ("contact_timeconst_ms", "contact_timeconst", 1e-3, 0.0, True),
    ("contact_dampratio", "contact_dampratio", 1.0, 0.0, True),
    ("object_density", "object_density", 1.0, 0.0, True),
    ("link_density", "link_density", 1.0, 0.0, True),
    ("finger_mass", "finger_mass", 1.0, 0.0, True),
    ("grip_force_n", "grip_force", 1.0, 0.0, True),
    ("chamfer_mm", "chamfer", 1e-3, 0.0, False),
    ("clearance_mm", "clearance", 1e-3, 0.0, False),
    ("joint_bandwidth_hz", "joint_bandwidth", 1.0, 0.0, True),
    ("joint_damping_ratio", "joint_damping_ratio", 1.0, 0.0, True),
    ("max_joint_torque", "max_joint_torque", 1.0, 0.0, True),
    ("compliance_lateral_n_per_mm", "compliance_lateral", 1e3, 0.0, False),
    ("compliance_axial_n_per_mm", "compliance_axial", 1e3, 0.0, False),
    ("compliance_angular_nm_per_deg", "compliance_angular", 180.0 / math.pi, 0.0, False),
    ("compliance_centre_mm", "compliance_centre", 1e-3, -math.inf, False),
    ("compliance_travel_mm", "compliance_travel", 1e-3, 0.0, True),
    ("compliance_tilt_deg", "compliance_tilt", math.pi / 180.0, 0.0, True),
    ("damage_force_n", "damage_force", 1.0, 0.0, True),
)


@dataclass(frozen=True)
class PhysicsParams:
    """Contact and actuation parameters of the physics world (SI units)."""

    timestep: float = 1.0e-3
    friction: float = 0.3
    finger_friction: float = 1.0
    torsional_friction: float = 0.005
    contact_timeconst: float = 2.0e-3
    contact_dampratio: float = 1.0
    object_density: float = 7850.0
    link_density: float = 2700.0
    finger_mass: float = 0.05
    grip_force: float = 120.0
    chamfer: float = 1.0e-3
    clearance: float | None = None  # None: the fit the cell's geometry has
    joint_bandwidth: float = 12.0
    joint_damping_ratio: float = 1.0
    max_joint_torque: float = 400.0
    compliance_lateral: float = 5000.0  # N/m
    compliance_axial: float = 20000.0  # N/m
    compliance_angular: float = 20.0  # N m / rad
    compliance_centre: float = 0.06  # m along the tool axis from the tool point
    compliance_travel: float = 0.0025  # m each way, sideways and along the axis
    compliance_tilt: float = math.radians(3.0)  # rad each way
    damage_force: float = 100.0  # N: a contact load past this harms the arm, the tool or the cell

    def with_overrides(self, *, friction: float | None = None, clearance: float | None = None, where: str = "settings"
                       ) -> "PhysicsParams":
        """The same with the world's overrides (``--friction``, ``--clearance-mm``), checked."""
        out = self
        if friction is not None:
            if not (math.isfinite(friction) and friction >= 0.0):
                raise FileFormatError(where, f"friction must be a number >= 0, got {friction}")
            out = replace(out, friction=friction)
        if clearance is not None:
            if not (math.isfinite(clearance) and clearance >= 0.0):
                raise FileFormatError(where, f"clearance must be a length >= 0 mm, got {clearance * 1e3:g} mm")
            out = replace(out, clearance=clearance)
        return out

    def as_dict(self) -> dict[str, float | None]:
        """Every parameter in the units of the file's keys, for a trial's summary."""
        out: dict[str, float | None] = {}
        for key, name, scale, _, _ in _KEYS:
            value = getattr(self, name)
            out[key] = None if value is None else round(value / scale, 9)
        return out


def parse_physics(table: object, path: str) -> PhysicsParams:
    """The ``[physics]`` table of a cell file, checked; the defaults where keys are absent.

    Raises ``FileFormatError`` naming the file and the field for an unknown key, a value that is
    not a number, or one out of range (negative friction, a clearance below zero, a zero step)."""
    if table is None:
        return PhysicsParams()
    if not isinstance(table, dict):
        raise FileFormatError(path, "must be a table", "physics")
    known = {k[0]: k for k in _KEYS}
    values: dict[str, float] = {}
    for key, value in table.items():
        field = f"physics.{key}"
        if key not in known:
            raise FileFormatError(path, f"not a physics parameter; known: {', '.join(known)}", field)
        _, name, scale, lower, strict = known[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise FileFormatError(path, f"must be a finite number, got {value!r}", field)
        if value < lower or (strict and value == lower):
            bound = f"> {lower:g}" if strict else f">= {lower:g}"
            raise FileFormatError(path, f"must be {bound}, got {value:g}", field)
        values[name] = float(value) * scale
    params = PhysicsParams(**values)
    if params.contact_timeconst < 2.0 * params.timestep:
        raise FileFormatError(path, f"must be at least two physics steps ({2e3 * params.timestep:g} ms), "
                                    f"got {params.contact_timeconst * 1e3:g}", "physics.contact_timeconst_ms")
    return params


assert {f.name for f in fields(PhysicsParams)} == {k[1] for k in _KEYS}
