"""Metrics by name, found as every other kind is: a `Registry`, `METRIC_REGISTRY`. Built in:
the table (`metrics.METRICS`, each an `EpisodeResult` field and a results column). Beyond
it: `Metric`s registered in this process (`METRIC_REGISTRY.register(metric)`) or installed
by other packages under the entry-point group `dynabarn.metrics`, each computed from every
episode's facts (`metrics.EpisodeFacts`) into the result's `added_metrics` ({name: value},
in results rows and recordings too) and aggregated by a sweep's summary as its `summary`
says.

A metric registered at run time is computed by this process's episodes; a sweep's worker
processes know the built-in and installed ones (install it to have it everywhere).
"""

from __future__ import annotations

from dataclasses import fields

from dynabarn.metrics import METRICS, EpisodeResult, Metric
from dynabarn.registry import Registry

METRICS_GROUP = "dynabarn.metrics"
"""Entry-point group under which other packages add metrics (name = "module:METRIC")."""

SUMMARIES = (None, "mean", "successes")
"""How a summary may aggregate a metric (`Metric.summary`)."""


def _check_metric(item: object) -> None:
    """An added metric: a `Metric` under a name no result field has, aggregated a known way."""
    if not isinstance(item, Metric) or not callable(item.compute):
        raise TypeError("an added metric is a dynabarn.metrics.Metric with a compute(facts) function")
    if item.name in {f.name for f in fields(EpisodeResult)}:
        raise ValueError(f"metric {item.name} is already a field of every result")
    if item.summary not in SUMMARIES:
        raise ValueError(f"summary {item.summary!r}: use one of {', '.join(map(str, SUMMARIES))}")


METRIC_REGISTRY: Registry[Metric] = Registry(
    "metric", {m.name: m for m in METRICS}, group=METRICS_GROUP, check=_check_metric
)
"""Every metric by name: the table (built in), registered at run time, installed."""


def added_metrics() -> tuple[Metric, ...]:
    """The metrics beyond the table: installed (by entry-point name), then registered in
    this process (in the order registered). One installed that cannot load or breaks the
    contract is named in one warning and left out."""
    return (*METRIC_REGISTRY.installed_items().values(), *METRIC_REGISTRY.run_time_items())


def computed(facts) -> dict | None:
    """{name: value} of the added metrics for an ended episode's facts; None when there are none."""
    metrics = added_metrics()
    return {m.name: float(m.compute(facts)) for m in metrics} if metrics else None
