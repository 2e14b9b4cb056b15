"""`dynabarn-worlds`: generate, import, show and measure worlds."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from dynabarn.cli.common import (
    SET_OF_WORLD_HELP,
    WORLD_HELP,
    command,
    make_parser,
    progress_bar,
    run_command,
    subcommands,
)
from dynabarn.cli.worlds_certify import add_certify_arguments, worlds_certify
from dynabarn.cli.worlds_generate import add_generate_arguments, worlds_generate
from dynabarn.errors import DynabarnError
from dynabarn.files import file_name_part


# Over 80 lines on purpose: one parser, every subcommand's options with their help, in the order --help shows.
def build_parser() -> argparse.ArgumentParser:
    """`dynabarn-worlds`'s parser (its `--help`, and the documentation's page of the command)."""
    parser = make_parser("dynabarn-worlds", "Generate, import and inspect DynaBARN worlds.")
    # Imported once the parser exists: make_parser chose MuJoCo's OpenGL platform, which
    # MuJoCo reads when first imported (these modules import it).
    from dynabarn.provenance import WORLDS_ENV
    from dynabarn.worlds.importers import IMPORTERS

    sub = subcommands(parser)

    g = sub.add_parser(
        "generate",
        help="generate the 300 benchmark worlds (what `make worlds` runs)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    add_generate_arguments(g)

    im = sub.add_parser(
        "import", help="import worlds from another format", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    importers = IMPORTERS.loaded()  # a broken installed format is named once and left out
    im.add_argument("file", type=Path, help="file to import (e.g. ../shared/reference/dynabarn60.json)")
    im.add_argument(
        "--format",
        choices=sorted(importers),
        default="dynabarn-release",
        help="input format: " + "; ".join(f"{name}, {i.description}" for name, i in sorted(importers.items())),
    )
    im.add_argument("--out", type=Path, default=Path("imported_worlds"), help="output directory")
    im.add_argument(
        "--force",
        action="store_true",
        help="replace files in --out that its index.json does not list (by default they are never replaced)",
    )
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

    c = sub.add_parser(
        "certify",
        help="certify every world solvable or not: a space-time search against the exact schedules, its "
        "witness driven in MuJoCo; recorded in the set's index.json",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    add_certify_arguments(c)

    sh = sub.add_parser(
        "show", help="summarise a world and optionally plot it", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    sh.add_argument("world", nargs="?", default=None, help=WORLD_HELP + " (or --world)")
    sh.add_argument("--world", dest="world_option", default=None, help="the same as the positional world")
    sh.add_argument("--set", default=None, help=SET_OF_WORLD_HELP)
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
    st.add_argument(
        "--set", dest="set_options", action="append", default=[], help="a world set to compare (repeat for more)"
    )
    st.add_argument("--worlds", default=None, help="only these world ids, e.g. 0-19,200-219 (None: all)")
    st.add_argument(
        "--predict",
        default=None,
        metavar="RUNG",
        help="instead: each world's predicted success for this rung of the ladder (straight, dwa, teb, "
        "dwa@dwa_dynamic, teb@teb_dynamic, predictive, dagger, oracle_present), from the calibration shipped "
        "in dynabarn/bench/calibration.json and the world's certificate",
    )

    return parser


@command
def worlds_main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    return run_command(_WORLD_COMMANDS[args.command], args)


def _worlds_import(args: argparse.Namespace) -> int:
    from dynabarn.worlds.importers import import_worlds
    from dynabarn.worldset import PAPER_SET, write_worlds

    name = args.name if args.name is not None else file_name_part(args.file.stem)
    worlds = import_worlds(args.format, args.file, name=name, declared=args.declared_obstacles)
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
    index = write_worlds(
        worlds, args.out, meta=meta, sets=sets, progress=progress_bar("importing", len(worlds)), force=args.force
    )
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

    if (args.world is None) == (args.world_option is None):
        raise DynabarnError("name one world: dynabarn-worlds show [--set NAME] --world ID (or show ID)")
    path = resolve_world(args.world or args.world_option, args.set)
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
    for line in _certificate_lines(path):
        print(f"  {line}")
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


def _certificate_lines(path: Path) -> list[str]:
    """The world's certificates from its folder's index (`certify`), one line per protocol."""
    from dynabarn.worldset import own_certificates, read_index

    try:
        entries = read_index(path.parent)["worlds"]
    except DynabarnError:
        return []
    entry = next((e for e in entries if e.get("file") == path.name), {})
    lines = []
    for protocol, record in sorted(own_certificates(entry).items()):
        trials = record.get("trials", [])
        slack = f", the witnesses {record['slack']:.2f} s slower than in an empty arena" if "slack" in record else ""
        failed = [t for t in trials if not t.get("certified")]
        why = f"; seed {failed[0]['seed']}: {failed[0]['reason']}" if failed else ""
        lines.append(
            f"certified solvable ({protocol}): {record.get('certified_trials')} of {len(trials)} trials{slack}{why}"
        )
    return lines


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

    names = [str(f) for f in [*args.sets, *args.set_options]] or [str(worlds_dir())]
    ids = parse_ids(args.worlds)
    if args.predict is not None:
        return _predict(names, ids, args.predict)
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


def _predict(names: list[str], ids: list[int] | None, rung: str) -> int:
    """Each world's predicted success for `rung` (`bench.calibration`)."""
    import hashlib

    from dynabarn.bench.calibration import predict, read_calibration, slack_by_world
    from dynabarn.errors import unknown_choice
    from dynabarn.mjcf import read_world
    from dynabarn.world_file import world_bytes
    from dynabarn.worlds.difficulty import calibration_features
    from dynabarn.worldset import read_index, set_folder, world_set

    calibration = read_calibration()
    if rung not in calibration["rungs"]:
        raise DynabarnError(unknown_choice("calibrated rung", rung, list(calibration["rungs"])))
    fit = calibration["rungs"][rung]
    print(f"predicted success of {rung} (held-back worlds: Spearman {fit['spearman']:+.2f}, AUC {fit['auc']:.2f})")
    print(f"{'set':<24}{'world':>7}{'difficulty':>12}{'predicted':>11}")
    for name in names:
        slack = slack_by_world([read_index(set_folder(name)[0])])
        for world_id, file, difficulty in world_set(name, ids):
            data = world_bytes(Path(file))  # read once: parsed, and hashed to find its certificate
            world = read_world(file, data)
            features = calibration_features(world)
            features["slack"] = slack.get((world.name, hashlib.sha256(data).hexdigest()), float("nan"))
            print(f"{name:<24}{world_id:>7}{difficulty:>12}{predict(fit, features):>11.2f}")
    return 0


_WORLD_COMMANDS = {
    "generate": worlds_generate,
    "import": _worlds_import,
    "certify": worlds_certify,
    "show": _worlds_show,
    "stats": _worlds_stats,
}
