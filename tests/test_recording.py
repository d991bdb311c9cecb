"""Rerun recordings (esp_gym/viz/recording.py): written, then read back with
``rerun.chunk.RrdReader`` and compared with the simulator; cut short by termination and by
signals, they stay readable and complete.

Precision: scalar series are stored as float64 (Rerun's Scalar component), so they must equal
the simulator's diagnostics bit for bit. 3-D geometry is stored in Rerun's float32 component
types (Position3D, Translation3D, TransformMat3x3, Vector3D), so it must equal the float64
state rounded once to float32 (``np.float32(x)``), exactly.
"""
import signal
import subprocess
import sys
import threading

import gymnasium as gym
import numpy as np
import pyarrow as pa
import pytest
from rerun.chunk import RrdReader

import esp_gym
from esp_gym.kernels.env.arrays import SENSORS
from esp_gym.kernels.step.disturbance import DISTURBANCE
from esp_gym.viz import recording as R
from esp_gym.viz.recording import RecordRerun

ENV_ID = "ElasticStringPendulum-v0"
PARTS = ("kinetic_string", "kinetic_body", "kinetic_pivot", "potential_gravity", "potential_elastic", "work")
WORLD_ENTITIES = {R.STRING, R.BODY, R.BODY_SHAPE, R.BODY_COM, R.BODY_TORQUE, R.PIVOT, R.PIVOT_FORCE, R.LOAD_TRAIL}
DIAG_ENTITIES = {"/diag/energy/total", "/diag/energy/parts", "/diag/energy_residual", "/diag/pi3",
                 "/diag/pi3_residual", "/diag/orthogonality", "/diag/stretched_length", "/diag/newton_iterations"}
RL_ENTITIES = {"/rl/reward/total", "/rl/reward/terms", "/rl/return", "/rl/action", R.TARGET_PIVOT, R.TARGET_LOAD,
               R.ENV_WIND, R.ENV_HOOK_TENSION, R.ENV_PUSH, R.ENV_DRAG, R.WIND, R.PUSH, R.HOOK_TENSION}


def read(path, entity):
    """The temporal rows of ``entity``, sorted by step: {column: list}, ``time`` in ns, None where
    a row's chunk has no such column (an env's torque arrow: origins at resets, vectors at every
    sample). Uses ``stream()``, which also reads a file without its footer."""
    rows, count = {}, 0
    for chunk in RrdReader(path).stream():
        if chunk.entity_path != entity or chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        for name in batch.schema.names:
            col = batch.column(name)
            if name == "time":
                col = col.cast(pa.int64())
            rows.setdefault(name, [None] * count).extend(col.to_pylist())
        count += batch.num_rows
        for col in rows.values():
            col.extend([None] * (count - len(col)))
    order = np.argsort(rows["step"], kind="stable")
    return {k: [v[i] for i in order] for k, v in rows.items()}


def values(path, entity, component="Scalars:scalars"):
    """(steps, values) of the rows of ``entity`` where ``component`` is not null; a
    one-element batch is unwrapped."""
    rows = read(path, entity)
    keep = [i for i, v in enumerate(rows[component]) if v is not None]
    vals = [rows[component][i] for i in keep]
    vals = [v[0] if len(v) == 1 else v for v in vals]
    return np.array([rows["step"][i] for i in keep]), vals


def entities(path):
    return {chunk.entity_path for chunk in RrdReader(path).stream()}


def rollout(env, steps, seed=0, actions_seed=0):
    """Reset and step with seeded random actions (some outside [-1, 1], so clipped); returns
    the simulator's diagnostics after the reset and each step, the actions and the step
    results."""
    rng = np.random.default_rng(actions_seed)
    env.reset(seed=seed)
    sim = env.unwrapped.sim
    diags, actions, results = [sim.diagnostics()], [], []
    for _ in range(steps):
        a = rng.uniform(-1.3, 1.3, 6)
        out = env.step(a)
        diags.append(sim.diagnostics())
        actions.append(a)
        results.append(out)
        _, _, terminated, truncated, _ = out
        if terminated or truncated:
            break
    return diags, np.array(actions), results


