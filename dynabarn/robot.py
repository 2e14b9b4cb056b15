"""The Clearpath Jackal: its numbers, its MJCF (built with MjSpec) and its laser geometry.

The committed `assets/jackal/jackal.xml` is the output of `build_jackal_spec()`; a test
checks they agree, and `python -m dynabarn.robot` rewrites it. `assets/jackal/README.md`
gives the source of every number below.

Model: a planar base (slide x, slide y, hinge yaw on one body) driven by three velocity
actuators through a site at the base centre: `v` along the body's x axis, `slip` along
its y axis (commanded 0: no side slip) and `w` about z. Wheels are visual only: four
physically driven wheels skid badly in MuJoCo (yaw rate 30-40% of the command) and cost
3-4x more (DESIGN.md, measured on mujoco 4.0).
"""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from dynabarn.provenance import ASSETS_DIR

PHYSICS_TIMESTEP = 0.005
"""[s] The physics step the robot and every world are written with (DESIGN: at 0.01 s and
above a 2 m/s obstacle passes through the robot); `SimConfig.dt` may run another."""

JACKAL_XML = ASSETS_DIR / "jackal" / "jackal.xml"
"""The committed robot file (in a wheel: the copy under `dynabarn/data/assets`)."""
JACKAL_REL = Path("assets") / "jackal" / "jackal.xml"
"""Where a world set's root keeps the robot: world files name it relative to their folder."""


class GeomGroup(enum.IntEnum):
    """Geom groups shared by the world compiler, the laser and the viewers."""

    STATIC = 0
    """Floor and walls."""
    OBSTACLE = 1
    """Moving obstacles (mocap bodies)."""
    ROBOT_VISUAL = 2
    """The Jackal's visual geoms (no contacts)."""
    ROBOT_COLLISION = 3
    """The Jackal's collision box."""
    MARKER = 4
    """Goal and other markers (no contacts, invisible to the laser)."""


LASER_GEOM_GROUPS = np.array([1, 1, 0, 0, 0, 0], dtype=np.uint8)
"""mj_multiRay geomgroup mask: the laser sees static geoms and obstacles only."""


@dataclass(frozen=True, slots=True)
class JackalParams:
    """Every physical number of the model (sources in assets/jackal/README.md)."""

    length: float = 0.508  # [m] Clearpath Jackal spec, overall L
    width: float = 0.430  # [m] overall W
    height: float = 0.250  # [m] overall H
    mass: float = 17.0  # [kg] Clearpath spec ("17 kg")
    wheel_radius: float = 0.098  # [m] Clearpath jackal_description (Menagerie uses 0.095)
    wheel_width: float = 0.04  # [m] visual only
    wheel_x: float = 0.131  # [m] wheel base half-length (Menagerie jackal.xml)
    wheel_y: float = 0.187795  # [m] track half-width (Menagerie jackal.xml)
    v_min: float = -0.5  # [m/s] paper's command space
    v_max: float = 2.0  # [m/s] Jackal top speed
    w_max: float = 3.14  # [rad/s] paper's command space
    velocity_gain: float = 50.0  # [1/s] actuator bandwidth: tracks a step in ~0.1 s
    laser_beams: int = 720  # Hokuyo UST-10 as on the BARN Jackal
    laser_fov: float = 2.35619  # [rad] half field of view (+-135 deg)
    laser_range_min: float = 0.1  # [m]
    laser_range_max: float = 30.0  # [m]
    laser_noise_std: float = 0.001  # [m] Gaussian noise of the BARN Jackal's laser plugin
    laser_x: float = 0.12  # [m] front mount, ahead of the base centre
    laser_z: float = 0.30  # [m] above the ground, just over the top plate

    @property
    def yaw_inertia(self) -> float:
        """[kg m^2] of a uniform box of the footprint about z."""
        return self.mass * (self.length**2 + self.width**2) / 12.0

    @property
    def footprint_radius(self) -> float:
        """[m] circumscribed radius of the footprint (for planners' inflation)."""
        return math.hypot(self.length / 2, self.width / 2)

    def laser_angles(self) -> np.ndarray:
        """(laser_beams,) beam angles in the robot frame [rad], right to left."""
        return np.linspace(-self.laser_fov, self.laser_fov, self.laser_beams)


JACKAL = JackalParams()


