"""Keeping each step safe: the multirotors' braking margin, the fixed-wing turn-ahead guard,
the swept FCL check of every commanded step with feasible alternatives when it would touch
something, and agent deconfliction (conflicting pairs stop their multirotors).

The last resort of the check (no feasible alternative is safe) and of deconfliction is a stop
within one step, beyond ``max_accel`` when the agent was faster than ``max_accel * dt``: such
*hard stops* are counted per agent (``/summary`` ``hard_stops``). The braking margin keeps
them rare: commands are slowed so that a stop within ``max_accel`` always fits before the
nearest surface along the motion."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from swarmplan.core import Event
from swarmplan.flight.kinematics import (
    AgentParams,
    checked_radius,
    limit_multirotor,
    limit_velocity,
    safety_margin,
    turn_states,
)
from swarmplan.flight.lookahead import CompiledGuard, guard_commands, horizon_steps
from swarmplan.geometry.collision import SLACK, first_hits, first_hits_fcl
from swarmplan.geometry.vec3 import norm3
from swarmplan.runtime.compiled import kernel_module, read_only, use_compiled_checks
from swarmplan.sim.braking import keeping_clearance, shrink, stoppable_speed
from swarmplan.sim.deconflict import deconflict
from swarmplan.sim.guard_clearance import MoverCentres, guard_clearance
from swarmplan.sim.metrics import NOTHING, Tally
from swarmplan.sim.network import Beliefs
from swarmplan.sim.obstacles import Obstacles
from swarmplan.world.model import World


def guard_kernel():  # noqa: ANN201
    """:mod:`swarmplan.sim._guard_kernel` (numba loads with it at the first call)."""
    return kernel_module("swarmplan.sim._guard_kernel")


@dataclass(frozen=True)
class AgentMotion:
    """Every agent's position and velocity (``(n, 3)`` each, rows by agent index)."""

    position: np.ndarray
    velocity: np.ndarray


@dataclass(frozen=True)
class Commands:
    """The flying agents (``idx``, agent indices) and their commanded velocities (rows of ``idx``);
    with ``comms``, what they believe of the others and the pairs (N, N) that can agree on their
    steps within this one (``swarmplan.sim.deconflict``)."""

    idx: np.ndarray
    velocity: np.ndarray
    beliefs: Beliefs | None = None
    agreed: np.ndarray | None = None


@dataclass(frozen=True)
class StepWindow:
    """The step from ``t0`` to ``t1`` and every obstacle's pose at both ends (``q0``, ``q1``)."""

    t0: float
    t1: float
    q0: np.ndarray
    q1: np.ndarray


@dataclass(frozen=True)
class Filtered:
    """What :meth:`SafetyFilter.filter` made of a step: where every agent ends it, whether each
    flying agent's step was cleared with the safety margin (rows of ``Commands.idx``), and the
    stops it had to make."""

    end: AgentMotion
    validated: np.ndarray
    tally: Tally


