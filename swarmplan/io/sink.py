"""The log's writer: foxglove-sdk (Rust) writes the MCAP file and, when a live view is
started, serves the same channels over the Foxglove WebSocket protocol.

:class:`LogSink` offers the slice of ``mcap.writer.Writer`` the recorder and the Foxglove
scene use (``register_schema``, ``register_channel``, ``add_message``) on top of foxglove-sdk
channels of a context of its own: one ``add_message`` hands the bytes to every sink of that
context (the file, and the WebSocket server while one runs). Channels are numbered in the
order they are registered; the file writes a channel when its first message comes.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import foxglove
from foxglove.mcap import MCAPCompression, MCAPWriteOptions

CHUNK_BYTES = 256 * 1024
# zstd level 1: ~20 % less CPU than the default level for ~4 % more bytes (64 agents +
# 32 movers); compression on the calling thread (no worker threads competing for the cores).
_OPTIONS = {"chunk_size": CHUNK_BYTES, "compression_level": 1, "compression_threads": 0}


class LogSink:
    """An MCAP file at ``path`` written by foxglove-sdk; :meth:`serve` adds a live server."""

    def __init__(self, path: str | Path):
        self.context = foxglove.Context()
        options = MCAPWriteOptions(compression=MCAPCompression.Zstd, profile="", **_OPTIONS)
        self._file = foxglove.open_mcap(
            Path(path), allow_overwrite=True, context=self.context, writer_options=options
        )
        self._schemas: list[foxglove.Schema] = []
        self._log: list[Callable[..., None]] = []
        self._server: foxglove.WebSocketServer | None = None

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        self._schemas.append(foxglove.Schema(name=name, encoding=encoding, data=data))
        return len(self._schemas)

    def register_channel(self, topic: str, message_encoding: str, schema_id: int) -> int:
        channel = foxglove.Channel(
            topic,
            schema=self._schemas[schema_id - 1],
            message_encoding=message_encoding,
            context=self.context,
        )
        self._log.append(channel.log)
        return len(self._log)

    def add_message(
        self, channel_id: int, log_time: int, data: bytes, publish_time: int = 0, sequence: int = 0
    ) -> None:
        """One message (``publish_time`` is ``log_time``; foxglove-sdk numbers each channel's messages)."""
        self._log[channel_id - 1](data, log_time=log_time)

    def serve(self, host: str, port: int) -> int:
        """Serve the channels live (Foxglove WebSocket protocol) on ``host:port``; the port bound."""
        self._server = foxglove.start_server(name="swarmplan", host=host, port=port, context=self.context)
        return int(self._server.port)

    def flush(self) -> None:
        self._file.flush()

    def close(self) -> None:
        """Finish the file and stop the server (if any)."""
        try:
            self._file.close()
        finally:
            if self._server is not None:
                self._server.stop()
                self._server = None