def _beam_quat(angle: float) -> list[float]:
    """Quaternion turning a site's +z (the rangefinder axis) to the horizontal `angle`."""
    qy = np.array([math.cos(math.pi / 4), 0.0, math.sin(math.pi / 4), 0.0])  # z -> x
    qz = np.array([math.cos(angle / 2), 0.0, 0.0, math.sin(angle / 2)])
    q = np.empty(4)
    mujoco.mju_mulQuat(q, qz, qy)
    return [round(float(c), 9) for c in q]


# Over 80 lines on purpose: one MJCF model read top to bottom in the order of the XML it
# writes (chassis, wheels, laser, sensors), like the URDF it follows.
def build_jackal_spec(
    p: JackalParams = JACKAL, *, laser_interval: float = 0.1, beam_sensors: bool = True
) -> mujoco.MjSpec:
    """The Jackal as an MjSpec: one `base_link` body, visuals, collision box, laser, actuators.

    Args:
        p: the robot's numbers.
        laser_interval: period [s] at which MuJoCo evaluates the 720 rangefinders; the
            runner casts its scans itself with mj_multiRay at the planner rate, so the
            sensors only serve viewers and users of the bare model.
        beam_sensors: False leaves out the 720 beam sites and rangefinders (the runner's
            variant: their site kinematics alone cost ~4.7 us per physics step, more than
            the rest of the step). Everything else is identical.
    """
    spec = mujoco.MjSpec()
    spec.modelname = "jackal"
    spec.compiler.degree = False
    spec.option.timestep = PHYSICS_TIMESTEP
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST

    main = spec.default
    main.geom.contype = 0
    main.geom.conaffinity = 0
    visual = spec.add_default("jackal_visual", main)
    visual.geom.group = GeomGroup.ROBOT_VISUAL
    visual.geom.contype = 0
    visual.geom.conaffinity = 0
    visual.geom.density = 0
    collision = spec.add_default("jackal_collision", main)
    collision.geom.group = GeomGroup.ROBOT_COLLISION
    collision.geom.contype = 1
    collision.geom.conaffinity = 1
    collision.geom.density = 0
    collision.geom.rgba = [0.9, 0.2, 0.2, 0.3]

    black = spec.add_material(name="jackal_black", rgba=[0.12, 0.12, 0.12, 1])
    yellow = spec.add_material(name="jackal_yellow", rgba=[0.95, 0.75, 0.1, 1])
    grey = spec.add_material(name="jackal_grey", rgba=[0.4, 0.4, 0.42, 1])
    del black, yellow, grey  # referenced by name below

    base = spec.worldbody.add_body(name="base_link")
    base.explicitinertial = True
    base.mass = p.mass
    iz = p.yaw_inertia
    ix = p.mass * (p.width**2 + p.height**2) / 12.0
    iy = p.mass * (p.length**2 + p.height**2) / 12.0
    base.inertia = [ix, iy, iz]
    base.ipos = [0, 0, p.height / 2]
    for name, axis, jtype in (
        ("base_x", [1, 0, 0], mujoco.mjtJoint.mjJNT_SLIDE),
        ("base_y", [0, 1, 0], mujoco.mjtJoint.mjJNT_SLIDE),
        ("base_yaw", [0, 0, 1], mujoco.mjtJoint.mjJNT_HINGE),
    ):
        base.add_joint(name=name, type=jtype, axis=axis)

    box = mujoco.mjtGeom.mjGEOM_BOX
    cyl = mujoco.mjtGeom.mjGEOM_CYLINDER
    # Collision: the whole footprint, ground clearance 1 cm (the floor makes no contacts).
    base.add_geom(
        name="collision",
        default=collision,
        type=box,
        size=[p.length / 2, p.width / 2, (p.height - 0.01) / 2],
        pos=[0, 0, 0.01 + (p.height - 0.01) / 2],
    )
    # Visuals: chassis, top plate, bumpers, wheels, laser.
    chassis_h = 0.12
    base.add_geom(
        name="chassis",
        default=visual,
        type=box,
        size=[0.21, p.wheel_y - p.wheel_width / 2 - 0.005, chassis_h / 2],
        pos=[0, 0, 0.065 + chassis_h / 2],
        material="jackal_black",
    )
    base.add_geom(
        name="top_plate",
        default=visual,
        type=box,
        size=[0.19, 0.14, 0.01],
        pos=[0, 0, 0.065 + chassis_h + 0.01],
        material="jackal_yellow",
    )
    for side, x in (("front", 1), ("rear", -1)):
        base.add_geom(
            name=f"bumper_{side}",
            default=visual,
            type=box,
            size=[0.02, 0.16, 0.03],
            pos=[x * (p.length / 2 - 0.02), 0, 0.12],
            material="jackal_black",
        )
    for fx, fy, label in ((1, 1, "front_left"), (1, -1, "front_right"), (-1, 1, "rear_left"), (-1, -1, "rear_right")):
        base.add_geom(
            name=f"wheel_{label}",
            default=visual,
            type=cyl,
            size=[p.wheel_radius, p.wheel_width / 2, 0],
            pos=[fx * p.wheel_x, fy * p.wheel_y, p.wheel_radius],
            euler=[math.pi / 2, 0, 0],
            material="jackal_grey",
        )
    base.add_geom(
        name="laser_body",
        default=visual,
        type=cyl,
        size=[0.03, 0.035, 0],
        pos=[p.laser_x, 0, p.laser_z - 0.02],
        material="jackal_black",
    )

    base.add_site(name="base_center", pos=[0, 0, 0], group=5)
    base.add_site(name="laser", pos=[p.laser_x, 0, p.laser_z], group=5, size=[0.01, 0, 0])
    for i, a in enumerate(p.laser_angles() if beam_sensors else ()):
        base.add_site(name=f"laser_{i:03d}", pos=[p.laser_x, 0, p.laser_z], quat=_beam_quat(float(a)), group=5)
        spec.add_sensor(
            name=f"laser_{i:03d}",
            type=mujoco.mjtSensor.mjSENS_RANGEFINDER,
            objtype=mujoco.mjtObj.mjOBJ_SITE,
            objname=f"laser_{i:03d}",
            cutoff=p.laser_range_max,
            interval=[laser_interval, 0.0],
            intprm=[1 << int(mujoco.mjtRayDataField.mjRAYDATA_DIST), 0, 0],  # distance only
        )

    if not beam_sensors:
        # Every contact (any in these worlds is the robot's), per physics step: how a period
        # stepped in one call into C learns that a step touched (`sim.physics_period`).
        spec.add_sensor(name="contact", type=mujoco.mjtSensor.mjSENS_CONTACT, intprm=[1, 0, 1])

    for name, gear, lim, inertia in (
        ("v", [1, 0, 0, 0, 0, 0], (p.v_min, p.v_max), p.mass),
        ("slip", [0, 1, 0, 0, 0, 0], (-1.0, 1.0), p.mass),
        ("w", [0, 0, 0, 0, 0, 1], (-p.w_max, p.w_max), iz),
    ):
        act = spec.add_actuator(name=name, target="base_center", trntype=mujoco.mjtTrn.mjTRN_SITE)
        act.gear = gear
        act.set_to_velocity(kv=inertia * p.velocity_gain)
        act.ctrlrange = list(lim)
        act.ctrllimited = True

    # No keyframe: a world attaching the robot would warn about the keyframe conflict on
    # every load; the runner places the robot at the protocol's spawn.
    return spec


