"""Fixed-wing tracking: a coordinated-turn aircraft flies the recorded trajectory of a fixed wing.

Vehicle (point mass in coordinated flight, SI units):

- heading ``psi' = g tan(phi) / V`` (a coordinated turn: the bank ``phi`` tilts the lift, no
  sideslip); the bank follows its command with a first-order lag (``roll_time_constant``) at
  a roll rate of at most ``max_roll_rate_deg_s``, and never beyond ``max_bank_deg``. The
  aircraft rolls at least as the airframe the simulation flew (the log's ``roll_rate``): at
  its roll rate when that is faster, and with a lag that settles (four time constants, 98 %)
  within the airframe's roll-in, the time its roll rate takes to the bank of a minimum-radius
  turn at cruise speed (paper 001's world at 1:50 rolls into 83 degrees in 0.18 s);
- flight-path angle ``gamma' = (gamma_cmd - gamma) / tau``, ``tau`` the ``pitch_time_constant``,
  or the bank's lag when the airframe's is shorter (an airframe that rolls into a
  minimum-radius turn within a fraction of a second pulls up as quickly: the simulated model
  may climb or dive on a curve of R_min from one step to the next, as it turns), ``|gamma|``
  within the world's climb angle plus ``climb_margin_deg``;
- airspeed ``V' = (T - D) / m - g sin(gamma)``: the thrust channel commands the specific
  thrust-minus-drag, within ``±thrust_accel_factor * max_accel``, and the airspeed stays within
  the world's [speed.min, speed.max].

Guidance and control:

- lateral: L1 guidance (Park, Deyst and How, 2004) on the reference trajectory: the aim point
  is the reference ``l1_time`` seconds ahead of the current reference time, ``eta`` the
  horizontal angle between the velocity and the line to it, and the commanded lateral
  acceleration ``2 V^2 sin(eta) / L`` (``L`` the distance to the aim point) gives the bank
  ``atan(a / g)``. On a circle of radius R it asks exactly for V^2 / R.
- energy (TECS-like): the thrust channel holds the total energy rate — the reference's
  acceleration plus a PD on the along-track error feeds ``V'``, and ``g sin(gamma)`` is added
  so climbing does not bleed speed; the pitch channel distributes it — ``gamma`` from the
  reference's climb angle plus a proportional term on the height error.

The default bank limit is what the world's own minimum turn radius needs at the top speed,
``atan(speed.max^2 / (g R_min))``, plus ``bank_margin_deg`` (at most 88 degrees): the recorded
path may turn at R_min at any speed, and a vehicle with less bank could not fly it. The roll
is that of an agile aircraft (0.1 s lag, 360 deg/s): the simulator's model may enter a turn at
R_min from one step to the next, and at 55 m/s on a 40 m radius (paper 001's world at 1:50)
that is an 82 degree bank, which a slower roll would enter metres late. ``max_load_factor``
(1 / cos(bank)) shows what a world's turn radius asks of the airframe.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from swarmplan.world.tracker_config import G

from .reference import build_reference


@dataclass(frozen=True)
class FixedWingConfig:
    """Aircraft dynamics and guidance gains of the fixed-wing tracker (defaults are ours)."""

    roll_time_constant: float = 0.1  # s, bank lag
    max_roll_rate_deg_s: float = 360.0
    bank_margin_deg: float = 10.0  # over the bank R_min needs at speed.max
    max_bank_cap_deg: float = 88.0
    pitch_time_constant: float = 0.3  # s
    climb_margin_deg: float = 5.0  # over the world's max_climb_angle
    thrust_accel_factor: float = 1.5  # |V'| from thrust within this times max_accel
    l1_time: float = 0.6  # s of reference ahead: the L1 aim point
    along_kp: float = 1.5  # 1/s^2 on along-track error
    along_kd: float = 2.0  # 1/s on along-track speed error
    height_k: float = 1.5  # 1/s: gamma correction = height_k * height error / V
    dt_max: float = 0.02  # s, integration step (at most rec.dt / 5)


@dataclass(frozen=True)
class Aircraft:
    """One fixed-wing agent's limits, from the log's /world."""

    speed_min: float
    speed_max: float
    max_accel: float
    min_turn_radius: float
    max_climb_deg: float
    roll_rate_deg_s: float = 0.0  # the simulated airframe's (0: not in the log)
    speed_cruise: float | None = None


@dataclass(frozen=True)
class FixedWingFlight:
    """The tracked flight of one fixed wing on its own grid ``times``."""

    times: np.ndarray  # (K,)
    ref_pos: np.ndarray  # (K, 3)
    pos: np.ndarray  # (K, 3)
    vel: np.ndarray  # (K, 3)
    bank_deg: np.ndarray  # (K,)
    error: np.ndarray  # (K,)
    max_bank_limit_deg: float
    error_limit_m: float

    def to_json(self) -> dict[str, Any]:
        k = int(np.argmax(self.error))
        load = 1.0 / np.cos(np.radians(self.bank_deg))
        return {
            "model": "fixed_wing",
            "max_error_m": round(float(self.error.max()), 4),
            "rms_error_m": round(float(np.sqrt(np.mean(self.error**2))), 4),
            "time_of_max_error_s": round(float(self.times[k]), 3),
            "max_bank_deg": round(float(np.abs(self.bank_deg).max()), 2),
            "bank_limit_deg": round(self.max_bank_limit_deg, 2),
            "max_load_factor": round(float(load.max()), 3),
            "error_limit_m": round(self.error_limit_m, 4),
            "within_error_limit": bool(self.error.max() <= self.error_limit_m),
            "skipped": None,
        }


def aircraft_of(world: dict[str, Any], agent_id: str) -> Aircraft:
    """The agent's fixed-wing limits from a /world message (agent keys over agent_defaults)."""
    defaults = world.get("agent_defaults") or {}
    entry: dict[str, Any] = {}
    for a in world.get("agents") or []:
        if str(a.get("id")) == agent_id:
            entry = a
    merged = {**defaults, **entry}
    speed = {**(defaults.get("speed") or {}), **(entry.get("speed") or {})}
    return Aircraft(
        speed_min=float(speed.get("min", 0.0)),
        speed_max=float(speed.get("max", 10.0)),
        max_accel=float(merged.get("max_accel", 5.0)),
        min_turn_radius=float(merged.get("min_turn_radius", 1.0)),
        max_climb_deg=float(merged.get("max_climb_angle", 30.0)),
        roll_rate_deg_s=float(merged.get("roll_rate") or 0.0),
        speed_cruise=None if speed.get("cruise") is None else float(speed["cruise"]),
    )


