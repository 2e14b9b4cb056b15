"""WorldSpec -> MJCF, built with `mujoco.MjSpec`, and MJCF -> WorldSpec.

A world file holds the whole world: floor, the three walls, a goal marker, one mocap body
per obstacle, the obstacles' schedules as `<custom><numeric name="obstacle_NNN_keyframes">`
(flattened [t, x, y] rows) and the rest of the `WorldSpec` as JSON in
`<custom><text name="dynabarn_world">`. The Jackal is not copied in: the file names
`assets/jackal/jackal.xml` with `<asset><model>` and places it with
`<attach model="jackal" prefix="jackal/">`, so MuJoCo itself loads the file
(`python -m mujoco.viewer --mjcf generated_worlds/world_137.xml`, from a checkout or a wheel).
A world folder outside the checkout carries its own copy (`DIR/assets/jackal/jackal.xml`).

MjSpec builds everything it can express; it inlines attached models when it writes XML,
so the two robot-reference elements are added to its output as the only text edit.
"""

from __future__ import annotations

import copy
import functools
import hashlib
import json
import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np

from dynabarn.errors import WorldError
from dynabarn.files import write_atomically
from dynabarn.provenance import DATA_ROOT
from dynabarn.robot import JACKAL_REL, JACKAL_XML, PHYSICS_TIMESTEP, GeomGroup
from dynabarn.robot_mjcf import build_jackal_spec
from dynabarn.world_file import check_self_contained, parse_xml, world_bytes
from dynabarn.worlds.spec import WorldSpec

METADATA_TEXT = "dynabarn_world"
ROBOT_PREFIX = "jackal/"
STATIC_FIELD_BODY = "static_obstacles"


def keyframes_numeric_name(obstacle_name: str) -> str:
    return f"{obstacle_name}_keyframes"


# Over 80 lines on purpose: one MJCF world read top to bottom in the order of the XML it
# writes (assets, floor, walls, goal, obstacles, static field, custom data).
def build_world_spec(world: WorldSpec) -> mujoco.MjSpec:
    """The world without the robot, as an MjSpec (compiles on its own)."""
    spec = mujoco.MjSpec()
    spec.modelname = world.name
    spec.compiler.degree = False
    spec.option.timestep = PHYSICS_TIMESTEP
    spec.option.integrator = mujoco.mjtIntegrator.mjINT_IMPLICITFAST
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 720
    # Bright, even light for top-down pictures: headlight plus a sun straight above.
    spec.visual.headlight.ambient = [0.35, 0.35, 0.35]
    spec.visual.headlight.diffuse = [0.45, 0.45, 0.45]

    spec.add_texture(
        name="grid",
        type=mujoco.mjtTexture.mjTEXTURE_2D,
        builtin=mujoco.mjtBuiltin.mjBUILTIN_CHECKER,
        rgb1=[0.82, 0.82, 0.80],
        rgb2=[0.74, 0.74, 0.72],
        width=512,
        height=512,
    )
    floor_mat = spec.add_material(name="floor", texrepeat=[20, 20], reflectance=0.0)
    floor_mat.textures[mujoco.mjtTextureRole.mjTEXROLE_RGB] = "grid"
    spec.add_material(name="wall", rgba=[0.55, 0.55, 0.6, 1])
    spec.add_material(name="obstacle", rgba=[0.85, 0.15, 0.12, 1])
    spec.add_material(name="goal", rgba=[0.1, 0.8, 0.2, 1])

    wb = spec.worldbody
    wb.add_light(
        name="sun",
        pos=[0, 0, 20],
        dir=[0, 0, -1],
        type=mujoco.mjtLightType.mjLIGHT_DIRECTIONAL,
        castshadow=False,
        diffuse=[0.5, 0.5, 0.5],
    )
    half = world.layout.arena_half_size
    wb.add_geom(
        name="floor",
        type=mujoco.mjtGeom.mjGEOM_PLANE,
        size=[half + 7, half + 7, 0.1],
        pos=[1, 0, 0],
        material="floor",
        contype=0,
        conaffinity=0,
        group=GeomGroup.STATIC,
    )
    for wall in world.layout.walls:
        wb.add_geom(
            name=wall.name,
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[wall.size[0] / 2, wall.size[1] / 2, wall.size[2] / 2],
            pos=[wall.centre[0], wall.centre[1], wall.size[2] / 2],
            material="wall",
            contype=1,
            conaffinity=1,
            group=GeomGroup.STATIC,
        )
    # Static cylinders in a body of their own (no joints: still part of the static world),
    # so the runner's laser can leave them to its closed-form scan.
    field = wb.add_body(name=STATIC_FIELD_BODY) if world.layout.cylinders else None
    for k, (cx, cy, r) in enumerate(world.layout.cylinders):
        field.add_geom(
            name=f"static_{k:03d}",
            type=mujoco.mjtGeom.mjGEOM_CYLINDER,
            size=[r, 0.5, 0],
            pos=[cx, cy, 0.5],
            material="wall",
            contype=1,
            conaffinity=1,
            group=GeomGroup.STATIC,
        )
    wb.add_geom(
        name="goal",
        type=mujoco.mjtGeom.mjGEOM_CYLINDER,
        size=[0.075, 0.001, 0],
        pos=[world.layout.goal[0], world.layout.goal[1], 0.001],
        material="goal",
        contype=0,
        conaffinity=0,
        group=GeomGroup.MARKER,
    )
    for k, obstacle in enumerate(world.obstacles):
        x0, y0 = obstacle.trajectory.xy[0]
        # The body sits at the shape's centre; its fixed yaw is the mocap body's orientation.
        z = obstacle.radius if obstacle.shape == "capsule" else obstacle.height / 2
        body = wb.add_body(name=obstacle.name, mocap=True, pos=[x0, y0, z], quat=_yaw_quat(obstacle.yaw))
        body.info = f"{world.name}, obstacle {k}"
        geom = body.add_geom(
            name=obstacle.name,
            material="obstacle",
            contype=1,
            conaffinity=1,
            group=GeomGroup.OBSTACLE,
        )
        if obstacle.shape == "box":
            geom.type = mujoco.mjtGeom.mjGEOM_BOX
            geom.size = [obstacle.half_length, obstacle.half_width, obstacle.height / 2]
        elif obstacle.shape == "capsule":  # axis along the body's x: turn the capsule's z onto x
            geom.type = mujoco.mjtGeom.mjGEOM_CAPSULE
            geom.size = [obstacle.radius, obstacle.half_length, 0]
            geom.quat = [math.cos(math.pi / 4), 0, math.sin(math.pi / 4), 0]
        else:
            geom.type = mujoco.mjtGeom.mjGEOM_CYLINDER
            geom.size = [obstacle.radius, obstacle.height / 2, 0]
        kf = np.column_stack([obstacle.trajectory.times, obstacle.trajectory.xy]).ravel()
        spec.add_numeric(name=keyframes_numeric_name(obstacle.name), data=kf.tolist())
    spec.add_text(name=METADATA_TEXT, data=json.dumps(world.metadata(), sort_keys=True, separators=(",", ":")))
    return spec


