"""Quadrotor rigid body under 004's cascaded PID, vectorized over agents.

State per agent (13 numbers): position p, velocity v (world frame, z up), Euler angles
(roll, pitch, yaw; R = Rz(yaw) Ry(pitch) Rx(roll)), body rates w, and the actual collective
thrust T (the motors follow the command with a first-order lag).

    p' = v
    v' = T/m * R e3 - g e3 - drag/m * |v| v
    eta' = W(roll, pitch) w          (Euler-angle kinematics)
    w' = J^-1 (tau - w x J w)
    T' = (T_cmd - T) / motor_time_constant,  T_cmd in [0, thrust_to_weight * m g]

Controller (held constant over each control period, as on a flight computer):

    position PID -> desired specific force  a_ref + kp e_p + kd e_v + ki ∫e_p  (+ g, + expected drag)
                  -> tilt limited, thrust limited (vertical first), inverted into
                     desired roll/pitch (yaw held at 0) and collective thrust (projected on the
                     current body z axis)
    attitude P(ID) -> desired body rates (through W^-1), clipped to max_rate
    rate PID       -> torque  J * (PID output) + w x J w

Body torques are not saturated: with a thrust-to-weight ratio of 2 the differential thrust
left for attitude is ample for the rates used here; the collective thrust is the limit that
binds, and it is modelled. The dynamics are integrated with classical RK4 at the control
period.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from swarmplan.world.tracker_config import G, TrackerConfig

from .reference import Reference

# Clamp of the integral terms' contribution (m/s^2 for position, rad/s^2 for rates): anti-windup
# so a large error (an infeasible reference) does not leave a long drift behind it.
_POS_I_LIMIT = 1.0
_RATE_I_LIMIT = 5.0


@dataclass(frozen=True)
class Flight:
    """Tracked states on the reference grid: arrays (A, K, 3) or (A, K)."""

    times: np.ndarray  # (K,)
    pos: np.ndarray
    vel: np.ndarray
    euler: np.ndarray  # roll, pitch, yaw in rad
    thrust: np.ndarray  # actual collective thrust, N
    tilt_deg: np.ndarray  # angle of the body z axis from vertical
    saturated: np.ndarray  # bool: thrust command clipped at max or tilt limit active


def _body_z(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    return _body_z_of(np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw))


def _body_z_of(
    cr: np.ndarray, sr: np.ndarray, cp: np.ndarray, sp: np.ndarray, cy: np.ndarray, sy: np.ndarray
) -> np.ndarray:
    """The body z axis (..., 3) from the cosines and sines of roll, pitch and yaw."""
    z = np.empty((*cr.shape, 3))
    z[..., 0] = cr * sp * cy + sr * sy
    z[..., 1] = cr * sp * sy - sr * cy
    z[..., 2] = cr * cp
    return z


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (A, 3) arrays (np.cross costs ~10x more on small arrays)."""
    out = np.empty_like(a)
    out[:, 0] = a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1]
    out[:, 1] = a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2]
    out[:, 2] = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    return out


def rotation(euler: np.ndarray) -> np.ndarray:
    """Body-to-world rotation matrices (..., 3, 3) of Euler angles (..., 3) (roll, pitch, yaw;
    R = Rz(yaw) Ry(pitch) Rx(roll)): the columns are the body x, y and z axes."""
    cr, sr = np.cos(euler[..., 0]), np.sin(euler[..., 0])
    cp, sp = np.cos(euler[..., 1]), np.sin(euler[..., 1])
    cy, sy = np.cos(euler[..., 2]), np.sin(euler[..., 2])
    r = np.empty((*euler.shape[:-1], 3, 3))
    r[..., 0, 0] = cy * cp
    r[..., 0, 1] = cy * sp * sr - sy * cr
    r[..., 0, 2] = cy * sp * cr + sy * sr
    r[..., 1, 0] = sy * cp
    r[..., 1, 1] = sy * sp * sr + cy * cr
    r[..., 1, 2] = sy * sp * cr - cy * sr
    r[..., 2, 0] = -sp
    r[..., 2, 1] = cp * sr
    r[..., 2, 2] = cp * cr
    return r