class SafetyFilter:
    """Turns commanded velocities into steps that touch nothing (or stops, and says so)."""

    def __init__(self, world: World, params: AgentParams, obstacles: Obstacles):
        self.world = world
        self.params = params
        self.obstacles = obstacles
        self._bounds = (
            np.ascontiguousarray(world.bounds_min, dtype=float),
            np.ascontiguousarray(world.bounds_max, dtype=float),
        )
        # Swarm-sized worlds over flat ground check many steps in one compiled call.
        self._compiled = use_compiled_checks(len(params.ids), bool(params.fixed_wing.any()))
        self._batched = self._compiled and not world.peaks
        self._fixed_wings = bool(params.fixed_wing.any())
        self._checked_radius = checked_radius(params.radius)
        self._checked_radius.setflags(write=False)
        self.checked_radius = self._checked_radius
        self._every = np.arange(len(params.radius))  # the rows of a step where every agent flies
        # The fixed wings' turn states (the curvature of their last step, rows by agent; :meth:`fly`
        # keeps them, the simulation's reset zeroes them): every fixed-wing step rolls on from them.
        self.turn = np.zeros((len(params.radius), 2))
        # Movers' centres by step number from a first one (the guard's predictions).
        self._centers = MoverCentres(world)
        # Meshes have no compiled distance: a guard near one measures in numpy.
        self.mesh_bodies = set(obstacles.distances.meshes)
        # Per fixed wing, the guard's manoeuvre last found safe (checked first: the same answers).
        self._prefer = np.zeros(len(params.radius), dtype=np.int64)

    def guard_fixed_wings(
        self,
        idx: np.ndarray,
        pos0: np.ndarray,
        vel0: np.ndarray,
        v_cmd: np.ndarray,
        d: np.ndarray,
        clearance: np.ndarray,
        t0: float,
    ) -> tuple[np.ndarray, Tally]:
        """Fixed wings keep the field's command only while they could still turn away
        (``swarmplan.flight.lookahead``). Only agents with an obstacle, the terrain or the bounds within
        reach of the horizon (obstacles' own motion included) are checked, and only against the
        obstacles within that reach. Returns the commands and the guarded steps (``guard_steps``)."""
        p = self.params
        fw = p.fixed_wing[idx] if self._fixed_wings else None
        if fw is None or not fw.any():
            return v_cmd, NOTHING
        dt = self.world.dt
        speed = np.linalg.norm(vel0[idx], axis=1)
        horizon = 2 * horizon_steps(p, idx[fw], speed[fw], dt) * dt  # a manoeuvre settling: twice
        required = p.radius[idx]
        reach = (speed + self.obstacles.max_obstacle_speed) * horizon + p.clearance[idx] + p.radius[idx]
        obstacle_clear = (d - p.radius[idx, None]).min(axis=1) if d.shape[1] else np.full(len(idx), np.inf)
        q = pos0[idx]
        bounds_clear = (
            np.minimum(q - self.world.bounds_min, self.world.bounds_max - q).min(axis=1) - p.radius[idx]
        )
        near = fw & (np.minimum(np.minimum(clearance, obstacle_clear), bounds_clear) < reach)
        if not near.any():
            return v_cmd, NOTHING
        rows = np.flatnonzero(near)
        close = np.flatnonzero((d[rows] < reach[rows, None]).any(axis=0)) if d.shape[1] else np.array([], int)
        obstacles = self.world.obstacles

        batch = self.obstacles.distances
        static = [j for j in close if not obstacles[j].moving]
        movers = [j for j in close if obstacles[j].moving]

        moving = np.flatnonzero(self.obstacles.moving_mask)
        static_cols = np.array(static, dtype=np.int64)
        mover_cols = np.array(movers, dtype=np.int64)
        origin = np.array([obstacles[j].position for j in movers], dtype=float).reshape(-1, 3)
        compiled = not (self.mesh_bodies & set(close))
        bodies = (batch.bodies.code, batch.bodies.prm, batch.position, batch.rotation, batch.identity)

        def centers_at(times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            """The close movers' centres (T, movers, 3) and each time's row of them."""
            if not movers:
                return np.zeros((1, 0, 3)), np.zeros(len(times), dtype=np.int64)
            steps = np.rint(times / dt).astype(np.int64)
            table, base = self._centers.at_steps(int(steps.min()), int(steps.max()))
            return table[:, np.searchsorted(moving, mover_cols)], steps - base

        def clearance_at(
            points: np.ndarray, radii: np.ndarray, times: np.ndarray, extra: np.ndarray
        ) -> np.ndarray:
            ground = self.world.terrain_height(points[:, :2])
            centers, row = centers_at(times)
            args = (points, radii, extra, ground, self._bounds[0], self._bounds[1], static_cols, mover_cols,
                    origin, centers, row)  # fmt: skip
            if compiled:
                f = np.ascontiguousarray
                return guard_kernel().clearances(*(f(a) for a in args), bodies)
            return guard_clearance(batch, *args)

        def scene(times: np.ndarray) -> tuple[tuple, np.ndarray]:
            centers, row = centers_at(times)
            f = np.ascontiguousarray
            return (*self._bounds, static_cols, mover_cols, f(origin), f(centers), bodies), f(row)

        def first_safe_at(
            rollout: tuple, times: np.ndarray, radii: np.ndarray, extra: np.ndarray, required: np.ndarray
        ) -> tuple[np.ndarray, np.ndarray]:
            places, row = scene(times)
            f = np.ascontiguousarray
            return guard_kernel().first_safe(rollout, row, f(radii), f(extra), f(required), places)

        def least_at(rollout: tuple, times: np.ndarray, *rows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            places, row = scene(times)
            radii, extra, required = (np.ascontiguousarray(a) for a in rows)
            return guard_kernel().least_clearances(rollout, row, radii, extra, required, places)

        fused = CompiledGuard(first_safe_at, least_at) if compiled and not self.world.peaks else None
        agents = idx[rows]
        prefer = self._prefer[agents]
        guarded, replaced = guard_commands(
            p, agents, pos0[agents], vel0[agents], v_cmd[rows], t0, dt, clearance_at, required[rows],
            self.turn[agents], prefer, fused,
        )  # fmt: skip
        self._prefer[agents] = prefer
        out = v_cmd.copy()
        out[rows] = guarded
        return out, Tally(counts=tuple(("guard_steps", i) for i in idx[rows][replaced].tolist()))

    def braking_margin(
        self,
        idx: np.ndarray,
        pos0: np.ndarray,
        vel0: np.ndarray,
        v_cmd: np.ndarray,
        q0: np.ndarray,
        q1: np.ndarray,
        goal: np.ndarray | None = None,
    ) -> np.ndarray:
        """Multirotor commands slowed so that the agent can always still brake within ``max_accel``.

        Goal (``goal``, per agent of ``idx``): the speed is capped at ``max(a dt, v_safe(d - tol))``
        with ``d`` the distance to the goal, ``tol`` the goal tolerance and ``v_safe(D)`` the
        largest ``v`` with ``v^2/(2a) + v dt <= D``: the agent reaches the tolerance sphere at
        no more than ``a dt``, the speed one step can stop, so arrival (which freezes the agent,
        ``swarmplan.sim.contacts.arrivals``) happens where it first enters the tolerance and
        within the acceleration limit.

        Obstacles: the velocity the command leads to is followed, as a straight swept sphere (radius plus
        the filter's margin), for the distance a stop from it takes: ``v^2 / (2 a) + v dt``
        (one step at ``v``, then braking at ``a``; the discrete stop needs ``v^2/(2a) + v dt/2``).
        Where that sweep touches something (obstacle, terrain, ground, bounds) at a distance
        ``D``, the command's speed is capped at the largest ``v`` with ``v^2/(2a) + v dt <= D``.
        Kept every step, this leaves the filter a feasible braking step, so the one-step stop it
        falls back to is rarely needed. Moving obstacles enter with their motion over this step
        only (their own future motion is the field's relative-velocity term's job).
        """
        p = self.params
        mr = ~p.fixed_wing[idx]
        if not mr.any():
            return v_cmd
        dt = self.world.dt
        k = np.flatnonzero(mr)
        rows = idx[k]
        if self._batched:
            fused = self._braking_margin_compiled(k, rows, pos0, vel0, v_cmd, q0, q1, goal)
            if fused is not None:
                return fused[0]
        amax = p.max_accel[rows]
        cap = np.full(len(k), np.inf)
        if goal is not None:
            room = np.maximum(norm3(goal[k] - pos0[rows]) - self.world.goal_tolerance, 0.0)
            cap = np.maximum(amax * dt, stoppable_speed(room, amax, dt))
        s_cmd = norm3(v_cmd[k])
        # Multirotors only: limit_velocity's own model, row by row.
        vmax = p.speed_max[rows]
        v1 = limit_multirotor(vel0[rows], v_cmd[k] * shrink(s_cmd, cap), vmax, amax, dt)
        speed = norm3(v1)
        # Slower than a dt, a single step can stop the agent.
        probe = np.flatnonzero(speed > amax * dt)
        if len(probe):
            u = v1[probe] / speed[probe, None]
            reach = speed[probe] ** 2 / (2.0 * amax[probe]) + speed[probe] * dt
            radii = self._checked_radius[rows[probe]]
            start = pos0[rows[probe]]
            hit, free = self._free_distances(start, u, reach, radii, q0, q1)
            at = probe[hit]
            cap[at] = np.minimum(cap[at], stoppable_speed(free, amax[at], dt))
        else:
            at = probe
        limited = np.isfinite(cap)
        if not limited.any():
            return v_cmd
        out = v_cmd.copy()
        capped = v_cmd[k] * shrink(s_cmd, cap)
        # Only the rows whose cap the sweep lowered change their command: the others keep v1.
        v1c = v1
        if len(at):
            v1c = v1.copy()
            v1c[at] = limit_multirotor(vel0[rows[at]], capped[at], vmax[at], amax[at], dt)
        # The acceleration budget is shared by braking and turning: when the capped command still
        # leaves the agent above the cap (it asks for a turn), brake straight instead, which is
        # what keeps the margin from one step to the next.
        too_fast = norm3(v1c) > cap + 1e-9
        s0 = norm3(vel0[rows])
        brake = vel0[rows] * shrink(s0, cap)
        out[k] = np.where(too_fast[:, None], brake, capped)
        return out

    def brake_and_limit(
        self,
        idx: np.ndarray,
        pos0: np.ndarray,
        vel0: np.ndarray,
        v_cmd: np.ndarray,
        q0: np.ndarray,
        q1: np.ndarray,
        goal: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
        """:meth:`braking_margin`'s commands (rows of ``idx``), the velocities they lead to
        within the kinematic limits (``kinematics.limit_velocity``) and, when at hand, per row
        whether the step at that velocity touches nothing (:meth:`steps_free` with the filter's
        radii, the first check of :meth:`filter`): in swarm worlds of multirotors all three
        from one compiled call; else the third is None."""
        p = self.params
        if self._batched and not (self._fixed_wings and p.fixed_wing[idx].any()):
            k = np.arange(len(idx))
            fused = self._braking_margin_compiled(k, idx, pos0, vel0, v_cmd, q0, q1, goal, check_step=True)
            if fused is not None:
                out, vel1, status = fused
                free = status == 0
                undecided = (status == 2).nonzero()[0]
                if len(undecided):
                    rows = idx[undecided]
                    ends = pos0[rows] + vel1[undecided] * self.world.dt
                    radii = self._checked_radius[rows]
                    mv = self.obstacles.moving_mask
                    hits = first_hits_fcl(self.obstacles.collision, pos0[rows], ends, radii, q0[mv], q1[mv])
                    free[undecided] = [h is None for h in hits]
                return out, vel1, free
        v_cmd = self.braking_margin(idx, pos0, vel0, v_cmd, q0, q1, goal)
        return v_cmd, limit_velocity(p, vel0[idx], v_cmd, self.world.dt, idx, self.turn[idx]), None

    def fly(
        self, cmd: Commands, start: AgentMotion, window: StepWindow, modes: np.ndarray, brake_goal: np.ndarray
    ) -> Filtered:
        """The step of agents ``cmd.idx`` from ``start``: their commands braked and limited
        (:meth:`brake_and_limit`, toward ``brake_goal``), flown for one step and filtered
        (:meth:`filter`); the other agents stay where they are, at rest."""
        idx, (pos0, vel0), dt = cmd.idx, (start.position, start.velocity), self.world.dt
        v_cmd, v_new, free = self.brake_and_limit(
            idx, pos0, vel0, cmd.velocity, window.q0, window.q1, brake_goal
        )
        if len(idx) == len(pos0):  # every row (the same values as through idx)
            vel1 = np.array(v_new, dtype=float)
            pos1 = pos0 + vel1 * dt
        else:
            vel1 = np.zeros_like(vel0)
            pos1 = pos0.copy()
            vel1[idx] = v_new
            pos1[idx] = pos0[idx] + vel1[idx] * dt
        braked = Commands(idx, v_cmd, cmd.beliefs, cmd.agreed)
        out = self.filter(braked, start, AgentMotion(pos1, vel1), window, modes, free, wanted=cmd.velocity)
        fw = idx[self.params.fixed_wing[idx]] if self._fixed_wings else ()
        if len(fw):  # the curvature each fixed wing flew, which its next step rolls on from
            self.turn[fw] = turn_states(self.params, vel0[fw], out.end.velocity[fw], dt, fw)
        return out

    def _braking_margin_compiled(
        self,
        k: np.ndarray,
        rows: np.ndarray,
        pos0: np.ndarray,
        vel0: np.ndarray,
        v_cmd: np.ndarray,
        q0: np.ndarray,
        q1: np.ndarray,
        goal: np.ndarray | None,
        check_step: bool = False,
    ) -> tuple[np.ndarray, np.ndarray | None, np.ndarray] | None:
        """:meth:`braking_margin` for the multirotor rows ``k`` (agents ``rows``) in one compiled
        call (the same bits), with the velocities the commands lead to when every row is a
        multirotor (else None) and, with ``check_step``, the kernel's answer for each row's step
        at that velocity (0 free, 1 touches, 2 FCL must decide); None when a braking sweep
        needs FCL's decision (then the numpy path runs)."""
        p = self.params
        mv = self.obstacles.moving_mask
        cw = self.obstacles.collision
        dt = self.world.dt
        all_rows = len(k) == len(v_cmd)
        every = all_rows and len(rows) == len(pos0) and bool((rows == self._every).all())
        if every:  # every agent, in order: the arrays themselves
            start, v0, amax, vmax, radii = pos0, vel0, p.max_accel, p.speed_max, self._checked_radius
        else:
            start, v0, amax, vmax = pos0[rows], vel0[rows], p.max_accel[rows], p.speed_max[rows]
            radii = self._checked_radius[rows]
        row_arrays = (
            np.ascontiguousarray(start, dtype=float),
            np.ascontiguousarray(v0, dtype=float),
            np.ascontiguousarray(v_cmd if all_rows else v_cmd[k], dtype=float),
            np.ascontiguousarray(start if goal is None else goal[k], dtype=float),
            amax,
            vmax,
            read_only(radii),
        )
        out, vel1, status, decided = step_kernels().braking_margin(
            row_arrays, goal is not None, (dt, dt**2, float(self.world.goal_tolerance)), self._bounds,
            cw.kernel_statics(), cw.kernel_movers(q0[mv], q1[mv]), SLACK, 6, check_step and all_rows,
        )  # fmt: skip
        if not decided:
            return None
        if all_rows:
            return out, vel1, status
        full = v_cmd.copy()
        full[k] = out
        return full, None, status

    def _free_distances(
        self,
        start: np.ndarray,
        u: np.ndarray,
        reach: np.ndarray,
        radii: np.ndarray,
        q0: np.ndarray,
        q1: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray]:
        """Rows whose sweep ``start -> start + u * reach`` touches something, and for them the
        free distance along ``u``: a bisection on the swept check (monotone in length), 6
        halvings, under-estimated by at most reach / 64.

        In swarm-sized worlds over flat ground the compiled kernel runs every row's bisection;
        rows where it cannot decide a check (a body within ``BAND`` of contact, or a mesh),
        terrain worlds and smaller worlds run the same bisection through :func:`first_hits`
        (FCL decides)."""
        mv = self.obstacles.moving_mask
        cw = self.obstacles.collision
        redo = np.arange(len(start))
        hit_rows, free = [], []
        if self._compiled and not self.world.peaks:
            status, lo = kernel_module("swarmplan.geometry.swept_kernels").free_distances(
                np.ascontiguousarray(start), np.ascontiguousarray(u), reach, radii, self._bounds,
                cw.kernel_statics(), cw.kernel_movers(q0[mv], q1[mv]), SLACK, 6,
            )  # fmt: skip
            hit_rows.append(np.flatnonzero(status == 1))
            free.append(lo[status == 1])
            redo = np.flatnonzero(status == 2)
        if len(redo):

            def touches(length: np.ndarray, sel: np.ndarray) -> np.ndarray:
                ends = start[sel] + u[sel] * length[:, None]
                hits = first_hits(cw, start[sel], ends, radii[sel], q0[mv], q1[mv])
                return np.array([h is not None for h in hits], dtype=bool)

            hit = redo[touches(reach[redo], redo)]
            lo, hi = np.zeros(len(hit)), reach[hit].copy()
            for _ in range(6):
                mid = 0.5 * (lo + hi)
                h = touches(mid, hit)
                hi, lo = np.where(h, mid, hi), np.where(h, lo, mid)
            hit_rows.append(hit)
            free.append(lo)
        if not hit_rows:
            return np.zeros(0, dtype=np.intp), np.zeros(0)
        rows, lo = np.concatenate(hit_rows), np.concatenate(free)
        order = np.argsort(rows, kind="stable")
        return rows[order], lo[order]

    def margin(self, i: int | np.ndarray) -> np.ndarray:
        return safety_margin(self.params.radius[i])

    def step_is_safe(self, i: int, p0: np.ndarray, p1: np.ndarray, q0: np.ndarray, q1: np.ndarray) -> bool:
        mv = self.obstacles.moving_mask
        return (
            self.obstacles.collision.first_hit(p0, p1, self._checked_radius[i], q0[mv], q1[mv])
            is None
        )

    def steps_free(
        self, p0: np.ndarray, p1: np.ndarray, radii: np.ndarray, q0: np.ndarray, q1: np.ndarray
    ) -> np.ndarray:
        """Per step ``p0 -> p1`` (swept radius ``radii``, obstacles at ``q0`` -> ``q1``, all
        obstacles' rows): whether it touches nothing (``first_hits`` is None). At swarm size over
        flat ground one compiled call answers, FCL the steps it leaves undecided."""
        mv = self.obstacles.moving_mask
        cw = self.obstacles.collision
        if not self._batched:
            return np.array([h is None for h in first_hits(cw, p0, p1, radii, q0[mv], q1[mv])], dtype=bool)
        status = step_kernels().touches_many(
            np.ascontiguousarray(p0, dtype=float), np.ascontiguousarray(p1, dtype=float),
            np.ascontiguousarray(radii, dtype=float), self._bounds,
            cw.kernel_statics(), cw.kernel_movers(q0[mv], q1[mv]), SLACK,
        )  # fmt: skip
        free = status == 0
        undecided = np.flatnonzero(status == 2)
        if len(undecided):
            hits = first_hits_fcl(cw, p0[undecided], p1[undecided], radii[undecided], q0[mv], q1[mv])
            free[undecided] = [h is None for h in hits]
        return free

    def filter(
        self,
        commands: Commands,
        start: AgentMotion,
        end: AgentMotion,
        window: StepWindow,
        mode: np.ndarray,
        free: np.ndarray | None = None,
        wanted: np.ndarray | None = None,
    ) -> Filtered:
        """Replace steps that would touch an obstacle by the closest safe feasible alternative.

        ``end`` is where the commands lead (within the kinematic limits), ``mode`` every agent's
        mode, ``free`` (optional, rows of ``commands.idx``) :meth:`steps_free`'s answer for
        those steps when already known (:meth:`brake_and_limit`), ``wanted`` (optional, rows of
        ``commands.idx``) the commands before the braking margin: a multirotor within its margin
        of a surface takes the step that keeps its clearance nearest that (the braking margin,
        which sweeps its body with the whole margin, stops it dead there). Returns the filtered end of
        the step, per agent of ``commands.idx`` whether its final step was cleared with the
        safety margin, and the stops made.
        """
        idx, v_cmd = commands.idx, commands.velocity
        pos0, vel0 = start.position, start.velocity
        pos1, vel1 = end.position.copy(), end.velocity.copy()
        q0, q1, t1 = window.q0, window.q1, window.t1
        events: list[Event] = []
        dt = self.world.dt
        ids = self.params.ids
        radii = self._checked_radius[idx]
        validated = self.steps_free(pos0[idx], pos1[idx], radii, q0, q1) if free is None else free.copy()
        unsafe = (~validated).nonzero()[0]
        alternatives: list[list[np.ndarray]] = []
        free: list[np.ndarray] = []
        if len(unsafe) and self._batched:
            # Every alternative of every such agent in one check (the same yes/no per step).
            alternatives = [self.alternative_velocities(idx[k], vel0[idx[k]]) for k in unsafe]
            sizes = [len(c) for c in alternatives]
            rows = np.repeat(idx[unsafe], sizes)
            ends = pos0[rows] + np.array([v for c in alternatives for v in c]) * dt
            ok = self.steps_free(pos0[rows], ends, np.repeat(radii[unsafe], sizes), q0, q1)
            free = np.split(ok, np.cumsum(sizes)[:-1])
        counts: list[tuple[str, int]] = []
        for n_k, k in enumerate(unsafe):
            i = idx[k]
            if self._batched:
                safe = [v for v, f in zip(alternatives[n_k], free[n_k], strict=True) if f]
            else:
                cands = self.alternative_velocities(i, vel0[i])
                safe = [v for v in cands if self.step_is_safe(i, pos0[i], pos0[i] + v * dt, q0, q1)]
            margin = bool(safe)  # cleared with the whole safety margin (else the committed step is checked)
            want = v_cmd[k]
            if not safe and not self.params.fixed_wing[i]:
                cands = [vel1[i], *(alternatives[n_k] if self._batched else cands)]
                safe = keeping_clearance(self, i, pos0[i], cands, (q0, q1))
                want = want if wanted is None else wanted[k]
            if safe:
                best = min(safe, key=lambda v: float(np.linalg.norm(v - want)))
                vel1[i] = best
                validated[k] = margin
            elif not self.params.fixed_wing[i]:
                # No feasible command avoids contact: stop (beyond the accel limit) and say so.
                vel1[i] = 0.0
                counts += self.stop_counts(i, vel0[i])
                events.append(
                    Event(t1, ids[i], "emergency_stop", {"speed": round(float(np.linalg.norm(vel0[i])), 6)})
                )
            pos1[i] = pos0[i] + vel1[i] * dt
        # Agents: conflicting pairs stop the multirotor(s) involved (swarmplan.sim.deconflict).
        stops = deconflict(self, commands, (pos0, vel0), (pos1, vel1), mode, window)
        events, counts, stopped = events + stops[0], counts + stops[1], stops[2]
        tally = Tally(events=tuple(events), counts=tuple(counts)) if events or counts else NOTHING
        if stopped.any():
            validated &= ~stopped[idx]
        return Filtered(AgentMotion(pos1, vel1), validated, tally)

    def stop_counts(self, i: int, v0: np.ndarray) -> list[tuple[str, int]]:
        """The counters an emergency stop of agent ``i`` from velocity ``v0`` adds to: always
        ``emergency_stops``; ``hard_stops`` too when the stop to zero within one step needs more
        than ``max_accel`` (``/summary`` ``hard_stops``): the kinematic model's limit broken,
        unflyable for a real multirotor (docs/tracking.md)."""
        counts = [("emergency_stops", int(i))]
        if float(np.linalg.norm(v0)) > self.params.max_accel[i] * self.world.dt * (1.0 + 1e-9):
            counts.append(("hard_stops", int(i)))
        return counts

    def brake(self, i: int, v0: np.ndarray) -> np.ndarray:
        sp = float(np.linalg.norm(v0))
        dv = self.params.max_accel[i] * self.world.dt
        return v0 * max(0.0, sp - dv) / sp if sp > 1e-12 else np.zeros(3)

    def alternative_velocities(self, i: int, v0: np.ndarray) -> list[np.ndarray]:
        """Feasible next velocities spanning the model's envelope (brake, turn, climb, dive)."""
        dt = self.world.dt
        p = self.params
        if not p.fixed_wing[i]:
            dv = p.max_accel[i] * dt
            dirs = [np.array(v, float) for v in np.ndindex(3, 3, 3) if v != (1, 1, 1)]
            dirs = [(d - 1) / np.linalg.norm(d - 1) for d in dirs]
            out = [self.brake(i, v0)] + [v0 + dv * d for d in dirs]
            vmax = p.speed_max[i]
            return [v if np.linalg.norm(v) <= vmax else v * vmax / np.linalg.norm(v) for v in out]
        speed = float(np.linalg.norm(v0))
        psi = math.atan2(v0[1], v0[0])
        cmds = []
        for dpsi in (-1.0, -0.5, 0.0, 0.5, 1.0):
            for gam in (-1.0, 0.0, 1.0):
                for sp in (p.speed_min[i], speed, p.speed_max[i]):
                    a = psi + dpsi * math.pi / 2
                    g = gam * p.max_climb[i]
                    cmds.append(
                        sp * np.array([math.cos(g) * math.cos(a), math.cos(g) * math.sin(a), math.sin(g)])
                    )
        cmds = np.array(cmds)
        rows = np.full(len(cmds), i)
        v = limit_velocity(p, np.repeat(v0[None], len(cmds), 0), cmds, dt, rows, self.turn[rows])
        return list(v)


def step_kernels():  # noqa: ANN201
    """:mod:`swarmplan.sim._step_kernels` (numba loads with it at the first call)."""
    return kernel_module("swarmplan.sim._step_kernels")
