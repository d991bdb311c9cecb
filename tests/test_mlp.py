"""The deployed actor in float64 (agents/mlp.py): the trained networks' function, and the same bits
whatever processor the loops are compiled for."""
import hashlib
import math
import os
import subprocess
import sys

import numpy as np
import pytest

from agents import ROOT
from agents.mlp import MLPActor, UnsupportedNetwork, actor_of_rllib, actor_of_sb3

#: float32 against float64 evaluation of the same weights: the float32 forward's round-off on
#: actions of order 1 through two 128-wide layers (measured 1.7e-7 to 2.8e-7; 1e-5 is a margin).
FLOAT32_TOLERANCE = 1e-5


def random_actor(seed=0, widths=(40, 128, 128, 6)) -> MLPActor:
    rng = np.random.default_rng(seed)
    weights = tuple(rng.normal(0.0, 1.0 / np.sqrt(a), (b, a)) for a, b in zip(widths[:-1], widths[1:]))
    biases = tuple(rng.normal(0.0, 0.1, b) for b in widths[1:])
    return MLPActor(weights, biases, ("Tanh",) * (len(widths) - 2) + ("Identity",))


def sequential_reference(actor: MLPActor, x: np.ndarray) -> np.ndarray:
    """The actor's sums one term at a time in Python floats, left to right (the documented order),
    tanh from the C library (math.tanh, as the compiled loops call it)."""
    out = []
    for row in x:
        a = [float(v) for v in row]
        for w, b, act in zip(actor.weights, actor.biases, actor.activations):
            nxt = []
            for j in range(w.shape[0]):
                s = float(b[j])
                for k in range(w.shape[1]):
                    s += float(w[j, k]) * a[k]
                nxt.append(math.tanh(s) if act == "Tanh" else max(s, 0.0) if act == "ReLU" else s)
            a = nxt
        out.append(a)
    return np.array(out)


def test_the_compiled_loops_sum_in_the_documented_order():
    """Every output equals, to the bit, the sums taken term by term in Python left to right; a BLAS
    product of the same float64 weights rounds differently somewhere (the negative control: the
    order of a sum is visible in its last bits, so this comparison can fail)."""
    actor = random_actor()
    x = np.random.default_rng(1).normal(size=(8, actor.input_size))
    assert np.array_equal(actor(x), sequential_reference(actor, x))
    blas = x
    for w, b, act in zip(actor.weights, actor.biases, actor.activations):
        blas = blas @ w.T + b
        blas = np.tanh(blas) if act == "Tanh" else blas
    assert np.allclose(blas, actor(x), rtol=0, atol=1e-12) and not np.array_equal(blas, actor(x))


_BITS = """
import hashlib
import numpy as np
from tests.test_mlp import random_actor
actor = random_actor()
x = np.random.default_rng(1).normal(size=(64, actor.input_size))
print(hashlib.sha256(actor(x).tobytes()).hexdigest())
"""


