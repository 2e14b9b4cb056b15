"""`dynabarn-worlds generate`: its options, the profile they make, and the generation."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from dynabarn.cli.common import MAX_SEED, progress_bar, ranged
from dynabarn.errors import DynabarnError
from dynabarn.files import file_name_part

DEFAULT_PROFILES = "table1"
"""The profile set `generate` draws from without --profiles or --profile-file (the paper's Table I)."""


class _Chosen(argparse.Action):
    """Stores the value and notes that it was given (`NAME_chosen`): a default is not a choice
    (`--profiles` beside `--profile-file` or `--tier` is refused; its default is not)."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        setattr(namespace, self.dest, values)
        setattr(namespace, f"{self.dest}_chosen", True)


# Over 80 lines on purpose: every option of `generate` with its help, in the order --help shows.
def add_generate_arguments(g: argparse.ArgumentParser) -> None:
    """`generate`'s options, in the order `--help` shows them."""
    from dynabarn.sim.behaviors import BEHAVIORS
    from dynabarn.worlds.generate import DEFAULT_BASE_SEED
    from dynabarn.worlds.profiles import PROFILE_SETS, SHAPE_MIXES, STATIC_FIELDS
    from dynabarn.worlds.tiers import TIERS

    g.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output directory (default: ./generated_worlds for the paper's worlds, ./mixed_worlds when "
        "--shapes, --static or --behavior is given; never into an installed package); outside the "
        "repository the folder carries the robot the worlds name, in DIR/assets/jackal/",
    )
    g.add_argument(
        "--force",
        action="store_true",
        help="replace files in --out that its index.json does not list (by default they are never replaced)",
    )
    g.add_argument(
        "--seed",
        type=ranged(int, 0, MAX_SEED),
        default=DEFAULT_BASE_SEED,
        help="base seed; world i uses SeedSequence([seed, i])",
    )
    g.add_argument(
        "--profiles",
        choices=sorted(PROFILE_SETS.loaded()),
        default=DEFAULT_PROFILES,
        action=_Chosen,
        help="motion profile set: table1 = the paper's Table I; release2022 = measured from the 2022 release "
        "(the base the options below change; not with --profile-file, which holds its own)",
    )
    g.add_argument(
        "--tier",
        choices=[*TIERS, "all"],
        default=None,
        help="generate a tier beyond the paper's hard instead (its own shipped profile, seed and the paper's "
        "60 ids), into generated_tiers/NAME unless --out says otherwise; all = every tier. `--set NAME` "
        "generates one on first use",
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
        choices=sorted(SHAPE_MIXES.loaded()),
        default=None,
        help="obstacle shapes (beyond the paper): cylinder = the paper's; mixed = cylinders, boxes and "
        "capsules in equal shares, sizes drawn per obstacle (default: the profile file's, else cylinder)",
    )
    g.add_argument(
        "--static",
        choices=["none", *sorted(STATIC_FIELDS.loaded())],
        default=None,
        help="static obstacles beside the moving ones (beyond the paper): barn-grid = a BARN-style "
        "cellular-automaton field of r 0.075 m cylinders across the arena's middle, always crossable "
        "(default: the profile file's, else none)",
    )
    behaviors = BEHAVIORS.loaded()  # a broken installed one is named once and left out
    g.add_argument(
        "--behavior",
        choices=sorted(behaviors),
        default=None,
        help="every obstacle's behaviour (beyond the paper; default: the profile file's, else scripted): "
        + "; ".join(f"{name} = {kind.summary()}" for name, kind in sorted(behaviors.items())),
    )


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

    if args.profile_file is not None and getattr(args, "profiles_chosen", False):
        raise ProfileError("--profiles and --profile-file both name the motion profiles: give one")
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


def worlds_generate(args: argparse.Namespace) -> int:
    from dynabarn.provenance import WORLDS_ENV, worlds_dir
    from dynabarn.worlds.generate import N_WORLDS
    from dynabarn.worlds.spec import SCRIPTED
    from dynabarn.worldset import generate_profile_worlds

    if args.tier is not None:
        return _generate_tiers(args)
    profile, behavior_params, custom = generation_profile(args)
    variant = profile.shapes is not None or profile.static_field is not None or profile.behavior != SCRIPTED
    default_out = f"{file_name_part(profile.profile_set.name)}_worlds" if custom else None
    out = args.out or Path(default_out or ("mixed_worlds" if variant else "generated_worlds"))
    t0 = time.perf_counter()
    index = generate_profile_worlds(
        profile,
        out,
        behavior_params=behavior_params,
        base_seed=args.seed,
        interpolation=args.interpolation,
        end_behavior=args.end,
        profile_source=profile.source if custom else None,
        progress=progress_bar("generating", N_WORLDS),
        force=args.force,
    )
    print(f"wrote {N_WORLDS} worlds and {index} in {time.perf_counter() - t0:.1f} s")
    if Path(out).resolve() != worlds_dir().resolve():
        print(f"ids (--world 137, --set paper60) refer to them with {WORLDS_ENV}={Path(out).resolve()}")
    return 0


def _generate_tiers(args: argparse.Namespace) -> int:
    from dynabarn.worlds.tiers import TIERS, get_tier
    from dynabarn.worldset.tiers import generate_tier

    variants = ("profile_file", "shapes", "static", "behavior")
    others = [name for name in (*PROFILE_OPTIONS, *variants) if getattr(args, name)]
    others += ["profiles"] if getattr(args, "profiles_chosen", False) else []
    if others:
        raise DynabarnError(f"--tier takes its profile from its own file: drop --{others[0].replace('_', '-')}")
    names = list(TIERS) if args.tier == "all" else [args.tier]
    if args.out is not None and len(names) > 1:
        raise DynabarnError("--tier all writes each tier to its own folder: drop --out")
    for tier in map(get_tier, names):  # resolved once, then handed on
        t0 = time.perf_counter()
        index = generate_tier(tier, args.out, progress=progress_bar(f"generating {tier.name}", len(tier.ids)))
        print(f"wrote {len(tier.ids)} worlds of {tier.name} and {index} in {time.perf_counter() - t0:.1f} s")
    return 0
