"""A team's compiled task (esp_gym/kernels/team/task.py) against the task stated in NumPy here, from
the read-out's kinematics (``TeamCore.kinematics``): every agent's observation bit for bit (copies
and differences of the same numbers), the reward terms and each agent's shares to 1e-12, the
termination's code equal, over episodes of strong random actions that end (point pivots in both
observation modes, drones, a lift's winches, which read out in Python), and a moved target
(the negative control)."""
import math

import numpy as np
import pytest

from esp_gym.kernels.status import (TERM_COLLISION, TERM_DRONE_FLIPPED, TERM_NONE, TERM_OVERSTRETCH,
                                    TERM_WORKSPACE)
from esp_gym.kernels.tolerance import tolerance
from esp_gym.team.env import ElasticStringTeamEnv
from esp_gym.team.spaces import agent_layout
from esp_gym.team.tasks import AGENT_TERMS, COLLISION, FLIP_COSINE, REWARD_TERMS, SEPARATION

closeness = tolerance.py_func


def stated_observations(core, kin: dict) -> np.ndarray:
    """Every agent's observation (K, n) without noise, by esp_gym/team/spaces.py's layout."""
    L = agent_layout(core.size, core.observation, core.drones, core.winch)
    out = np.zeros((core.size, L.size))
    for k in range(core.size):
        o = out[k]
        o[L["pivot_position_error"]] = kin["pivot"][k] - core.pivot_targets[k]
        o[L["pivot_velocity"]] = kin["pivot_velocity"][k]
        if core.drones:
            o[L["drone_attitude_6d"]] = kin["drone_attitudes"][k][:, :2].T.ravel()
            o[L["drone_rates"]] = kin["drone_rates"][k]
        o[L["hook_tension"]] = kin["tension"][k]
        if core.winch:
            o[L["string_length"]] = kin["lengths"][k]
        if core.observation == "full":
            o[L["load_offset"]] = kin["load"] - kin["pivot"][k]
            o[L["load_position_error"]] = kin["load"] - core.load_target
            o[L["load_velocity"]] = kin["load_velocity"]
            o[L["load_attitude_6d"]] = kin["R"][:, :2].T.ravel()
            o[L["load_rates"]] = kin["Omega"]
        else:
            o[L["load_target_offset"]] = core.load_target - kin["pivot"][k]
        if core.size > 1:
            others = [(k + i) % core.size for i in range(1, core.size)]
            o[L["neighbours"]] = (kin["pivot"][others] - kin["pivot"][k]).ravel()
    return out


def stated_terms(core, kin: dict, action: np.ndarray) -> tuple:
    """``(the reward terms (each agent's shares for AGENT_TERMS), the pairs' distances)``
    (esp_gym/team/tasks.py ``TeamTask``)."""
    task, K = core.task, core.size
    pairs = [(i, j) for i in range(K) for j in range(i + 1, K)]
    distances = np.array([np.linalg.norm(kin["pivot"][i] - kin["pivot"][j]) for i, j in pairs])
    crowding = np.zeros(K)
    for (i, j), d in zip(pairs, distances):
        crowding[[i, j]] += 0.5 * max(0.0, 1.0 - d / SEPARATION) ** 2
    tilt = math.acos(min(1.0, max(-1.0, kin["R"][2, 2])))
    pivot_errors = np.linalg.norm(kin["pivot"] - core.pivot_targets, axis=1)
    terms = dict(
        load_position=task.w_load_position * closeness(np.linalg.norm(kin["load"] - core.load_target),
                                                       task.scale_position),
        load_velocity=task.w_load_velocity * closeness(np.linalg.norm(kin["load_velocity"] - core.target_velocity),
                                                       task.scale_velocity),
        tilt=task.w_tilt * closeness(tilt, task.scale_tilt),
        spin=task.w_spin * closeness(np.linalg.norm(kin["Omega"]), task.scale_spin),
        pivot_position=task.w_pivot_position * closeness(pivot_errors, task.scale_position) / K,
        control=-task.w_control * np.sum(action ** 2, axis=1) / (action.shape[1] * K),
        separation=-task.w_separation * crowding)
    return terms, distances


def stated_termination(core, kin: dict, distances: np.ndarray) -> int:
    """The task's termination code (TeamCore.step's order), TERM_NONE if none."""
    if distances.size and distances.min() < COLLISION:
        return TERM_COLLISION
    if core.drones and np.any(kin["drone_attitudes"][:, 2, 2] < FLIP_COSINE):
        return TERM_DRONE_FLIPPED
    if kin["stretch"].max() > core.task.max_stretch:
        return TERM_OVERSTRETCH
    radius = core.task.workspace_radius
    if (np.linalg.norm(kin["load"] - core.load_target) > radius
            or np.linalg.norm(kin["pivot"] - core.pivot_targets, axis=1).max() > radius):
        return TERM_WORKSPACE
    return TERM_NONE


CONFIGURATIONS = {"points": (3, {}), "hook, track": (2, {"task": "track", "observation": "hook"}),
                  "drones": (3, {"actuation": "thrust_rates"}), "lift": (3, {"task": "lift"})}


@pytest.mark.parametrize("name", sorted(CONFIGURATIONS))
def test_the_compiled_task_is_the_stated_one(name):
    size, options = CONFIGURATIONS[name]
    env = ElasticStringTeamEnv(size, **options)
    core = env.core
    env.reset(seed=5)
    rng = np.random.default_rng(5)
    ended = 0
    for _ in range(150):
        action = np.clip(rng.uniform(-1.0, 1.0, env.action_space.shape) + 0.6, -1.0, 1.0)  # astray: episodes end
        _, reward, terminated, _, info = env.step(action.astype(np.float32))
        kin = core.kinematics()
        task, _, smallest, code = core.evaluate(core.last_action, info["termination"])
        assert np.array_equal(task.obs, stated_observations(core, kin))
        terms, distances = stated_terms(core, kin, core.last_action)
        for term in REWARD_TERMS:
            assert info[f"reward_{term}"] == pytest.approx(float(np.sum(terms[term])), rel=0, abs=1e-12)
        for term in AGENT_TERMS:
            assert np.allclose(info[f"agent_{term}"], terms[term], rtol=0, atol=1e-12)
        if info["termination"] in (TERM_NONE,) + TASK_ENDS:
            assert reward == pytest.approx(sum(float(np.sum(v)) for v in terms.values()), rel=0, abs=1e-12)
            assert info["termination"] == stated_termination(core, kin, distances)
        assert np.allclose(task.distances, distances, rtol=0, atol=1e-15)
        assert smallest == (distances.min() if distances.size else np.inf)
        if terminated:
            ended += 1
            env.reset()
    assert ended >= 1  # the terminations were compared where they happen


TASK_ENDS = (TERM_COLLISION, TERM_DRONE_FLIPPED, TERM_OVERSTRETCH, TERM_WORKSPACE)


def test_a_moved_target_moves_the_compiled_observation():
    """The negative control: the stated observation with a pivot's target 1 mm away differs."""
    env = ElasticStringTeamEnv(3)
    env.reset(seed=0)
    core = env.core
    env.step(np.zeros(9, np.float32))
    kin = core.kinematics()
    compiled = core.evaluate(core.last_action)[0].obs.copy()
    core.pivot_targets[1, 0] += 1e-3
    assert not np.array_equal(compiled, stated_observations(core, kin))