@pytest.mark.parametrize("cpu", ["x86-64", "haswell", "skylake-avx512", "sapphirerapids"])
def test_the_actor_gives_the_same_bits_compiled_for_any_x86_64_processor(cpu, tmp_path):
    """The loops compiled for a baseline x86-64, an AVX2 (Haswell), an AVX-512 (Skylake-SP) and an
    AVX-512 + AMX (Sapphire Rapids) processor model give this machine's bits: no vector reduction
    and no fused multiply-add changes a sum, whichever instructions the processor has."""
    actor = random_actor()
    x = np.random.default_rng(1).normal(size=(64, actor.input_size))
    here = hashlib.sha256(actor(x).tobytes()).hexdigest()
    env = {**os.environ, "NUMBA_CPU_NAME": cpu, "NUMBA_CPU_FEATURES": "", "NUMBA_CACHE_DIR": str(tmp_path),
           "PYTHONPATH": str(ROOT)}
    proc = subprocess.run([sys.executable, "-c", _BITS], capture_output=True, text=True, env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert proc.stdout.split()[-1] == here


@pytest.mark.parametrize("name", ["stabilize_ppo", "stabilize_hard_ppo"])
def test_the_float64_actor_is_the_shipped_networks_mean_action(name):
    """The actor of a shipped PPO policy (plain, and with the privileged critic's masked inputs)
    is its torch network's deterministic action to float32's round-off; entries the actor does not
    read change nothing (the masked ones), entries it reads do."""
    import torch

    from agents.artifacts import load_model

    model = load_model(ROOT / "models" / name / "model.zip")
    actor = actor_of_sb3(model)
    x = np.random.default_rng(0).normal(size=(32, actor.input_size)).astype(np.float32)
    with torch.no_grad():
        mean = model.policy.get_distribution(torch.from_numpy(x)).distribution.mean.numpy()
    assert np.abs(actor(x) - mean).max() < FLOAT32_TOLERANCE
    if actor.inputs_kept is not None:
        hidden = actor.inputs_kept == 0
        assert hidden.any() and np.array_equal(actor(x + 10.0 * hidden), actor(x))
    assert not np.allclose(actor(x + 0.1), actor(x), rtol=0, atol=FLOAT32_TOLERANCE)


def test_the_float64_actor_of_sac_is_its_squashed_mean():
    import gymnasium as gym
    import torch
    from stable_baselines3 import SAC

    model = SAC("MlpPolicy", gym.make("Pendulum-v1"), policy_kwargs={"net_arch": [32, 32]}, seed=0, device="cpu")
    actor = actor_of_sb3(model)
    x = np.random.default_rng(0).normal(size=(16, 3)).astype(np.float32)
    with torch.no_grad():
        squashed = model.actor(torch.from_numpy(x), deterministic=True).numpy()
    assert np.abs(actor(x) - squashed).max() < FLOAT32_TOLERANCE


@pytest.mark.parametrize("model", ["team3_transport_hard_rllib", "team3_drones_transport_hard_rllib"])
def test_the_float64_actor_of_a_shipped_team_is_its_modules_mean(model):
    import torch
    from ray.rllib.core.columns import Columns
    from ray.rllib.core.rl_module.rl_module import RLModule

    from agents.team.train import MODULE_PATH

    module = RLModule.from_checkpoint((ROOT / "models" / model / "checkpoint" / MODULE_PATH).resolve())
    size = module.action_space.shape[0]
    actor = actor_of_rllib(module, size)
    x = np.random.default_rng(0).normal(size=(6, actor.input_size)).astype(np.float32)
    with torch.no_grad():
        out = module.forward_inference({Columns.OBS: torch.from_numpy(x)})[Columns.ACTION_DIST_INPUTS].numpy()
    assert out.shape == (6, 2 * size) and np.abs(actor(x) - out[:, :size]).max() < FLOAT32_TOLERANCE


def test_a_network_the_loops_do_not_evaluate_is_refused_by_its_part():
    import torch.nn as nn

    from agents.mlp import dense_chain

    with pytest.raises(UnsupportedNetwork, match="a LayerNorm layer"):
        dense_chain(nn.Sequential(nn.Linear(3, 4), nn.LayerNorm(4), nn.Tanh()), "policy_net")
    with pytest.raises(UnsupportedNetwork, match="activation 'ELU'"):
        MLPActor((np.ones((2, 3)),), (np.zeros(2),), ("ELU",))
    with pytest.raises(UnsupportedNetwork, match="do not chain"):
        MLPActor((np.ones((2, 3)), np.ones((2, 5))), (np.zeros(2), np.zeros(2)), ("Tanh", "Identity"))
    with pytest.raises(ValueError, match="takes 3 inputs"):
        MLPActor((np.ones((2, 3)),), (np.zeros(2),), ("Identity",))(np.zeros(4))