def _yaw_quat(yaw: float) -> list[float]:
    return [1.0, 0.0, 0.0, 0.0] if yaw == 0 else [math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)]


def asset_root_for(world_dir: Path) -> Path:
    """The folder whose `assets/jackal/jackal.xml` the worlds in `world_dir` name.

    Folders inside the data root (the checkout's `generated_worlds/`, `mixed_worlds/`, ...)
    share its robot (`../assets/jackal/jackal.xml`); any other folder carries its own copy
    (`assets/jackal/jackal.xml` inside it), so it opens in MuJoCo's viewer wherever it is
    moved and nothing is written outside it."""
    world_dir = Path(world_dir).resolve()
    data = DATA_ROOT.resolve()
    return data if world_dir.is_relative_to(data) else world_dir


def place_robot(asset_root: Path) -> Path:
    """Make sure `asset_root/assets/jackal/jackal.xml` is the package's robot (written
    atomically when missing); returns its path. An existing different file is not replaced."""
    target = Path(asset_root) / JACKAL_REL
    if target.resolve() == JACKAL_XML.resolve():
        return target
    data = JACKAL_XML.read_bytes()
    if target.is_file():
        if target.read_bytes() != data:
            raise WorldError(f"{target} exists and is not this package's robot; move it or write the worlds elsewhere")
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    write_atomically(target, data)
    return target


def robot_reference(world_dir: Path, asset_root: Path) -> str:
    """The robot file's path as written in a world in `world_dir` (relative to it)."""
    return Path(os.path.relpath(Path(asset_root).resolve() / JACKAL_REL, Path(world_dir).resolve())).as_posix()


def world_to_xml(world: WorldSpec, *, world_dir: Path, asset_root: Path | None = None) -> str:
    """The world's MJCF text for a file in `world_dir`, with the Jackal attached."""
    xml = build_world_spec(world).to_xml()
    ref = robot_reference(world_dir, asset_root if asset_root is not None else asset_root_for(world_dir))
    model = f'    <model name="jackal" file="{ref}"/>\n'
    attach = f'    <attach model="jackal" body="base_link" prefix="{ROBOT_PREFIX}"/>\n'
    for anchor in ("  <asset>\n", "  </worldbody>\n"):
        if xml.count(anchor) != 1:  # pragma: no cover - guards against an MjSpec format change
            raise RuntimeError(f"unexpected MjSpec XML layout: {anchor.strip()!r} not found once")
    xml = xml.replace("  <asset>\n", "  <asset>\n" + model, 1)
    return xml.replace("  </worldbody>\n", attach + "  </worldbody>\n", 1)


