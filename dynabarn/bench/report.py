"""`report.html`: one self-contained page per results folder, to look into a sweep and
compare its planners.

The page is rendered by Jinja2 from the package's template (`report_assets/`), with its
style, its script, plotly.js (from the `plotly` wheel) and every still inlined, and its data
in a JSON block: it opens from disk with no network, and its Content-Security-Policy admits
nothing but its own script and style, by their hashes. It shows:

- the summary with intervals and the skill over the floor;
- the episodes: worlds as rows, planners side by side (each planner's trials as cells of
  its column group), one sort for all, filters by planner, outcome and difficulty; a cell
  opens its episode (outcome, reason, every metric, its still with every shape as it is,
  the replay command relative to the report, the MCAP link); the table as CSV;
- charts (plotly, with hover and a planner toggled by its legend): success against measured
  difficulty, success per difficulty as in the paper's Fig. 5, and the distributions of
  time, SPL, clearance and jerk;
- the tracking quality of planners with a tracker, the provenance (every invocation that
  wrote the folder, versions, machines, world set, profile sources, certificates) and the
  last `--verify` of the folder.

Written at the end of every sweep (a resumed one rewrites it with every row so far) and by
`dynabarn-bench --report DIR` for any folder, older ones included. Size: about 5 MB
(plotly.js) plus ~0.3 kB per episode and ~20 kB per recorded episode's still; the committed
paper60 folder (13 planners x 60 worlds x 10 trials, no recordings) is about 8 MB.
"""

from __future__ import annotations

import base64
import hashlib
import json
from importlib import resources
from pathlib import Path

from dynabarn.bench.report_charts import difficulty_chart, fig5_chart, planner_colours, plotly_bundle
from dynabarn.bench.report_data import (
    OUTCOMES,
    STILLS,
    episode_table,
    json_block,
    provenance,
    read_worlds,
    recordings,
)
from dynabarn.bench.results import METADATA, RESULTS, certified_episodes, paper_worlds, read_results
from dynabarn.bench.stats import FEW_WORLDS_NOTE, skill_text
from dynabarn.bench.summary import DIFFICULTIES, FLOOR, few_worlds, summarise
from dynabarn.bench.verify import VERIFICATION
from dynabarn.errors import DynabarnError
from dynabarn.files import write_atomically

REPORT = "report.html"
OUTCOME_COLOURS = {"success": "#2e7d32", "collision": "#c62828", "timeout": "#f9a825", "error": "#6a1b9a"}
__all__ = ["OUTCOMES", "OUTCOME_COLOURS", "REPORT", "STILLS", "render_report", "write_report"]


def write_report(out_dir: Path, rows: list[dict] | None = None, **options) -> Path:
    """Render `OUT/report.html` (atomically) from the folder's rows, or from `rows` where the
    caller has them already (the end of a sweep, a comparison); `options` go to
    `render_report`. Returns its path."""
    out = Path(out_dir)
    if rows is None:
        if not (out / RESULTS).is_file():
            raise DynabarnError(f"{out}: no {RESULTS} (not a results folder of dynabarn-bench)")
        rows = read_results(out / RESULTS)
    if not rows:
        raise DynabarnError(f"{out / RESULTS}: no results rows yet")
    html = render_report(out, rows, **options)
    path = out / REPORT
    try:
        # A row's text may hold a lone surrogate (JSON allows "\ud800"): shown as U+FFFD.
        write_atomically(path, html.encode("utf-8", "replace"))
    except OSError as exc:
        raise DynabarnError(f"cannot write {path}: {exc.strerror or exc}") from None
    return path


def csp_hash(text: str) -> str:
    """A Content-Security-Policy source admitting exactly the inline `text` (CSP level 2)."""
    return "sha256-" + base64.b64encode(hashlib.sha256(text.encode("utf-8")).digest()).decode("ascii")


