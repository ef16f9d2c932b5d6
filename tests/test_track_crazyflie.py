"""The Crazyflie under its firmware's commander, Mellinger controller and motor mix: exact answers
on a hover, straight lines and the flat body rates."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from swarmplan.track.crazyflie import (
    PWM_MAX,
    Crazyflie,
    Setpoints,
    body_rates,
    fly,
    hover_integral,
    mix,
)
from swarmplan.world.tracker_config import G

CF = Crazyflie()


def line(v: float, seconds: float, start=(0.0, 0.0, 1.0), direction=(1.0, 0.0, 0.0)) -> Setpoints:
    """Set-points of one vehicle on a straight line at constant speed ``v`` (0: a hover)."""
    t = CF.commander_dt * np.arange(int(round(seconds / CF.commander_dt)) + 1)
    d = np.asarray(direction, float)
    pos = (np.asarray(start, float) + v * t[:, None] * d)[None]
    vel = np.broadcast_to(v * d, pos.shape).copy()
    return Setpoints(t, pos, vel, np.zeros_like(pos), np.zeros_like(pos))


def test_a_hover_holds_exactly():
    sp = line(0.0, 1.0)
    flight = fly(sp)
    np.testing.assert_allclose(flight.pos[0], sp.pos[0], atol=1e-12)
    np.testing.assert_allclose(flight.euler[0], 0.0, atol=1e-12)
    # the height integrator closes the gap between the firmware's thrust mapping and the weight
    gain = CF.mass_thrust * CF.max_thrust / PWM_MAX
    assert gain * (CF.mass * G + CF.ki_z * hover_integral(CF)) == pytest.approx(CF.mass * G, rel=1e-12)


def zoh_lag(cf: Crazyflie, v: float) -> float:
    """The commander holds each set-point for a tick while the controller samples the position
    ``sub`` times in it: with the mean error of those samples zero, the vehicle is
    ``v (commander_dt - control_dt) / 2`` behind the set-point at each tick."""
    return v * (cf.commander_dt - cf.control_dt) / 2.0


def test_a_straight_line_at_constant_speed_is_tracked_with_zero_steady_state_error():
    # Without drag and without the integral, the error the controller sees averages zero over
    # each commander tick: the vehicle runs exactly the hold's lag behind, nothing more.
    cf = replace(CF, k_aero=(0.0, 0.0, 0.0), ki_xy=0.0)
    v, d = 1.5, np.array([0.6, 0.8, 0.0])
    sp = line(v, 3.0, direction=tuple(d))
    err = sp.pos[0] - fly(sp, cf).pos[0]
    np.testing.assert_allclose(err[-1], zoh_lag(cf, v) * d, atol=1e-6)


def test_rotor_drag_adds_the_lag_drag_over_stiffness_without_the_integral():
    # Steady on a line at speed v the position error's force, through the thrust mapping,
    # balances the rotor drag: e = c v / (gain kp), beside the hold's lag.
    cf = replace(CF, ki_xy=0.0)
    v = 0.5
    sp = line(v, 4.0)
    err = sp.pos[0] - fly(sp, cf).pos[0]
    gain = cf.mass_thrust * cf.max_thrust / PWM_MAX
    assert err[-1, 0] == pytest.approx(cf.rotor_drag[0] * v / (gain * cf.kp_xy) + zoh_lag(cf, v), rel=1e-3)
    assert err[-1, 0] == pytest.approx(cf.tracking_lag(v), rel=1e-3)  # the horizontal lag is the larger
    assert abs(err[-1, 1]) < 1e-9 and abs(err[-1, 2]) < 1e-5
    # Förster's rotor drag: K_aero times the four rotors' speed at hover
    assert cf.rotor_drag[0] == pytest.approx(9.1785e-7 * 4 * math.sqrt(cf.mass * G / 4 / 1.28e-8))


def test_the_integral_removes_the_drag_lag():
    # The integral drives the drag lag towards the hold's lag alone, at about ki / kp (the
    # firmware's 0.125 1/s; here ten times that, for a short test).
    cf = replace(CF, ki_xy=0.5)
    v = 0.5
    sp = line(v, 5.0)
    lag = (sp.pos[0] - fly(sp, cf).pos[0])[:, 0] - zoh_lag(cf, v)
    assert lag[-1] < 0.05 * lag.max()


def test_body_rates_of_a_flat_trajectory():
    j = 2.0
    w = body_rates(np.zeros((3, 3)), np.array([[j, 0, 0], [0, j, 0], [0, 0, j]]), np.zeros(3), np.zeros(3))
    np.testing.assert_allclose(w, [[0, j / G, 0], [-j / G, 0, 0], [0, 0, 0]], atol=1e-15)


def test_the_motor_mix_and_its_cap():
    thrust, tau, capped = mix(np.array([30000.0]), np.array([[1000.0, -2000.0, 500.0]]), CF)
    k = CF.thrust_max_motor / PWM_MAX
    a = CF.arm_length / math.sqrt(2)
    assert thrust[0] == pytest.approx(4 * 30000 * k)
    expected = [2 * a * k * 1000, -2 * a * k * 2000, 4 * CF.thrust_to_torque * k * 500]
    np.testing.assert_allclose(tau[0], expected)
    assert not capped[0]
    # A motor above full PWM lowers all four by the excess: the torques stay, the thrust drops.
    thrust, tau, capped = mix(np.array([65000.0]), np.array([[2000.0, 0.0, 0.0]]), CF)
    excess = 65000 + 1000 - PWM_MAX
    assert capped[0] and thrust[0] == pytest.approx(4 * (65000 - excess) * k)
    np.testing.assert_allclose(tau[0], [2 * a * k * 2000, 0.0, 0.0])


def test_the_thrust_mapping_leaves_part_of_an_acceleration_to_the_position_error():
    # Without drag and integral, at a constant acceleration a the feed-forward m a gives only
    # gain m a: the position error makes up the rest, (1 - gain) m a / (gain kp), beside the
    # hold's lag at the speed reached.
    cf = replace(CF, k_aero=(0.0, 0.0, 0.0), ki_xy=0.0)
    a = 0.5
    t = cf.commander_dt * np.arange(301)
    z = np.zeros_like(t)
    col = lambda u, h=0.0: np.column_stack([u, z, z + h])[None]  # noqa: E731
    sp = Setpoints(t, col(0.5 * a * t**2, 1.0), col(a * t), col(a + z), col(z))
    err = (sp.pos[0] - fly(sp, cf).pos[0])[-1, 0]
    assert err == pytest.approx(cf.tracking_lag(a * t[-1], a), rel=2e-2)
    gain = cf.mass_thrust * cf.max_thrust / PWM_MAX
    assert cf.tracking_lag(0.0, a) == pytest.approx((1 - gain) * cf.mass * a / (gain * cf.kp_xy))


def test_the_tracking_lag_bounds_a_flight_that_speeds_up_and_slows_down():
    # A line whose speed rises to 1.4 m/s and falls back (the position loop is damped, 0.95 of
    # critical): the vehicle never runs farther behind than the lag at the top speed and
    # acceleration.
    t = CF.commander_dt * np.arange(601)
    s = np.clip(t / 6.0, 0.0, 1.0)
    x = 4.5 * (10 * s**3 - 15 * s**4 + 6 * s**5)  # top speed 4.5 * 1.875 / 6 = 1.406 m/s
    v = 4.5 * (30 * s**2 - 60 * s**3 + 30 * s**4) / 6.0
    a = 4.5 * (60 * s - 180 * s**2 + 120 * s**3) / 36.0
    j = 4.5 * (60 - 360 * s + 360 * s**2) / 216.0
    z = np.zeros_like(t)
    col = lambda u, h=0.0: np.column_stack([u, z, z + h])[None]  # noqa: E731
    sp = Setpoints(t, col(x, 1.0), col(v), col(a), col(j))
    err = np.linalg.norm(sp.pos[0] - fly(sp).pos[0], axis=1)
    lag = CF.tracking_lag(float(v.max()), float(np.abs(a).max()))
    assert err.max() <= lag
    assert err.max() >= 0.7 * lag  # and that is what it runs behind


def test_the_jerk_limit_keeps_the_body_rates_within_the_gyro_range():
    # Accelerating downwards at the limit leaves the least thrust, g - a: there a jerk across
    # the thrust at the limit asks for exactly the gyro's range, anywhere else for less.
    a_max = 2.0
    j = CF.max_jerk(a_max)
    assert j == pytest.approx(math.radians(2000.0) * (G - a_max))
    w = body_rates(np.array([[0.0, 0.0, -a_max]]), np.array([[j, 0.0, 0.0]]), np.zeros(1), np.zeros(1))
    assert np.linalg.norm(w) == pytest.approx(CF.gyro_range)
    rng = np.random.default_rng(3)
    acc = rng.normal(size=(2000, 3))
    acc *= (a_max * rng.uniform(size=2000) / np.linalg.norm(acc, axis=1))[:, None]
    jerk = rng.normal(size=(2000, 3))
    jerk *= (j / np.linalg.norm(jerk, axis=1))[:, None]
    rates = body_rates(acc, jerk, np.zeros(2000), np.zeros(2000))
    assert np.linalg.norm(rates, axis=1).max() <= CF.gyro_range * (1 + 1e-12)
