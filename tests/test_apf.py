"""Potential-field directions on simple layouts, and a goal beside an obstacle stays reachable."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import audit, base_world, describe_failure, make_world, run_to_end

from swarmplan.flight.apf import ApfField, FieldInputs, Flyers, Swarm, commanded_velocity
from swarmplan.flight.kinematics import AgentParams, safety_margin
from swarmplan.geometry.shapes import ObstacleField
from swarmplan.world.motion import poses_at


def _unit(v):
    return np.asarray(v, float) / np.linalg.norm(v)


def field_forces(world, pos, vel=None, t=0.0):
    """APF force on every agent of ``world`` placed at ``pos`` (N, 3) with ``vel``, at time ``t``."""
    pos = np.asarray(pos, float).reshape(-1, 3)
    vel = np.zeros_like(pos) if vel is None else np.asarray(vel, float).reshape(-1, 3)
    params = AgentParams.from_world(world)
    idx = np.arange(len(pos))
    goal = np.array([a.goal for a in world.agents], float)
    q, qv = poses_at(world.obstacles, t)
    moving = np.array([o.moving for o in world.obstacles], bool)
    if len(world.obstacles):
        d, g = ObstacleField(world.obstacles).query(pos, q)
    else:
        d, g = np.zeros((len(pos), 0)), np.zeros((len(pos), 0, 3))
    radii = np.array([o.bounding_radius for o in world.obstacles])
    inputs = FieldInputs(d, g, qv * moving[:, None], moving, radii, q.reshape(-1, 3))
    return apf_forces(world, params, idx, pos, vel, goal, inputs, pos, vel)


def apf_forces(world, params, idx, pos, vel, goal, inputs, all_pos, all_vel, parked=None, target=None):
    """The world's field on agents ``idx`` (rows of pos/vel/goal, pulled at ``target``, default
    their goals) among the whole swarm."""
    flyers = Flyers(idx, pos, vel, goal, target)
    return ApfField(world, params).forces(flyers, inputs, Swarm(all_pos, all_vel, parked))


def world_of(obstacles=(), start=(30, 50, 25), goal=(90, 50, 25), **kw):
    raw = base_world(
        obstacles=list(obstacles), agents=[{"id": "a", "start": list(start), "goal": list(goal)}]
    )
    raw.update(kw)
    return make_world(raw)


def test_free_space_force_points_at_the_goal():
    w = world_of(start=(30, 40, 25), goal=(70, 65, 30))
    f = field_forces(w, [30, 40, 25])[0]
    cos = float(np.dot(_unit(f), _unit(np.subtract((70, 65, 30), (30, 40, 25)))))
    assert cos > 0.9999
    # Inside the quadratic radius the attraction is k_att * (goal - p).
    near = np.array([66.0, 62, 29])
    f = field_forces(w, near)[0]
    np.testing.assert_allclose(f, 1.0 * (np.array([70, 65, 30]) - near), atol=1e-9)


def test_obstacle_between_repels_away_from_it():
    obstacle = {"id": "rock", "shape": "sphere", "radius": 5, "position": [45, 51, 25]}
    w_free = world_of()
    w = world_of([obstacle])
    p = np.array([30.0, 50, 25])
    rep = field_forces(w, p)[0] - field_forces(w_free, p)[0]
    away = _unit(p - np.array([45, 51, 25]))
    assert np.linalg.norm(rep) > 0.5
    # The repulsion points along the outward surface normal, i.e. away from the centre.
    assert float(np.dot(_unit(rep), away)) > 0.999
    assert rep[0] < 0 and rep[1] < 0  # back from it and sideways away from its off-centre bulk


def test_a_body_that_holds_the_agent_turns_its_push_along_its_surface():
    """Held by a body square across its way (the field's force makes less than a quarter of
    the pull's way), the agent also gets the opposing part of the push turned along the surface
    towards the body's nearer side (here -y: the agent is south of its centre)."""
    obstacle = {"id": "rock", "shape": "sphere", "radius": 5, "position": [45, 51, 25]}
    w_free, w = world_of(), world_of([obstacle])
    p = np.array([38.0, 50, 25])
    f = field_forces(w, p)[0]
    pull = _unit(np.subtract((90, 50, 25), p))
    assert float(np.dot(f, pull)) < 0.25 * 10.0  # held: k_att * quadratic_radius = 10
    rep = f - field_forces(w_free, p)[0]
    away = _unit(p - np.array([45, 51, 25]))
    side = _unit(np.cross(np.cross(away, [0.0, -1.0, 0.0]), away))  # tangent towards -y
    rho0 = w.planner_config.apf.influence
    k = 50.0 * (1 / (np.linalg.norm(p - [45, 51, 25]) - 5 - 1.0) - 1 / rho0)
    np.testing.assert_allclose(float(np.dot(rep, away)), k, rtol=1e-9)  # k_rep (1/rho - 1/rho0)
    # ... times how much the body blocks the pull, fading in from one to two influences off the goal.
    turn = min(1.0, 52.0 / rho0 - 1.0)
    np.testing.assert_allclose(float(np.dot(rep, side)), k * float(np.dot(pull, -away)) * turn, rtol=1e-9)


def test_repulsion_grows_as_the_surface_nears_and_vanishes_beyond_influence():
    obstacle = {"id": "rock", "shape": "box", "size": [4, 40, 40], "position": [60, 50, 25]}
    # The goal is off to the side and far, so the goal-distance factor stays 1.
    apf = {"planner": {"apf": {"influence": 40.0}}}
    w_free, w = world_of(goal=(10, 95, 25), **apf), world_of([obstacle], goal=(10, 95, 25), **apf)
    mags = []
    for x in (10.0, 20.0, 40.0, 50.0, 55.0):
        p = np.array([x, 50, 25])
        rep = field_forces(w, p)[0] - field_forces(w_free, p)[0]
        mags.append(-rep[0])
        assert abs(rep[1]) < 1e-9 and abs(rep[2]) < 1e-9
    # Surface at x = 58; influence 40 m (+ radius 1): nothing at x <= 17, then monotone growth.
    assert mags[0] == pytest.approx(0.0, abs=1e-12)
    assert 0 < mags[1] < mags[2] < mags[3] < mags[4]


#: A sphere coming straight at an agent at (30, 50, 25) flying +x.
HEAD_ON_MOVER = {
    "id": "intruder",
    "shape": "sphere",
    "radius": 3,
    "position": [70, 50, 25],
    "motion": {"type": "linear", "velocity": [-10, 0, 0]},
}


def test_moving_obstacle_on_collision_course_gives_a_lateral_push():
    mover = HEAD_ON_MOVER
    w_mov = world_of([mover])
    w_static = world_of([dict(mover, motion=None)])
    p, v = np.array([30.0, 50, 25]), np.array([6.0, 0, 0])
    f_mov = field_forces(w_mov, p, v)[0]
    f_static = field_forces(w_static, p, v)[0]
    lateral = np.linalg.norm(f_mov[1:])
    # The static sphere dead ahead only pushes straight back: no sideways component.
    assert np.linalg.norm(f_static[1:]) < 1e-9
    # On a collision course the field steers sideways, and noticeably.
    assert lateral > 0.2 * np.linalg.norm(f_mov)
    # Head-on symmetry is broken to the agent's right (z up): -y when flying +x.
    assert f_mov[1] < 0


@pytest.mark.parametrize(
    "walls, side", [((45.0,), [0, 1, 0]), ((45.0, 55.0), [0, 0, 1])], ids=["right", "both"]
)
def test_head_on_mover_beside_a_wall_is_dodged_where_there_is_room(walls, side):
    """Head-on, the mover's push goes to the agent's right unless a static surface hems that
    side in within the mover's radius and the agent's: then to the left, or over both sides."""
    mover = HEAD_ON_MOVER
    # Walls along the way, their faces 3.5 m from the agent's surface (radius 1): within 3 + 1.
    bodies = [
        {"id": f"w{k}", "shape": "box", "size": [100, 1, 40], "position": [50, y, 25]}
        for k, y in enumerate(walls)
    ]
    p, v = np.array([30.0, 50, 25]), np.array([6.0, 0, 0])
    push = field_forces(world_of([mover, *bodies]), p, v)[0] - field_forces(world_of(bodies), p, v)[0]
    assert float(np.dot(_unit(push), side)) > 0.99, push


def _miss_distance(p, v, q, qv, horizon=4.0):
    """Closest predicted centre distance within ``horizon`` seconds at constant velocities."""
    dp, dv = p - q, v - qv
    tau = np.clip(-np.dot(dp, dv) / max(np.dot(dv, dv), 1e-12), 0.0, horizon)
    return float(np.linalg.norm(dp + tau * dv))


@pytest.mark.parametrize(
    "mover_pos, mover_vel",
    [([45, 70, 25], [0, -8, 0]), ([70, 50, 25], [-10, 0, 0]), ([57, 38, 25], [-3, 4, 0])],
    ids=["crossing", "head-on", "oblique"],
)
def test_mover_on_collision_course_steers_to_a_wider_miss(mover_pos, mover_vel):
    """Flying along the field's force instead of straight on enlarges the predicted miss distance."""
    mover = {
        "id": "m",
        "shape": "sphere",
        "radius": 2,
        "position": mover_pos,
        "motion": {"type": "linear", "velocity": mover_vel},
    }
    w = world_of([mover])
    p, v = np.array([30.0, 50, 25]), np.array([6.0, 0, 0])
    q, qv = np.array(mover_pos, float), np.array(mover_vel, float)
    before = _miss_distance(p, v, q, qv)
    assert before < 3.0  # the layouts are collision courses (radii sum 3)
    f = field_forces(w, p, v)[0]
    after = _miss_distance(p, 6.0 * _unit(f), q, qv)
    assert after > before + 2.0, (before, after, f)


def test_commanded_velocity_cruise_brake_and_surface_limit():
    w = world_of()
    params = AgentParams.from_world(w)
    idx = np.array([0])
    goal = np.array([[90.0, 50, 25]])
    far = np.array([[30.0, 50, 25]])
    inf, up = np.array([np.inf]), np.array([[0.0, 0, 1]])
    v = commanded_velocity(params, idx, np.array([[5.0, 0, 0]]), far, goal, inf, up, w.dt)
    np.testing.assert_allclose(v, [[8.0, 0, 0]])  # cruise speed along the force
    near = np.array([[89.0, 50, 25]])
    v = commanded_velocity(params, idx, np.array([[5.0, 0, 0]]), near, goal, inf, up, w.dt)
    # Braking distance to the goal: v <= sqrt(2 * 0.8 * amax * d) with amax 4, d 1.
    assert np.linalg.norm(v) == pytest.approx(np.sqrt(2 * 0.8 * 4 * 1.0))
    # A surface 1.5 m ahead (normal -x), more than a step away: the approach speed is cut to
    # the speed that brakes at the agent's safety margin from it, sqrt(2 0.8 a g).
    v = commanded_velocity(
        params, idx, np.array([[5.0, 0, 0]]), far, goal, np.array([1.5]), np.array([[-1.0, 0, 0]]), w.dt
    )
    margin = float(safety_margin(params.radius[0]))
    assert 0.0 < margin <= 0.25
    g, a = 1.5 - margin, 4.0
    assert g > 8.0 * w.dt
    assert v[0, 0] == pytest.approx(np.sqrt(2 * 0.8 * a * g))
    # Within a step of the margin (gap 0.05 m): the stop of one step at v, then braking at a,
    # fits the gap exactly (the lesser cap there).
    wall, normal = np.array([margin + 0.05]), np.array([[-1.0, 0, 0]])
    v = commanded_velocity(params, idx, np.array([[5.0, 0, 0]]), far, goal, wall, normal, w.dt)
    assert v[0, 0] * v[0, 0] / (2 * a) + v[0, 0] * w.dt == pytest.approx(0.05)


@pytest.mark.parametrize("gap", [0.0, 1e-8, 1e-4, 0.05, 1.0])
def test_a_command_along_a_surface_keeps_its_speed_and_its_stop_fits_the_gap(gap):
    """A multirotor at ``gap`` outside its margin from a wall (normal -x), pulled along it
    and a little into it: its speed along the wall stays cruise, and the stop along the whole
    command (one step, then braking at max_accel: the braking margin's sweep) fits the gap, so
    the braking margin leaves it its speed (within a step of the margin by the field's own cap,
    beyond it the small pull into the wall is within that stop anyway)."""
    w = world_of()
    params = AgentParams.from_world(w)
    idx, a = np.array([0]), 4.0
    margin = float(safety_margin(params.radius[0]))
    pos, goal = np.array([[30.0, 50, 25]]), np.array([[30.0, 0, 25]])
    force = np.array([[0.05, -5.0, 0.0]])  # mostly along the wall (-y), a little into it (+x)
    v = commanded_velocity(
        params, idx, force, pos, goal, np.array([margin + gap]), np.array([[-1.0, 0, 0]]), w.dt
    )[0]
    cruise = 8.0
    assert -v[1] == pytest.approx(cruise * 5.0 / np.hypot(5.0, 0.05))  # along: untouched
    speed = float(np.linalg.norm(v))
    if v[0] > 0.0:  # towards the wall: the straight stop reaches it no sooner than the gap allows
        assert (speed * speed / (2 * a) + speed * w.dt) * v[0] / speed <= gap * (1 + 1e-9)
    else:
        assert gap == 0.0 and v[0] == 0.0


@pytest.mark.parametrize(
    "obstacle, goal",
    [
        # Goal 1.5 m from the side of a sphere (0.5 m clearance for radius 1).
        ({"id": "rock", "shape": "sphere", "radius": 6, "position": [60, 50, 25]}, [60, 57.5, 25]),
        # Goal beside a wall, 2 m from its face.
        ({"id": "wall", "shape": "box", "size": [2, 30, 40], "position": [70, 50, 20]}, [67.0, 50, 25]),
        # Goal next to a tall cylinder, off the straight line.
        (
            {"id": "mast", "shape": "cylinder", "radius": 4, "height": 50, "position": [60, 50, 25]},
            [60, 56, 25],
        ),
    ],
    ids=["beside-sphere", "before-wall", "beside-mast"],
)
def test_goal_beside_an_obstacle_is_reached(tmp_path, obstacle, goal):
    w = world_of([obstacle], start=(10, 50, 25), goal=goal)
    log = tmp_path / "run.mcap"
    _sim, summary, _ = run_to_end(w, seed=0, log_path=log)
    assert summary["success"], describe_failure(summary, log)
    problems, _notes, stats = audit(log)
    assert problems == [], problems
    assert stats["arrived"] == 1


# Two agents parked at their goals either side of a third agent's goal, where bench.sim.swap_world
# put them (its a1 and a31 around a0's goal, seed 0): there 5 of 32 agents stalled 2.0-2.3 m
# from their goals behind their arrived neighbours until their escapes ran out.
_PARKED_GOALS = [[51.6, 43.8, 21.3], [51.6, 59.7, 22.6]]


def _parked_world():
    # the swap world's field: agents' influence 8 m (neighbouring goals 8.2 m apart are inside it)
    return make_world(
        base_world(
            planner={"optimizer": {"name": "none"}, "apf": {"influence": 8.0, "k_agent": 20.0}},
            agent_defaults={
                "model": "multirotor",
                "radius": 1.0,
                "speed": {"min": 0, "max": 10, "cruise": 7},
                "max_accel": 4,
                "min_altitude": 3,
                "separation": [3, 3, 2],
            },
            agents=[
                {"id": "left", "start": [80, 43.8, 21.3], "goal": _PARKED_GOALS[0]},
                {"id": "right", "start": [80, 59.7, 22.6], "goal": _PARKED_GOALS[1]},
                {"id": "late", "start": [95, 50, 20], "goal": [50, 50, 20]},
            ],
        )
    )


def test_parked_agents_repel_like_static_obstacles_near_the_goal():
    """An arrived (parked) agent's repulsion takes the goal-distance factor of static obstacles
    (Ge & Cui): where swap_world's agent stalled, 2.2 m before its goal, the two neighbours'
    repulsion cancelled the whole pull while they counted as flying; parked, they leave it."""
    w = _parked_world()
    params = AgentParams.from_world(w)
    goal = np.array([a.goal for a in w.agents], float)
    stall = goal[2] - np.array([0.68, -1.64, 1.31])  # the stalled agent, relative to its goal
    pos = np.array([*_PARKED_GOALS, stall])
    pull = np.linalg.norm(goal[2] - stall)  # the quadratic well's attraction, k_att = 1
    to_goal = (goal[2] - stall) / pull
    # The agent flies in at 3 m/s (at rest, with neighbours at rest, no pair has a speed to
    # brake from and nothing reaches beyond the separation ellipsoid; at 2 m/s the closest
    # approach lies near the horizon's end, where a predicted conflict weighs little).
    vel = np.zeros_like(pos)
    vel[2] = 3.0 * to_goal
    inputs = FieldInputs(
        np.zeros((1, 0)),
        np.zeros((1, 0, 3)),
        np.zeros((0, 3)),
        np.zeros(0, bool),
        np.zeros(0),
        np.zeros((0, 3)),
    )
    idx = np.array([2])
    args = (w, params, idx, pos[idx], vel[idx], goal[idx], inputs, pos, vel)
    assert float(apf_forces(*args)[0] @ to_goal) < 0.3 * pull  # flying: held off the goal
    parked = np.array([True, True, False])
    # Parked, the two neighbours take the goal factor and leave most of the pull.
    assert float(apf_forces(*args, parked=parked)[0] @ to_goal) > 0.6 * pull
    # At the goal itself parked agents add exactly nothing.
    at_goal = np.array([*_PARKED_GOALS, goal[2]])
    f = apf_forces(w, params, idx, at_goal[idx], vel[idx], goal[idx], inputs, at_goal, vel, parked=parked)
    np.testing.assert_allclose(f, 0.0, atol=1e-12)


def test_goal_between_parked_agents_is_reached(tmp_path):
    """The flight past parked agents also audits clean: replay counts an agent's clearance to
    agents that have arrived, as the simulation's summary does."""
    log = tmp_path / "run.mcap"
    _sim, summary, _ = run_to_end(_parked_world(), seed=0, log_path=log)
    assert summary["arrived"] == 3, describe_failure(summary, log)
    problems, _notes, stats = audit(log)
    assert problems == [], problems
    assert summary["collisions"] == 0


def test_fixed_wings_keep_the_full_repulsion_of_parked_agents(monkeypatch):
    """Only agents that can stop take the goal factor on parked agents: a fixed wing near its
    goal circles at speed past them (rscdwoa_multi_uav, woa seed 9: uav1 circled its goal for
    50 s with the factor, arrived at 60 s without it). A multirotor takes the factor."""
    import swarmplan.sim.steering as steering
    from swarmplan.flight.capture import height_first
    from swarmplan.sim import Simulation

    fixed = {"model": "fixed_wing", "speed": {"min": 8, "max": 14, "cruise": 10}, "min_turn_radius": 20}
    w = make_world(
        base_world(
            agents=[
                {"id": "parked", "start": [50, 50, 20], "goal": [50, 50, 20]},
                {"id": "fw", "start": [30, 56, 20], "goal": [45, 56, 20], **fixed},
                {"id": "mr", "start": [30, 44, 20], "goal": [45, 44, 20]},
            ]
        )
    )
    used = []
    real_cmd = steering.commanded_velocity
    monkeypatch.setattr(steering, "commanded_velocity", lambda *a: used.append(a[2].copy()) or real_cmd(*a))
    sim = Simulation(w)
    sim.reset(seed=0)
    sim.step()  # 'parked' starts on its goal: it arrives in this step
    assert [m.name for m in sim.state.mode] == ["ARRIVED", "APF", "APF"]
    pos0, vel0 = sim.state.position.copy(), sim.state.velocity.copy()
    sim.step()
    params = AgentParams.from_world(w)
    idx = np.array([1, 2])
    inputs = FieldInputs(
        np.zeros((2, 0)),
        np.zeros((2, 0, 3)),
        np.zeros((0, 3)),
        np.zeros(0, bool),
        np.zeros(0),
        np.zeros((0, 3)),
    )
    # The multirotor at cruise speed towards its goal (its reach is its braking from the speed
    # it has, which one step after the start does not reach the parked agent yet).
    to_goal = sim.state.goal[2] - pos0[2]
    cruise = vel0.copy()
    cruise[2] = params.speed_cruise[2] * to_goal / np.linalg.norm(to_goal)
    args = (w, params, idx, pos0[idx], cruise[idx], sim.state.goal[idx], inputs, pos0, cruise)
    factor = apf_forces(*args, parked=np.array([True, False, False]))
    full = apf_forces(*args)
    np.testing.assert_array_equal(factor[0], full[0])  # the fixed wing: parked or not, the same
    assert not np.allclose(factor[1], full[1])  # the multirotor takes the factor
    # The simulation's own step used the parked rule (the fixed wing pulled at its goal, at the
    # height its final approach aims at: ``capture.height_first``).
    goal = sim.state.goal[idx]
    target = height_first(params, idx, pos0[idx], goal, np.ones(2, bool), goal)
    args = (w, params, idx, pos0[idx], vel0[idx], goal, inputs, pos0, vel0)
    rule = apf_forces(*args, parked=np.array([True, False, False]), target=target)
    np.testing.assert_array_equal(used[-1], rule)


def test_agent_gain_left_out_scales_with_the_pull():
    """``planner.apf.k_agent`` left out is half the pull at cruise, ``0.5 k_att influence``: 16
    for agents of 8 m/s braking at 4 m/s² (a 32 m influence), times k_att; given, it is kept."""
    w = make_world(base_world())
    apf = w.planner_config.apf
    assert apf.influence == pytest.approx(2 * 8.0**2 / 4.0)
    assert apf.k_agent == pytest.approx(0.5 * apf.influence) == pytest.approx(16.0)
    raw = base_world()
    raw["planner"]["apf"]["k_att"] = 2.0
    assert make_world(raw).planner_config.apf.k_agent == pytest.approx(32.0)
    raw["planner"]["apf"]["k_agent"] = 20.0
    assert make_world(raw).planner_config.apf.k_agent == 20.0


def test_each_multirotor_is_pushed_within_its_own_room_only():
    """A slow multirotor sharing a world with a fast one flies the field at its own scale: a
    body 3 m off, inside the fast agent's room (32 m: 8 m/s braking at 4 m/s²) but beyond the
    slow one's (2 m: its two radii, more than its braking room), pushes only the fast one."""
    fast = {"id": "fast", "start": [30, 50, 25], "goal": [90, 50, 25]}
    slow = {
        "id": "slow",
        "start": [30, 80, 25],
        "goal": [90, 80, 25],
        "speed": {"min": 0, "max": 1.5, "cruise": 1},
    }
    bodies = [
        {"id": f"s{k}", "shape": "sphere", "radius": 1, "position": [30, y, 25]}
        for k, y in enumerate((55, 85))
    ]
    w = make_world(base_world(obstacles=bodies, agents=[fast, slow]))
    np.testing.assert_allclose(AgentParams.from_world(w).field_scale, [1.0, 2.0 / 32.0])
    f = field_forces(w, [fast["start"], slow["start"]])
    assert f[0, 1] < -0.1 * abs(f[0, 0])  # pushed off the body
    assert f[1, 1] == 0.0 and f[1, 0] > 0.0  # straight at its goal


def test_loitering_fixed_wings_give_way_to_arriving_ones():
    """A fixed wing loitering about its goal (``Swarm.yields``) gives way to the others: its push
    on a fixed wing closing in on its own goal takes that one's goal factor (nothing is left of
    it at the goal itself), while the loiterer feels the arriving one in full and makes room."""
    fixed = {"model": "fixed_wing", "speed": {"min": 8, "max": 14, "cruise": 10}, "min_turn_radius": 20}
    w = make_world(
        base_world(
            agents=[
                {"id": "loiter", "start": [50, 50, 20], "goal": [50, 50, 20], **fixed},
                {"id": "fw", "start": [30, 56, 20], "goal": [45, 52, 20], **fixed},
            ]
        )
    )
    params = AgentParams.from_world(w)
    field = ApfField(w, params)
    goal = np.array([a.goal for a in w.agents], float)
    vel = np.array([[0.0, 10.0, 0.0], [10.0, 0.0, 0.0]])
    idx = np.array([0, 1])
    no_bodies = (np.zeros((0, 3)), np.zeros(0, bool), np.zeros(0), np.zeros((0, 3)))
    inputs = FieldInputs(np.zeros((2, 0)), np.zeros((2, 0, 3)), *no_bodies)
    loitering = np.array([True, False])

    def forces(pos, yields=None):
        return field.forces(Flyers(idx, pos, vel, goal), inputs, Swarm(pos, vel, yields=yields))

    near = np.array([[46.0, 50.0, 20.0], [42.0, 52.0, 20.0]])  # 3 m short of its goal, 4.5 m apart
    full, given = forces(near), forces(near, loitering)
    np.testing.assert_array_equal(given[0], full[0])  # the loiterer: the arriving one in full
    away = _unit(near[1] - near[0])
    assert float(full[1] @ away) > float(given[1] @ away)  # the arriving one: pushed off less
    # At its goal the loiterer's push is gone: the force of the loiterer far out of reach.
    at_goal = np.array([[48.0, 50.0, 20.0], goal[1]])
    out_of_reach = np.array([[48.0, 50.0, 2000.0], goal[1]])
    np.testing.assert_allclose(forces(at_goal, loitering)[1], forces(out_of_reach)[1], atol=1e-12)


@pytest.mark.parametrize("speed", [4.0, 6.0])
def test_a_mover_on_collision_course_with_no_room_on_the_agents_side_sends_it_across(speed):
    """The sphere (3 m) comes head-on 2 m to the agent's left (+y): 2 m short of the 4 m miss its
    body and the agent's need. Away from its path (-y) a wall stands 1.5 m from the agent's
    surface, less than those 2 m: the push goes as head-on with the right hemmed in, to the
    left (+y), at every speed of the agent (pushed into the wall at one speed and to the
    right at another, an agent reversed each step and was struck where it hovered)."""
    mover = dict(HEAD_ON_MOVER, position=[70, 52, 25])
    wall = [{"id": "wall", "shape": "box", "size": [100, 1, 40], "position": [50, 47.0, 25]}]
    p, v = np.array([30.0, 50, 25]), np.array([speed, 0, 0])
    push = field_forces(world_of([mover, *wall]), p, v)[0] - field_forces(world_of(wall), p, v)[0]
    assert float(np.dot(_unit(push), [0, 1, 0])) > 0.99, push
    # With room on its side (the wall 3 m off), away from the mover's path as before.
    far = [dict(wall[0], position=[50, 45.5, 25])]
    push = field_forces(world_of([mover, *far]), p, v)[0] - field_forces(world_of(far), p, v)[0]
    assert push[1] < 0.0, push