def render_report(
    out: Path,
    rows: list[dict],
    *,
    site: bool = False,
    title: str = "",
    comparison: dict | None = None,
    summary: list[dict] | None = None,
) -> str:
    """The page's HTML for the folder `out` and its rows. Everything from the rows or the
    folder's files is text to the page: autoescaped or in the JSON block, every URL a quoted
    relative path inside the folder, every command quoted for the shell; the page's own
    scripts and styles run by their hashes and nothing else does. `site`: for the
    documentation site (a verdict only when complete). `comparison`: the paired table of
    `dynabarn-bench --compare` shown above the summary. `summary`: the rows' summary where
    the caller made it already (`summarise` with the folder's paper worlds and certificates)."""
    import jinja2

    worlds = read_worlds(out)
    if summary is None:
        summary = summarise(rows, paper_worlds(out), certified_episodes(out))
    planners = sorted({r["planner"] for r in rows}, key=lambda p: (p != FLOOR, p))
    table = episode_table(rows, worlds, planners)
    found, stills_note = recordings(out, rows, table)
    assets = resources.files("dynabarn.bench") / "report_assets"
    script = (assets / "report.js").read_text(encoding="utf-8")
    style = (assets / "report.css").read_text(encoding="utf-8")
    plotly_js, plotly_css = plotly_bundle()
    data = table | {
        "colours": planner_colours(planners),
        "outcome_colours": OUTCOME_COLOURS,
        "recordings": found,
        "difficulty_chart": difficulty_chart(rows, worlds),
        "fig5": fig5_chart(summary),
    }
    env = jinja2.Environment(
        loader=jinja2.FunctionLoader(lambda name: (assets / name).read_text(encoding="utf-8")),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
    )
    return env.get_template("report.html.j2").render(
        title=title or _title(out),
        summary=summary,
        skill_text=skill_text,
        few_worlds_note=FEW_WORLDS_NOTE if few_worlds(summary) else "",
        difficulties=(*DIFFICULTIES, "all"),
        planners=planners,
        outcomes=OUTCOMES,
        colours=OUTCOME_COLOURS,
        tracking=[s for s in summary if s.get("track_recall") is not None],
        stills_note=stills_note,
        provenance=provenance(out, worlds, rows),
        verification=_verification(out, site=site),
        comparison=comparison,
        n_rows=len(rows),
        data=json_block(data),
        script=script,
        script_hash=csp_hash(script),
        style=style,
        style_hash=csp_hash(style),
        plotly=plotly_js,
        plotly_hash=csp_hash(plotly_js),
        plotly_css=plotly_css,
        plotly_css_hash=csp_hash(plotly_css),
    )


def _title(out: Path) -> str:
    try:
        meta = json.loads((out / METADATA).read_text())
        args = meta.get("arguments", {})
        return f"{out.name}: set {args.get('set', '?')}, protocol {args.get('protocol', '?')}"
    except (OSError, ValueError, AttributeError, TypeError):
        return out.name


VERIFICATION_FIELDS = {"when": str, "checked": int, "identical": int, "ok": bool, "differences": list, "notes": list}
"""What the report shows of `verification.json`, with each field's type."""


def _verification(out: Path, *, site: bool = False) -> dict | None:
    """The folder's last verdict, as plain text fields; `damaged` says why when the file is
    there but not a verdict of `--verify` (the report shows that, never a template error).
    For the documentation site (`site`), only a complete verdict: every sampled row checked
    by an install with every extra (a local one that skipped rows says nothing of them)."""
    path = out / VERIFICATION
    if not path.is_file():
        return None
    if site:
        try:
            complete = json.loads(path.read_text(encoding="utf-8", errors="replace")).get("complete") is True
        except (OSError, ValueError, RecursionError, AttributeError):
            complete = False
        if not complete:
            return None
    try:
        data = json.loads(path.read_text(encoding="utf-8", errors="replace"))
    except (OSError, ValueError, RecursionError) as exc:
        return {"damaged": f"not JSON: {type(exc).__name__}"}
    if not isinstance(data, dict):
        return {"damaged": "not a JSON object"}
    for name, kind in VERIFICATION_FIELDS.items():
        value = data.get(name)
        if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
            return {"damaged": f"{name} is not a {kind.__name__}"}
    differences = [
        {k: str(d.get(k, ""))[:500] for k in ("key", "field", "old", "new")}
        for d in data["differences"][:1000]
        if isinstance(d, dict)
    ]
    notes = [str(n)[:500] for n in data["notes"][:100]]
    unchecked = data.get("not_checked")
    return {"damaged": "", **{k: data[k] for k in ("when", "checked", "identical", "ok")}} | {
        "not_checked": unchecked if isinstance(unchecked, int) and not isinstance(unchecked, bool) else 0,
        "differences": differences,
        "notes": notes,
    }