def test_env_recording_holds_the_simulator_diagnostics(tmp_path):
    path = tmp_path / "env.rrd"
    env = RecordRerun(gym.make(ENV_ID), path)
    u = env.unwrapped
    diags, actions, results = rollout(env, 20)
    env.close()
    n = len(diags)
    assert n == 21

    reader = RrdReader(path)
    assert len(reader.recordings()) == 1 and len(reader.blueprints()) >= 1  # the default blueprint
    assert len(reader.store()) > 0  # closed: the file has its footer and manifest
    assert WORLD_ENTITIES | DIAG_ENTITIES | RL_ENTITIES <= entities(path)

    # timelines: the control step, and time = step x control period [s]
    rows = read(path, "/diag/energy/total")
    assert rows["step"] == list(range(n))
    assert rows["time"] == [round(k * 0.02 * 1e9) for k in range(n)]

    # scalars: float64, bit for bit the simulator's diagnostics
    for entity, key in [("/diag/energy/total", "energy"), ("/diag/energy_residual", "energy_balance_residual"),
                        ("/diag/pi3", "pi3"), ("/diag/pi3_residual", "pi3_balance_residual"),
                        ("/diag/orthogonality", "orthogonality"), ("/diag/stretched_length", "stretched_length")]:
        steps, vals = values(path, entity)
        assert len(vals) == n, entity
        assert vals == [d[key] for d in diags], entity
    _, parts = values(path, "/diag/energy/parts")
    assert parts == [[d[p] for p in PARTS] for d in diags]
    assert max(abs(d["energy_balance_residual"]) for d in diags) > 0  # a non-trivial comparison

    # what env.step applied and returned, from the first step on (the reset sample has none)
    steps, reward = values(path, "/rl/reward/total")
    assert list(steps) == list(range(1, n))
    assert reward == [r[1] for r in results]
    _, terms = values(path, "/rl/reward/terms")
    assert terms == [[r[4]["reward_" + t] for t in R.REWARD_TERMS] for r in results]
    _, action = values(path, "/rl/action")
    assert np.array_equal(action, np.clip(actions, -1.0, 1.0))
    _, ret = values(path, "/rl/return")
    assert np.allclose(ret, np.cumsum(reward), rtol=1e-12, atol=1e-12)
    _, newton = values(path, "/diag/newton_iterations")
    assert len(newton) == n - 1 and all(1.0 <= x <= 20.0 for x in newton)

    # 3-D: float32 of the state
    rows = read(path, R.BODY)
    f32 = lambda x: np.asarray(x, dtype=np.float32)  # noqa: E731
    assert np.array_equal(f32(rows["Transform3D:translation"])[:, 0], f32([d["attach_position"] for d in diags]))
    st = u.sim.state  # the last state: R column-major (Rerun's TransformMat3x3 layout)
    assert np.array_equal(f32(rows["Transform3D:mat3x3"][-1][0]), f32(st.R.T.reshape(-1)))
    strips = f32(read(path, R.STRING)["LineStrips3D:strips"][-1])  # (N, 2, 3)
    assert np.array_equal(strips[:, 0], f32(st.r[:-1])) and np.array_equal(strips[:, 1], f32(st.r[1:]))
    assert np.array_equal(f32(read(path, R.PIVOT)["Points3D:positions"][-1][0]), f32(st.r[0]))
    setup = u.setup
    force = read(path, R.PIVOT_FORCE)["Arrows3D:vectors"]
    expected = 0.05 * ((setup.hover + setup.force_limit * np.clip(actions[:, :3], -1, 1)) - setup.hover)
    assert np.allclose(f32([v[0] for v in force[1:]]), expected, rtol=1e-6, atol=1e-7)
    trail = read(path, R.LOAD_TRAIL)["LineStrips3D:strips"]
    load = st.r[-1] + st.R @ np.asarray(u.scene.body.rho_c)
    assert np.allclose(trail[-1][0][-1], load, atol=1e-6)  # the trail ends at the load
    assert len(trail[-1][0]) == 5  # 20 steps: the samples 20, 15, 10, 5, 0 (every 0.1 s)
    steps, pivot_target = values(path, R.TARGET_PIVOT, "Points3D:positions")
    assert list(steps) == [0] and np.array_equal(f32(pivot_target[0]), f32(u.target[:3]))

    # still air: the wind, push and drag series are zeros; the hook still pulls
    for entity, width in [(R.ENV_WIND, 3), (R.ENV_PUSH, 2), (R.ENV_DRAG, 6)]:
        steps, vals = values(path, entity)
        assert list(steps) == list(range(n)) and np.array_equal(vals, np.zeros((n, width))), entity
    _, tension = values(path, R.ENV_HOOK_TENSION)
    assert tension[-1] == u.control.sensors[SENSORS["hook_tension"]].tolist() and np.linalg.norm(tension[-1]) > 0


