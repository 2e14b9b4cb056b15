"""A world file as untrusted input: read within a size bound, parsed, then checked to be
self-contained and bounded before MuJoCo sees it, or one `WorldError` line."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

from dynabarn.errors import WorldError

MAX_WORLD_BYTES = 64 * 1024 * 1024
"""Largest world file read (the 300 generated worlds are 3-25 kB; a 3,000-obstacle world is
about 5 MB)."""
_REFUSED_ELEMENTS = {"include", "plugin", "extension", "instance"}
"""MJCF elements that make MuJoCo read other files or run other code."""
WORLD_ELEMENTS = frozenset(
    {
        "mujoco", "compiler", "option", "flag", "size", "statistic", "visual", "global", "headlight", "quality",
        "map", "scale", "rgba", "default", "asset", "model", "texture", "material", "worldbody", "body", "frame",
        "geom", "site", "camera", "light", "inertial", "attach", "custom", "numeric", "text",
    }
)  # fmt: skip
"""The MJCF a world may hold: what the generator and the importers write, and harmless
neighbours. Everything else (replicate, flexcomp, composite, height fields, meshes, joints,
actuators, ...) is refused before MuJoCo compiles anything: some of it expands a few bytes
into millions of elements, and none of it belongs in a world."""
WORLD_COUNT_LIMITS = {"body": 5_000, "geom": 20_000, "numeric": 2_000, "material": 1_000, "light": 16}
"""How many of an element a world may hold (the largest shipped kind, a static BARN field,
has about 800 geoms; at most 500 moving obstacles with a numeric each)."""
MAX_TEXTURE_PIXELS = 4096 * 4096
MAX_NUMERIC_SIZE = 300_000  # 100,000 keyframes of [t, x, y]


def world_bytes(path: Path | str) -> bytes:
    """A world file's bytes, read once (what is hashed is what is parsed and compiled)."""
    path = Path(path)
    if not path.is_file():
        raise WorldError(f"world file not found: {path}")
    try:
        size = path.stat().st_size
        if size > MAX_WORLD_BYTES:
            raise WorldError(f"{path}: {size / 1e6:.0f} MB is larger than a world file can be (64 MB)")
        return path.read_bytes()
    except OSError as exc:
        raise WorldError(f"{path}: cannot read ({exc.strerror})") from None


def _parse(path: Path, data: bytes) -> ET.Element:
    try:
        root = ET.fromstring(data)
    except ET.ParseError as exc:
        raise WorldError(f"{path}: not valid XML ({exc})") from None
    if root.tag != "mujoco":
        raise WorldError(f"{path}: not an MJCF file (root element <{root.tag}>)")
    return root


def check_self_contained(path: Path, root: ET.Element) -> None:
    """A world file is data: it may name the project's Jackal (`<model name="jackal">`, which
    is always taken from this package) and nothing else outside itself. `<include>`, plugins,
    and every file reference (meshes, textures, height fields, skins, compiler folders) are
    refused with one line naming the element."""
    robots = 0
    counts: dict[str, int] = {}
    for element in root.iter():
        tag = element.tag if isinstance(element.tag, str) else "?"
        if tag in _REFUSED_ELEMENTS:
            raise WorldError(f"{path}: <{tag}> is not allowed: a world file loads nothing but itself and the Jackal")
        for attribute, value in element.attrib.items():
            if not (attribute.startswith("file") or (tag == "compiler" and attribute.endswith("dir"))):
                continue
            if tag == "model" and attribute == "file" and element.get("name") == "jackal":
                robots += 1
                continue
            raise WorldError(
                f"{path}: <{tag} {attribute}={value!r}> refers to another file; world files must be self-contained"
            )
        if tag not in WORLD_ELEMENTS:
            raise WorldError(f"{path}: <{tag}> is not allowed in a world file (bodies, geoms, lights, materials are)")
        counts[tag] = counts.get(tag, 0) + 1
        if counts[tag] > WORLD_COUNT_LIMITS.get(tag, counts[tag]):
            raise WorldError(f"{path}: more than {WORLD_COUNT_LIMITS[tag]:,} <{tag}> elements; a world holds fewer")
        _check_sizes(path, tag, element)
    if robots > 1:
        raise WorldError(f"{path}: more than one <model name='jackal'>")


def check_world_data(path: Path, data: bytes) -> None:
    """The checks every world file passes, on bytes from elsewhere (a recording's attached
    world): parsed, then self-contained and bounded, or one `WorldError`."""
    check_self_contained(path, _parse(path, data))


def _check_sizes(path: Path, tag: str, element: ET.Element) -> None:
    """Sizes MuJoCo would allocate before it could say no: a texture's pixels, a numeric's
    declared size, the offscreen buffer."""

    def number(name: str) -> float:
        try:
            return float(element.get(name, "0"))
        except ValueError:
            raise WorldError(f"{path}: <{tag} {name}={element.get(name)!r}> is not a number") from None

    if tag == "texture" and number("width") * number("height") > MAX_TEXTURE_PIXELS:
        raise WorldError(f"{path}: <texture> of {number('width'):g} x {number('height'):g} pixels is too large")
    if tag == "numeric" and number("size") > MAX_NUMERIC_SIZE:
        raise WorldError(f"{path}: <numeric size={element.get('size')}> is larger than {MAX_NUMERIC_SIZE:,}")
    if tag == "global" and max(number("offwidth"), number("offheight")) > 8192:
        raise WorldError(f"{path}: an offscreen buffer over 8192 pixels wide or high")