def write_world(world: WorldSpec, path: Path, *, asset_root: Path | None = None) -> str:
    """Write the world's MJCF to `path` (and the robot it names, when missing); returns the
    file's sha256. `asset_root` defaults to `asset_root_for(path.parent)`."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    root = asset_root if asset_root is not None else asset_root_for(path.parent)
    place_robot(root)
    xml = world_to_xml(world, world_dir=path.parent, asset_root=root)
    data = xml.encode()
    write_atomically(path, data)
    return hashlib.sha256(data).hexdigest()


def read_world(path: Path | str, data: bytes | None = None) -> WorldSpec:
    """The WorldSpec stored in a world MJCF file (no compilation needed); `data`: the file's
    bytes when already read."""
    return open_world(path, data)[1]


def open_world(path: Path | str, data: bytes | None = None) -> tuple[ET.Element, WorldSpec]:
    """A world file parsed and checked once: its document (what `load_model` compiles,
    `root=`) and its WorldSpec."""
    path = Path(path)
    root = parse_xml(path, world_bytes(path) if data is None else data)
    check_self_contained(path, root)
    return root, _world_spec(path, root)


def _world_spec(path: Path, root: ET.Element) -> WorldSpec:
    text = root.find(f"./custom/text[@name='{METADATA_TEXT}']")
    if text is None or (text.get("data") is None and not (text.text or "").strip()):
        raise WorldError(f"{path}: not a DynaBARN world (no <text name='{METADATA_TEXT}'>)")
    try:
        meta = json.loads(text.get("data") or text.text or "")
    except (json.JSONDecodeError, RecursionError) as exc:
        raise WorldError(f"{path}: world metadata is not valid JSON ({type(exc).__name__})") from None
    numerics = {n.get("name"): n.get("data", "") for n in root.findall("./custom/numeric")}
    keyframes = []
    obstacles = meta.get("obstacles") if isinstance(meta, dict) else None
    for od in obstacles if isinstance(obstacles, list) else []:
        if not isinstance(od, dict):
            raise WorldError(f"{path}: an obstacle's description is not an object")
        raw = numerics.get(keyframes_numeric_name(str(od.get("name"))))
        if raw is None:
            raise WorldError(f"{path}: obstacle {od.get('name')!r} has no keyframes numeric")
        try:
            values = np.array(raw.split(), dtype=np.float64)
        except ValueError:
            raise WorldError(f"{path}: obstacle {od.get('name')!r} keyframes are not numbers") from None
        if values.size % 3:
            raise WorldError(f"{path}: obstacle {od.get('name')!r} keyframes are not [t, x, y] triples")
        keyframes.append(values.reshape(-1, 3))
    try:
        return WorldSpec.from_dict(meta, keyframes)
    except WorldError as exc:
        raise WorldError(f"{path}: {exc}") from None


_ROBOT_ASSET = "jackal.xml"


@functools.cache
def _robot_xml(beam_sensors: bool) -> bytes:
    """The package's Jackal: the committed file, or the runner's variant without the 720
    beam sites and rangefinders (it casts the scan with mj_multiRay), built in memory."""
    return JACKAL_XML.read_bytes() if beam_sensors else build_jackal_spec(beam_sensors=False).to_xml().encode()


def load_model(
    path: Path | str, *, beam_sensors: bool = True, data: bytes | None = None, root: ET.Element | None = None
) -> mujoco.MjModel:
    """Compile a world file with MuJoCo, turning its errors into one clear line.

    The world is checked to be self-contained (`check_self_contained`) and compiled from its
    bytes (`data` when already read) with the package's Jackal handed to MuJoCo through its
    asset dictionary, so nothing else is read and the current directory does not matter.
    `beam_sensors=False` gives the runner's variant of the robot; `root`: the document
    `open_world` parsed and checked (so a load parses once)."""
    path = Path(path)
    if root is None:
        root = parse_xml(path, world_bytes(path) if data is None else data)
        check_self_contained(path, root)
    else:  # `open_world`'s document, parsed and checked: rewritten below, so a copy
        root = copy.deepcopy(root)
    # MuJoCo compiles the document that was checked, written out anew, never the file's own
    # spelling: attributes in any order or quoting, entities, a second parser's reading of
    # the same bytes cannot bring in anything the check did not see. The Jackal's one
    # reference now names the package's robot, handed over in memory.
    for model in root.iter("model"):
        if model.get("name") == "jackal" and "file" in model.attrib:
            model.set("file", _ROBOT_ASSET)
    for text in root.iter("text"):  # MuJoCo reads a <text>'s content only from CDATA, which
        if text.text and text.get("data") is None:  # ElementTree does not write: the attribute
            text.set("data", text.text)
            text.text = None
    try:
        xml = ET.tostring(root, encoding="unicode")
        return mujoco.MjModel.from_xml_string(xml, assets={_ROBOT_ASSET: _robot_xml(beam_sensors)})
    except ValueError as exc:
        first = str(exc).strip().splitlines()[0] if str(exc).strip() else "unknown error"
        raise WorldError(f"{path}: MuJoCo cannot load this world: {first}") from None
