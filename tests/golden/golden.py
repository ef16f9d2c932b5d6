"""Frozen behaviour: MCAP logs of a few worlds, stored as digests, reproduced exactly.

The logs are made with a frozen wall clock (``time.perf_counter`` returns a constant while
a run is made), so the wall-clock fields (``/optimizer`` ``wall_ms``, ``/summary``
``wall_time``, ``global_plan`` ``planning_ms``) are 0 and the content depends only on the
world, the seed and the code. ``digests.json`` holds, per case, the sha256 of the file
plus small facts (message counts per topic, last state time, event kinds) that help tell
where a mismatch starts. The digest covers the log's content - header, schemas, channels and
every message (channel, times, sequence, payload) in file order - not the container's bytes:
the zstd chunks' compressed bytes change with the zstandard release while the log they hold
does not; likewise the header's ``library`` (the writer's name and version) is left out.

Re-store after a deliberate behaviour change (and say so in the commit message)::

    PYTHONPATH=$PWD python tests/golden/golden.py
"""

from __future__ import annotations

import collections
import hashlib
import json
import sys
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
DIGESTS = Path(__file__).with_name("digests.json")

# name -> (world file, max_time override); one optimizer (each world's own), seed 0.
# Short horizons keep the default suite fast while still covering escapes, movers and
# global routes.
CASES: dict[str, tuple[str, float]] = {
    "quickstart": ("worlds/quickstart.yaml", 60.0),
    "concave_wall": ("worlds/traps/concave_wall.yaml", 40.0),
    "goal_beside_obstacle": ("worlds/traps/goal_beside_obstacle.yaml", 40.0),
    "narrow_gap_swap": ("worlds/traps/narrow_gap_swap.yaml", 40.0),
    "u_pocket": ("worlds/traps/u_pocket.yaml", 40.0),
    "crossing_movers": ("worlds/crossing_movers.yaml", 40.0),
    "rscdwoa_multi_uav": ("worlds/papers/rscdwoa_multi_uav.yaml", 30.0),
}
SEED = 0


@contextmanager
def frozen_clock():
    """Every ``time.perf_counter()`` returns the same value: wall-clock durations are 0."""
    real = time.perf_counter
    time.perf_counter = lambda: 1000.0
    try:
        yield
    finally:
        time.perf_counter = real


def make_log(name: str, out_dir: Path) -> Path:
    from swarmplan.io.runner import apply_overrides, simulate
    from swarmplan.world import load_world

    world_file, max_time = CASES[name]
    world = apply_overrides(load_world(ROOT / world_file), None, max_time)
    path = out_dir / f"{name}.mcap"
    with frozen_clock():
        simulate(world, SEED, path)
    return path


def describe(path: Path) -> dict[str, Any]:
    """The digest of one log's content and a few facts to debug a mismatch with."""
    from mcap.reader import make_reader

    digest = hashlib.sha256()
    counts: collections.Counter[str] = collections.Counter()
    kinds: collections.Counter[str] = collections.Counter()
    data_bytes = 0
    last_t = None
    summary: dict[str, Any] = {}
    with path.open("rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        digest.update(repr(header.profile).encode())
        seen_channels: set[int] = set()
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            if channel.id not in seen_channels:
                seen_channels.add(channel.id)
                digest.update(repr((channel.id, channel.topic, channel.message_encoding)).encode())
                digest.update(repr(sorted(channel.metadata.items())).encode())
                if schema is not None:
                    digest.update(repr((schema.id, schema.name, schema.encoding)).encode())
                    digest.update(schema.data)
            digest.update(
                repr((channel.id, message.log_time, message.publish_time, message.sequence)).encode()
            )
            digest.update(message.data)
            data_bytes += len(message.data)
            counts[channel.topic] += 1
            if channel.topic == "/agents/state":
                last_t = json.loads(message.data)["t"]
            elif channel.topic == "/events":
                kinds[json.loads(message.data)["kind"]] += 1
            elif channel.topic == "/summary":
                s = json.loads(message.data)
                summary = {k: s[k] for k in ("arrived", "collisions", "steps", "success")}
    return {
        "sha256": digest.hexdigest(),
        "message_bytes": data_bytes,
        "messages": dict(sorted(counts.items())),
        "last_state_t": last_t,
        "events": dict(sorted(kinds.items())),
        "summary": summary,
    }


def store(out_dir: Path) -> dict[str, Any]:
    table = {name: describe(make_log(name, out_dir)) for name in CASES}
    DIGESTS.write_text(json.dumps(table, indent=1, sort_keys=True) + "\n")
    return table


if __name__ == "__main__":
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        for name, row in store(Path(tmp)).items():
            print(name, row["sha256"][:16], row["message_bytes"], row["summary"], file=sys.stderr)
