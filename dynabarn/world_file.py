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
WORLD_COUNT_LIMITS = {
    "body": 5_000, "geom": 20_000, "numeric": 2_000, "material": 1_000, "light": 16, "frame": 5_000,
    "inertial": 5_000, "site": 5_000, "camera": 64, "texture": 64, "default": 1_000, "text": 64, "attach": 4,
    "model": 4, "custom": 4,
}  # fmt: skip
"""How many of an element a world may hold (the largest shipped kind, a static BARN field,
has about 800 geoms; at most 500 moving obstacles with a numeric each); every element kind
MuJoCo allocates is counted (500,000 `<site>` in 22 MB compiled for minutes)."""
DEFAULT_COUNT_LIMIT = 16
"""Any other kind a world may hold (`option`, `visual`'s children, ...): a few of each."""
MAX_ELEMENTS = 50_000
"""Elements of every kind together."""
MAX_DEPTH = 64
"""Nesting depth of the document (the generated worlds nest 4 deep): checked before anything
recurses over it (writing it out anew, MuJoCo's parser), so 990 nested `<frame>`s are one
line, not a RecursionError."""
NUMERIC_ATTRIBUTES = frozenset(
    {
        "pos", "size", "quat", "euler", "axisangle", "xyaxes", "zaxis", "fromto", "rgba", "gravity", "wind",
        "magnetic", "density", "viscosity", "timestep", "iterations", "ls_iterations", "noslip_iterations",
        "ccd_iterations", "impratio", "tolerance", "ls_tolerance", "mass", "diaginertia", "fullinertia", "friction",
        "solref", "solimp", "margin", "gap", "priority", "condim", "width", "height", "specular", "shininess",
        "reflectance", "emission", "diffuse", "ambient", "dir", "attenuation", "cutoff", "exponent", "fovy",
        "ipd", "extent", "meaninertia", "meanmass", "meansize", "center", "znear", "zfar", "haze",
        "fogstart", "fogend", "o_margin", "o_solref", "o_solimp", "o_friction", "texrepeat", "offwidth",
        "offheight", "shadowsize", "offsamples", "numslices", "numstacks", "numquads", "framelength",
        "framewidth", "forcewidth", "contactwidth", "contactheight", "connect", "com", "selectpoint", "light",
        "jointlength", "jointwidth", "actuatorlength", "actuatorwidth", "slidercrank", "constraint",
        "bvh_depth", "range", "rgb1", "rgb2", "markrgb", "random", "builtin_size", "group", "user",
    }
)  # fmt: skip
"""Attributes whose value is numbers: each must be finite and within `MAX_MAGNITUDE`
(a `<numeric>`'s data are keyframes, checked as such with the world's schedule)."""
MAX_MAGNITUDE = 1e6
"""Largest magnitude of any number in a world's attributes (the arena is 20 m; 1e308 or inf
sizes made MuJoCo's bounding volumes and the recording's scene meaningless)."""
OPTION_RANGES = {"timestep": (1e-5, 0.1), "iterations": (1, 1000), "ls_iterations": (1, 1000)}
"""`<option>` values with their own physical range (a negative time step, 1e9 iterations)."""
MAX_TEXTURE_PIXELS = 4096 * 4096
MAX_TEXTURE_PIXELS_TOTAL = 2 * MAX_TEXTURE_PIXELS
"""All of a world's textures together (each is allocated at 3-4 bytes a pixel, and more in
the renderer): 60 textures of the largest size each would take gigabytes."""
MAX_NUMERIC_TOTAL = 8_000_000
"""Numbers in all of a world's `<numeric>` elements together (8 bytes each in MuJoCo; what
a 64 MiB file can hold, where a declared `size` would otherwise allocate without bound)."""
MAX_NUMERIC_SIZE = 300_000  # 100,000 keyframes of [t, x, y]


def world_sha256(path: Path | str) -> str | None:
    """sha256 of a world file as it is on disk, read in 1 MiB pieces and never through a link
    at `path` (`files.open_plain`): a sparse 40 GB file is refused by its size, never read
    whole. None when it is over `MAX_WORLD_BYTES` or not a regular file; OSError when it
    cannot be opened."""
    import errno
    import hashlib
    import os

    from dynabarn.files import open_plain

    try:
        fd = open_plain(path, os.O_RDONLY)
    except OSError as exc:
        if exc.errno == errno.EPERM:  # a link, a device, a FIFO
            return None
        raise
    with os.fdopen(fd, "rb") as f:
        if os.fstat(fd).st_size > MAX_WORLD_BYTES:
            return None
        digest, read = hashlib.sha256(), 0
        while piece := f.read(1 << 20):
            read += len(piece)
            if read > MAX_WORLD_BYTES:
                return None
            digest.update(piece)
    return digest.hexdigest()


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


