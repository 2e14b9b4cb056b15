"""The certificates' tables (issue 43): how many worlds of each set are certified solvable,
and each rung's success over the certified episodes beside its success over all.

Certificates come from the sets' index.json (`dynabarn-worlds certify`): the shipped 300
worlds' (`generated_worlds/index.json`), the tiers' committed records
(`dynabarn/worlds/tier_profiles/*.certified.json`) and, for sets that are not part of the
repository (the release's 60, imported from reference data), their certificates alone in
`results/certificates/NAME.json` (`python benchmarks/certified_tables.py --export DIR NAME`).
A certificate belongs to the world file with its sha256: a results folder's worlds are
matched by name and sha256 (its worlds.json).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

from dynabarn.bench.summary import certified_success

ROOT = Path(__file__).resolve().parents[1]
RESULTS_DIR = ROOT / "results"
CERTIFICATES_DIR = RESULTS_DIR / "certificates"
PROTOCOL = "barn"


def _entries_of(index: dict) -> list[dict]:
    from dynabarn.worldset import own_certificates

    return [
        {"name": e.get("name"), "id": e["id"], "difficulty": e.get("difficulty"), "sha256": e.get("sha256")}
        | ({"certificates": own_certificates(e)} if own_certificates(e) else {})
        for e in index["worlds"]
    ]


def certified_sets() -> dict[str, list[dict]]:
    """Set title -> its worlds with their certificates (name, id, difficulty, sha256)."""
    from dynabarn.worlds.tiers import TIERS

    sets: dict[str, list[dict]] = {}
    shipped = json.loads((ROOT / "generated_worlds" / "index.json").read_text())
    worlds = _entries_of(shipped)
    paper = set(shipped["sets"]["paper60"])
    sets["paper60"] = [w for w in worlds if w["id"] in paper]
    sets["unseen 240"] = [w for w in worlds if w["id"] not in paper]
    for path in sorted(CERTIFICATES_DIR.glob("*.json")):
        sets[path.stem.replace("original60", "original 60")] = json.loads(path.read_text())["worlds"]
    for name, tier in TIERS.items():
        record = tier.certified()
        if record:
            sets[name] = [
                {"name": f"world_{int(i):03d}", "id": int(i), "certificates": c}
                for i, c in sorted(record["certificates"].items(), key=lambda kv: int(kv[0]))
            ]
    return sets


def certified_map(worlds_json: Path, sets: dict[str, list[dict]]) -> dict:
    """A results folder's (world name, protocol) -> (certified seeds, certified-or-not seeds)."""
    known = {(w["name"], w.get("sha256")): w["certificates"] for ws in sets.values() for w in ws if "certificates" in w}
    out = {}
    for w in json.loads(worlds_json.read_text())["worlds"] if worlds_json.is_file() else []:
        for protocol, record in known.get((w["name"], w.get("sha256")), {}).items():
            trials = record.get("trials", [])
            out[(w["name"], protocol)] = ({t["seed"] for t in trials if t["certified"]}, {t["seed"] for t in trials})
    return out


def _kind(reason: str) -> str:
    """A reason without its numbers: what kind of failure it is."""
    if reason.startswith("the spawn"):
        return "the spawn inside the margin at the start"
    if reason.startswith("no collision-free motion beyond t = "):
        t = float(reason.rsplit("= ", 1)[1].split()[0])
        return "no way on within the first 2 s" if t < 2.0 else "no way on later"
    return reason


VERSIONS = {2: "the disc, breadth-first", 3: "the footprint, breadth-first", 4: "goal-guided"}
"""What each version of the search's resolution is, in a few words (`CertificateConfig`)."""


