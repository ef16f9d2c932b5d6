"""Fixed-wing tracking (swarmplan.track.fixed_wing): the coordinated-turn aircraft flies what a
fixed wing can fly within centimetres to metres, needs the bank a turn of that radius needs, and
cannot follow what no fixed wing can fly."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarmplan.track.fixed_wing import Aircraft, FixedWingConfig, bank_limit_deg, error_limit, fly
from swarmplan.world.tracker_config import G

DT = 0.1


def _aircraft(radius: float = 50.0) -> Aircraft:
    return Aircraft(speed_min=14.0, speed_max=26.0, max_accel=3.0, min_turn_radius=radius, max_climb_deg=15.0)


def _circle(
    radius: float, speed: float, seconds: float, climb_deg: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Straight for 5 s, then a (climbing) circle of horizontal radius ``radius`` at ``speed``."""
    t = DT * np.arange(int(seconds / DT) + 1)
    g = math.radians(climb_deg)
    vh, vz = speed * math.cos(g), speed * math.sin(g)
    w = vh / radius
    straight = np.minimum(t, 5.0)
    turn = np.maximum(t - 5.0, 0.0)
    x = vh * straight + radius * np.sin(w * turn)
    y = radius * (1.0 - np.cos(w * turn))
    z = 100.0 + vz * t
    return t, np.stack([x, y, z], axis=1)


def test_a_level_turn_at_the_minimum_radius_is_flown_with_the_bank_it_needs():
    ac = _aircraft(50.0)
    t, p = _circle(50.0, 20.0, 40.0)
    f = fly(t, p, ac, FixedWingConfig(), DT)
    j = f.to_json()
    assert j["max_error_m"] < 1.0 and j["within_error_limit"]
    # Coordinated turn: tan(bank) = V^2 / (g R).
    need = math.degrees(math.atan(20.0**2 / (G * 50.0)))
    steady = f.times > 15.0
    assert np.abs(f.bank_deg[steady]).mean() == pytest.approx(need, abs=1.0)
    assert j["max_bank_deg"] <= j["bank_limit_deg"] + 1e-9


def test_a_climbing_turn_is_tracked_in_height_too():
    ac = _aircraft(50.0)
    t, p = _circle(50.0, 20.0, 40.0, climb_deg=10.0)
    f = fly(t, p, ac, FixedWingConfig(), DT)
    assert f.error.max() < 1.5
    assert abs(f.pos[-1, 2] - p[-1, 2]) < 0.5


def test_a_corner_no_fixed_wing_can_fly_is_reported_beyond_the_limit():
    """Negative control: a right-angle corner at 20 m/s (no radius at all) cannot be flown."""
    ac = _aircraft(50.0)
    t = DT * np.arange(301)
    leg = np.minimum(t, 15.0)
    p = np.stack([20.0 * leg, 20.0 * np.maximum(t - 15.0, 0.0), np.full_like(t, 100.0)], axis=1)
    f = fly(t, p, ac, FixedWingConfig(), DT)
    assert f.error.max() > error_limit(ac)
    assert not f.to_json()["within_error_limit"]


def test_the_bank_limit_covers_the_minimum_radius_at_top_speed():
    ac = _aircraft(40.0)
    need = math.degrees(math.atan(26.0**2 / (G * 40.0)))
    assert bank_limit_deg(ac, FixedWingConfig()) == pytest.approx(min(80.0, need + 10.0))
    assert error_limit(ac) == 5.0 and error_limit(_aircraft(2000.0)) == 100.0


def test_airspeed_stays_within_the_aircrafts_band():
    ac = _aircraft(50.0)
    t, p = _circle(50.0, 20.0, 30.0)
    f = fly(t, p, ac, FixedWingConfig(), DT)
    s = np.linalg.norm(f.vel, axis=1)
    assert s.min() >= ac.speed_min - 1e-9 and s.max() <= ac.speed_max + 1e-9
