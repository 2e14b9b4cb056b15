"""Command-line entry points. Each takes `argv` and returns an exit code.

Errors a person can cause (`DynabarnError`) print one line on stderr and exit 2; a
traceback appears only with `--debug`. Ctrl-C exits 130.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path

from dynabarn.errors import DynabarnError

EXIT_USAGE = 2
EXIT_INTERRUPTED = 130


def _version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("dynabarn")
    except PackageNotFoundError:  # pragma: no cover - running from a source tree
        return "0+unknown"


def _parser(prog: str, description: str) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=prog, description=description, formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}")
    p.add_argument("--debug", action="store_true", help="show full tracebacks on errors")
    return p


def _run(body: Callable[[argparse.Namespace], int], args: argparse.Namespace) -> int:
    try:
        return body(args)
    except DynabarnError as exc:
        if args.debug:
            raise
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED


def _progress(desc: str, total: int | None = None):
    from tqdm import tqdm

    return lambda it: tqdm(it, desc=desc, total=total, unit="world", disable=None, leave=False)


# -- dynabarn-worlds ---------------------------------------------------------------------


def worlds_main(argv: Sequence[str] | None = None) -> int:
    from dynabarn.mjcf import GENERATED_WORLDS
    from dynabarn.profiles import PROFILE_SETS
    from dynabarn.world import DEFAULT_BASE_SEED

    parser = _parser("dynabarn-worlds", "Generate, import and inspect DynaBARN worlds.")
    sub = parser.add_subparsers(dest="command", required=True)

    g = sub.add_parser(
        "generate",
        help="generate the 300 benchmark worlds (what `make worlds` runs)",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    g.add_argument("--out", type=Path, default=GENERATED_WORLDS, help="output directory")
    g.add_argument(
        "--seed", type=int, default=DEFAULT_BASE_SEED, help="base seed; world i uses SeedSequence([seed, i])"
    )
    g.add_argument(
        "--profiles",
        choices=sorted(PROFILE_SETS),
        default="table1",
        help="motion profile set: table1 = the paper's Table I; release2022 = measured from the 2022 release",
    )

    im = sub.add_parser(
        "import", help="import worlds from another format", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    im.add_argument("file", type=Path, help="file to import (e.g. ../shared/reference/dynabarn60.json)")
    im.add_argument("--format", choices=["dynabarn-release"], default="dynabarn-release", help="input format")
    im.add_argument("--out", type=Path, default=Path("imported_worlds"), help="output directory")
    im.add_argument(
        "--declared-obstacles",
        action="store_true",
        help="use the plugins the world files name instead of `effective_obstacles` (what Gazebo ran)",
    )

    sh = sub.add_parser(
        "show", help="summarise a world and optionally plot it", formatter_class=argparse.ArgumentDefaultsHelpFormatter
    )
    sh.add_argument("world", help="generated world id (0-299) or path of a world .xml")
    sh.add_argument("--plot", type=Path, default=None, help="write a top-down PNG of the trajectories here")

    args = parser.parse_args(argv)
    return _run(_WORLD_COMMANDS[args.command], args)


def _worlds_generate(args: argparse.Namespace) -> int:
    from dynabarn.profiles import get_profile_set
    from dynabarn.world import N_WORLDS
    from dynabarn.worldset import generate_worlds

    t0 = time.perf_counter()
    index = generate_worlds(
        get_profile_set(args.profiles), args.out, base_seed=args.seed, progress=_progress("generating", N_WORLDS)
    )
    print(f"wrote {N_WORLDS} worlds and {index} in {time.perf_counter() - t0:.1f} s")
    return 0


def _worlds_import(args: argparse.Namespace) -> int:
    from dynabarn.release import import_release, load_release_json
    from dynabarn.worldset import write_worlds

    data = load_release_json(args.file)
    worlds = import_release(data, use_effective=not args.declared_obstacles)
    sets = {
        "all": [w.world_id for w in worlds],
        "easy": [w.world_id for w in worlds if w.difficulty == "easy"],
        "medium": [w.world_id for w in worlds if w.difficulty == "medium"],
        "hard": [w.world_id for w in worlds if w.difficulty == "hard"],
    }
    meta = {"generator": "dynabarn import", "format": args.format, "source_file": args.file.name}
    index = write_worlds(worlds, args.out, meta=meta, sets=sets, progress=_progress("importing", len(worlds)))
    print(f"imported {len(worlds)} worlds into {args.out} (index {index})")
    return 0


def _worlds_show(args: argparse.Namespace) -> int:
    import numpy as np

    from dynabarn.mjcf import load_model, read_world, resolve_world

    path = resolve_world(args.world)
    world = read_world(path)
    model = load_model(path)
    print(f"{world.name}  ({path})")
    print(
        f"  difficulty {world.difficulty.value}  branch {world.count_class and world.count_class.value}"
        f"/{world.motion_class and world.motion_class.value}  profile set {world.profile_set}  seed {world.seed}"
    )
    print(
        f"  playback {world.interpolation.value}/{world.end_behavior.value}  goal {world.layout.goal}  "
        f"MuJoCo: {model.nbody} bodies, {model.nmocap} mocap, {model.nsensor} sensors"
    )
    print(f"  {'obstacle':<14}{'profile':<9}{'order':>6}{'wpts':>6}{'duration':>10}{'speed min-max':>16}")
    for o in world.obstacles:
        tr = o.trajectory
        s = tr.segment_speeds()
        print(
            f"  {o.name:<14}{tr.profile:<9}{tr.order:>6}{len(tr.times):>6}{tr.duration:>9.1f}s"
            f"{np.min(s):>9.2f}-{np.max(s):.2f}"
        )
    if args.plot:
        from dynabarn.plot import plot_world

        print(f"wrote {plot_world(world, args.plot)}")
    return 0


_WORLD_COMMANDS = {"generate": _worlds_generate, "import": _worlds_import, "show": _worlds_show}


if __name__ == "__main__":  # pragma: no cover
    sys.exit(worlds_main())