def parse_xml(path: Path, data: bytes) -> ET.Element:
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
    _check_depth(path, root)
    robots = 0
    counts: dict[str, int] = {}
    totals = {"texture": 0.0, "numeric": 0.0}
    for total, element in enumerate(root.iter(), start=1):
        if total > MAX_ELEMENTS:
            raise WorldError(f"{path}: more than {MAX_ELEMENTS:,} elements; a world holds fewer")
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
        limit = WORLD_COUNT_LIMITS.get(tag, DEFAULT_COUNT_LIMIT)
        if counts[tag] > limit:
            raise WorldError(f"{path}: more than {limit:,} <{tag}> elements; a world holds fewer")
        _check_numbers(path, tag, element)
        _check_sizes(path, tag, element, totals)
    if robots > 1:
        raise WorldError(f"{path}: more than one <model name='jackal'>")


def check_world_data(path: Path, data: bytes) -> None:
    """The checks every world file passes, on bytes from elsewhere (a recording's attached
    world): parsed, then self-contained and bounded, or one `WorldError`."""
    check_self_contained(path, parse_xml(path, data))


def _check_depth(path: Path, root: ET.Element) -> None:
    """No deeper than `MAX_DEPTH`, found without recursion."""
    stack = [(root, 1)]
    while stack:
        element, depth = stack.pop()
        if depth > MAX_DEPTH:
            raise WorldError(f"{path}: elements nested more than {MAX_DEPTH} deep; a world nests a few levels")
        stack.extend((child, depth + 1) for child in element)


def _check_numbers(path: Path, tag: str, element: ET.Element) -> None:
    """Every number attribute finite and within `MAX_MAGNITUDE`; `<option>`'s within their
    physical range (`OPTION_RANGES`). Words where numbers go are left to MuJoCo, which says so."""
    for attribute, value in element.attrib.items():
        if attribute not in NUMERIC_ATTRIBUTES:
            continue
        for token in value.split():
            try:
                number = float(token)
            except ValueError:
                continue
            if not abs(number) <= MAX_MAGNITUDE:  # also NaN
                raise WorldError(
                    f"{path}: <{tag} {attribute}={value[:60]!r}> holds {token[:24]!r}: numbers in a world are finite, "
                    f"within {MAX_MAGNITUDE:g}"
                )
            if tag == "option" and attribute in OPTION_RANGES:
                low, high = OPTION_RANGES[attribute]
                if not low <= number <= high:
                    raise WorldError(f"{path}: <option {attribute}={value!r}> is not in [{low:g}, {high:g}]")


def _check_sizes(path: Path, tag: str, element: ET.Element, totals: dict[str, float]) -> None:
    """Sizes MuJoCo would allocate before it could say no: a texture's pixels, a numeric's
    declared size, the offscreen buffer; and the textures' and numerics' sums (`totals`,
    added to here)."""

    def number(name: str) -> float:
        try:
            return float(element.get(name, "0"))
        except ValueError:
            raise WorldError(f"{path}: <{tag} {name}={element.get(name)!r}> is not a number") from None

    if tag == "texture":
        pixels = number("width") * number("height")
        if pixels > MAX_TEXTURE_PIXELS:
            raise WorldError(f"{path}: <texture> of {number('width'):g} x {number('height'):g} pixels is too large")
        totals["texture"] += max(pixels, 0.0)
        if totals["texture"] > MAX_TEXTURE_PIXELS_TOTAL:
            raise WorldError(
                f"{path}: textures of more than {MAX_TEXTURE_PIXELS_TOTAL:,} pixels in all; a world needs far fewer"
            )
    if tag == "numeric":
        size = max(number("size"), float(len(element.get("data", "").split())))
        if size > MAX_NUMERIC_SIZE:
            raise WorldError(f"{path}: <numeric size={element.get('size')}> is larger than {MAX_NUMERIC_SIZE:,}")
        totals["numeric"] += size
        if totals["numeric"] > MAX_NUMERIC_TOTAL:
            raise WorldError(f"{path}: <numeric> data of more than {MAX_NUMERIC_TOTAL:,} numbers in all")
    if tag == "global" and max(number("offwidth"), number("offheight")) > 8192:
        raise WorldError(f"{path}: an offscreen buffer over 8192 pixels wide or high")
