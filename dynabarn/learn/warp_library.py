"""The worlds of one Warp batch, padded to one model: what lets a batch hold the worlds of a
set (each its own static field, obstacle count and shapes) and not only copies of one.

MuJoCo Warp steps one model for every world of a batch; a model field with a leading world
dimension (`geom_size`, `geom_pos`, `body_quat`, ...) may differ per world. So every world
of the library is compiled by MuJoCo's C compiler into the *same structure*:

- the static field padded to the library's largest count of standing cylinders;
- obstacle slot k holds one mocap body for each shape any world has at k (in
  `SHAPE_NAMES`' order): a world's own obstacle k in the body of its shape, stand-ins in
  the others;
- every stand-in (a static cylinder or an obstacle of another shape) 100 m below the floor:
  no ray of the laser's plane and no contact reaches it.

The fields that differ between the compiled worlds are stacked (`fields`: the world
dimension first); any other difference of a field the simulation reads is refused, so a
world the padding does not cover fails here, not in a wrong step. The obstacles' keyframes
(`keyframes_of` of each padded world) are joined into flat arrays, world k's obstacle i
at `k * n_obstacles + i`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

import mujoco
import numpy as np

from dynabarn.errors import DynabarnError
from dynabarn.mjcf import load_model, open_world, world_to_xml
from dynabarn.worlds.schedule import keyframes_of
from dynabarn.worlds.spec import SHAPE_NAMES, EndBehavior, Interpolation, Obstacle, WorldSpec
from dynabarn.worlds.trajectory import Trajectory

BELOW = -100.0
"""Where a stand-in's geom sits [m, z]: far under the laser's plane and the robot."""
PAD = "pad_"
"""The name prefix of every stand-in (a world's own names never start with it)."""
PER_WORLD_FIELDS = ("geom_size", "geom_pos", "geom_quat", "geom_aabb", "geom_rbound", "body_pos", "body_quat")
"""What differs between the worlds of a library: the model fields MuJoCo Warp batches."""
NOT_SIMULATED = ("body_mass", "body_inertia", "body_ipos", "body_iquat", "body_subtreemass", "stat", "light_poscom0")
NOT_SIMULATED += ("bvh_aabb", "bvh_nodeid")
"""Fields that differ too but that no step of MuJoCo Warp reads for these worlds: the mass
and inertia of bodies without joints (the static field, the mocap obstacles), the lights,
and the C engine's mid-phase trees (MuJoCo Warp 4.0 builds none from them)."""


@dataclass(frozen=True)
class Padding:
    """The structure every world of a library is compiled to: standing cylinders, and the
    shapes of each obstacle slot."""

    n_static: int
    slots: tuple[tuple[str, ...], ...]

    @classmethod
    def covering(cls, worlds: list[WorldSpec]) -> Padding:
        n_slots = max(len(w.obstacles) for w in worlds)
        shapes = [set() for _ in range(n_slots)]
        for w in worlds:
            for k, o in enumerate(w.obstacles):
                shapes[k].add(o.shape)
        return cls(
            n_static=max(len(w.layout.cylinders) for w in worlds),
            slots=tuple(tuple(s for s in SHAPE_NAMES if s in slot) for slot in shapes),
        )


_STAND_IN_SIZE = {"cylinder": {"radius": 0.1}, "box": {"radius": 0.0, "half_length": 0.1, "half_width": 0.1}}
_STAND_IN_SIZE["capsule"] = {"radius": 0.1, "half_length": 0.1}


def padded_world(world: WorldSpec, padding: Padding) -> WorldSpec:
    """`world` in `padding`'s structure: its own cylinders and obstacles where they are,
    stand-ins named `PAD...` everywhere else (moved below the floor by `compile_padded`)."""
    still = Trajectory(times=np.array([0.0, 1.0]), xy=np.zeros((2, 2)), profile="stand-in")
    obstacles: list[Obstacle] = []
    for k, shapes in enumerate(padding.slots):
        own = world.obstacles[k] if k < len(world.obstacles) else None
        for shape in shapes:
            if own is not None and own.shape == shape:
                obstacles.append(own)
            else:
                obstacles.append(Obstacle(f"{PAD}{k:03d}_{shape}", still, shape=shape, **_STAND_IN_SIZE[shape]))
    layout = world.layout
    cylinders = layout.cylinders + ((0.0, 0.0, 0.1),) * (padding.n_static - len(layout.cylinders))
    return dataclasses.replace(
        world, obstacles=tuple(obstacles), layout=dataclasses.replace(layout, cylinders=cylinders)
    )


def compile_padded(path: Path, padded: WorldSpec, own_statics: int) -> mujoco.MjModel:
    """A padded world (`padded_world`, its own static cylinders the first `own_statics`)
    compiled by MuJoCo with the Jackal's 720 rangefinders, its stand-ins moved `BELOW` the
    floor (a field of the model, which the library batches)."""
    xml = world_to_xml(padded, world_dir=path.parent)
    model = load_model(path, beam_sensors=True, data=xml.encode())
    padded_geoms = np.zeros(model.ngeom, dtype=bool)
    for g in range(model.ngeom):
        name = model.geom(g).name
        padded_geoms[g] = name.startswith((PAD, "static_")) or model.body_mocapid[model.geom_bodyid[g]] >= 0
        if name.startswith(PAD) or (name.startswith("static_") and int(name.removeprefix("static_")) >= own_statics):
            model.geom_pos[g, 2] += BELOW
    # The compiler marks a geom placed at its body's frame, or a body whose inertia is there,
    # so that kinematics may skip its offset: true of a world's own cylinder, false of the
    # stand-in sharing its slot in another world. Every slot takes the general path (the
    # same placement, one more transform), so every world has one structure.
    model.geom_sameframe[padded_geoms] = mujoco.mjtSameFrame.mjSAMEFRAME_NONE
    model.body_sameframe[np.unique(model.geom_bodyid[padded_geoms])] = mujoco.mjtSameFrame.mjSAMEFRAME_NONE
    return model


class WorldLibrary:
    """The worlds of a Warp batch (world files, refused when reactive), padded to one
    model: `model` (the first world's, which MuJoCo Warp is given), `fields` (each
    per-world field stacked, the world first), the joined keyframes, and per world its
    goal, end behaviour and interpolation."""

    def __init__(self, world_paths: list[Path | str]):
        if not world_paths:
            raise DynabarnError("a Warp batch needs at least one world")
        self.paths = [Path(p) for p in world_paths]
        self.worlds = [open_world(p)[1] for p in self.paths]
        for path, world in zip(self.paths, self.worlds, strict=True):
            reactive = sorted({o.behavior for o in world.obstacles if o.reactive})
            if reactive:
                raise DynabarnError(
                    f"{path}: obstacles that react to the robot ({', '.join(reactive)}) are not on the Warp backend"
                )
        self.padding = Padding.covering(self.worlds)
        padded = [padded_world(w, self.padding) for w in self.worlds]
        models = [
            compile_padded(path, pw, len(w.layout.cylinders))
            for path, pw, w in zip(self.paths, padded, self.worlds, strict=True)
        ]
        self.model = models[0]
        _check_same_structure(models, self.paths)
        self.fields = {name: np.stack([getattr(m, name) for m in models]) for name in PER_WORLD_FIELDS}
        self.placed = _static_placement(models)
        self.n_obstacles = sum(len(s) for s in self.padding.slots)
        self.keys = _joined_keyframes(padded)
        self.goal = np.array([w.layout.goal[:2] for w in self.worlds], dtype=np.float32)
        self.loop = np.array([EndBehavior(w.end_behavior) is EndBehavior.LOOP for w in self.worlds], dtype=np.int32)
        self.spline = np.array(
            [Interpolation(w.interpolation) is Interpolation.SPLINE for w in self.worlds], dtype=np.int32
        )

    def __len__(self) -> int:
        return len(self.worlds)


def _static_placement(models: list[mujoco.MjModel]) -> dict[str, np.ndarray]:
    """Every geom's place in the world frame per world (MuJoCo's kinematics at the model's
    rest), stacked: MuJoCo Warp places the geoms of the world body once, when its data is
    made, so a batch world that changes worlds takes its new world's static geoms from here."""
    placed: dict[str, list] = {"geom_xpos": [], "geom_xmat": []}
    for model in models:
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        placed["geom_xpos"].append(data.geom_xpos.copy())
        placed["geom_xmat"].append(data.geom_xmat.copy())
    return {name: np.stack(rows) for name, rows in placed.items()}


def _joined_keyframes(padded: list[WorldSpec]) -> dict[str, np.ndarray] | None:
    """Every padded world's keyframe arrays end to end: world k's obstacle i at
    k * n + i, its segments' indices shifted by the keys before its world."""
    tables = [keyframes_of(w) for w in padded]
    if not tables[0].n:
        return None
    shift = np.cumsum([0] + [len(t.flat_t) for t in tables[:-1]])
    return {
        "durations": np.concatenate([t.durations for t in tables]).astype(np.float32),
        "seg_lo": np.concatenate([t.seg_lo + s for t, s in zip(tables, shift, strict=True)]).astype(np.int32),
        "seg_hi": np.concatenate([t.seg_hi + s for t, s in zip(tables, shift, strict=True)]).astype(np.int32),
        "flat_t": np.concatenate([t.flat_t for t in tables]).astype(np.float32),
        "flat_p": np.concatenate([t.flat_p for t in tables]).astype(np.float32),
        "flat_m": np.concatenate([t.flat_m for t in tables]).astype(np.float32),
    }


def _check_same_structure(models: list[mujoco.MjModel], paths: list[Path]) -> None:
    """Every compiled world has the first one's structure and differs from it only in the
    per-world fields (or in fields nothing simulated reads)."""
    first = models[0]
    allowed = set(PER_WORLD_FIELDS) | set(NOT_SIMULATED)
    sizes = ("nq", "nv", "nu", "nbody", "ngeom", "nsensor", "nsensordata", "nmocap", "njnt")
    for path, m in zip(paths[1:], models[1:], strict=True):
        for size in sizes:
            if getattr(m, size) != getattr(first, size):
                raise DynabarnError(f"{path}: padded to another {size} than the batch's first world")
        for name in dir(first):
            if name in allowed or name.startswith(("name", "text", "numeric", "tex", "mat", "_")):
                continue
            a, b = getattr(first, name), getattr(m, name)
            if isinstance(a, np.ndarray) and a.shape == getattr(b, "shape", None) and not np.array_equal(a, b):
                raise DynabarnError(f"{path}: the padded model's {name} differs from the batch's first world's")
