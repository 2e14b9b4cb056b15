"""`dynabarn-bench` on results that exist: `--verify` (re-run a results file's rows and
compare), `--report` and the golden set (`--verify-golden`, `--update-golden`)."""

from __future__ import annotations

import argparse
import contextlib
import json
import time
from pathlib import Path

from dynabarn.cli.common import planner_config
from dynabarn.errors import DynabarnError


def golden_command(args: argparse.Namespace) -> int:

    from tqdm import tqdm

    from dynabarn.bench import golden
    from dynabarn.provenance import machine

    if args.jobs < 1:
        raise DynabarnError("--jobs must be at least 1")
    reference = args.reference or golden.DEFAULT_REFERENCE

    def progress(stream, total):
        return tqdm(stream, total=total, desc="golden episodes", unit="ep", disable=None)

    if args.update_golden:
        path = golden.update(reference, jobs=args.jobs, progress=progress)
        print(f"wrote {len(golden.CASES)} golden episodes to {path}")
        return 0
    t0 = time.perf_counter()
    report = golden.verify(reference, jobs=args.jobs, progress=progress)
    print(f"machine: {json.dumps(machine(), sort_keys=True)}")
    for note in report.version_notes:
        print(f"versions differ: {note}")
    for case in report.skipped:
        print(f"skipped (no reference data under {reference}): {case}")
    for m in report.mismatches:
        print(f"MISMATCH {m}")
    cases = len({m.case for m in report.mismatches})
    verdict = "identical" if report.ok else f"{len(report.mismatches)} fields differ in {cases} episodes"
    print(
        f"golden set: {report.checked} episodes checked, {len(report.skipped)} skipped, {verdict} "
        f"({time.perf_counter() - t0:.1f} s)"
    )
    return 0 if report.ok else 1


def check_command(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from dynabarn import worldset
    from dynabarn.bench.report import write_report
    from dynabarn.bench.verify import exit_code, verify_results

    code = 0
    if args.verify is not None:

        def progress(stream, total):
            return tqdm(stream, total=total, desc="re-running rows", unit="row", disable=None)

        # What the person verifying names: planners from code, the options a row may not supply,
        # and where worlds may be.
        code = _load_code_planners_to_verify(args.planner) if args.planner_given else set()
        given, set_dir = command_line_config(args), worldset.set_folder(args.set)[0] if args.set_given else None
        verdict = verify_results(
            args.verify,
            sample=args.sample,
            jobs=args.jobs,
            progress=progress,
            given=given,
            set_dir=set_dir,
            code=code,
        )
        for row in verdict["rows"]:
            if row["not_checked"]:
                print(f"not checked  {row['key']}  {row['not_checked']} ({row['install']})")
                continue
            print(f"{'identical' if row['identical'] else 'DIFFERS  '}  {row['key']}  {row['problem']}".rstrip())
        for d in verdict["differences"]:
            if d["field"] != "-":
                print(f"  {d['key']}: {d['field']}: row {d['old']!r}, now {d['new']!r}")
        for note in verdict["notes"]:
            print(note)
        unchecked = f", {verdict['not_checked']} not checked here" if verdict["not_checked"] else ""
        print(f"{verdict['checked']} rows re-run: {verdict['identical']} identical{unchecked}")
        code = exit_code(verdict)
        folder = Path(verdict["results"]).parent
        if args.report is None and (folder / "report.html").is_file():
            report_so_far(folder)  # the report shows the verification (a read-only folder keeps its own)
    if args.report is not None:
        print(f"wrote {write_report(args.report)}")
    return code


def _load_code_planners_to_verify(text: str) -> set[str]:
    """`--planner` with `--verify`: the planners from code the rows need, loaded here (a row
    never names code that --verify loads)."""
    from dynabarn.planners.from_code import is_code_spec, load_code_planner

    names = set()
    for spec in (p.strip() for p in text.split(",")):
        if not is_code_spec(spec):
            raise DynabarnError(
                f"--planner {spec!r}: with --verify, --planner names only planners from code (MODULE:CLASS or "
                "FILE.py:CLASS); installed planners need no naming"
            )
        names.add(load_code_planner(spec).name)
    return names


def command_line_config(args: argparse.Namespace) -> dict:
    """The planner options this command line gives: every planner's in a sweep; with
    `--verify` (no `--ros-stack` there), what a row may not supply."""
    config = planner_config(args.planner_config)
    if args.policy is not None:
        config["policy"] = str(args.policy.resolve())
    if args.ros_launch is not None:
        config["launch"] = args.ros_launch
    if args.ros_stack is not None:
        from dynabarn.ros.stacks import STACKS

        config["stack"] = args.ros_stack
        if STACKS[args.ros_stack].ros != 1:  # Nav2: the bridge on ROS 2 (ROS 1's rows keep their configuration)
            config["ros"] = STACKS[args.ros_stack].ros
    return config


def report_so_far(out: Path) -> None:
    """A sweep cut short: its report shows the rows so far (a resumed sweep rewrites it)."""
    from dynabarn.bench.report import write_report

    with contextlib.suppress(DynabarnError, OSError):
        write_report(out)


def compare_command(args: argparse.Namespace) -> int:
    """`--compare A B`: print the paired comparison; with `--out`, its report and JSON."""
    from dynabarn.bench.compare import compare, format_comparison, side
    from dynabarn.bench.report import write_report
    from dynabarn.bench.results import WORLDS
    from dynabarn.files import write_atomically

    first, second = args.compare
    names = [p.strip() for p in args.planner.split(",")] if args.planner_given else [None, None]
    if len(names) == 1:
        names = names * 2  # the same planner in two folders
    if len(names) != 2 or not all(n is None or n for n in names):
        raise DynabarnError(f"--planner {args.planner!r}: with --compare, one planner or two (A_PLANNER,B_PLANNER)")
    if first.resolve() == second.resolve() and names[0] is None:
        raise DynabarnError("--compare of one folder with itself: name its two planners with --planner A,B")
    (a, a_rows), (b, b_rows) = side(first, names[0]), side(second, names[1])
    result = compare(a_rows, b_rows)
    if not result["shared"]:
        raise DynabarnError(f"{first} ({a}) and {second} ({b}) share no episode (same world file, protocol and seed)")
    labels = (f"A: {a} ({first.name})", f"B: {b} ({second.name})")
    print(format_comparison(result, f"{a} ({first.name})", f"{b} ({second.name})"))
    if args.out is not None:
        out = Path(args.out)
        if out.exists() and not out.is_dir():
            raise DynabarnError(f"--out {out}: exists and is not a folder")
        out.mkdir(parents=True, exist_ok=True)
        if (first / WORLDS).is_file():  # the measured difficulty of the worlds
            write_atomically(out / WORLDS, (first / WORLDS).read_bytes())
        write_atomically(
            out / "comparison.json", json.dumps({"a": labels[0], "b": labels[1]} | result, indent=1) + "\n"
        )
        rows = [
            {k: v for k, v in r.items() if k != "recording"} | {"planner": label}
            for label, rs in zip(labels, (a_rows, b_rows), strict=True)
            for r in rs
        ]
        left_out = result["a_only"] + result["b_only"]
        note = f"{left_out} episodes ran on one side only and are left out of the comparison." if left_out else ""
        comparison = {"a": labels[0], "b": labels[1], "note": note} | result
        page = write_report(out, rows, title=f"{labels[0]} against {labels[1]}", comparison=comparison)
        print(f"wrote {page}, {out / 'comparison.json'}")
    return 0
