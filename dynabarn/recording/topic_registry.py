"""Recording topics beyond the table (`topics.TOPICS`), found as every other kind is: a
`Registry`, `TOPIC_REGISTRY`, of JSON topics made each tick, registered in this process
(`TOPIC_REGISTRY.register(topic)`) or installed by other packages under the entry-point
group `dynabarn.topics`.

The recording's writer process (`background`) finds the installed ones itself; those
registered here are handed to it with each episode, by reference (pickled: the topic's
`per_tick` must be a function at a module's top level, which registering checks). Every
recorder writes the table, then the installed topics (by name), then the registered ones,
in that order, in this process or the writer's: the same bytes either way.
"""

from __future__ import annotations

import pickle

from dynabarn.errors import DynabarnError
from dynabarn.recording.topics import TOPICS, Topic
from dynabarn.registry import Registry

TOPICS_GROUP = "dynabarn.topics"
"""Entry-point group under which other packages add JSON per-tick topics (name = "module:TOPIC")."""


def _check_topic(topic: object) -> None:
    """What may be added to the table: a JSON topic made each tick under a new name."""
    if not isinstance(topic, Topic) or topic.json_schema is None or topic.per_tick is None:
        raise TypeError("an added topic is a Topic with a json_schema and a per_tick function")
    if topic.name in {t.name for t in TOPICS}:
        raise ValueError(f"topic {topic.name} is already recorded")


class TopicRegistry(Registry[Topic]):
    """`Registry.register`, and what a topic registered at run time needs besides: a name no
    installed topic has, and a `per_tick` the writer process can be handed by reference."""

    def register(self, item, legacy=None, *, name=None):
        taken = {t.name for t in (*installed_topics(), *run_time_topics())}
        if isinstance(item, Topic) and item.name in taken:
            raise self.error(f"recording topic {item.name}: topic {item.name} is already recorded")
        item = super().register(item, legacy, name=name)
        try:
            pickle.dumps(item)
        except Exception as exc:  # a lambda or a nested function: not importable by the writer
            self.pop(name or item.name, None)
            raise self.error(
                f"recording topic {item.name}: its per_tick cannot be handed to the recording's writer "
                f"process ({type(exc).__name__}); define it at a module's top level"
            ) from None
        return item


TOPIC_REGISTRY: TopicRegistry = TopicRegistry("recording topic", {}, group=TOPICS_GROUP, check=_check_topic)
"""The topics beyond the table: registered in this process or installed by other packages
under `TOPICS_GROUP`, each checked (`_check_topic`)."""


def run_time_topics() -> tuple[Topic, ...]:
    """The topics registered in this process, in the order they were registered."""
    return TOPIC_REGISTRY.run_time_items()


def installed_topics() -> tuple[Topic, ...]:
    """The topics other packages installed, by entry-point name. One that cannot load, is
    not a JSON topic made each tick, or reuses a name is named in one warning and left out:
    the table's topics are recorded whatever another package installs."""
    extra: list[Topic] = []
    for name, topic in TOPIC_REGISTRY.installed_items().items():
        if topic.name in {t.name for t in extra}:
            TOPIC_REGISTRY.warn(
                name, DynabarnError(f"recording topic {name!r}: topic {topic.name} is already recorded")
            )
            continue
        extra.append(topic)
    return tuple(extra)


def recorded_topics() -> tuple[Topic, ...]:
    """The table, then the topics other packages installed, then those registered in this
    process: what the recorder writes and the replay plots."""
    return (*TOPICS, *installed_topics(), *run_time_topics())


def plotted() -> list[tuple[Topic, str]]:
    """(topic, field) of every time series the replay draws, in table order."""
    return [(t, f) for t in recorded_topics() for f in t.plots]
