"""Swarms on what each agent hears, on random valid worlds: hypothesis draws a small lab or field
world (``swarmplan.bench.random_worlds``) and a network for it (broadcast rate, delay with
jitter, loss, and a hearing and sensing range or none), and each world is flown to its end with
the default planner. Asserted per world: no collision, every multirotor within its acceleration
limit, every agent home within three times the straight-line time plus 30 s. A range is drawn
no shorter than what two agents closing at cruise speed need to learn of each other and stop:
both braking distances, the distance flown while a message is on its way and the wait for the
next broadcast, and the pair's separation (a shorter range is a world no planner can fly)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import flight_draw_settings
from hypothesis import given, settings
from hypothesis import strategies as st

from swarmplan.bench.random_worlds import random_world
from swarmplan.bench.reach import fly

EXAMPLES = {"lab": 4, "field": 2}
"""Worlds drawn per class in the default suite."""

EXAMPLES_SLOW = 25
"""Worlds drawn per class by the slow study."""

_SETTINGS = flight_draw_settings()

networks = st.fixed_dictionaries(
    {
        "rate": st.sampled_from([10.0, 20.0, 50.0]),
        "delay": st.floats(0.0, 0.3),
        "jitter": st.floats(0.0, 0.5),  # a share of the delay
        "loss": st.floats(0.0, 0.3),
        "range": st.one_of(st.none(), st.floats(1.5, 6.0)),  # a multiple of the shortest safe range
        "sensing": st.one_of(st.none(), st.floats(1.5, 6.0)),
    }
)
draws = st.tuples(st.integers(0, 2**32 - 1), st.integers(1, 3), st.integers(0, 3), networks)


def _shortest_range(raw: dict, net: dict) -> float:
    """What two agents closing at cruise speed need to hear of each other and stop in time."""
    wait = net["delay"] * (1.0 + net["jitter"]) + 1.0 / net["rate"]
    need = 0.0
    for a in raw["agents"]:
        v, acc = float(a["speed"]["cruise"]), float(a["max_accel"])
        body = 2.0 * float(a["radius"]) + max(a.get("separation", [0.0]))
        need = max(need, v * v / acc + 2.0 * v * wait + body)
    return need


def _with_network(raw: dict, net: dict) -> dict:
    comms: dict = {"rate": net["rate"], "loss": net["loss"]}
    jitter = net["delay"] * net["jitter"]
    comms["delay"] = {"mean": net["delay"], "jitter": jitter} if jitter > 0.0 else net["delay"]
    shortest = _shortest_range(raw, net)
    if net["range"] is not None:
        comms["range"] = net["range"] * shortest
    raw = dict(raw, comms=comms)
    if net["sensing"] is not None:
        raw["sensing"] = {"range": net["sensing"] * shortest}
    return raw


def _fly(kind: str, seed: int, agents: int, bodies: int, net: dict) -> tuple[dict, dict]:
    raw = random_world(kind, np.random.default_rng(seed), name=f"comms-{kind}-{seed}", max_agents=agents,
                       max_bodies=bodies, small=True)  # fmt: skip
    raw["seed"] = seed % 1000
    raw = _with_network(raw, net)
    return raw, fly(raw)


def _check(raw: dict, rec: dict) -> None:
    name = f"{raw['name']} comms={raw['comms']} sensing={raw.get('sensing')}"
    hit = [(a["id"], a["collided_with"]) for a in rec["agents"] if a["collisions"]]
    assert not hit, f"{name}: collided (id, with): {hit}"
    over = [(a["id"], a["limit_ratio"]) for a in rec["agents"] if a["limit_break"]]
    assert not over, f"{name}: over the acceleration limit: {over}"
    away = [(a["id"], a["cause"], a["distance_to_goal"]) for a in rec["agents"] if not a["home"]]
    assert not away, f"{name}: not home (id, cause, distance m): {away}"


def _over_draws(kind: str, examples: int) -> None:
    @settings(max_examples=examples, **_SETTINGS)
    @given(draws)
    def run(draw: tuple) -> None:
        _check(*_fly(kind, *draw))

    run()


@pytest.mark.parametrize("kind", list(EXAMPLES))
def test_random_worlds_fly_home_on_what_agents_hear(kind):
    _over_draws(kind, EXAMPLES[kind])


@pytest.mark.slow
@pytest.mark.parametrize("kind", list(EXAMPLES))
def test_random_worlds_fly_home_on_what_agents_hear_many(kind):
    _over_draws(kind, EXAMPLES_SLOW)


def test_the_shortest_range_grows_with_speed_and_delay():
    """Exact on one agent: 2 m/s, 4 m/s^2, radius 0.1, separation 0.2; 0.1 s delay with a 0.5
    jitter share at 20 Hz: wait 0.15 + 0.05 = 0.2 s; need 1 + 0.8 + 0.2 + 0.2 = 2.2 m."""
    agent = {"speed": {"cruise": 2.0}, "max_accel": 4.0, "radius": 0.1, "separation": [0.2, 0.2, 0.1]}
    raw = {"agents": [agent]}
    net = {"delay": 0.1, "jitter": 0.5, "rate": 20.0}
    assert math.isclose(_shortest_range(raw, net), 2.2)
