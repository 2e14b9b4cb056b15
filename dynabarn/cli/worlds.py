"""`dynabarn-worlds`: generate, import, show and measure worlds."""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    MAX_SEED,
    WORLD_HELP,
    command,
    make_parser,
    progress_bar,
    ranged,
    run_command,
    subcommands,
)
from dynabarn.errors import DynabarnError, ImportFormatError
from dynabarn.files import file_name_part


# Over 80 lines on purpose: the declarations of the four subcommands' options, one after
# the other, as `--help` shows them.
def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-worlds`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser("dynabarn-worlds", "Generate, import and inspect DynaBARN worlds.")
    # Imported once the parser exists: make_parser chose MuJoCo's OpenGL platform, which
    # MuJoCo reads when first imported (these modules import it).
    from dynabarn.provenance import WORLDS_ENV
    from dynabarn.sim.behaviors import available_behaviors, get_behavior
    from dynabarn.worlds.generate import DEFAULT_BASE_SEED
    from dynabarn.worlds.profiles import PROFILE_SETS, SHAPE_MIXES, STATIC_FIELDS

    sub = subcommands(parser)

    g = sub.add_parser(
        "generate",
        help="generate the 300 benchmark worlds (what `make worlds` runs)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    g.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output directory (default: ./generated_worlds for the paper's worlds, ./mixed_worlds when "
        "--shapes, --static or --behavior is given; never into an installed package); outside the "
        "repository the folder carries the robot the worlds name, in DIR/assets/jackal/",
    )
    g.add_argument(
        "--seed",
        type=ranged(int, 0, MAX_SEED),
        default=DEFAULT_BASE_SEED,
        help="base seed; world i uses SeedSequence([seed, i])",
    )
    g.add_argument(
        "--profiles",
        choices=PROFILE_SETS.names(),
        default="table1",
        help="motion profile set: table1 = the paper's Table I; release2022 = measured from the 2022 release "
        "(the base the options below change; not used with --profile-file)",
    )
    g.add_argument(
        "--profile-file",
        type=Path,
        default=None,
        help="your own profile (TOML or JSON): each motion branch's profiles (order, speed and std "
        "ranges), Fig. 2's count ranges, optionally shapes, a static field and a behaviour; see the "
        "tutorial 'Motion profiles of your own'",
    )
    g.add_argument("--profile-name", default=None, help="name of the profile set (default: the file's or the base's)")
    for branch in ("easy", "hard"):
        for key, unit in (("order", "polynomial order, whole numbers"), ("speed", "m/s"), ("std", "m/s")):
            g.add_argument(
                f"--{branch}-{key}",
                metavar="MIN,MAX",
                default=None,
                help=f"{key} range ({unit}) of every profile of Fig. 2's {branch} motion branch "
                "(default: the profile file's, else --profiles')",
            )
    for branch in ("low", "high"):
        g.add_argument(
            f"--{branch}-count",
            metavar="MIN,MAX",
            default=None,
            help=f"obstacle count range of Fig. 2's {branch} branch (default: the profile file's, else 5,9 / 10,19)",
        )
    g.add_argument(
        "--waypoints",
        choices=["integer", "release"],
        default=None,
        help="where waypoints lie along each path: integer = every integer x (the paper); release = as "
        "the 2022 release (default: the profile file's, else --profiles')",
    )
    g.add_argument(
        "--interpolation",
        choices=["linear", "spline"],
        default="linear",
        help="playback between waypoints: linear (the paper) or spline (Gazebo's PoseAnimation)",
    )
    g.add_argument("--end", choices=["loop", "hold"], default="loop", help="after the last waypoint")
    g.add_argument(
        "--shapes",
        choices=SHAPE_MIXES.names(),
        default=None,
        help="obstacle shapes (beyond the paper): cylinder = the paper's; mixed = cylinders, boxes and "
        "capsules in equal shares, sizes drawn per obstacle (default: the profile file's, else cylinder)",
    )
    g.add_argument(
        "--static",
        choices=["none", *STATIC_FIELDS.names()],
        default=None,
        help="static obstacles beside the moving ones (beyond the paper): barn-grid = a BARN-style "
        "cellular-automaton field of r 0.075 m cylinders across the arena's middle, always crossable "
        "(default: the profile file's, else none)",
    )
    g.add_argument(
        "--behavior",
        choices=available_behaviors(),
        default=None,
        help="every obstacle's behaviour (beyond the paper; default: the profile file's, else scripted): "
        + "; ".join(f"{name} = {get_behavior(name).summary()}" for name in available_behaviors()),
    )

    im = sub.add_parser(
        "import", help="import worlds from another format", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    im.add_argument("file", type=Path, help="file to import (e.g. ../shared/reference/dynabarn60.json)")
    im.add_argument(
        "--format",
        choices=["dynabarn-release", "barn-static"],
        default="dynabarn-release",
        help="input format: the DynaBARN release's 60 worlds, or the 300 static BARN worlds",
    )
    im.add_argument("--out", type=Path, default=Path("imported_worlds"), help="output directory")
    im.add_argument(
        "--name",
        default=None,
        help="the set's name (a letter, then letters, digits, _ or -), the start of every world's name (<name>_<id>), "
        "so two imported sets never collide in a results table (default: the file's name without .json)",
    )
    im.add_argument(
        "--declared-obstacles",
        action="store_true",
        help="use the plugins the world files name instead of `effective_obstacles` (what Gazebo ran)",
    )

    sh = sub.add_parser(
        "show", help="summarise a world and optionally plot it", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    sh.add_argument("world", help=WORLD_HELP)
    sh.add_argument("--plot", type=Path, default=None, help="write a top-down PNG of the trajectories here")

    st = sub.add_parser(
        "stats",
        help="per-difficulty means of world sets' measured difficulty and obstacle motion, side by side",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    st.add_argument(
        "sets",
        nargs="*",
        default=[],
        help="world sets to compare side by side: paper60, dynabarn300, or folders with index.json "
        f"(default: ${WORLDS_ENV}, else the shipped 300 worlds)",
    )
    st.add_argument("--worlds", default=None, help="only these world ids, e.g. 0-19,200-219 (None: all)")

    return parser


@command
def worlds_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_command(_WORLD_COMMANDS[args.command], args)


PROFILE_OPTIONS = (
    "easy_order",
    "easy_speed",
    "easy_std",
    "hard_order",
    "hard_speed",
    "hard_std",
    "low_count",
    "high_count",
    "waypoints",
    "profile_name",
)
"""Options that change the motion profiles or counts: with any, the set is a profile of its own."""


def generation_profile(args: argparse.Namespace):
    """The `GenerationProfile` `generate` draws from: --profile-file, else --profiles, changed by
    the options; every value checked where a profile file's is (one line, exit 2)."""
    from dynabarn.errors import ProfileError
    from dynabarn.sim.behaviors import available_behaviors, get_behavior
    from dynabarn.worlds.profile_file import load_profile_data, profile_from_dict
    from dynabarn.worlds.profiles import get_profile_set

    if args.profile_file is not None:
        data, source = load_profile_data(args.profile_file)
        where = f"{args.profile_file}: "
    else:
        data, source, where = get_profile_set(args.profiles).to_dict(), {"profiles": args.profiles}, ""
    changed = [name for name in PROFILE_OPTIONS if getattr(args, name) is not None]
    data = dict(data)
    for branch in ("easy", "hard"):
        for key in ("order", "speed", "std"):
            value = getattr(args, f"{branch}_{key}")
            if value is not None:
                pair = _pair_option(f"--{branch}-{key}", value)
                data[f"{branch}_motion"] = [dict(p, **{key: pair}) for p in data.get(f"{branch}_motion", [])]
    for branch in ("low", "high"):
        value = getattr(args, f"{branch}_count")
        if value is not None:
            data[f"{branch}_count"] = _pair_option(f"--{branch}-count", value)
    for option, key in (("waypoints", "waypoints"), ("profile_name", "name"), ("shapes", "shapes")):
        if getattr(args, option) is not None:
            data[key] = getattr(args, option)
    if args.static is not None:
        data["static"] = args.static
    if args.behavior is not None:
        data["behavior"] = args.behavior
    if changed:
        source = {**source, "options": {name: getattr(args, name) for name in changed}}
        if args.profile_name is None and args.profile_file is None:
            data["name"] = f"{args.profiles}-custom"  # never mistaken for the shipped set of that name
    try:
        profile = profile_from_dict(data, default_name=args.profiles, source=source)
    except ProfileError as exc:
        raise ProfileError(f"{where}{exc}") from None
    if profile.behavior not in available_behaviors():
        raise ProfileError(f"{where}behavior {profile.behavior!r}: not one of {', '.join(available_behaviors())}")
    defaults = get_behavior(profile.behavior).defaults()
    unknown = sorted(set(profile.behavior_params) - set(defaults))
    if unknown:
        raise ProfileError(f"{where}behavior.params: {profile.behavior} has no parameter {unknown[0]!r}")
    custom = args.profile_file is not None or bool(changed)
    return profile, defaults | profile.behavior_params, custom


def _pair_option(option: str, value: str) -> list[float]:
    from dynabarn.errors import ProfileError

    parts = value.split(",")
    try:
        if len(parts) != 2:
            raise ValueError
        return [float(p) for p in parts]
    except ValueError:
        raise ProfileError(f"{option} {value!r}: expected MIN,MAX (two numbers)") from None


def _worlds_generate(args: argparse.Namespace) -> int:
    from dynabarn.provenance import WORLDS_ENV, worlds_dir
    from dynabarn.worlds.generate import N_WORLDS
    from dynabarn.worldset import generate_worlds

    profile, behavior_params, custom = generation_profile(args)
    variant = profile.shapes is not None or profile.static_field is not None or profile.behavior != "scripted"
    default_out = f"{file_name_part(profile.profile_set.name)}_worlds" if custom else None
    out = args.out or Path(default_out or ("mixed_worlds" if variant else "generated_worlds"))
    t0 = time.perf_counter()
    index = generate_worlds(
        profile.profile_set,
        out,
        base_seed=args.seed,
        interpolation=args.interpolation,
        end_behavior=args.end,
        shapes=profile.shapes,
        static_field=profile.static_field,
        behavior=profile.behavior,
        behavior_params=behavior_params,
        profile_source=profile.source if custom else None,
        progress=progress_bar("generating", N_WORLDS),
    )
    print(f"wrote {N_WORLDS} worlds and {index} in {time.perf_counter() - t0:.1f} s")
    if Path(out).resolve() != worlds_dir().resolve():
        print(f"ids (--world 137, --set paper60) refer to them with {WORLDS_ENV}={Path(out).resolve()}")
    return 0


def _worlds_import(args: argparse.Namespace) -> int:
    from dynabarn.worldset import PAPER_SET, write_worlds

    name = args.name if args.name is not None else file_name_part(args.file.stem)
    if args.format == "barn-static":
        from dynabarn.worlds.importers.barn import import_barn_static, load_barn_json

        worlds = import_barn_static(load_barn_json(args.file), name=name)
    else:
        from dynabarn.worlds.importers.release import import_release, load_release_json

        data = load_release_json(args.file)
        try:
            worlds = import_release(data, name=name, use_effective=not args.declared_obstacles)
        except ImportFormatError as exc:
            raise ImportFormatError(f"{args.file}:\n  " + str(exc).replace("\n", "\n  ")) from None
    sets = {
        "all": [w.world_id for w in worlds],
        "easy": [w.world_id for w in worlds if w.difficulty == "easy"],
        "medium": [w.world_id for w in worlds if w.difficulty == "medium"],
        "hard": [w.world_id for w in worlds if w.difficulty == "hard"],
    }
    paper = [w.world_id for w in worlds if (w.provenance or {}).get("paper_set")]
    if paper:
        sets[PAPER_SET] = paper
    meta = {"generator": "dynabarn import", "source_format": args.format, "source_file": args.file.name}
    index = write_worlds(worlds, args.out, meta=meta, sets=sets, progress=progress_bar("importing", len(worlds)))
    print(f"imported {len(worlds)} worlds into {args.out} (index {index})")
    for line in count_notes(worlds):
        print(f"note: {line}")
    return 0


def count_notes(worlds) -> list[str]:
    """One line per count class outside the paper's low (5-9) and high (10-19) branches."""
    from dynabarn.worlds.profiles import CountClass

    notes = []
    for cls, what in ((CountClass.BELOW_LOW, "fewer than 5"), (CountClass.ABOVE_HIGH, "more than 19")):
        outside = [w for w in worlds if w.count_class is cls]
        if outside:
            counts = sorted({len(w.obstacles) for w in outside})
            notes.append(
                f"{len(outside)} world(s) with {what} obstacles ({', '.join(map(str, counts))}): count class "
                f"{cls.value}, outside the paper's branches (Fig. 2 difficulty as the nearer branch)"
            )
    return notes


def _worlds_show(args: argparse.Namespace) -> int:
    import numpy as np

    from dynabarn.mjcf import load_model, read_world
    from dynabarn.sim import Simulation
    from dynabarn.worldset import resolve_world

    path = resolve_world(args.world)
    world = read_world(path)
    model = load_model(path)
    Simulation(path)  # what `dynabarn-run` refuses (e.g. an obstacle without its body), this does too
    print(f"{world.name}  ({path})")
    print(
        f"  difficulty {world.difficulty.value}  branch {world.count_class and world.count_class.value}"
        f"/{world.motion_class and world.motion_class.value}  profile set {world.profile_set}  seed {world.seed}"
    )
    print(
        f"  playback {world.interpolation.value}/{world.end_behavior.value}  goal {world.layout.goal}  "
        f"MuJoCo: {model.nbody} bodies, {model.nmocap} mocap, {model.nsensor} sensors"
    )
    if world.layout.cylinders:
        print(f"  static cylinders: {len(world.layout.cylinders)}")
    for line in count_notes([world]):
        print(f"  note: {line}")
    provenance = world.provenance or {}
    if provenance.get("source_file"):
        paper = "one of the paper's" if provenance.get("paper_set") else "not one of the paper's worlds"
        print(
            f"  imported from {provenance['source_file']} (sha256 {str(provenance.get('source_sha256'))[:12]}...), "
            f"set {provenance.get('set')}, {paper}; recommended protocol {provenance.get('recommended_protocol')}"
        )
    print(
        f"  {'obstacle':<14}{'profile':<9}{'order':>6}{'wpts':>6}{'duration':>10}{'speed min-max':>16}"
        f"  {'shape':<26}{'behavior'}"
    )
    for o in world.obstacles:
        tr = o.trajectory
        s = tr.segment_speeds()
        size = {
            "cylinder": f"cylinder r {o.radius:.2f}",
            "box": f"box {2 * o.half_length:.2f} x {2 * o.half_width:.2f}",
            "capsule": f"capsule r {o.radius:.2f} l {2 * o.half_length:.2f}",
        }[o.shape]
        print(
            f"  {o.name:<14}{tr.profile:<9}{tr.order:>6}{len(tr.times):>6}{tr.duration:>9.1f}s"
            f"{np.min(s):>9.2f}-{np.max(s):.2f}  {size:<26}{o.behavior}"
        )
    if args.plot:
        from dynabarn.worlds.plot import plot_world

        if args.plot.suffix.lower() not in (".png", ".pdf", ".svg"):
            raise DynabarnError(f"--plot {args.plot}: use a .png, .pdf or .svg file name")

        print(f"wrote {plot_world(world, args.plot)}")
    return 0


STATS_COLUMNS = (
    ("obstacles", "obst", 5, 1),
    ("outside", "outside", 8, 0),
    ("static", "static", 7, 0),
    ("corridor_blocked", "blocked", 8, 2),
    ("corridor_occupancy", "occup.", 7, 2),
    ("crossings_per_minute", "cross/min", 10, 1),
    ("time_in_corridor", "in corr.", 9, 3),
    ("speed", "speed", 6, 2),
    ("loop_duration", "loop s", 7, 1),
    ("y_span", "y span", 7, 1),
    ("y_zero_crossings", "y=0 x", 6, 1),
)
"""(measure, title, width, digits); `outside`: worlds whose count is outside the paper's 5-19."""


def _set_measures(name: str, ids: list[int] | None) -> dict[str, list[dict]]:
    """Per difficulty, each world's obstacle counts and measured difficulty."""
    from dynabarn.mjcf import read_world
    from dynabarn.worlds.difficulty import world_measures
    from dynabarn.worlds.profiles import CountClass
    from dynabarn.worldset import world_set

    rows: dict[str, list[dict]] = {}
    chosen = world_set(name, ids)
    for _, file, difficulty in progress_bar(f"measuring {name}", len(chosen))(chosen):
        world = read_world(file)
        row = {"obstacles": len(world.obstacles), "static": len(world.layout.cylinders)}
        row["outside"] = world.count_class in (CountClass.BELOW_LOW, CountClass.ABOVE_HIGH)
        row |= world_measures(world)
        rows.setdefault(difficulty, []).append(row)
    return rows


def _worlds_stats(args: argparse.Namespace) -> int:
    import numpy as np

    from dynabarn.provenance import worlds_dir
    from dynabarn.worldset import parse_ids

    names = [str(f) for f in args.sets] or [str(worlds_dir())]
    ids = parse_ids(args.worlds)
    measured = {name: _set_measures(name, ids) for name in names}
    width = max(11, *(len(n) + 2 for n in names))
    print(
        "means per difficulty (difficulty from the schedules over 60 s; motion per obstacle; "
        "outside: worlds with fewer than 5 or more than 19 obstacles)"
    )
    head = f"{'difficulty':<11}{'set':<{width}}{'worlds':>7}"
    print(head + "".join(f"{title:>{w}}" for _, title, w, _ in STATS_COLUMNS))
    for difficulty in ("easy", "medium", "hard"):
        for k, name in enumerate(names):
            rs = measured[name].get(difficulty, [])
            if not rs:
                continue
            cells = "".join(
                f"{(np.sum if key == 'outside' else np.mean)([r.get(key, np.nan) for r in rs]):>{w}.{digits}f}"
                for key, _, w, digits in STATS_COLUMNS
            )
            label = difficulty if k == 0 or not measured[names[0]].get(difficulty) else ""
            print(f"{label:<11}{name:<{width}}{len(rs):>7}" + cells)
    return 0


_WORLD_COMMANDS = {
    "generate": _worlds_generate,
    "import": _worlds_import,
    "show": _worlds_show,
    "stats": _worlds_stats,
}
