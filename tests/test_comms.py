"""Worlds with ``comms`` and ``sensing``: each agent flies on the states it has heard.

The format's sections and their errors; a perfect network gives the run without one, bit for
bit; the broadcast schedule, delays, losses and range on exact cases; the same seed gives the
same messages; an agent's decisions read nothing of the others' true states beyond what it
heard or senses (a property over random swarms); the log's ``/comms`` channel and summary;
circle swaps with delay and loss stay contact-free over several seeds."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers import base_world, make_world
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from swarmplan.bench.swarm_scenarios import rmader_circle
from swarmplan.core import Mode
from swarmplan.sim import Simulation
from swarmplan.sim.deconflict import belief_margin
from swarmplan.sim.network import AgentView
from swarmplan.sim.safety import AgentMotion, Commands, StepWindow
from swarmplan.world import WorldError, parse_world


def _circle(n: int = 6, seed: int = 0, comms: dict | None = None, sensing: dict | None = None) -> dict:
    raw = rmader_circle(n, seed, altitude=2.0)
    if comms is not None:
        raw["comms"] = comms
    if sensing is not None:
        raw["sensing"] = sensing
    return raw


def _fly(raw: dict, seed: int | None = None, planner: str = "world") -> tuple[Simulation, np.ndarray, list]:
    sim = Simulation(parse_world(raw), planner)
    sim.reset(seed)
    path, events = [sim.state.position.copy()], []
    while True:
        r = sim.step()
        path.append(r.state.position.copy())
        events += [(e.t, e.agent, e.kind) for e in r.events]
        if r.terminated or r.truncated:
            return sim, np.array(path), events


# ---------------------------------------------------------------- the world format


def test_sections_resolve_with_their_defaults():
    comms = {"rate": 20, "delay": {"mean": 0.1, "jitter": 0.02}, "loss": 0.1, "range": 50}
    w = make_world(base_world(comms=comms, sensing={"range": 15}))
    assert (w.comms.rate, w.comms.delay, w.comms.jitter, w.comms.loss, w.comms.range) == (
        20,
        0.1,
        0.02,
        0.1,
        50,
    )
    assert w.sensing.range == 15
    msg = w.to_message(0)
    assert msg["comms"] == {"rate": 20.0, "delay": {"mean": 0.1, "jitter": 0.02}, "loss": 0.1, "range": 50.0}
    assert msg["sensing"] == {"range": 15.0}
    bare = make_world(base_world(comms={}))
    assert (bare.comms.rate, bare.comms.delay, bare.comms.loss, bare.comms.range) == (
        None,
        0.0,
        0.0,
        math.inf,
    )
    assert bare.comms.period(0.1) == 0.1 and w.comms.period(0.1) == 0.1  # at most one broadcast a step
    assert make_world(base_world(comms={"rate": 2})).comms.period(0.1) == 0.5
    plain = make_world(base_world())
    assert plain.comms is None and plain.sensing is None
    assert "comms" not in plain.to_message(0) and "sensing" not in plain.to_message(0)


@pytest.mark.parametrize(
    ("comms", "sensing", "problem"),
    [
        ({"rate": 0}, None, "comms.rate: must be > 0"),
        ({"delay": -0.1}, None, "comms.delay: must be >= 0"),
        ({"delay": {"mean": 0.1, "jitter": 0.2}}, None, "comms.delay.jitter: must be <= the mean"),
        ({"delay": {"jitter": 0.2}}, None, "comms.delay.mean: required key is missing"),
        ({"loss": 1.0}, None, "comms.loss: must be < 1"),
        ({"loss": -0.5}, None, "comms.loss: must be >= 0"),
        ({"range": 0}, None, "comms.range: must be > 0"),
        ({"rnage": 5}, None, "comms.rnage: unknown key (did you mean 'range'?)"),
        ("fast", None, "comms: expected a mapping"),
        (None, {}, "sensing.range: required key is missing"),
        (None, {"range": "far"}, "sensing.range: expected a number"),
    ],
)
def test_bad_sections_are_refused_by_name(comms, sensing, problem):
    raw = base_world()
    if comms is not None:
        raw["comms"] = comms
    if sensing is not None:
        raw["sensing"] = sensing
    with pytest.raises(WorldError) as err:
        make_world(raw)
    assert any(p.startswith(problem) for p in err.value.problems), err.value.problems


# ---------------------------------------------------------------- a perfect network


@pytest.mark.parametrize("comms", [{}, {"rate": 20, "delay": 0.0, "loss": 0.0}])
def test_a_perfect_network_flies_the_run_without_one(comms):
    """Zero delay, no loss, unlimited range, a broadcast every step: every agent knows what
    the truth is at every step start, so the run is the run without ``comms``, bit for bit."""
    _, alone, ev_alone = _fly(_circle(6, 1))
    sim, heard, ev_heard = _fly(_circle(6, 1, comms))
    np.testing.assert_array_equal(alone, heard)
    assert ev_alone == ev_heard
    c = sim.summary()["comms"]
    assert c["lost"] == 0 and c["out_of_range"] == 0 and c["sent"] > 0 and c["oldest_age_max"] == 0.0


# ---------------------------------------------------------------- the network on exact cases


def _network_sim(n: int, comms: dict, spacing: float = 10.0, **top) -> Simulation:
    agents = [{"id": f"a{i}", "start": [10 + spacing * i, 50, 20], "goal": [10 + spacing * i, 60, 20]}
              for i in range(n)]  # fmt: skip
    sim = Simulation(make_world(base_world(agents=agents, comms=comms, **top)), "none")
    sim.reset(0)
    return sim


def test_ages_and_extrapolation_with_a_fixed_delay():
    """One broadcast a step (dt 0.1 s), delay 0.2 s, no loss: at every step start from the
    third on, every state heard is exactly 0.2 s old, and believed where it was then, moved on
    by its velocity then."""
    sim = _network_sim(4, {"rate": 10, "delay": 0.2})
    history = [(sim.state.position.copy(), sim.state.velocity.copy())]
    for _ in range(8):
        sim.step()
        history.append((sim.state.position.copy(), sim.state.velocity.copy()))
        if len(history) < 3:
            continue
        t = sim.state.t
        net = sim.network
        net.deliver(t)
        b = net.beliefs(
            np.arange(4), t, sim.state.position, sim.state.velocity, np.zeros(4, bool), np.zeros(4)
        )
        off = ~np.eye(4, dtype=bool)
        rows = b.view
        assert (rows >= 0).all()
        np.testing.assert_array_equal(b.agent[rows], np.broadcast_to(np.arange(4), (4, 4)))
        np.testing.assert_allclose(b.age[rows[off]], 0.2, atol=1e-9)
        p, v = history[-3]
        expected = p[None] + v[None] * 0.2
        np.testing.assert_allclose(b.pos[rows][off], np.broadcast_to(expected, (4, 4, 3))[off], atol=1e-12)
        np.testing.assert_array_equal(b.pos[rows][~off], sim.state.position)
        np.testing.assert_array_equal(b.age[rows][~off], 0.0)


def test_schedule_losses_and_range_are_counted():
    """rate 5 Hz at dt 0.1 s: each agent speaks every second step (spread over the period);
    a 30 % loss loses 30 % of the copies (binomial: within 4 sigma); agents 10 m apart with a
    25 m range hear their two nearest neighbours on each side and no farther."""
    sim = _network_sim(6, {"rate": 5, "loss": 0.3, "range": 25})
    sent = []
    for _ in range(100):
        before = sim.network.sent
        sim.step()
        sent.append(sim.network.sent - before)
    assert sum(sent) == 100 // 2 * 6 * 5  # every agent once per 2 steps, 5 copies each
    assert 0 < min(sent) and max(sent) < 6 * 5  # spread: never the whole swarm in one step
    net = sim.network
    far = sim.network.out_of_range
    # Pairs of 6 agents in a row 10 m apart (they fly in parallel): 2x(3+2+1) = 12 of 30 beyond 25 m.
    assert far == pytest.approx(net.sent * 12 / 30, rel=0.02)
    heard = net.sent - far
    share = net.lost / heard
    sigma = math.sqrt(0.3 * 0.7 / heard)
    assert abs(share - 0.3) < 4 * sigma


def test_belief_margin_grows_with_age():
    """The other may have accelerated at its limit since its state was true: a (age + dt)^2 / 2."""
    m = belief_margin(np.array([2.0, 8.0]), np.array([0.0, 0.3]), 0.1)
    np.testing.assert_allclose(m, [0.5 * 2.0 * 0.01, 0.5 * 8.0 * 0.16])


# ---------------------------------------------------------------- seeds


def test_same_seed_same_messages_and_run():
    comms = {"rate": 20, "delay": {"mean": 0.1, "jitter": 0.05}, "loss": 0.2}
    a, pa, ea = _fly(_circle(6, 2, comms), seed=3)
    b, pb, eb = _fly(_circle(6, 2, comms), seed=3)
    np.testing.assert_array_equal(pa, pb)
    assert ea == eb and a.summary()["comms"] == b.summary()["comms"]
    c, _, _ = _fly(_circle(6, 2, comms), seed=4)
    assert c.summary()["comms"]["lost"] != a.summary()["comms"]["lost"]


# ---------------------------------------------------------------- no peeking


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    n=st.integers(3, 6),
    steps=st.integers(2, 25),
    delay=st.sampled_from([0.05, 0.1, 0.25]),
    loss=st.sampled_from([0.0, 0.2]),
    sensing=st.sampled_from([None, 1.5]),
    seed=st.integers(0, 2**16),
)
def test_decisions_read_only_what_an_agent_heard(n, steps, delay, loss, sensing, seed):
    """After some steps of a circle swap, the command of every flyer, the step its safety filter
    makes of it (deconflicted on its beliefs) and the state its planner sees stay the same when
    the other agents' true states are moved, except those it senses (within ``sensing.range``,
    left where they are)."""
    raw = _circle(n, seed % 7, {"rate": 20, "delay": delay, "loss": loss},
                  None if sensing is None else {"range": sensing})  # fmt: skip
    sim = Simulation(parse_world(raw), "world")
    sim.reset(seed)
    for _ in range(steps):
        if sim.step().terminated:
            return
    s = sim.state
    rng = np.random.default_rng(seed)

    def decisions() -> tuple:
        sim.network.deliver(s.t)
        idx = np.flatnonzero(s.active)
        q0, qv0 = sim.obstacles.poses(s.t)
        distances = sim.distances.query(s.position, q0)
        parked = ~sim.loiter.flying(s, s.active)
        cmd = sim.steering.commands(s, idx, s.position, s.velocity, distances, q0, qv0, parked)
        views = [AgentView(sim, int(i)).state for i in idx]
        own = [(v.position[i], v.velocity[i], v.mode[i]) for v, i in zip(views, idx, strict=True)]
        # The step its own safety filter makes of its command (deconflicted on its beliefs).
        window = StepWindow(s.t, s.t + sim.world.dt, q0, sim.obstacles.poses(s.t + sim.world.dt)[0])
        brake_goal = sim.evasion.brake_goals(idx, cmd.position, cmd.goal)
        commands = Commands(idx, cmd.velocity, cmd.beliefs, sim.network.agreed(s.t))
        flown = sim.safety.fly(commands, AgentMotion(s.position, s.velocity), window, s.mode, brake_goal)
        return idx, np.hstack([cmd.velocity, flown.end.velocity[idx]]), own, views

    for i in np.flatnonzero(s.active):
        idx, v_before, own_before, views_before = decisions()
        k = int(np.flatnonzero(idx == i)[0])
        # Everything i does not sense moves; i itself and what it senses stay.
        keep = np.zeros(sim.n, dtype=bool)
        keep[i] = True
        if sensing is not None:
            keep |= np.linalg.norm(s.position - s.position[i], axis=1) <= sensing
        saved = s.position.copy(), s.velocity.copy()
        moved = np.where(keep[:, None], s.position, s.position + rng.normal(0, 3.0, s.position.shape))
        if sensing is not None:  # a moved agent stays out of i's sensing (it would see it, rightly)
            off = moved - s.position[i]
            d = np.linalg.norm(off, axis=1)
            inside = ~keep & (d <= sensing)
            out = off[inside] / np.maximum(d[inside], 1e-9)[:, None]
            moved[inside] = s.position[i] + out * (sensing + 0.5)
        s.position = moved
        s.velocity = np.where(keep[:, None], s.velocity, s.velocity + rng.normal(0, 2.0, s.velocity.shape))
        _, v_after, _, views_after = decisions()
        s.position, s.velocity = saved
        np.testing.assert_array_equal(v_before[k], v_after[k])
        np.testing.assert_array_equal(views_before[k].position, views_after[k].position)
        np.testing.assert_array_equal(views_before[k].velocity, views_after[k].velocity)
        assert list(views_before[k].mode) == list(views_after[k].mode)
        assert own_before[k][2] in (Mode.APF, Mode.ESCAPE, Mode.SMOOTHING)


# ---------------------------------------------------------------- the log


def test_comms_channel_summary_and_replay(tmp_path):
    from helpers import audit, read_log

    from swarmplan.cli.replay import describe
    from swarmplan.io.recording import McapRecorder
    from swarmplan.io.runner import run_episode
    from swarmplan.replay.recording import load

    comms = {"rate": 20, "delay": {"mean": 0.1, "jitter": 0.02}, "loss": 0.1}
    sim = Simulation(parse_world(_circle(4, 0, comms)), "world")
    path = tmp_path / "run.mcap"
    summary = run_episode(sim, 0, recorder=McapRecorder(path, foxglove=False))
    msgs = [m for _, m in read_log(path)["/comms"]]
    states = read_log(path)["/agents/state"]
    assert len(msgs) == len(states) - 1  # every step, none at t = 0
    last = msgs[-1]
    assert {k: last[k] for k in ("sent", "lost", "out_of_range")} == {
        k: summary["comms"][k] for k in ("sent", "lost", "out_of_range")
    }
    ages = [a["age"] for m in msgs for a in m["agents"] if a["age"] is not None]
    assert max(ages) == pytest.approx(summary["comms"]["oldest_age_max"])
    assert min(ages) >= 0.08 - 1e-9  # 0.1 s +- 0.02 s at least
    problems, _, _ = audit(path)
    assert not problems
    assert any(line.startswith("comms: ") for line in describe(load(path)))


# ---------------------------------------------------------------- flown with delay and loss


def test_circle_swaps_with_delay_and_loss_stay_clear():
    """10 agents on RMADER's circle, 300 ms delay, 10 % loss, 20 Hz, three seeds: no contact
    and every agent home."""
    for seed in range(3):
        sim, _, _ = _fly(_circle(10, seed, {"rate": 20, "delay": 0.3, "loss": 0.1}), seed=seed)
        s = sim.summary()
        assert s["collisions"] == 0 and s["arrived"] == 10, (seed, s["collisions"], s["arrived"])


def _two(believed_x: float, age: float = 0.0, vel: tuple = (2.0, 0.0, 0.0)) -> tuple[np.ndarray, list]:
    """Agent a (radius 1, 4 m/s², dt 0.1) at x = 10 flying +x at 2 m/s, and what its
    deconfliction makes of that step when it believes agent b at rest at ``believed_x``."""
    from swarmplan.sim.deconflict import belief_conflicts
    from swarmplan.sim.network import Beliefs

    agents = [{"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20]},
              {"id": "b", "start": [60, 50, 20], "goal": [60, 90, 20]}]  # fmt: skip
    sim = Simulation(make_world(base_world(agents=agents, comms={"delay": 0.1})), "none")
    sim.reset(0)
    pos0 = np.array([[10.0, 50, 20], [60.0, 50, 20]])  # b's truth: far away
    vel0 = np.array([vel, [0.0, 0, 0]])
    pos1, vel1 = pos0 + vel0 * 0.1, vel0.copy()
    table = np.array([pos0[0], [believed_x, 50.0, 20.0]])
    rest, ages = np.zeros((2, 3)), np.array([0.0, age])
    beliefs = Beliefs(np.array([0]), pos0[:1], table, rest, np.zeros(2, bool), np.zeros(2), ages,
                      np.array([0, 1]), np.array([[0, 1]]), table, rest, np.zeros(2, bool))  # fmt: skip
    q = sim.obstacles.poses(0.0)[0]
    window = StepWindow(0.0, 0.1, q, q)
    events, _, stopped = belief_conflicts(
        sim.safety, beliefs, (pos0, vel0), (pos1, vel1), np.array([True, False]), None, window
    )
    return vel1[0], events


def test_deconfliction_on_beliefs_exact_geometry():
    """need = 1 + 1 + 0.2 + 4 (age + 0.1)^2 / 2. Believed at x = 12.3 (2.3 m, closing to 2.1 m
    < 2.22 m): the slide (no x at all) is beyond one step's 0.4 m/s, braking to 1.6 m/s still
    closes within 2.22 m, so it brakes within its limit (no stop, no event). Believed at 30 m:
    the step stands, wherever b truly is. Believed at 12.3 m with age 0.5 s (need 2.92 m):
    the same brake. Believed just behind at x = 8: the step widens the gap, no conflict. Flying
    (0.3, 2, 0) with b believed at x = 12.1: it slides, its x part dropped (0.3 m/s: within one
    step's change)."""
    v, events = _two(12.3)
    np.testing.assert_allclose(v, [1.6, 0, 0])
    assert events == []
    v, _ = _two(30.0)
    np.testing.assert_array_equal(v, [2.0, 0, 0])
    v, _ = _two(12.3, age=0.5)
    np.testing.assert_allclose(v, [1.6, 0, 0])
    v, _ = _two(8.0)
    np.testing.assert_array_equal(v, [2.0, 0, 0])
    v, _ = _two(12.1, vel=(0.3, 2.0, 0.0))
    np.testing.assert_allclose(v, [0.0, 2.0, 0.0])


def _room(believed_x: float, age: float, vel_b: tuple, cmd: tuple = (5.0, 0.0, 0.0)) -> np.ndarray:
    """Agent a (radius 1, 4 m/s², dt 0.1) at x = 10 commanded ``cmd``, believing agent b at
    ``believed_x`` moving at ``vel_b``, heard ``age`` s ago: its command after
    :func:`braking_room`."""
    from swarmplan.sim.deconflict import braking_room
    from swarmplan.sim.network import Beliefs

    agents = [{"id": "a", "start": [10, 50, 20], "goal": [90, 50, 20]},
              {"id": "b", "start": [60, 50, 20], "goal": [60, 90, 20]}]  # fmt: skip
    sim = Simulation(make_world(base_world(agents=agents, comms={"delay": 0.1})), "none")
    table = np.array([[10.0, 50, 20], [believed_x, 50.0, 20.0]])
    vel = np.array([cmd, vel_b], dtype=float)
    ages = np.array([0.0, age])
    beliefs = Beliefs(np.array([0]), table[:1], table, vel, np.zeros(2, bool), np.zeros(2), ages,
                      np.array([0, 1]), np.array([[0, 1]]), table, vel, np.zeros(2, bool))  # fmt: skip
    return braking_room(sim.params, beliefs, np.array([cmd], dtype=float), 0.1)[0]


def test_braking_room_exact_geometry():
    """Two bodies of 1 m (4 m/s², braking at 0.8 of it: 3.2 m/s²), each with its 0.2 m safety
    margin, b believed 6 m ahead (x = 16), heard 0.2 s ago: the gap is 6 - 2.4 - 4 0.2^2 / 2 =
    3.52 m. Believed at rest, b may have set off towards a since (at 4 0.2 = 0.8 m/s at most):
    its step of reaction and braking, 0.08 + 0.8^2 / 6.4 = 0.18, come out of the gap, and a may
    close in at the speed that stops in the rest after its own step of reaction: v 0.1 +
    v^2 / 6.4 = 3.34, v = 3.2 (sqrt(0.01 + 2.0875) - 0.1) = 4.3145 m/s. Moving away at 3 m/s
    (2.2 m/s after what it may have lost since), its braking at its full limit, 2.2^2 / 8, adds
    to the room; coming closer at 1 m/s (1.8 m/s at worst), its own reaction and braking come
    out of it. Only the part along the line is cut; beyond reach, or heard this very step
    (age 0), the command stands; in contact, a does not close in."""
    gap = 6.0 - 2.4 - 0.5 * 4.0 * 0.2**2

    def allowed(room: float) -> float:
        return 3.2 * (math.sqrt(0.01 + 2.0 * room / 3.2) - 0.1)

    def coming(w: float) -> float:
        return w * 0.1 + w * w / 6.4

    v = allowed(gap - coming(0.8))
    assert v == pytest.approx(4.3145, abs=1e-4)
    np.testing.assert_allclose(_room(16.0, 0.2, (0, 0, 0)), [v, 0, 0], rtol=1e-12)
    np.testing.assert_allclose(_room(16.0, 0.2, (0, 0, 0), cmd=(5.0, 2.0, 0.0)), [v, 2.0, 0], rtol=1e-12)
    np.testing.assert_allclose(_room(14.0, 0.2, (3, 0, 0)), [allowed(4.0 - 2.4 - 0.08 + 2.2**2 / 8.0), 0, 0])
    np.testing.assert_allclose(_room(16.0, 0.2, (3, 0, 0)), [allowed(gap + 2.2**2 / 8.0), 0, 0], rtol=1e-12)
    assert allowed(10.0 - 2.4 - 0.08 + 2.2**2 / 8.0) > 5.0
    np.testing.assert_array_equal(_room(20.0, 0.2, (3, 0, 0)), [5.0, 0, 0])
    np.testing.assert_allclose(_room(16.0, 0.2, (-1, 0, 0)), [allowed(gap - coming(1.8)), 0, 0], rtol=1e-12)
    np.testing.assert_array_equal(_room(70.0, 0.2, (-1, 0, 0)), [5.0, 0, 0])
    np.testing.assert_array_equal(_room(16.0, 0.0, (-1, 0, 0)), [5.0, 0, 0])
    np.testing.assert_array_equal(_room(11.0, 0.2, (0, 0, 0)), [0.0, 0, 0])


def test_belief_doubt_is_half_the_limit_times_the_age_squared():
    """An agent heard ``age`` ago may be a age^2 / 2 from its state moved on at the velocity
    sent; 0 for a state of now and for an unknown age; the deconfliction's margin is the doubt
    at the step's end."""
    from swarmplan.sim.network_passes import belief_doubt

    d = belief_doubt(np.array([2.0, 8.0, 8.0]), np.array([0.0, 0.3, np.inf]))
    np.testing.assert_allclose(d, [0.0, 0.5 * 8.0 * 0.09, 0.0])
    np.testing.assert_array_equal(
        belief_margin(np.array([8.0]), np.array([0.3]), 0.1), belief_doubt(np.array([8.0]), np.array([0.4]))
    )


def test_a_loiterer_is_believed_to_give_way_only_once_heard():
    """Whether an agent loiters (a fixed wing circling its goal gives way, ``apf.Swarm.yields``)
    travels in its broadcasts like the rest of its state: its own row says so at once, the
    others' rows of it only after a state sent while it loitered has arrived."""
    sim = _network_sim(4, {"rate": 10, "delay": 0.2})
    for _ in range(3):
        sim.step()
    s, net = sim.state, sim.network
    loiters = np.array([False, True, False, False])
    b = net.beliefs(np.arange(4), s.t, s.position, s.velocity, np.zeros(4, bool), np.zeros(4), yields=loiters)
    np.testing.assert_array_equal(b.yields[b.view[1, 1]], True)  # its own row
    assert not b.yields[b.view[[0, 2, 3], 1]].any()  # heard before it loitered
    # A broadcast sent while it loiters reaches the others after the delay.
    for _ in range(4):
        t0 = s.t
        s.t = t0 + sim.world.dt
        net.broadcast(t0, s, np.zeros(4, bool), np.zeros((4, 3)), loiters)
    b = net.beliefs(np.arange(4), s.t, s.position, s.velocity, np.zeros(4, bool), np.zeros(4), yields=loiters)
    np.testing.assert_array_equal(b.yields[b.view[:, 1]], True)
    assert not b.yields[b.view[:, [0, 2, 3]]].any()
