"""`dynabarn-worlds certify SET`: every world's solvability certificate, into its index.json."""

from __future__ import annotations

import argparse
import statistics

from dynabarn.cli.common import SET_HELP, add_jobs, progress_bar, ranged
from dynabarn.errors import DynabarnError

MAX_CERTIFY_TRIALS = 100


def add_certify_arguments(c: argparse.ArgumentParser) -> None:
    """`certify`'s options, in the order `--help` shows them."""
    c.add_argument("set", nargs="?", default=None, help=SET_HELP + " (or --set)")
    c.add_argument("--set", dest="set_option", default=None, help="the same as the positional set")
    c.add_argument(
        "--protocol",
        default="barn",
        help="the protocol whose spawn, goal region and time limit the certificates hold for "
        "(a registered name or a protocol JSON file)",
    )
    c.add_argument(
        "--trials",
        type=ranged(int, 1, MAX_CERTIFY_TRIALS),
        default=10,
        help="certify the clock offsets of trial seeds 0..N-1 (those a sweep of N trials runs)",
    )
    c.add_argument("--worlds", default=None, help="only these world ids, e.g. 0-19,200-219 (None: all)")
    c.add_argument(
        "--redraw",
        action="store_true",
        help="for a tier: from its first draws, draw every world that is not certified for every trial again "
        "from the next seed of its own sequence until all are, and write the draws and certificates beside "
        "its profile (dynabarn/worlds/tier_profiles/*.certified.json, committed)",
    )
    c.add_argument(
        "--recertify",
        action="store_true",
        help="for a tier: certify its committed draws again at this resolution (--footprint, --beam, --budget) "
        "and write those certificates beside its profile in place of the old; the worlds stay the ones every "
        "committed result ran (no redraw)",
    )
    c.add_argument(
        "--verify",
        action="store_true",
        help="compute the selected worlds' certificates again and compare them with those the index holds "
        "(whether each trial is certified, the witness's arrival, the reason); write nothing; exit 1 on a "
        "difference",
    )
    c.add_argument(
        "--budget",
        type=ranged(int, 1, 10**12),
        default=None,
        metavar="STATES",
        help="stop a trial's search after it has expanded this many states without a witness and try the exact "
        "oracle's episode instead (recorded in the index; --verify uses it); default: no limit, the search runs "
        "to the time limit (in static fields that can take minutes a trial)",
    )
    c.add_argument(
        "--footprint",
        action="store_true",
        help="search with the Jackal's own rectangle at its heading against the static field, not the disc "
        "around it (resolution version 3: passages the robot drives through lengthwise are searched too; the "
        "committed sets were certified without it, at version 2); default: off",
    )
    c.add_argument(
        "--beam",
        type=ranged(int, 1, 10**9),
        default=None,
        metavar="STATES",
        help="keep at most this many states per control tick, those nearest the goal along the static map "
        "(resolution version 4: a goal-guided search that reaches through static fields within a budget, and "
        "makes no claim where it finds no witness); default: none, breadth-first",
    )
    add_jobs(c)


