"""The environment's bits: sha256 of the observations, rewards and final state of seeded
rollouts in each configuration (plain, hard preset, implicit string, winch, both, track, a drone
in each rig: at its centre, with the winch, at an offset hook, under the hard preset; and a
batched hard vector env). A refactor of the compiled step must leave them unchanged; a change of
the physics or the tasks that moves them says so in its commit and recomputes them here."""
import hashlib

import gymnasium as gym
import numpy as np
import pytest

import esp_gym

#: First computed at commit f939cf3, before the environment's arrays became EnvArrays and its
#: observation, reward and termination separate stages (unchanged by both).
ROLLOUT_SHA256 = {
    "plain": "824b98c44070cfc7cf1505f2930faa552fa3bf8178ae0d533ffd8930c6d4384c",
    "hard": "f6c28dd8771e742a52ef9d2f92c107a1901909b2f9fdf70b43f7bc913097400e",
    "implicit": "03715f1c4f3954417596b2f7bb2844325aa26ef27c17a99f00c628e84a110969",
    "winch": "d769738964bd02d636627dc3dbb4a8b1d125487cb51acd5edc31d8c5ac17b4ea",
    "implicit_winch": "ce41b43796f4bca643ef77f593da471fce5b4df91c7ff55033b7fa2860fbf46d",
    "track": "84ee7e866206d03ffaaa55e8194c1303cffd732e29a66b2e90b1ca0ab6fa7a8a",
    # the drone's, recomputed at 6d5cb47: quadrotor_load at elements auto (1; 2 with the winch) and
    # its 800 Hz rate loop
    "drone": "6b16b260ef507e16dd39d3c5665790a2479b917ef6fa42a4c44fe7e046ec9685",
    "drone_winch": "cefcbd73cbf9fbddd3c3402f97e72f352e3c838a594a1c0af102a7d5efa08d58",
    "drone_hook": "de9773d02e0f3396dad4c95c65f8f835ce2956bfdbd6da7b2a11a63090f763b9",
    "drone_hard": "c7ba241d5a287d9ebe72ab02a16e9af448a9930742fadc20d2afcd1652fbb92c",
}
VECTOR_SHA256 = "df5ef1b76b3f23c29de03347dd59fa263f7ea298a785ef2ff8945a79329299d9"

CONFIGURATIONS = {"plain": {}, "hard": {"preset": "hard"},
                  "implicit": {"scene_overrides": {"solver": {"string": "implicit"}}},
                  "winch": {"task": "lower", "winch": True},
                  "implicit_winch": {"task": "lower", "winch": True,
                                     "scene_overrides": {"string": {"EA": 2e5}, "solver": {"string": "implicit"}}},
                  "track": {"task": "track"},
                  "drone": {"scene": "quadrotor_load"},
                  "drone_winch": {"scene": "quadrotor_load", "task": "lower", "winch": True},
                  "drone_hook": {"scene": "quadrotor_load", "scene_overrides": {"pivot": {"drone": {"rho_q": [0, 0, -0.05]}}}},
                  "drone_hard": {"scene": "quadrotor_load", "preset": "hard"}}


def rollout_digest(env, steps: int, seed: int) -> str:
    """sha256 of a rollout under seeded Gaussian actions (clipped): the observations and rewards
    of every step, resets included, and the final state's positions and momenta."""
    rng, digest = np.random.default_rng(seed), hashlib.sha256()
    obs, _ = env.reset(seed=seed)
    digest.update(obs.tobytes())
    for _ in range(steps):
        action = np.clip(0.5 * rng.standard_normal(env.action_space.shape), -1, 1).astype(np.float32)
        obs, reward, terminated, truncated, _ = env.step(action)
        digest.update(obs.tobytes())
        digest.update(np.asarray(reward, dtype=np.float64).tobytes())
        if np.any(terminated) or np.any(truncated):
            if not hasattr(env, "num_envs"):
                obs, _ = env.reset()
                digest.update(obs.tobytes())
    if not hasattr(env, "num_envs"):
        state = env.unwrapped.sim.state
        digest.update(state.r.tobytes())
        digest.update(state.p.tobytes())
    return digest.hexdigest()


@pytest.mark.parametrize("name", list(CONFIGURATIONS))
def test_the_environments_rollouts_keep_their_bits(name):
    env = gym.make(esp_gym.ENV_ID, disable_env_checker=True, **CONFIGURATIONS[name])
    assert rollout_digest(env, 300, 5) == ROLLOUT_SHA256[name]


def test_the_vector_environments_rollout_keeps_its_bits():
    env = gym.make_vec(esp_gym.ENV_ID, num_envs=3, vectorization_mode="vector_entry_point", preset="hard")
    assert rollout_digest(env, 200, 1) == VECTOR_SHA256


def test_the_digest_sees_one_bit():
    """Negative control: one seed apart, the digests differ."""
    env = gym.make(esp_gym.ENV_ID, disable_env_checker=True)
    assert rollout_digest(env, 5, 5) != rollout_digest(env, 5, 6)
