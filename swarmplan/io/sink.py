"""The log's writer: foxglove-sdk (Rust) writes the MCAP file and, for a live view, serves the
same channels over the Foxglove WebSocket protocol (``foxglove.websocket.v1``).

:class:`LogSink` offers the slice of ``mcap.writer.Writer`` the recorder and the Foxglove
scene use (``register_schema``, ``register_channel``, ``add_message``) on top of foxglove-sdk
channels of a context of its own. Channels are numbered in the order they are registered; the
file writes a channel when its first message comes.

Live (``live=(host, port)``): the server is started first (a port in use fails before the
file is touched) on a second context whose channels mirror the file's, so every message goes
to both. Messages sent once (``/world``, ``/scene/world``) and the latest path overview are
sent again whenever a viewer subscribes, so a viewer that connects mid-run sees the whole
scene; the server's clock follows simulation time (:meth:`LogSink.tick`).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import foxglove
from foxglove import channel as foxglove_channel
from foxglove.mcap import MCAPCompression, MCAPWriteOptions
from foxglove.websocket import Capability, ChannelView, Client, ServerListener

CHUNK_BYTES = 256 * 1024
# zstd level 1: ~20 % less CPU than the default level for ~4 % more bytes (64 agents +
# 32 movers); compression on the calling thread (no worker threads competing for the cores).
_OPTIONS = {"chunk_size": CHUNK_BYTES, "compression_level": 1, "compression_threads": 0}
LATCHED = ("/world", "/scene/world", "/scene/paths/overview")
"""Topics whose latest message a viewer that subscribes late gets again."""


class _Subscriptions(ServerListener):
    """Notes that a viewer subscribed (the next message re-sends the latched ones); every other
    callback of the protocol (unsubscribe, a viewer leaving, ...) is ServerListener's no-op."""

    def __init__(self) -> None:
        self.pending = False

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        self.pending = True


class LogSink:
    """An MCAP file at ``path`` written by foxglove-sdk; with ``live`` also a WebSocket server."""

    def __init__(self, path: str | Path, live: tuple[str, int] | None = None):
        self.context = foxglove.Context()
        self._schemas: list[foxglove.Schema] = []
        self._log: list[Callable[..., None]] = []
        self._channels: list[foxglove.Channel] = []
        self._server: foxglove.WebSocketServer | None = None
        self._live_context: foxglove.Context | None = None
        self._live_log: list[Callable[..., None]] = []
        self._latched_ids: set[int] = set()
        self._latched: dict[int, tuple[bytes, int]] = {}
        self._subscriptions = _Subscriptions()
        if live is not None:
            self._live_context = foxglove.Context()
            self._server = foxglove.start_server(
                name="swarmplan",
                host=live[0],
                port=live[1],
                context=self._live_context,
                capabilities=[Capability.Time],
                server_listener=self._subscriptions,
            )
        options = MCAPWriteOptions(compression=MCAPCompression.Zstd, profile="", **_OPTIONS)
        try:
            self._file = foxglove.open_mcap(
                Path(path), allow_overwrite=True, context=self.context, writer_options=options
            )
        except BaseException:
            self._stop_server()
            raise

    @property
    def port(self) -> int | None:
        """The live server's port (None without one)."""
        return None if self._server is None else int(self._server.port)

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        self._schemas.append(foxglove.Schema(name=name, encoding=encoding, data=data))
        return len(self._schemas)

    def register_channel(self, topic: str, message_encoding: str, schema_id: int) -> int:
        schema = self._schemas[schema_id - 1]
        channel = foxglove.Channel(
            topic, schema=schema, message_encoding=message_encoding, context=self.context
        )
        self._channels.append(channel)  # kept: released in close()
        self._log.append(channel.base.log)  # bytes only: foxglove.Channel.log's checks skipped
        if self._live_context is not None:
            live = foxglove.Channel(
                topic, schema=schema, message_encoding=message_encoding, context=self._live_context
            )
            self._channels.append(live)
            self._live_log.append(live.base.log)
            if topic in LATCHED:
                self._latched_ids.add(len(self._log))
        return len(self._log)

    def add_message(
        self, channel_id: int, log_time: int, data: bytes, publish_time: int = 0, sequence: int = 0
    ) -> None:
        """One message (``publish_time`` is ``log_time``; foxglove-sdk numbers each channel's messages)."""
        self._log[channel_id - 1](data, log_time)
        if self._server is not None:
            if self._subscriptions.pending:
                self._subscriptions.pending = False
                for k, (old, t) in self._latched.items():
                    self._live_log[k - 1](old, t)
            self._live_log[channel_id - 1](data, log_time)
            if channel_id in self._latched_ids:
                self._latched[channel_id] = (data, log_time)

    def tick(self, ns: int) -> None:
        """The live server's clock at simulation time ``ns`` (nothing without a server)."""
        if self._server is not None:
            self._server.broadcast_time(ns)

    def flush(self) -> None:
        self._file.flush()

    def close(self) -> None:
        """Finish the file, stop the server (if any) and let the channels go."""
        try:
            self._file.close()
        finally:
            self._stop_server()
            self._release_channels()

    def _release_channels(self) -> None:
        # foxglove-sdk keeps every Channel it made in a module-level registry (for its
        # foxglove.log helper, which this sink does not use): without this, a process that
        # records many runs (a sweep worker) would keep every run's channels.
        registry = getattr(foxglove_channel, "_channels_by_id", {})
        for channel in self._channels:
            channel.close()
            registry.pop(channel.base.id(), None)
        self._channels.clear()
        self._log.clear()
        self._live_log.clear()

    def _stop_server(self) -> None:
        if self._server is not None:
            self._server.stop()
            self._server = None
