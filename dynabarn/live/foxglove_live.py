"""Streaming an episode to Foxglove as it runs: foxglove-sdk's WebSocket server on loopback.

The recorder (`McapRecorder(live=...)`) sends every message to the server's context as well
as to the MCAP file: the same topics, schemas and bytes, so the shipped layout works live
as it does on a recording. The server advertises the `time` capability and is told the
simulated time after every tick, so Foxglove's clock follows the episode. A viewer that
subscribes after the start is sent the messages written once (world metadata, walls and
goal) again, as ROS latches them.

Open Foxglove, "Open connection", `ws://127.0.0.1:8765` (or `--port`).
"""

from __future__ import annotations

import sys
import threading
import time

import foxglove
from foxglove.websocket import Capability, ChannelView, Client, ServerListener

from dynabarn.interfaces.events import EpisodeObserver
from dynabarn.recording import McapRecorder

HOST = "127.0.0.1"
"""Loopback only: a simulator has no business listening on every interface (use an SSH
tunnel to watch from another machine)."""
BACKLOG = 16384
"""Messages the server queues per client before it drops the oldest (foxglove-sdk's default
is 1024). A paced episode at 10x real time streams about 2,500 messages a second (a
transform every physics step), so the default is 0.4 s of a client that reads slowly: the
first to go are the oldest, the world's metadata sent once at the start (a test lost it
so, under load). 16384 is 6 s of that stream, a few MB of transforms."""
SETTLE = 0.2
"""Seconds without a new subscription after which a waiting episode starts."""


class _Latch(ServerListener):
    """Resends the latched messages of a topic to the server when a client subscribes."""

    def __init__(self, live: FoxgloveLive) -> None:
        self.live = live

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.live.last_subscription = time.monotonic()
        self.live.subscribed.set()
        self.live.resend(channel.topic)


class FoxgloveLive(EpisodeObserver):
    """A Foxglove WebSocket server for one episode; pass `context` to the recorder's `live`.

    Args:
        port: the TCP port on 127.0.0.1 (0: any free port; `port` says which afterwards).
        name: the server's name, shown in Foxglove.
        wait: seconds the episode's start waits for a client to subscribe (its channels
            exist from the start on, so this is when a client can see them).
    """

    def __init__(self, port: int = 8765, *, name: str = "dynabarn", wait: float = 0.0) -> None:
        self.wait = wait
        self.context = foxglove.Context()
        self.subscribed = threading.Event()
        self.last_subscription = 0.0
        self.recorder: McapRecorder | None = None
        self._lock = threading.Lock()
        self.server = foxglove.start_server(
            name=name,
            host=HOST,
            port=port,
            capabilities=[Capability.Time],
            server_listener=_Latch(self),
            context=self.context,
            message_backlog_size=BACKLOG,
        )

    @property
    def port(self) -> int:
        return self.server.port

    @property
    def url(self) -> str:
        return f"ws://{HOST}:{self.port}"

    def attach(self, recorder: McapRecorder) -> None:
        """The recorder whose latched messages late subscribers get again."""
        self.recorder = recorder

    def resend(self, topic: str) -> None:
        recorder = self.recorder
        if recorder is None or topic not in recorder.latched:
            return
        channels = recorder.live_channels(self.context)
        with self._lock:
            for data, ns in list(recorder.latched[topic]):
                if topic in channels:
                    channels[topic].log(data, log_time=ns)

    def wait_for_client(self, timeout: float | None) -> bool:
        """Block until a client subscribes to something (or `timeout` seconds pass), then
        until its subscriptions settle (SETTLE seconds without a new one): a client that
        connected before the channels existed subscribes to them one advertisement at a time,
        and the episode must not start between its first and its last."""
        if not self.subscribed.wait(timeout):
            return False
        while (quiet := time.monotonic() - self.last_subscription) < SETTLE:
            time.sleep(SETTLE - quiet)
        return True

    # -- EpisodeObserver: the server's clock follows simulated time ---------------------
    def on_start(self, start) -> None:
        self.server.broadcast_time(0)
        if self.wait > 0 and not self.wait_for_client(self.wait):
            print(f"no Foxglove client after {self.wait:g} s; starting anyway", file=sys.stderr, flush=True)

    def on_tick(self, tick) -> None:
        self.server.broadcast_time(round(tick.time * 1e9))

    def on_poses(self, times, poses) -> None: ...

    def on_end(self, result) -> None:
        self.server.broadcast_time(round(result.sim_time * 1e9))

    def stop(self) -> None:
        self.server.stop()
