"""The Jackal's MJCF model, built with MjSpec from its numbers (`dynabarn.robot`).

The committed `assets/jackal/jackal.xml` is the output of `build_jackal_spec()`; a test
checks they agree, and `python -m dynabarn.robot_mjcf` rewrites it. Only what builds or
compiles models imports this module (and MuJoCo with it): the planners and behaviours
read the robot's numbers from `dynabarn.robot` and never load MuJoCo.

Model: a planar base (slide x, slide y, hinge yaw on one body) driven by three velocity
actuators through a site at the base centre: `v` along the body's x axis, `slip` along
its y axis (commanded 0: no side slip) and `w` about z. Wheels are visual only: four
physically driven wheels skid badly in MuJoCo (yaw rate 30-40% of the command) and cost
3-4x more (assets/jackal/README.md, measured on mujoco 4.0).
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco
import numpy as np

from dynabarn.robot import JACKAL, JACKAL_XML, PHYSICS_TIMESTEP, GeomGroup, JackalParams


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