@pytest.mark.filterwarnings("ignore:RRD file has no footer")
@pytest.mark.parametrize("flush_on_episode_end", [True, False])
def test_recording_cut_by_early_termination_is_complete(tmp_path, flush_on_episode_end):
    path = tmp_path / "cut.rrd"
    env = RecordRerun(gym.make(ENV_ID), path, flush_on_episode_end=flush_on_episode_end)
    env.reset(seed=1)
    steps = 0
    while True:  # full force along x: the pivot leaves the 4 m workspace within ~1.2 s
        _, _, terminated, truncated, info = env.step(np.array([1.0, 0, 0, 0, 0, 0]))
        steps += 1
        if terminated or truncated:
            break
    assert terminated and steps < 500, info
    if flush_on_episode_end:  # written at the episode's end: readable before close, no footer yet
        steps_seen, _ = values(path, "/diag/energy/total")
        assert list(steps_seen) == list(range(steps + 1))
        with pytest.raises(RuntimeError):
            RrdReader(path).store()
    env.close()
    assert len(RrdReader(path).store()) > 0
    steps_seen, reward = values(path, "/rl/reward/total")
    assert list(steps_seen) == list(range(1, steps + 1))


def test_episodes_follow_each_other_on_the_step_timeline(tmp_path):
    path = tmp_path / "two.rrd"
    env = RecordRerun(gym.make(ENV_ID, max_episode_steps=5), path, flush_every=4)  # flushes mid-episode
    for seed in (0, 1):
        env.reset(seed=seed)
        truncated = False
        while not truncated:
            _, _, _, truncated, _ = env.step(np.zeros(6))
    env.close()
    steps, energy = values(path, "/diag/energy/total")
    assert list(steps) == list(range(12))  # reset 0, steps 1-5, reset 6, steps 7-11
    steps, reward = values(path, "/rl/reward/total")
    assert list(steps) == [1, 2, 3, 4, 5, 7, 8, 9, 10, 11]
    _, ret = values(path, "/rl/return")  # restarts with each episode
    assert np.allclose(ret, np.r_[np.cumsum(reward[:5]), np.cumsum(reward[5:])], rtol=1e-12)
    steps, _ = values(path, R.TARGET_LOAD, "Points3D:positions")
    assert list(steps) == [0, 6]
    trail = read(path, R.LOAD_TRAIL)["LineStrips3D:strips"]
    assert len(trail[6][0]) == 1  # the trail restarts at a reset


