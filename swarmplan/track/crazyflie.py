"""A Crazyflie flying a trajectory as its firmware does: the high-level commander evaluates the
polynomial, the Mellinger controller tracks it, the legacy power distribution drives the motors.

Everything below follows bitcraze/crazyflie-firmware (``src/modules/src``):

- **Commander** (``crtp_commander_high_level.c``, ``pptraj.c``): at 100 Hz (``RATE_HL_COMMANDER``)
  the set-point is the trajectory's position, velocity and acceleration, yaw, and the body
  rates a differentially flat quadrotor needs (``poly4d_eval``: the jerk orthogonal to the
  thrust axis over the thrust's magnitude, ``omega = (-h . y_b, h . x_b, z_b,z dyaw)``). The
  set-point is held between commander ticks.
- **Controller** (``controller_mellinger.c``, its default gains), at 500 Hz
  (``ATTITUDE_RATE``): the desired force
  ``F = m (a_ref + g e3) + kp e_p + kd e_v + ki int e_p`` (xy: 0.4 N/m, 0.2 N s/m, 0.05 N/(m s),
  integral within 2 m s; z: 1.25, 0.4, 0.05, within 0.4 m s), the thrust its projection on the
  body z axis times ``massThrust`` = 132000 PWM/N, the desired attitude with z along ``F`` and
  the set-point's yaw, the rotation error ``eR = vee(Rd^T R - R^T Rd)`` (no factor 1/2, as the
  firmware), and the moment in PWM units ``M = -kR eR + kw (w_ref - w) + ki_m int(-eR)`` plus
  ``kd_omega`` times the derivative of the roll and pitch rate errors (kR 70000 / 60000 yaw,
  kw 20000 / 12000, ki_m 0 / 500 within 1 / 1500, kd_omega 200), each clamped to +-32000.
- **Motors** (``power_distribution_quadrotor.c``, ``powerDistributionLegacy`` and
  ``powerDistributionCap``): ``m_i = thrust -+ roll/2 -+ pitch/2 -+ yaw``; when one motor asks
  for more than 65535 all are lowered by the excess (attitude before thrust), none below 0.
  A motor's force is its PWM over 65535 times ``THRUST_MAX`` = 0.12 N (the firmware's
  battery-compensated thrust mapping, ``platform_defaults_cf2.h``), at ``ARM_LENGTH`` 0.046 m
  on the diagonals, its drag torque ``THRUST2TORQUE`` = 0.00699 m times its force.

- **Gyro** (``src/hal/src/sensors_bmi088_bmp3xx.c``): the BMI088 is set to +-2000 deg/s
  (``SENSORS_BMI088_GYRO_FS_CFG``); the body rates a trajectory may ask for
  (:meth:`Crazyflie.max_jerk`).

The body is the rigid-body model of ``quadrotor.py`` (one model), with the Crazyflie 2.1's
mass (``CF_MASS`` 0.029 kg), the inertia identified by Förster (System Identification of the
Crazyflie 2.0 Nano Quadrocopter, ETH Zurich 2015: 16.6e-6, 16.6e-6, 29.3e-6 kg m^2) and its
rotor drag, linear in the velocity: ``K_aero`` = 9.1785e-7 (xy) and 10.311e-7 (z) kg/rad times
the rotors' summed speed at hover (each rotor's hover thrust ``m g / 4`` over the thrust
coefficient 1.28e-8 N s^2 of the same identification, about 2350 rad/s). The motors follow
their command with a 0.02 s lag. The state estimate is the true state.

The flight starts at rest in a settled hover at the trajectory's first set-point (the height
integrator at the value that holds the hover, as after the take-off that precedes a
trajectory).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from swarmplan.world.tracker_config import G

from .quadrotor import rk4_step, rotation

PWM_MAX = 65535.0
K_AERO = (9.1785e-7, 9.1785e-7, 10.311e-7)  # kg/rad, rotor drag per unit rotor speed (Förster)
THRUST_COEFFICIENT = 1.28e-8  # N s^2 / rad^2, rotor thrust per squared rotor speed (Förster)


@dataclass(frozen=True)
class Crazyflie:
    """The vehicle, its firmware's constants and the Mellinger controller's default gains."""

    mass: float = 0.029  # kg, CF_MASS
    inertia: tuple[float, float, float] = (16.6e-6, 16.6e-6, 29.3e-6)  # kg m^2
    arm_length: float = 0.046  # m, ARM_LENGTH: centre to motor
    thrust_max_motor: float = 0.12  # N per motor at PWM 65535, THRUST_MAX
    thrust_to_torque: float = 0.0069928948992470565  # m, THRUST2TORQUE
    motor_time_constant: float = 0.02  # s
    drag: float = 0.0  # N s^2/m^2: no drag quadratic in the speed beyond the rotor drag
    k_aero: tuple[float, float, float] = K_AERO  # kg/rad, rotor drag per unit rotor speed
    gyro_range: float = math.radians(2000.0)  # rad/s: the BMI088 gyro's range as the firmware sets it
    control_dt: float = 1.0 / 500.0  # s, ATTITUDE_RATE
    commander_dt: float = 1.0 / 100.0  # s, RATE_HL_COMMANDER
    mass_thrust: float = 132000.0  # PWM per N
    kp_xy: float = 0.4
    kd_xy: float = 0.2
    ki_xy: float = 0.05
    i_range_xy: float = 2.0
    kp_z: float = 1.25
    kd_z: float = 0.4
    ki_z: float = 0.05
    i_range_z: float = 0.4
    kR_xy: float = 70000.0
    kw_xy: float = 20000.0
    ki_m_xy: float = 0.0
    i_range_m_xy: float = 1.0
    kR_z: float = 60000.0
    kw_z: float = 12000.0
    ki_m_z: float = 500.0
    i_range_m_z: float = 1500.0
    kd_omega_rp: float = 200.0

    @property
    def max_thrust(self) -> float:
        """N, all four motors at full PWM."""
        return 4.0 * self.thrust_max_motor

    def max_jerk(self, accel_limit: float) -> float:
        """m/s^3: the largest jerk a trajectory whose acceleration stays within ``accel_limit`` may
        ask for, so that the body rates it needs stay within the gyro's range.

        A flat trajectory needs the body rates ``|w_xy| = |j_perp| / |a + g e3|`` (the jerk across
        the thrust axis over the thrust acceleration; :func:`body_rates`). With ``|a| <= a_max``
        the thrust acceleration is at least ``g - a_max``, so ``|j| <= gyro_range (g - a_max)``
        keeps every rate within ``gyro_range``: a rate the gyro cannot measure is one the rate
        loop cannot hold."""
        return self.gyro_range * max(G - accel_limit, 0.0)

    def tracking_lag(self, speed: float, accel: float = 0.0) -> float:
        """m: how far the controller runs behind a trajectory flown at up to ``speed`` and
        ``accel`` (the most of the horizontal and the vertical axis). The feed-forward of the
        trajectory's velocity and acceleration leaves two forces to the position error: the
        rotor drag ``c v``, which it does not carry, and the part of ``m a`` the thrust mapping
        does not give (it gives ``gain`` = ``massThrust`` 4 ``THRUST_MAX`` / 65535 = 0.967 N per
        N asked; the height integrator makes up the weight's part, not an acceleration's). The
        position loop balances them at ``(c v + (1 - gain) m a) / (gain kp)``; it is damped
        (0.95 of critical in the plane), so a force that changes within those bounds moves it
        no farther. Beside them the commander holds each set-point for a tick while the
        controller samples it five times: ``v (commander_dt - control_dt) / 2`` more. The
        integral wins the drag's part back slowly (ki / kp = 0.125 per second)."""
        gain = self.mass_thrust * self.max_thrust / PWM_MAX
        kp = np.array([self.kp_xy, self.kp_xy, self.kp_z])
        force = self.rotor_drag * speed + abs(1.0 - gain) * self.mass * accel
        return float(np.max(force / (gain * kp))) + speed * 0.5 * (self.commander_dt - self.control_dt)

    @property
    def rotor_drag(self) -> np.ndarray:
        """N s/m per world axis: ``K_aero`` times the four rotors' speed at hover."""
        omega = math.sqrt(self.mass * G / 4.0 / THRUST_COEFFICIENT)
        return np.asarray(self.k_aero) * 4.0 * omega