def _deriv(
    x: np.ndarray,
    t_cmd: np.ndarray,
    tau: np.ndarray,
    cfg: TrackerConfig,
    inertia: np.ndarray,
    rotor_drag: np.ndarray | None = None,
) -> np.ndarray:
    """The state's rate of change (A, 13). ``cfg`` gives ``mass``, the quadratic ``drag`` and the
    ``motor_time_constant``; ``rotor_drag`` (3,), N s/m per world axis, adds a drag linear in the
    velocity (a small rotor's blade flapping and induced drag)."""
    v = x[:, 3:6]
    roll, pitch, yaw = x[:, 6], x[:, 7], x[:, 8]
    w = x[:, 9:12]
    thrust = x[:, 12]
    dx = np.empty_like(x)
    dx[:, 0:3] = v
    speed = np.sqrt(np.einsum("ij,ij->i", v, v))
    sr, cr = np.sin(roll), np.cos(roll)
    tp, cp = np.tan(pitch), np.cos(pitch)
    body_z = _body_z_of(cr, sr, cp, np.sin(pitch), np.cos(yaw), np.sin(yaw))
    acc = (thrust / cfg.mass)[:, None] * body_z - (cfg.drag / cfg.mass) * speed[:, None] * v
    if rotor_drag is not None:
        acc -= (rotor_drag / cfg.mass) * v
    acc[:, 2] -= G
    dx[:, 3:6] = acc
    p, q, r = w[:, 0], w[:, 1], w[:, 2]
    dx[:, 6] = p + (sr * q + cr * r) * tp
    dx[:, 7] = cr * q - sr * r
    dx[:, 8] = (sr * q + cr * r) / cp
    jw = w * inertia
    dx[:, 9:12] = (tau - _cross(w, jw)) / inertia
    dx[:, 12] = (t_cmd - thrust) / cfg.motor_time_constant
    return dx


def rk4_step(
    x: np.ndarray,
    t_cmd: np.ndarray,
    tau: np.ndarray,
    cfg: TrackerConfig,
    inertia: np.ndarray,
    dt: float,
    rotor_drag: np.ndarray | None = None,
) -> np.ndarray:
    """The state ``dt`` later, the commands held over the step (classical RK4)."""
    k1 = _deriv(x, t_cmd, tau, cfg, inertia, rotor_drag)
    k2 = _deriv(x + 0.5 * dt * k1, t_cmd, tau, cfg, inertia, rotor_drag)
    k3 = _deriv(x + 0.5 * dt * k2, t_cmd, tau, cfg, inertia, rotor_drag)
    k4 = _deriv(x + dt * k3, t_cmd, tau, cfg, inertia, rotor_drag)
    return x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)