def error_limit(ac: Aircraft) -> float:
    """The tracking error a flyable fixed-wing path should stay within: max(5 m, 0.05 R_min)."""
    return max(5.0, 0.05 * ac.min_turn_radius)


def roll_limits(ac: Aircraft, cfg: FixedWingConfig) -> tuple[float, float]:
    """The tracking aircraft's roll rate (rad/s) and bank lag (s): ``cfg``'s, or the simulated
    airframe's roll rate when faster, with a lag of at most a quarter of its roll-in time (the
    time that roll rate takes to the bank of a minimum-radius turn at cruise speed)."""
    rate, lag = cfg.max_roll_rate_deg_s, cfg.roll_time_constant
    if ac.roll_rate_deg_s > 0.0:
        rate = max(rate, ac.roll_rate_deg_s)
        v = ac.speed_cruise if ac.speed_cruise is not None else ac.speed_max
        bank = math.degrees(math.atan(v * v / (G * max(ac.min_turn_radius, 1e-9))))
        lag = min(lag, 0.25 * bank / ac.roll_rate_deg_s)
    return math.radians(rate), lag


def bank_limit_deg(ac: Aircraft, cfg: FixedWingConfig) -> float:
    need = math.degrees(math.atan(ac.speed_max**2 / (G * max(ac.min_turn_radius, 1e-9))))
    return min(cfg.max_bank_cap_deg, need + cfg.bank_margin_deg)


