"""The deployed actor of a trained network, evaluated the same way on every x86-64 processor.

A chaotic closed-loop episode grows a last-bit difference in an action into a different return, so
the documented comparisons (docs/compare) can be rerun to 1e-6 only if every action is the same to
the bit on every machine. torch's float32 matrix products do not promise that: MKL and oneDNN take
other code paths on other processors (AVX2, AVX-512, AMX), and so does a BLAS's float64 product.
:class:`MLPActor` therefore evaluates the actor's layers in float64 with compiled loops whose order
of operations is fixed: each unit's sum runs over its inputs in order, with no BLAS, no
reassociation (esp_gym's kernels compile without fastmath, so no SIMD reduction and no fused
multiply-add) and tanh from the C library, as the environment's own kernels. The weights are the
network's float32 weights, exactly; the result is the trained function evaluated more exactly than
in float32 (the two differ by about 1e-6 of an action, tests/test_mlp.py).

Shapes handled: Stable-Baselines3's ``ActorCriticPolicy`` (PPO, A2C: features, ``policy_net``,
``action_net``; the mean of its Gaussian is the deterministic action, clipped to the action box), its
:class:`agents.privileged.AsymmetricPolicy` (the actor's masked inputs), SAC's actor (``latent_pi``,
``mu``, tanh-squashed) and RLlib's default PPO module (``encoder.actor_encoder``, ``pi``; the first
half of its output is the mean). Anything else raises :class:`UnsupportedNetwork` naming the part.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from esp_gym.compiled import kernel

#: Activation codes of :func:`mlp_forward` by the torch module's class name.
ACTIVATIONS = {"Identity": 0, "Tanh": 1, "ReLU": 2}


class UnsupportedNetwork(ValueError):
    """A network whose shape :class:`MLPActor` does not evaluate (the message names the part)."""


@kernel(entry=True)
def mlp_forward(x, params, widths, activations, out, a, b):
    """``out[i] = f_L(W_L ... f_1(W_1 x[i] + b_1) ... + b_L)`` for every row ``i`` of ``x``.

    x: (batch, widths[0]); params: every layer's W (row-major, widths[l+1] x widths[l]) then its
    bias, layer after layer; widths: (L + 1,) int64; activations: (L,) int64 codes of ACTIVATIONS;
    out: (batch, widths[L]); a, b: scratch of at least max(widths) entries. Each unit's sum is
    ``b_j + W_j0 x_0 + W_j1 x_1 + ...`` left to right, so the result does not depend on the
    processor."""
    for i in range(x.shape[0]):
        for k in range(widths[0]):
            a[k] = x[i, k]
        start = 0
        for layer in range(activations.shape[0]):
            n_in, n_out = widths[layer], widths[layer + 1]
            bias = start + n_in * n_out
            for j in range(n_out):
                row = start + j * n_in
                s = params[bias + j]
                for k in range(n_in):
                    s += params[row + k] * a[k]
                if activations[layer] == 1:
                    s = math.tanh(s)
                elif activations[layer] == 2 and s < 0.0:
                    s = 0.0
                b[j] = s
            for j in range(n_out):
                a[j] = b[j]
            start = bias + n_out
        for j in range(widths[-1]):
            out[i, j] = a[j]


@dataclass(frozen=True)
class MLPActor:
    """A chain of dense layers: ``weights[l]`` (out, in) and ``biases[l]`` (out,) as float64,
    ``activations[l]`` a key of ACTIVATIONS; ``inputs_kept``: None, or a 0/1 mask of the inputs
    the actor reads (the rest are set to 0 first); ``outputs``: how many leading outputs are the
    action (RLlib's head also gives the log standard deviations). SAC's squashed action is a last
    layer with Tanh."""

    weights: tuple
    biases: tuple
    activations: tuple
    inputs_kept: np.ndarray | None = None
    outputs: int | None = None

    def __post_init__(self):
        widths = [self.weights[0].shape[1]] + [w.shape[0] for w in self.weights]
        for layer, (w, bias) in enumerate(zip(self.weights, self.biases)):
            if w.shape[1] != widths[layer] or bias.shape != (w.shape[0],):
                raise UnsupportedNetwork(f"layer {layer}: weights {w.shape} and bias {bias.shape} do not chain "
                                         f"from {widths[layer]} inputs")
        if len(self.activations) != len(self.weights):
            raise UnsupportedNetwork(f"{len(self.activations)} activations for {len(self.weights)} layers")
        unknown = [a for a in self.activations if a not in ACTIVATIONS]
        if unknown:
            raise UnsupportedNetwork(f"activation {unknown[0]!r} is not one of {', '.join(ACTIVATIONS)}")
        object.__setattr__(self, "_widths", np.array(widths, dtype=np.int64))
        object.__setattr__(self, "_codes", np.array([ACTIVATIONS[a] for a in self.activations], dtype=np.int64))
        object.__setattr__(self, "_params", np.concatenate(
            [np.concatenate([np.asarray(w, dtype=np.float64).ravel(), np.asarray(bias, dtype=np.float64)])
             for w, bias in zip(self.weights, self.biases)]))

    @property
    def input_size(self) -> int:
        return int(self._widths[0])

    def __call__(self, x) -> np.ndarray:
        """The action for observations ``x`` (..., input_size), float64 (..., outputs)."""
        x = np.asarray(x, dtype=np.float64)
        if x.shape[-1:] != (self.input_size,):
            raise ValueError(f"the network takes {self.input_size} inputs, got observations of shape {x.shape}")
        rows = np.ascontiguousarray(x.reshape(-1, self.input_size))
        if self.inputs_kept is not None:
            rows = rows * self.inputs_kept
        out = np.empty((rows.shape[0], int(self._widths[-1])))
        scratch = int(self._widths.max())
        mlp_forward(rows, self._params, self._widths, self._codes, out, np.empty(scratch), np.empty(scratch))
        out = out[:, :self.outputs] if self.outputs is not None else out
        return out.reshape(x.shape[:-1] + out.shape[-1:])


def dense_chain(modules, where: str) -> tuple:
    """(weights, biases, activations) of a torch chain of Linear layers, each followed by at most
    one activation (none: Identity)."""
    weights, biases, activations = [], [], []
    for module in modules:
        kind = type(module).__name__
        if kind == "Linear":
            weights.append(module.weight.detach().cpu().numpy().astype(np.float64))
            bias = module.bias
            biases.append(np.zeros(module.out_features) if bias is None else bias.detach().cpu().numpy().astype(np.float64))
            activations.append("Identity")
        elif kind in ACTIVATIONS and kind != "Identity":
            if not activations or activations[-1] != "Identity":
                raise UnsupportedNetwork(f"{where}: {kind} does not follow a Linear layer")
            activations[-1] = kind
        elif kind not in ("Identity", "Flatten"):
            raise UnsupportedNetwork(f"{where}: a {kind} layer (MLPActor evaluates Linear, Tanh and ReLU)")
    return weights, biases, activations


def kept_inputs(extractor, where: str):
    kind = type(extractor).__name__
    if kind == "FlattenExtractor":
        return None
    if kind == "MaskedFlatten":  # agents.privileged: the actor's view
        return extractor.keep.detach().cpu().numpy().astype(np.float64)
    raise UnsupportedNetwork(f"{where}: the features extractor {kind} (MLPActor evaluates flat observations)")


def actor_of_sb3(model) -> MLPActor:
    """The deterministic actor of the Stable-Baselines3 ``model`` (PPO, A2C or SAC; MLP policies)."""
    policy = model.policy
    kind = type(policy).__name__
    if hasattr(policy, "actor") and hasattr(policy.actor, "mu"):  # SAC
        actor = policy.actor
        if getattr(actor, "use_sde", False):
            raise UnsupportedNetwork(f"{kind}: gSDE actors")
        kept = kept_inputs(actor.features_extractor, kind)
        w1, b1, a1 = dense_chain(actor.latent_pi, f"{kind}.actor.latent_pi")
        w2, b2, _ = dense_chain([actor.mu], f"{kind}.actor.mu")
        # the squash in the loops (the C library's tanh), not NumPy's, whose code path is the processor's
        return MLPActor(tuple(w1 + w2), tuple(b1 + b2), tuple(a1) + ("Tanh",), kept)
    if not (hasattr(policy, "mlp_extractor") and hasattr(policy, "action_net")):
        raise UnsupportedNetwork(f"{kind}: not an actor-critic MLP policy nor SAC's")
    if getattr(policy, "use_sde", False) or getattr(policy, "squash_output", False):
        raise UnsupportedNetwork(f"{kind}: gSDE or squashed outputs")
    kept = kept_inputs(policy.pi_features_extractor, kind)
    w1, b1, a1 = dense_chain(policy.mlp_extractor.policy_net, f"{kind}.mlp_extractor.policy_net")
    w2, b2, a2 = dense_chain([policy.action_net], f"{kind}.action_net")
    return MLPActor(tuple(w1 + w2), tuple(b1 + b2), tuple(a1 + a2), kept)


def actor_of_rllib(module, action_size: int) -> MLPActor:
    """The deterministic actor of an RLlib PPO ``module`` whose first ``action_size`` outputs are
    the mean: RLlib's default module (``encoder.actor_encoder`` then the ``pi`` head) or
    :class:`agents.team.critic_module.CentralCriticModule` (``pi`` on the first ``actor_inputs``
    entries of the observation: the actor's input size is that)."""
    kind = type(module).__name__
    if hasattr(module, "actor_inputs"):  # the centralised critic's module: pi is the whole actor
        chains = [(module.pi, f"{kind}.pi")]
    elif hasattr(module, "encoder") and hasattr(module.encoder, "actor_encoder"):
        chains = [(module.encoder.actor_encoder.net.mlp, f"{kind}.encoder.actor_encoder"),
                  (module.pi.net.mlp, f"{kind}.pi")]
    else:
        raise UnsupportedNetwork(f"{kind}: neither RLlib's default PPO module nor CentralCriticModule")
    weights, biases, activations = [], [], []
    for chain, where in chains:
        w, b, a = dense_chain(chain, where)
        weights += w
        biases += b
        activations += a
    return MLPActor(tuple(weights), tuple(biases), tuple(activations), outputs=action_size)