def simulate(ref: Reference, cfg: TrackerConfig) -> Flight:
    """Fly every agent of ``ref`` from rest-at-reference (hover thrust) with the cascaded PID."""
    n_a, n_k = ref.pos.shape[0], len(ref.times)
    dt = float(ref.times[1] - ref.times[0]) if n_k > 1 else cfg.dt
    inertia = np.asarray(cfg.inertia, float)
    t_max = cfg.max_thrust
    tan_tilt = np.tan(np.radians(cfg.max_tilt_deg))
    max_rate = np.radians(cfg.max_rate_deg_s)
    pos_g, att_g, rate_g = cfg.position, cfg.attitude, cfg.rate

    x = np.zeros((n_a, 13))
    x[:, 0:3] = ref.pos[:, 0]
    x[:, 3:6] = ref.vel[:, 0]
    x[:, 12] = cfg.mass * G
    i_pos = np.zeros((n_a, 3))
    i_att = np.zeros((n_a, 3))
    i_rate = np.zeros((n_a, 3))
    prev_att_err = np.zeros((n_a, 3))
    prev_rate_err = np.zeros((n_a, 3))

    out_pos = np.empty((n_a, n_k, 3))
    out_vel = np.empty((n_a, n_k, 3))
    out_eul = np.empty((n_a, n_k, 3))
    out_thr = np.empty((n_a, n_k))
    out_sat = np.zeros((n_a, n_k), bool)
    sat_prev = np.zeros(n_a, bool)

    for k in range(n_k):
        p, v = x[:, 0:3], x[:, 3:6]
        roll, pitch, yaw = x[:, 6], x[:, 7], x[:, 8]
        out_pos[:, k] = p
        out_vel[:, k] = v
        out_eul[:, k] = x[:, 6:9]
        out_thr[:, k] = x[:, 12]
        if k == n_k - 1:
            break

        # --- position loop (PID, velocity error as the derivative of the position error)
        e_p = ref.pos[:, k] - p
        e_v = ref.vel[:, k] - v
        # Conditional integration: no integrating while the last command was saturated (a jump
        # in the reference would otherwise charge the integrator and leave a slow drift behind).
        i_lim = _POS_I_LIMIT / max(pos_g.ki, 1e-12)
        i_pos = np.clip(i_pos + np.where(sat_prev[:, None], 0.0, e_p * dt), -i_lim, i_lim)
        a_cmd = ref.acc[:, k] + pos_g.kp * e_p + pos_g.kd * e_v + pos_g.ki * i_pos
        f = cfg.mass * a_cmd
        f[:, 2] += cfg.mass * G
        if cfg.drag_feedforward:
            vr = ref.vel[:, k]
            f += cfg.drag * np.linalg.norm(vr, axis=1)[:, None] * vr
        # Limits, vertical first: hold altitude before chasing the horizontal error.
        fz = np.clip(f[:, 2], 0.05 * cfg.mass * G, t_max)
        h = np.linalg.norm(f[:, :2], axis=1)
        h_max = np.minimum(fz * tan_tilt, np.sqrt(np.maximum(t_max**2 - fz**2, 0.0)))
        scale = np.minimum(1.0, h_max / np.maximum(h, 1e-12))
        sat = (scale < 1.0 - 1e-9) | (f[:, 2] > t_max) | (f[:, 2] < 0.05 * cfg.mass * G)
        f[:, 0] *= scale
        f[:, 1] *= scale
        f[:, 2] = fz
        b3d = f / np.linalg.norm(f, axis=1)[:, None]
        roll_d = np.arcsin(np.clip(-b3d[:, 1], -1.0, 1.0))
        pitch_d = np.arctan2(b3d[:, 0], b3d[:, 2])
        b3 = _body_z(roll, pitch, yaw)
        t_cmd = np.clip(np.einsum("ij,ij->i", f, b3), 0.0, t_max)
        out_sat[:, k] = sat
        sat_prev = sat

        # --- attitude loop: Euler-angle PID -> Euler rates -> body rates (W^-1)
        e_att = np.empty((n_a, 3))
        e_att[:, 0], e_att[:, 1], e_att[:, 2] = roll_d - roll, pitch_d - pitch, -yaw
        i_att += e_att * dt
        eta_dot = att_g.kp * e_att + att_g.ki * i_att + att_g.kd * (e_att - prev_att_err) / dt * (k > 0)
        prev_att_err = e_att
        sr, cr, sp, cp = np.sin(roll), np.cos(roll), np.sin(pitch), np.cos(pitch)
        w_d = np.empty((n_a, 3))
        w_d[:, 0] = eta_dot[:, 0] - sp * eta_dot[:, 2]
        w_d[:, 1] = cr * eta_dot[:, 1] + sr * cp * eta_dot[:, 2]
        w_d[:, 2] = -sr * eta_dot[:, 1] + cr * cp * eta_dot[:, 2]
        w_d = np.clip(w_d, -max_rate, max_rate)

        # --- rate loop: PID on body rates -> torque
        w = x[:, 9:12]
        e_w = w_d - w
        lim = _RATE_I_LIMIT / max(rate_g.ki, 1e-12)
        i_rate = np.clip(i_rate + e_w * dt, -lim, lim)
        alpha = rate_g.kp * e_w + rate_g.ki * i_rate + rate_g.kd * (e_w - prev_rate_err) / dt * (k > 0)
        prev_rate_err = e_w
        tau = inertia * alpha + _cross(w, w * inertia)

        # --- RK4 with the commands held over the period
        x = rk4_step(x, t_cmd, tau, cfg, inertia, dt)

    b3_all = _body_z(out_eul[..., 0], out_eul[..., 1], out_eul[..., 2])
    tilt = np.degrees(np.arccos(np.clip(b3_all[..., 2], -1.0, 1.0)))
    return Flight(ref.times, out_pos, out_vel, out_eul, out_thr, tilt, out_sat)