def test_free_simulation_via_the_cli(tmp_path):
    out = tmp_path / "paper.rrd"
    proc = subprocess.run([sys.executable, "-m", "esp_gym.cli", "record", "--scene", "paper_example",
                           "--t-final", "0.2", "--out", str(out), "--no-progress"],
                          capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert len(RrdReader(out).store()) > 0
    assert WORLD_ENTITIES | DIAG_ENTITIES <= entities(out)
    assert not (RL_ENTITIES & entities(out))
    # default: ~50 samples per simulated second, h = 1e-4 s -> every 200 steps, t = 0 included
    sim = esp_gym.Simulator(esp_gym.load_scene("paper_example"))
    expected = [sim.diagnostics()]
    for _ in range(10):
        sim.step(200)
        expected.append(sim.diagnostics())
    rows = read(out, "/diag/energy/total")
    assert rows["step"] == [200 * k for k in range(11)]
    assert rows["time"] == [round(200 * k * 1e-4 * 1e9) for k in range(11)]
    for entity, key in [("/diag/energy/total", "energy"), ("/diag/energy_residual", "energy_balance_residual"),
                        ("/diag/pi3", "pi3"), ("/diag/pi3_residual", "pi3_balance_residual")]:
        assert values(out, entity)[1] == [d[key] for d in expected], entity  # reruns are bit-identical
    newton_steps, newton = values(out, "/diag/newton_iterations")
    assert list(newton_steps) == [200 * k for k in range(1, 11)]
    static = {c.entity_path: c.to_record_batch().schema.names for c in RrdReader(out).stream() if c.is_static}
    assert "Mesh3D:vertex_positions" in static[R.BODY_SHAPE]  # the paper's elliptic cylinder


def default_sigint() -> None:
    """In a child before it starts: SIGINT's default disposition, so Python raises KeyboardInterrupt."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT])
def test_recording_of_a_killed_process_is_complete(tmp_path, signum):
    """A rollout buffering everything (no flush before the signal) is killed mid-episode: the
    file is closed with its footer and holds every step the child reported."""
    path = tmp_path / "killed.rrd"
    child = (
        "import sys, numpy as np, gymnasium as gym, esp_gym\n"
        "from esp_gym.viz.recording import RecordRerun\n"
        "env = RecordRerun(gym.make('ElasticStringPendulum-v0'), sys.argv[1], flush_every=100000, flush_seconds=1e6)\n"
        "env.reset(seed=0)\n"
        "k = 0\n"
        "while True:\n"
        "    env.step(np.zeros(6))\n"
        "    k += 1\n"
        "    print(k, flush=True)\n"
    )
    # SIGINT as a terminal leaves it (a shell's background job ignores it, and so would the child),
    # and a watchdog: a child the signal does not stop would record until the disk is full
    proc = subprocess.Popen([sys.executable, "-c", child, str(path)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
    watchdog = threading.Timer(120, proc.kill)
    watchdog.start()
    try:
        while True:
            line = proc.stdout.readline()
            assert line, f"the child ended early: {proc.stderr.read()}"
            if int(line) >= 30:
                break
        proc.send_signal(signum)
        printed = proc.stdout.read().split()  # to EOF, from the same (buffered) file object
        err = proc.stderr.read()
        proc.wait(timeout=60)
    finally:
        watchdog.cancel()
        proc.kill()
    last = int(printed[-1]) if printed else 30
    assert proc.returncode == -signum, err  # ends as the signal would have ended it
    assert len(RrdReader(path).store()) > 0  # closed: footer and manifest written
    steps, _ = values(path, "/rl/reward/total")
    assert len(steps) in (last, last + 1) and list(steps) == list(range(1, len(steps) + 1))
    steps, _ = values(path, "/diag/energy/total")
    assert list(steps) == list(range(len(steps)))


def test_equivalent_box_and_quaternion():
    """A shape-less body is drawn as the box of its mass and inertia about the centre of mass:
    the rod of large_offset (0.3 m long, radius 0.03 m) becomes a 0.3 m long box."""
    scene = esp_gym.load_scene("large_offset")
    half, Q = R.equivalent_box(scene.body.mass, scene.body.J, scene.body.rho_c)
    assert np.isclose(half.max(), 0.15, rtol=1e-6) and abs(abs(Q[:, np.argmax(half)] @ [1, 0, 0]) - 1) < 1e-9
    rng = np.random.default_rng(0)
    for _ in range(20):
        A, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        A *= np.sign(np.linalg.det(A))
        x, y, z, w = R.quaternion_xyzw(A)
        K = np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]])
        assert np.allclose(np.eye(3) + 2 * w * K + 2 * K @ K, A, atol=1e-12)


def windy_rollout(env, seeds):
    """One episode per seed with zero actions, recorded; per sample (each reset and step): the
    control step's sensors and disturbance (copies), and each episode's body."""
    control = env.unwrapped.control
    sensors, disturbance, bodies = [], [], []
    for seed in seeds:
        env.reset(seed=seed)
        bodies.append(env.unwrapped.scene.body)
        done = False
        while True:
            sensors.append(control.sensors.copy())
            disturbance.append(control.disturbance.copy())
            if done:
                break
            _, _, terminated, truncated, _ = env.step(np.zeros(6))
            done = terminated or truncated
    env.close()
    return np.array(sensors), np.array(disturbance), bodies


def test_env_recording_holds_the_wind_the_hook_tension_and_each_episodes_body(tmp_path):
    path = tmp_path / "hard.rrd"
    env = RecordRerun(gym.make(ENV_ID, preset="hard", max_episode_steps=6), path, flush_every=4)
    sensors, disturbance, bodies = windy_rollout(env, (0, 1))
    n = len(sensors)
    assert n == 14  # reset 0, steps 1-6, reset 7, steps 8-13
    assert RL_ENTITIES <= entities(path)

    # the series: float64, bit for bit the control step's sensors and disturbance
    steps, tension = values(path, R.ENV_HOOK_TENSION)
    assert list(steps) == list(range(n))
    assert tension == sensors[:, SENSORS["hook_tension"]].tolist()
    _, wind = values(path, R.ENV_WIND)
    assert wind == disturbance[:, DISTURBANCE["wind"]].tolist()
    assert np.all(np.linalg.norm(wind, axis=1) > 1.0)  # 6 m/s: a non-trivial comparison
    _, drag = values(path, R.ENV_DRAG)
    parts = [disturbance[:, DISTURBANCE[name]] for name in ("load_drag", "line_drag")]
    assert drag == np.hstack(parts).tolist()

    # the arrows: float32 of the scaled vectors, the wind's from the load's centre of mass
    f32 = lambda x: np.asarray(x, dtype=np.float32)  # noqa: E731
    arrows = read(path, R.HOOK_TENSION)
    assert np.array_equal(f32(arrows["Arrows3D:vectors"])[:, 0], f32(sensors[:, SENSORS["hook_tension"]] * 0.05))
    assert np.array_equal(f32(arrows["Arrows3D:origins"]), f32(read(path, R.PIVOT)["Points3D:positions"]))
    arrows = read(path, R.WIND)
    assert np.array_equal(f32(arrows["Arrows3D:vectors"])[:, 0], f32(disturbance[:, DISTURBANCE["wind"]] * 0.05))
    st = env.unwrapped.sim.state  # the last state, of the second episode: its own rho_c
    load = st.r[-1] + st.R @ np.asarray(bodies[1].rho_c)
    assert np.allclose(arrows["Arrows3D:origins"][-1][0], load, atol=1e-6)

    # each episode's body at its reset, on both timelines: the second's box, not the first's
    shape = read(path, R.BODY_SHAPE)
    assert shape["step"] == [0, 7] and shape["time"] == [0, round(7 * 0.02 * 1e9)]
    halves = f32([h[0] for h in shape["Boxes3D:half_sizes"]])
    assert np.array_equal(halves, f32([0.5 * np.asarray(b.shape.size) for b in bodies]))
    assert not np.allclose(halves[0], halves[1], rtol=1e-3)  # randomised: the episodes' boxes differ
    assert np.array_equal(f32(shape["Boxes3D:centers"][1][0]), f32(bodies[1].rho_c))
    steps, com = values(path, R.BODY_COM, "Points3D:positions")
    assert list(steps) == [0, 7] and np.array_equal(f32(com), f32([b.rho_c for b in bodies]))
    steps, origin = values(path, R.BODY_TORQUE, "Arrows3D:origins")
    assert list(steps) == [0, 7] and np.array_equal(f32(origin), f32([b.rho_c for b in bodies]))
    static = {c.entity_path for c in RrdReader(path).stream() if c.is_static}
    assert not ({R.BODY_SHAPE, R.BODY_COM} & static)  # a static body would hide the episodes' own


def test_env_recording_holds_the_pushes(tmp_path):
    path = tmp_path / "pushed.rrd"
    wind = {"speed": 6.0, "gust_std": 1.5, "push_rate": 1e3, "push_speed": 0.5}  # a push every step
    env = RecordRerun(gym.make(ENV_ID, randomize=True, wind=wind, max_episode_steps=5), path, force_scale=0.02)
    _, disturbance, _ = windy_rollout(env, (3,))
    push = disturbance[:, DISTURBANCE["push"]]
    assert np.linalg.norm(push[1:], axis=1).min() > 0 and np.all(push[:, 2] == 0)  # horizontal
    steps, series = values(path, R.ENV_PUSH)
    assert list(steps) == list(range(len(push))) and series == push[:, :2].tolist()
    vectors = read(path, R.PUSH)["Arrows3D:vectors"]
    f32 = lambda x: np.asarray(x, dtype=np.float32)  # noqa: E731
    assert np.array_equal(f32(vectors)[:, 0], f32(push * 0.02))


def recorded_rollout(path, actions, seed, **make_kwargs) -> list:
    """Record an ElasticStringPendulum-v0 (``make_kwargs``) rollout of ``actions`` from the reset
    of ``seed`` to ``path``; the simulator's diagnostics at the reset and after each step."""
    env = RecordRerun(gym.make("ElasticStringPendulum-v0", **make_kwargs), path)
    env.reset(seed=seed)
    sim = env.unwrapped.sim
    reported = [sim.diagnostics()]
    for action in actions:
        env.step(action)
        reported.append(sim.diagnostics())
    env.close()
    return reported


def test_env_recording_holds_the_winch(tmp_path):
    """A `lower` rollout reeling out, then in: the recording holds the unstretched length, the
    reel speed and the winch's work of every sample as the simulator reports them, and its
    E - E0 - W includes the winch's work (it stays below 1 % of the work: measured 1.0 mJ of 0.92 J).
    Negative control: a recording without a winch has no /winch entities."""
    path = tmp_path / "winch.rrd"
    reels = [0.5] * 20 + [-0.25] * 20
    reported = recorded_rollout(path, [np.r_[np.zeros(6), reel] for reel in reels], seed=4, task="lower")
    for entity, key in ((R.WINCH_LENGTH, "unstretched_length"), (R.WINCH_SPEED, "reel_speed"),
                        (R.WINCH_WORK, "winch_work")):
        steps, got = values(path, entity)
        assert list(steps) == list(range(41))
        assert np.array_equal(got, [d[key] for d in reported]), entity
    _, residual = values(path, "/diag/energy_residual")
    assert np.allclose(residual, [d["energy_balance_residual"] for d in reported], rtol=0, atol=1e-12)
    assert max(abs(d["winch_work"]) for d in reported) > 1e2 * np.max(np.abs(residual))  # measured 900x
    plain = tmp_path / "plain.rrd"
    recorded_rollout(plain, [np.zeros(6)], seed=4, task="transport")
    assert not {e for e in entities(plain) if e.startswith("/winch")}


def test_env_recording_holds_the_drone(tmp_path):
    """A drone rollout: the recording's drone frame is at the pivot, turned by R_q, at every
    sample (float32 of the simulator's), its rates and rotor speeds are the simulator's (float64,
    the same bits), and the action series holds the drone's four entries. Negative control: a
    point pivot's recording has no /drone entities."""
    path = tmp_path / "drone.rrd"
    reported = recorded_rollout(path, [np.array([0.1, 0.5, -0.3, 0.2])] * 20, seed=0, scene="quadrotor_load")
    rows = read(path, R.DRONE)
    f32 = lambda a: np.asarray(a, dtype=np.float32)  # noqa: E731
    assert len(rows["step"]) == 21
    for k, d in enumerate(reported):
        assert np.array_equal(f32(rows["Transform3D:mat3x3"][k][0]), f32(d["drone_attitude"].T.reshape(-1)))
        assert np.array_equal(f32(rows["Transform3D:translation"][k][0]), f32(d["pivot_position"]))
    assert np.abs(reported[-1]["drone_attitude"] - np.eye(3)).max() > 0.05  # it did turn
    _, rates = values(path, R.DRONE_RATES)
    _, speeds = values(path, R.DRONE_ROTORS)
    assert np.array_equal(rates, [d["drone_rates"] for d in reported])
    assert np.array_equal(speeds, [d["rotor_speeds"] for d in reported])
    _, actions = values(path, "/rl/action")
    assert np.allclose(actions[-1], [0.1, 0.5, -0.3, 0.2], rtol=0, atol=1e-7)
    assert R.DRONE_FRAME in {c.entity_path for c in RrdReader(path).stream() if c.is_static}
    plain = tmp_path / "plain.rrd"
    recorded_rollout(plain, [np.zeros(6)], seed=0)
    assert not {e for e in entities(plain) if "drone" in e}


def _off_axis_deg(position, target, point):
    """The angle [deg] between the eye's view direction and the direction to ``point``."""
    view, to = np.asarray(target) - position, np.asarray(point) - position
    return np.degrees(np.arccos(view @ to / np.linalg.norm(view) / np.linalg.norm(to)))


@pytest.mark.parametrize("scene", ["quadrotor_load", "drone_load", "paper_example", "short_stiff"])
def test_the_default_view_frames_the_whole_rig(scene):
    """The recording's 3-D eye (entities.rig_eye) sees the pivot, a drone's rotors on it and the
    load at rest within 20 degrees of its view direction (a viewer's field of view is wider).
    Negative control: an eye 0.5 m from the load, looking at it, has the pivot out of that cone."""
    from esp_gym.pendulum.tasks import hanging_depth
    from esp_gym.viz.entities import rig_eye

    s = esp_gym.load_scene(scene)
    position, target = rig_eye(s)
    pivot = np.asarray(s.pivot.position, dtype=float)
    load = pivot + np.array([0.0, 0.0, hanging_depth(s)])
    rotors = [pivot + np.array([0.3, 0.3, 0.0]), pivot - np.array([0.3, 0.3, 0.0])]
    assert max(_off_axis_deg(position, target, p) for p in [pivot, load] + rotors) < 20.0
    close = load + np.array([0.5, 0.0, 0.0])
    assert _off_axis_deg(close, load, pivot) > 20.0
