"""Kept for ``from swarmplan.recording import McapRecorder``; the recorder lives in
:mod:`swarmplan.io.recording`."""

from swarmplan.io.recording import SCHEMAS, McapRecorder

__all__ = ["SCHEMAS", "McapRecorder"]