def certification_table(sets: dict[str, list[dict]]) -> str:
    """Per set: worlds certified for every trial, trials certified, the witnesses' slack,
    and the worlds that are not certified with what stopped their trials."""
    lines = [
        "| worlds | search version | certified (every trial) | trials certified "
        "| by the search / by the oracle's episode | witness slack, median [s] | not certified |",
        "|---|---|---|---|---|---|---|",
    ]
    for title, worlds in sets.items():
        records = [(w, w["certificates"][PROTOCOL]) for w in worlds if PROTOCOL in w.get("certificates", {})]
        if not records:
            continue
        trials = [t for _, r in records for t in r["trials"]]
        slack = [r["slack"] for _, r in records if "slack" in r]
        failed = [w["id"] for w, r in records if not r["certified"]]
        kinds: dict[str, int] = {}
        for t in trials:
            if not t["certified"]:
                kinds[_kind(t["reason"])] = kinds.get(_kind(t["reason"]), 0) + 1
        why = "; ".join(f"{n} trials: {k}" for k, n in sorted(kinds.items(), key=lambda kv: -kv[1]))
        not_certified = f"worlds {', '.join(map(str, failed))} ({why})" if failed else "-"
        by_oracle = sum(1 for t in trials if t["certified"] and t.get("by"))
        by_search = sum(t["certified"] for t in trials) - by_oracle
        versions = sorted({r.get("resolution_version", 2) for _, r in records})
        version = ", ".join(f"{v} ({VERSIONS[v]})" if v in VERSIONS else str(v) for v in versions)
        lines.append(
            f"| {title} | {version} | {sum(r['certified'] for _, r in records)} of {len(records)} "
            f"| {sum(t['certified'] for t in trials)} of {len(trials)} | {by_search} / {by_oracle} "
            f"| {statistics.median(slack) if slack else float('nan'):.2f} | {not_certified} |"
        )
    return "\n".join(lines)


def certified_ladder(folders: dict, sets: dict[str, list[dict]], titles: dict[str, str], ladder) -> str:
    """Each rung's success over all episodes and over the certified ones, per world set."""
    lines = [
        "| rung | worlds | episodes | success, all | certified episodes | success on certified [95% CI] |",
        "|---|---|---|---|---|---|",
    ]
    for planner, _, what in ladder:
        for folder, title in titles.items():
            rows = [r for r in folders.get(folder, ([], []))[0] if r["planner"] == planner]
            if not rows:
                continue
            certified = certified_map(RESULTS_DIR / folder / "worlds.json", sets)
            c = certified_success(rows, certified)
            if c["certified_episodes"] is None:
                continue
            success = sum(r["outcome"] == "success" for r in rows) / len(rows)
            on = "-"
            if c["success_certified"] is not None:
                on = f"{c['success_certified']:.2f} [{c['certified_lo']:.2f}, {c['certified_hi']:.2f}]"
            lines.append(
                f"| {what} (`{planner}`) | {title} | {len(rows)} | {success:.2f} "
                f"| {c['certified_episodes']} of {c['certificate_known']} | {on} |"
            )
    return "\n".join(lines)


def calibration_table() -> str:
    """Each rung's calibration on the held-back worlds (`dynabarn/bench/calibration.json`)."""
    from dynabarn.bench.calibration import CALIBRATION_FILE, RUNGS

    if not CALIBRATION_FILE.is_file():
        return "(no calibration)"
    calibration = json.loads(CALIBRATION_FILE.read_text())
    lines = [
        "| rung | worlds | held back | success, held back | Spearman (predicted difficulty, success) "
        "| its ceiling (success rates tie) | AUC | Spearman (crossings per minute, success) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for rung in (r for r in RUNGS if r in calibration["rungs"]):
        fit = calibration["rungs"][rung]
        lines.append(
            f"| `{rung}` | {fit['worlds']} | {fit['held_back']} | {fit['success']:.2f} | {fit['spearman']:+.2f} "
            f"| {fit['spearman_ceiling']:+.2f} | {fit['auc']:.2f} | {fit['spearman_baseline']:+.2f} |"
        )
    return "\n".join(lines)


def export(index_dir: Path, name: str) -> Path:
    """Write the certificates of the set in `index_dir` (e.g. the imported release) alone to
    results/certificates/NAME.json: its worlds' names, ids, difficulties and sha256 with them."""
    from dynabarn.files import write_atomically
    from dynabarn.worldset import read_index

    index = read_index(index_dir)
    worlds = [w for w in _entries_of(index) if "certificates" in w]
    out = CERTIFICATES_DIR / f"{name}.json"
    CERTIFICATES_DIR.mkdir(parents=True, exist_ok=True)
    record = {"certification": index.get("certification", {}), "worlds": worlds}
    write_atomically(out, json.dumps(record, indent=1, sort_keys=True) + "\n")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--export", nargs=2, metavar=("DIR", "NAME"), help="export a set's certificates")
    args = parser.parse_args(argv)
    if args.export:
        print(f"wrote {export(Path(args.export[0]), args.export[1])}")
        return 0
    print(certification_table(certified_sets()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
