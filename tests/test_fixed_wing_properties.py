"""Fixed wings fly what a fixed wing can fly in any world: over random small worlds (static
bodies, moving ones, a wall with an opening), at every step of every fixed wing, before and
after its arrival (it loiters), its speed is at or above its floor, the curvature of its path
(the angle its direction turns over the distance flown at the slower of two speeds) is at most
1 / min_turn_radius, and the bank of that curvature, atan(k V^2 / g), changes by no more than
its roll rate allows in a step. Measured from the positions alone (the bank of the horizontal
turn: the climb or dive takes what a turn leaves of the budget, at the elevator's pace)."""

from __future__ import annotations

import math

import numpy as np
from helpers import base_world, make_world, run_to_end
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from swarmplan.core import Mode
from swarmplan.world.airframe import GRAVITY

DT = 0.1
SIZE = (500.0, 300.0, 120.0)

_body = st.tuples(
    st.sampled_from(["sphere", "cylinder", "box"]),
    st.floats(150.0, 400.0),  # x
    st.floats(40.0, 260.0),  # y
    st.floats(6.0, 18.0),  # size
)
_mover = st.tuples(
    st.floats(150.0, 400.0), st.floats(40.0, 260.0), st.floats(-8.0, 8.0), st.floats(-8.0, 8.0)
)


@st.composite
def fixed_wing_worlds(draw: st.DrawFn) -> dict:
    obstacles = []
    for k, (shape, x, y, s) in enumerate(draw(st.lists(_body, max_size=3))):
        spec = {"id": f"b{k}", "shape": shape, "position": [x, y, 60.0]}
        if shape == "sphere":
            spec["radius"] = s
        elif shape == "cylinder":
            spec.update(radius=s, height=120.0)
        else:
            spec["size"] = [2 * s, 2 * s, 120.0]
        obstacles.append(spec)
    for k, (x, y, vx, vy) in enumerate(draw(st.lists(_mover, max_size=2))):
        obstacles.append(
            {
                "id": f"m{k}",
                "shape": "sphere",
                "radius": 5.0,
                "position": [x, y, 60.0],
                "motion": {"type": "linear", "velocity": [vx, vy, 0.0]},
            }
        )
    if draw(st.booleans()):  # a wall across the field with an opening of 40-80 m
        gap_y, gap = draw(st.floats(100.0, 200.0)), draw(st.floats(40.0, 80.0))
        lo, hi = gap_y - gap / 2, gap_y + gap / 2
        obstacles.append(
            {"id": "w0", "shape": "box", "size": [4.0, lo, 120.0], "position": [250.0, lo / 2, 60.0]}
        )
        obstacles.append(
            {
                "id": "w1",
                "shape": "box",
                "size": [4.0, 300.0 - hi, 120.0],
                "position": [250.0, (300 + hi) / 2, 60.0],
            }
        )
    y0, y1 = draw(st.floats(60.0, 240.0)), draw(st.floats(60.0, 240.0))
    raw = base_world(
        bounds={"min": [0, 0, 0], "max": list(SIZE)},
        sim={"dt": DT, "max_time": 25.0, "goal_tolerance": 6.0},
        agent_defaults={
            "model": "fixed_wing",
            "radius": 1.0,
            "speed": {"min": 12, "max": 20, "cruise": 16},
            "max_accel": 3,
            "min_turn_radius": draw(st.floats(20.0, 40.0)),
            "max_climb_angle": 15,
            "min_altitude": 10,
            "separation": [8, 8, 3],
        },
        obstacles=obstacles,
        agents=[
            {"id": "a", "start": [30, y0, 60], "goal": [470, y1, 60]},
            {"id": "b", "start": [470, y1 + 20 if y1 < 200 else y1 - 20, 65], "goal": [60, y0, 55]},
        ],
    )
    return raw


def _turns(track: np.ndarray, climb: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per step: the speed (k,); per pair of steps (k-1,): the curvature (the angle between the
    two velocities over the distance at the slower speed) and the bank of the horizontal
    turn, atan(k_h V^2 / g) with k_h = c dpsi / distance (c the larger cos of the two
    flight-path angles, V the faster speed) for the pair's speeds and for the next pair's."""
    v = np.diff(track, axis=0) / DT
    speed = np.linalg.norm(v, axis=1)
    cos = np.einsum("ij,ij->i", v[:-1], v[1:]) / np.maximum(speed[:-1] * speed[1:], 1e-12)
    ds = np.minimum(speed[:-1], speed[1:]) * DT
    curvature = np.arccos(np.clip(cos, -1.0, 1.0)) / ds
    g = np.clip(np.arctan2(v[:, 2], np.hypot(v[:, 0], v[:, 1])), -climb, climb)
    c = np.where(g[:-1] * g[1:] <= 0, 1.0, np.cos(np.minimum(np.abs(g[:-1]), np.abs(g[1:]))))
    psi = np.arctan2(v[:, 1], v[:, 0])
    dpsi = (np.diff(psi) + np.pi) % (2 * np.pi) - np.pi
    k_h = c * dpsi / ds
    q = np.maximum(speed[:-1], speed[1:]) ** 2 / GRAVITY
    bank_now = np.arctan(k_h[1:] * q[1:])
    bank_before = np.arctan(k_h[:-1] * q[1:])  # the last turn's bank at this step's speed
    return speed, curvature, bank_now - bank_before


@settings(
    max_examples=6,
    deadline=None,
    derandomize=True,
    phases=[Phase.explicit, Phase.generate],
    suppress_health_check=[HealthCheck.too_slow],
)
@given(fixed_wing_worlds())
def test_every_step_of_a_random_fixed_wing_world_is_flyable(raw: dict) -> None:
    world = make_world(raw)
    sim, _summary, pos = run_to_end(world, seed=0)
    pos = np.array(pos)
    p = sim.params
    for i in range(sim.n):
        if sim.state.mode[i] == Mode.COLLIDED:
            continue  # a crash stops it where it struck (no such run is expected, but not asserted here)
        speed, curvature, roll = _turns(pos[:, i], float(p.max_climb[i]))
        assert speed.min() >= p.speed_min[i] * (1 - 1e-9), (i, speed.min())
        assert curvature.max() <= (1 + 1e-6) / p.min_turn_radius[i], (i, curvature.max())
        assert np.abs(roll).max() <= p.roll_rate[i] * DT * (1 + 1e-6) + 1e-9, (i, np.abs(roll).max())
        assert math.isfinite(float(p.roll_rate[i]))
