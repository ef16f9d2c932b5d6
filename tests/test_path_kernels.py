"""The compiled writer of the flown paths (``sample_paths``, ``line_entities``) gives the
bytes of the numpy path: chunks and overviews of random paths, with coordinates equal to +0.0 and -0.0 (proto3
leaves out the former only), ids of many lengths (one- and two-byte varint lengths) and chunk
numbers of several digits."""

from __future__ import annotations

import numpy as np
import pytest

from swarmplan.io.foxglove_paths import PathTrails
from swarmplan.io.json_floats import record_kernels
from swarmplan.io.wire import timestamp_bytes


def _trails_pair(seed: int, max_points: int = 16) -> tuple[PathTrails, PathTrails, list]:
    rng = np.random.default_rng(seed)
    n = int(rng.integers(1, 40))
    ids = tuple(("x" * int(rng.integers(0, 150))) + f"a{i}" for i in rng.permutation(n))
    pair = (PathTrails(max_points, 5), PathTrails(max_points, 5))
    for trails in pair:
        trails.grow(n + 3)  # slots beyond the agents' stay unused
    slots = rng.permutation(n + 3)[:n].astype(np.intp)
    pos = rng.normal(0, 50, (n, 3))
    steps = []
    for _ in range(60):
        pos = pos + rng.normal(0, 1, (n, 3)) * (rng.random((n, 1)) < 0.7)  # some agents stand
        pos[rng.random((n, 3)) < 0.05] = 0.0
        pos[rng.random((n, 3)) < 0.05] = -0.0
        steps.append(pos.copy())
    return pair, (ids, slots), steps


@pytest.mark.parametrize("seed", range(6))
def test_compiled_paths_equal_the_numpy_ones(seed):
    (compiled, plain), (ids, slots), steps = _trails_pair(seed)
    kernels = record_kernels()
    rng = np.random.default_rng(100 + seed)
    order = rng.permutation(len(ids))  # agents may come in another order at each sample
    for k, pos in enumerate(steps):
        t = 0.1 * (k + 1) + (1e-9 if k % 7 == 0 else 0.0)
        sel = order if k % 2 else np.arange(len(ids))
        step_ids = tuple(ids[i] for i in sel)
        compiled.sample(step_ids, pos[sel], slots[sel], kernels)
        plain.sample(step_ids, pos[sel], slots[sel])
        assert list(compiled.order.items()) == list(plain.order.items())
        assert (compiled.count == plain.count).all()
        assert compiled.points.tobytes() == plain.points.tobytes()
        if k % 3 == 2:
            stamp = timestamp_bytes(t)
            assert compiled.chunks(stamp, kernels) == plain.chunks(stamp)
        if k % 11 == 5:
            stamp = timestamp_bytes(t)
            assert compiled.overview(stamp, kernels) == plain.overview(stamp)
    assert compiled.chunk_index.max() >= 10  # chunk numbers of two digits were written
    assert compiled.chunks(timestamp_bytes(9.0), kernels) == plain.chunks(timestamp_bytes(9.0))


class _Messages:
    """The writer slice FoxgloveScene uses, keeping every message."""

    def __init__(self) -> None:
        self.topics: list[str] = []
        self.messages: list[tuple[str, int, bytes]] = []

    def register_schema(self, name: str, encoding: str, data: bytes) -> int:
        return 1

    def register_channel(self, topic: str, message_encoding: str, schema_id: int) -> int:
        self.topics.append(topic)
        return len(self.topics)

    def add_message(self, channel_id: int, log_time: int, data: bytes, publish_time: int = 0) -> None:
        self.messages.append((self.topics[channel_id - 1], log_time, data))


@pytest.mark.parametrize("seed", range(3))
def test_compiled_scene_steps_equal_the_numpy_ones(seed):
    """/tf, /scene and paths of random steps, compiled or not: the same messages, also on steps
    with a coordinate, a velocity or a heading component equal to +-0.0 (another layout)."""
    from swarmplan.core import AgentStates, Mode
    from swarmplan.io.foxglove_scene import FoxgloveScene

    rng = np.random.default_rng(seed)
    n = 20
    ids = tuple(f"u{i}" for i in range(n))
    world = {"agents": [{"id": a, "radius": 0.3 + 0.01 * i} for i, a in enumerate(ids)], "obstacles": []}
    modes = list(Mode)
    runs = []
    for compiled in (True, False):
        out = _Messages()
        scene = FoxgloveScene(out, world, scene_period=0.1, tf_period=0.1, path_period=0.3)
        scene.compiled = compiled
        rng = np.random.default_rng(seed)
        pos = rng.normal(0, 20, (n, 3))
        mode = np.array([Mode.APF] * n, dtype=object)
        for k in range(40):
            vel = np.round(rng.normal(0, 2, (n, 3)), 6)
            vel[rng.random(n) < 0.1, :2] = 0.0  # no horizontal motion: the last heading stays
            pos = np.round(pos + 0.1 * vel, 6)
            if k % 5 == 3:
                pos[rng.integers(n), rng.integers(3)] = 0.0 if k % 2 else -0.0
            if k % 4 == 1:
                mode[rng.integers(n)] = modes[rng.integers(len(modes))]
            agents = AgentStates(ids, pos.copy(), vel, mode.copy(), np.ones((n, 3)))
            scene.write_step(round(0.1 * (k + 1), 9), agents, [])
        scene.finish()
        runs.append(out.messages)
    assert len(runs[0]) > 100
    assert runs[0] == runs[1]


def test_compiled_speeds_have_numpys_bits():
    """Speeds rounded as np.round(np.sqrt(...), 6), their sum as numpy's pairwise sum (sizes
    around its blocks of 8 and 128) and their maximum."""
    rng = np.random.default_rng(7)
    kernels = record_kernels()
    for n in [*range(1, 140), 255, 256, 257, 511, 512, 513, 1100]:
        vel = rng.normal(0, 3, (n, 3)) * 10 ** rng.uniform(-4, 2, (n, 1))
        vel[rng.random(n) < 0.1] = 0.0
        out = np.empty(n)
        total, top = kernels.speeds(vel, out)
        want = np.round(np.sqrt((vel * vel).sum(axis=1)), 6)
        assert out.tobytes() == want.tobytes()
        assert (total / n, top) == (float(want.mean()), float(want.max()))
    vel[3, 1] = np.nan
    assert np.isnan(kernels.speeds(vel, np.empty(len(vel)))[1])