@dataclass(frozen=True)
class Setpoints:
    """The commander's set-points of ``A`` vehicles at its ticks ``times`` (K,), every
    ``commander_dt``: arrays (A, K, 3) (yaw 0 rad throughout)."""

    times: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    acc: np.ndarray
    jerk: np.ndarray


@dataclass(frozen=True)
class CrazyflieFlight:
    """The vehicles' states at the commander's ticks: arrays (A, K, 3) or (A, K)."""

    times: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    euler: np.ndarray
    thrust: np.ndarray  # N, actual collective thrust
    capped: np.ndarray  # bool: some motor asked for more than full PWM at the tick


def body_rates(acc: np.ndarray, jerk: np.ndarray, yaw: np.ndarray, yaw_rate: np.ndarray) -> np.ndarray:
    """The body rates (..., 3) a flat quadrotor needs on a trajectory (``pptraj.c``,
    ``poly4d_eval``)."""
    thrust = acc.copy()
    thrust[..., 2] += G
    mag = np.linalg.norm(thrust, axis=-1, keepdims=True)
    z_b = thrust / mag
    x_w = np.stack([np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)], axis=-1)
    y_b = np.cross(z_b, x_w)
    y_b /= np.linalg.norm(y_b, axis=-1, keepdims=True)
    x_b = np.cross(y_b, z_b)
    h = (jerk - np.sum(jerk * z_b, axis=-1, keepdims=True) * z_b) / mag
    return np.stack([-np.sum(h * y_b, axis=-1), np.sum(h * x_b, axis=-1), z_b[..., 2] * yaw_rate], axis=-1)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.stack(
        [
            a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
            a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
            a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0],
        ],
        axis=1,
    )


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]


