import mujoco
import numpy as np

from dynabarn.mjcf import load_model
from dynabarn.provenance import SHIPPED_WORLDS
from dynabarn.robot import JACKAL, JACKAL_XML, LASER_GEOM_GROUPS, PHYSICS_TIMESTEP
from dynabarn.robot_mjcf import build_jackal_spec

ASSET_DIR = JACKAL_XML.parent


def test_asset_folder_layout():
    for name in ("jackal.xml", "scene.xml", "README.md", "CHANGELOG.md", "LICENSE"):
        assert (ASSET_DIR / name).is_file(), name


def test_committed_model_matches_builder():
    assert JACKAL_XML.read_text() == build_jackal_spec().to_xml()


def test_scene_loads_without_a_warning(tmp_path):
    """MuJoCo writes its warnings to MUJOCO_LOG.TXT in the current folder: loading the scene
    (in a folder of its own) leaves none, and keeps the robot's physics options."""
    import subprocess
    import sys

    code = (
        "import mujoco, sys\n"
        "m = mujoco.MjModel.from_xml_path(sys.argv[1])\n"
        "print(m.nsensor, m.opt.timestep, int(m.opt.integrator == mujoco.mjtIntegrator.mjINT_IMPLICITFAST))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, str(ASSET_DIR / "scene.xml")], capture_output=True, text=True, cwd=tmp_path
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["720", str(PHYSICS_TIMESTEP), "1"]
    assert not (tmp_path / "MUJOCO_LOG.TXT").exists(), (tmp_path / "MUJOCO_LOG.TXT").read_text()


def _world_with_robot_at(x, y, yaw):
    m = load_model(SHIPPED_WORLDS / "world_000.xml")
    d = mujoco.MjData(m)
    d.qpos[:3] = [x, y, yaw]
    d.mocap_pos[:, :2] = 100.0  # obstacles far away
    mujoco.mj_forward(m, d)
    return m, d


def test_laser_never_sees_the_robot_and_sensors_agree_with_multiray():
    m, d = _world_with_robot_at(0.0, 0.0, np.pi)  # facing the back wall at x = -10
    ranges = d.sensordata[:720].copy()
    assert np.all(ranges > 5.0), "no beam may hit the robot's own geoms"
    site = m.site("jackal/laser").id
    pnt = d.site_xpos[site].copy()
    yaw = np.pi + JACKAL.laser_angles()
    vec = np.stack([np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)], axis=1).ravel()
    geomid = np.zeros(720, np.int32)
    dist = np.zeros(720)
    mujoco.mj_multiRay(m, d, pnt, vec, LASER_GEOM_GROUPS, 1, -1, geomid, dist, None, 720, 30.0)
    np.testing.assert_allclose(dist, ranges, atol=1e-4)
    # Straight ahead: back wall inner face at x = -9.75; laser 0.12 m ahead of the centre.
    assert abs(dist[359] - (9.75 - 0.12)) < 0.01


def test_velocity_actuators_track_commands():
    m, d = _world_with_robot_at(0.0, 0.0, 0.0)
    d.ctrl[:] = [1.0, 0.0, 0.5]
    mujoco.mj_step(m, d, 400)  # 2 s
    vx_body = np.cos(d.qpos[2]) * d.qvel[0] + np.sin(d.qpos[2]) * d.qvel[1]
    vy_body = -np.sin(d.qpos[2]) * d.qvel[0] + np.cos(d.qpos[2]) * d.qvel[1]
    assert abs(vx_body - 1.0) < 0.02 and abs(vy_body) < 0.02 and abs(d.qvel[2] - 0.5) < 0.02


def test_planners_and_behaviours_load_no_mujoco():
    """Every shipped planner (each one built with its defaults) and obstacle behaviour, in a
    fresh interpreter: the robot's numbers come from `dynabarn.robot`, not its MJCF model,
    so no simulator is loaded. (TEB's solver imports MuJoCo's linear algebra when it first
    runs, not before.)"""
    import subprocess
    import sys

    code = """
import importlib, pkgutil, sys
import dynabarn.planners as planners
for info in pkgutil.walk_packages(planners.__path__, "dynabarn.planners."):
    importlib.import_module(info.name)
from dynabarn.planners.registry import available_planners, planner_factory
from dynabarn.sim.behaviors import BEHAVIORS
for name in available_planners():
    if name not in ("ros", "bc", "td3", "dagger", "ppo"):  # ROS's bridge; PyTorch's policies (the learn extra)
        planner_factory(name)()
for name in BEHAVIORS.names():
    BEHAVIORS.get_item(name)
print(sorted(m for m in sys.modules if m == "mujoco" or m.startswith("mujoco.")))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True)
    assert out.stdout.strip() == "[]", out.stdout + out.stderr