def fly(
    times: np.ndarray, positions: np.ndarray, ac: Aircraft, cfg: FixedWingConfig, rec_dt: float
) -> FixedWingFlight:
    """Fly the recorded ``positions`` (T, 3) at ``times`` (T,) with the aircraft ``ac``."""
    dt = min(cfg.dt_max, rec_dt / 5.0)
    v_rec = np.diff(positions, axis=0) / np.diff(times)[:, None]
    v0 = np.vstack([v_rec[:1], v_rec[-1:]])[None]  # fixed wings start and end at speed
    ref = build_reference(times, positions[None], v0, dt, "velocity")
    rp, rv, ra = ref.pos[0], ref.vel[0], ref.acc[0]
    k_n = len(ref.times)
    ahead = max(1, int(round(cfg.l1_time / dt)))
    phi_max = math.radians(bank_limit_deg(ac, cfg))
    roll_rate, roll_lag = roll_limits(ac, cfg)
    pitch_lag = min(cfg.pitch_time_constant, roll_lag)
    gam_max = math.radians(ac.max_climb_deg + cfg.climb_margin_deg)
    a_thrust = cfg.thrust_accel_factor * ac.max_accel
    p = rp[0].copy()
    speed = float(np.clip(np.linalg.norm(rv[0]), ac.speed_min, ac.speed_max))
    psi = math.atan2(rv[0, 1], rv[0, 0])
    gam = math.atan2(rv[0, 2], math.hypot(rv[0, 0], rv[0, 1]))
    phi = 0.0
    pos = np.empty((k_n, 3))
    vel = np.empty((k_n, 3))
    bank = np.empty(k_n)
    for k in range(k_n):
        cg = math.cos(gam)
        v = speed * np.array([cg * math.cos(psi), cg * math.sin(psi), math.sin(gam)])
        pos[k], vel[k], bank[k] = p, v, math.degrees(phi)
        # Lateral: L1 aim point on the reference ahead.
        aim = rp[min(k + ahead, k_n - 1)]
        if k + ahead >= k_n:  # past the end: extend along the last reference velocity
            aim = rp[-1] + rv[-1] * (k + ahead - k_n + 1) * dt
        d = aim[:2] - p[:2]
        dist = math.hypot(d[0], d[1])
        if dist > 1e-9:
            eta = math.atan2(d[1], d[0]) - psi
            eta = (eta + math.pi) % (2 * math.pi) - math.pi
            eta = max(-math.pi / 2, min(math.pi / 2, eta))
            a_lat = 2.0 * speed**2 * math.sin(eta) / dist
        else:
            a_lat = 0.0
        phi_cmd = max(-phi_max, min(phi_max, math.atan2(a_lat, G)))
        dphi = max(-roll_rate * dt, min(roll_rate * dt, (phi_cmd - phi) * dt / roll_lag))
        phi = max(-phi_max, min(phi_max, phi + dphi))
        # Energy: thrust holds the speed profile (with the along-track error), pitch the height.
        ref_speed = float(np.linalg.norm(rv[k]))
        t_hat = rv[k] / max(ref_speed, 1e-9)
        along = float((rp[k] - p) @ t_hat)
        along_rate = ref_speed - float(v @ t_hat)
        acc_ref = float(ra[k] @ t_hat)
        v_dot = acc_ref + cfg.along_kp * along + cfg.along_kd * along_rate
        thrust = max(-a_thrust, min(a_thrust, v_dot + G * math.sin(gam)))
        gam_ref = math.atan2(rv[k, 2], math.hypot(rv[k, 0], rv[k, 1]))
        gam_cmd = gam_ref + cfg.height_k * (rp[k, 2] - p[2]) / max(speed, 1e-6)
        gam_cmd = max(-gam_max, min(gam_max, gam_cmd))
        # Integrate (semi-implicit Euler at dt).
        speed = min(ac.speed_max, max(ac.speed_min, speed + (thrust - G * math.sin(gam)) * dt))
        gam = gam + (gam_cmd - gam) * dt / pitch_lag
        psi = psi + G * math.tan(phi) / max(speed, 1e-6) * dt
        cg = math.cos(gam)
        p = p + speed * dt * np.array([cg * math.cos(psi), cg * math.sin(psi), math.sin(gam)])
    error = np.linalg.norm(pos - rp, axis=1)
    return FixedWingFlight(ref.times, rp, pos, vel, bank, error, math.degrees(phi_max), error_limit(ac))