def _unit(a: np.ndarray) -> np.ndarray:
    return a / np.sqrt(_dot(a, a))[:, None]


def hover_integral(cf: Crazyflie) -> float:
    """The height integrator (m s) at which the commanded thrust holds a hover (the thrust
    mapping gives ``massThrust * 4 * THRUST_MAX / 65535`` N per N asked, not exactly 1)."""
    gain = cf.mass_thrust * cf.max_thrust / PWM_MAX
    return float(np.clip(cf.mass * G * (1.0 / gain - 1.0) / cf.ki_z, -cf.i_range_z, cf.i_range_z))


def mix(
    thrust_pwm: np.ndarray, moment: np.ndarray, cf: Crazyflie
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Motor forces from the controller's output (legacy power distribution, capped): collective
    thrust (A,) N, body torques (A, 3) N m, and whether the cap was hit (A,)."""
    roll = np.trunc(np.clip(moment[:, 0], -32000.0, 32000.0))  # control_t holds int16
    pitch = np.trunc(np.clip(moment[:, 1], -32000.0, 32000.0))
    yaw = np.trunc(np.clip(moment[:, 2], -32000.0, 32000.0))
    on = thrust_pwm > 0
    roll, pitch, yaw = roll * on, pitch * on, yaw * on
    r, p = np.trunc(roll / 2.0), np.trunc(pitch / 2.0)
    m = np.stack(
        [
            thrust_pwm - r + p + yaw,
            thrust_pwm - r - p - yaw,
            thrust_pwm + r - p + yaw,
            thrust_pwm + r + p - yaw,
        ],
        axis=1,
    )
    excess = np.maximum(m.max(axis=1) - PWM_MAX, 0.0)
    m = np.maximum(m - excess[:, None], 0.0)
    f = m / PWM_MAX * cf.thrust_max_motor
    a = cf.arm_length / math.sqrt(2.0)
    # Motors 1-4 placed so that the roll, pitch and yaw commands are torques about +x, +y, +z.
    tau = np.stack(
        [
            a * (-f[:, 0] - f[:, 1] + f[:, 2] + f[:, 3]),
            a * (f[:, 0] - f[:, 1] - f[:, 2] + f[:, 3]),
            cf.thrust_to_torque * (f[:, 0] - f[:, 1] + f[:, 2] - f[:, 3]),
        ],
        axis=1,
    )
    return f.sum(axis=1), tau, excess > 0


def fly(sp: Setpoints, cf: Crazyflie | None = None) -> CrazyflieFlight:
    """Fly every vehicle of ``sp`` from a settled hover at its first set-point (module
    docstring); the states at each commander tick."""
    cf = cf or Crazyflie()
    n_a, n_k = sp.pos.shape[0], len(sp.times)
    sub = int(round(cf.commander_dt / cf.control_dt))
    dt = cf.control_dt
    inertia = np.asarray(cf.inertia, float)
    drag = cf.rotor_drag
    omega_ref = body_rates(sp.acc, sp.jerk, np.zeros(sp.acc.shape[:2]), np.zeros(sp.acc.shape[:2]))
    kp = np.array([cf.kp_xy, cf.kp_xy, cf.kp_z])
    kd = np.array([cf.kd_xy, cf.kd_xy, cf.kd_z])
    ki = np.array([cf.ki_xy, cf.ki_xy, cf.ki_z])
    i_range = np.array([cf.i_range_xy, cf.i_range_xy, cf.i_range_z])
    k_r = np.array([cf.kR_xy, cf.kR_xy, cf.kR_z])
    k_w = np.array([cf.kw_xy, cf.kw_xy, cf.kw_z])
    ki_m = np.array([cf.ki_m_xy, cf.ki_m_xy, cf.ki_m_z])
    i_range_m = np.array([cf.i_range_m_xy, cf.i_range_m_xy, cf.i_range_m_z])
    kd_w = np.array([cf.kd_omega_rp, cf.kd_omega_rp, 0.0])
    x_c = np.tile([1.0, 0.0, 0.0], (n_a, 1))  # desired yaw 0

    x = np.zeros((n_a, 13))
    x[:, 0:3] = sp.pos[:, 0]
    x[:, 3:6] = sp.vel[:, 0]
    x[:, 12] = cf.mass * G
    i_p = np.zeros((n_a, 3))
    i_p[:, 2] = hover_integral(cf)
    i_m = np.zeros((n_a, 3))
    prev_w = prev_w_ref = None
    tau = np.zeros((n_a, 3))
    lag = math.exp(-dt / cf.motor_time_constant)

    out_pos = np.empty((n_a, n_k, 3))
    out_vel = np.empty((n_a, n_k, 3))
    out_eul = np.empty((n_a, n_k, 3))
    out_thr = np.empty((n_a, n_k))
    out_cap = np.zeros((n_a, n_k), bool)
    for k in range(n_k):
        out_pos[:, k] = x[:, 0:3]
        out_vel[:, k] = x[:, 3:6]
        out_eul[:, k] = x[:, 6:9]
        out_thr[:, k] = x[:, 12]
        if k == n_k - 1:
            break
        p_ref, v_ref, a_ref, w_ref = sp.pos[:, k], sp.vel[:, k], sp.acc[:, k], omega_ref[:, k]
        for _ in range(sub):
            e_p = p_ref - x[:, 0:3]
            e_v = v_ref - x[:, 3:6]
            i_p = np.clip(i_p + e_p * dt, -i_range, i_range)
            force = cf.mass * a_ref + kp * e_p + kd * e_v + ki * i_p
            force[:, 2] += cf.mass * G
            rot = rotation(x[:, 6:9])
            r0, r1, r2 = rot[:, :, 0], rot[:, :, 1], rot[:, :, 2]
            current = _dot(force, r2)
            z_d = _unit(force)
            y_d = _unit(_cross(z_d, x_c))
            x_d = _cross(y_d, z_d)
            # vee(Rd^T R - R^T Rd), Rd's columns x_d, y_d, z_d and R's r0, r1, r2
            e_r = np.stack(
                [_dot(z_d, r1) - _dot(r2, y_d), _dot(x_d, r2) - _dot(r0, z_d), _dot(y_d, r0) - _dot(r1, x_d)],
                axis=1,
            )
            w = x[:, 9:12]
            e_w = w_ref - w
            d_w = np.zeros((n_a, 3)) if prev_w is None else ((w_ref - prev_w_ref) - (w - prev_w)) / dt
            prev_w, prev_w_ref = w.copy(), w_ref
            i_m = np.clip(i_m - e_r * dt, -i_range_m, i_range_m)
            moment = -k_r * e_r + k_w * e_w + ki_m * i_m + kd_w * d_w
            thrust_pwm = cf.mass_thrust * current
            off = thrust_pwm <= 0
            if off.any():  # the firmware resets its integrators with the motors off
                i_p[off] = 0.0
                i_m[off] = 0.0
            thrust, tau_cmd, capped = mix(thrust_pwm, moment, cf)
            out_cap[:, k + 1] |= capped
            # The four motors lag their commands: the body model lags the collective thrust, the
            # torques (the same motors' forces, mixed) lag here by the same time constant.
            tau = tau_cmd + (tau - tau_cmd) * lag
            x = rk4_step(x, thrust, tau, cf, inertia, dt, drag)  # type: ignore[arg-type]
    return CrazyflieFlight(sp.times, out_pos, out_vel, out_eul, out_thr, out_cap)