def write_jackal_xml(path: Path = JACKAL_XML) -> str:
    xml = build_jackal_spec().to_xml()
    path.write_text(xml)
    return xml


if __name__ == "__main__":  # pragma: no cover
    write_jackal_xml()
    print(f"wrote {JACKAL_XML}")


def to_robot_frame(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    """World points (n, 2) into the robot frame of pose (x, y, yaw)."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    if len(points) == 1:  # one point (a goal): the same products and sums on Python floats
        dx, dy = float(points[0][0]) - float(pose[0]), float(points[0][1]) - float(pose[1])
        return np.array([[c * dx + s * dy, -s * dx + c * dy]])
    d = np.asarray(points) - pose[:2]
    out = np.empty((len(d), 2))
    # The same products and sums as two column expressions, written into one array.
    np.add(c * d[:, 0], s * d[:, 1], out=out[:, 0])
    np.add(-s * d[:, 0], c * d[:, 1], out=out[:, 1])
    return out


def mounted_pose(pose: np.ndarray, offset) -> np.ndarray:
    """Pose (x, y, yaw) of a part mounted at `offset` (x, y) in the robot frame, for robot
    poses (3,) or (n, 3): e.g. the laser, `laser_x` ahead of the centre."""
    pose = np.asarray(pose, dtype=np.float64)
    c, s = np.cos(pose[..., 2]), np.sin(pose[..., 2])
    ox, oy = float(offset[0]), float(offset[1])
    if pose.ndim == 1:  # one pose (every control tick): the same products and sums, no stacking
        return np.array([pose[0] + c * ox - s * oy, pose[1] + s * ox + c * oy, pose[2]])
    return np.stack([pose[..., 0] + c * ox - s * oy, pose[..., 1] + s * ox + c * oy, pose[..., 2]], axis=-1)