def worlds_certify(args: argparse.Namespace) -> int:
    from dynabarn.bench.certify import certify_set
    from dynabarn.protocol import get_protocol
    from dynabarn.sim.certificate import CertificateConfig
    from dynabarn.worldset import parse_ids, set_folder

    if (args.set is None) == (args.set_option is None):
        raise DynabarnError("name one world set: dynabarn-worlds certify --set NAME (or certify NAME)")
    args.set = args.set or args.set_option
    protocol = get_protocol(args.protocol)
    if args.recertify:
        return _recertify(args, protocol)
    if args.redraw:
        from dynabarn.bench.certify import certify_tier
        from dynabarn.worlds.tiers import TIERS

        if args.footprint or args.beam:
            raise DynabarnError(
                "--redraw keeps the tiers' draws at the disc's resolution (version 2): not with --footprint or --beam"
            )
        if args.set not in TIERS or args.worlds is not None:
            raise DynabarnError(
                f"--redraw certifies a whole tier ({', '.join(TIERS)}), not {args.set!r} or some worlds"
            )
        record = certify_tier(
            args.set,
            protocol,
            trials=args.trials,
            jobs=args.jobs,
            budget=args.budget,
            progress=progress_bar(f"certifying {args.set}"),
        )
        print(f"wrote {len(record['certificates'])} certificates, {len(record['draws'])} world(s) redrawn")
    folder, chosen = set_folder(args.set)
    ids = parse_ids(args.worlds)
    if chosen is not None:
        ids = [i for i in chosen if ids is None or i in set(ids)]
    if ids is not None:
        from dynabarn.worldset import read_index

        missing = sorted(set(ids) - {e["id"] for e in read_index(folder)["worlds"]})
        if missing:
            raise DynabarnError(f"world id(s) {missing[:5]} not in set {args.set!r}")
    total = len(ids) if ids is not None else None
    if args.verify:
        from dynabarn.bench.certify import verify_set

        differences, checked, uncertified = verify_set(
            folder, protocol, ids=ids, jobs=args.jobs, progress=progress_bar(f"verifying {args.set}", total)
        )
        for line in differences:
            print(line)
        left = f"; {uncertified} world(s) without a certificate not checked" if uncertified else ""
        print(f"{checked} trials checked against {args.set}'s index: {len(differences) or 'no'} difference(s){left}")
        return 1 if differences else 0
    index = certify_set(
        folder,
        protocol,
        trials=args.trials,
        ids=ids,
        jobs=args.jobs,
        budget=args.budget,
        config=CertificateConfig(footprint=args.footprint, beam=args.beam or 0),
        progress=progress_bar(f"certifying {args.set}", total),
    )
    entries = [e for e in index["worlds"] if ids is None or e["id"] in set(ids)]
    print_certificates(args.set, entries, protocol.name)
    return 0


def print_certificates(name: str, entries: list[dict], protocol: str) -> None:
    """The summary: certified worlds (every trial) and trials per difficulty, the witnesses'
    slack, and each world that is not certified with its first reason."""
    records = {e["id"]: (e, e["certificates"][protocol]) for e in entries if protocol in e.get("certificates", {})}
    print(f"certificates of {name} under protocol {protocol} (a world is certified when every trial is)")
    print(f"{'difficulty':<11}{'worlds':>7}{'certified':>10}{'trials':>8}{'certified':>10}{'slack s':>9}")
    for difficulty in ("easy", "medium", "hard", "all"):
        rows = [r for e, r in records.values() if difficulty in ("all", e.get("difficulty"))]
        if not rows:
            continue
        n_trials = sum(len(r["trials"]) for r in rows)
        slacks = [r["slack"] for r in rows if "slack" in r]
        slack = f"{statistics.median(slacks):>9.2f}" if slacks else f"{'-':>9}"
        print(
            f"{difficulty:<11}{len(rows):>7}{sum(r['certified'] for r in rows):>10}{n_trials:>8}"
            f"{sum(r['certified_trials'] for r in rows):>10}{slack}"
        )
    for world_id, (_, record) in sorted(records.items()):
        if not record["certified"]:
            failed = [t for t in record["trials"] if not t["certified"]]
            print(
                f"  world {world_id}: {len(failed)} of {len(record['trials'])} trials not certified "
                f"(seed {failed[0]['seed']}: {failed[0]['reason']})"
            )


def _recertify(args: argparse.Namespace, protocol) -> int:
    from dynabarn.bench.certify import recertify_tier
    from dynabarn.sim.certificate import CertificateConfig
    from dynabarn.worlds.tiers import TIERS

    if args.redraw or args.verify or args.set not in TIERS or args.worlds is not None:
        raise DynabarnError(
            f"--recertify certifies a whole tier's committed draws ({', '.join(TIERS)}), not {args.set!r}, "
            "some worlds, or with --redraw or --verify"
        )
    ids = TIERS[args.set].ids
    record = recertify_tier(
        args.set,
        protocol,
        config=CertificateConfig(footprint=args.footprint, beam=args.beam or 0),
        trials=args.trials,
        jobs=args.jobs,
        budget=args.budget,
        progress=progress_bar(f"certifying {args.set} again", len(ids)),
    )
    trials = [t for c in record["certificates"].values() for t in c[protocol.name]["trials"]]
    by_oracle = sum(t["certified"] and "by" in t for t in trials)
    by_search = sum(t["certified"] and "by" not in t for t in trials)
    print(
        f"{args.set}: {len(ids)} worlds, {len(trials)} trials: {by_search} certified by the search, "
        f"{by_oracle} by the exact oracle's episode, {len(trials) - by_search - by_oracle} not certified "
        f"(resolution version {record['certification'][protocol.name]['resolution']['version']})"
    )
    return 0
