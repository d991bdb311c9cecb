"""A residual policy distilled from per-episode optimised feed-forwards (teacher and student).

The teacher is agents/headroom.py's: for each of ``episodes`` training episodes, the base
controller plus an open-loop feed-forward optimised for that episode alone (Powell's method).
Along each optimised episode the student's input (the observation and the base's features, as
:class:`~agents.residual.ResidualVecEnv` and SB3Policy build it) is recorded with the
feed-forward of that step as the target residual action (zero on the axes it does not drive).
The student is the PPO policy's actor mean, fitted by least squares on the normalised inputs, with
the normalisation statistics set to the teacher's data, so the model ships and loads as any
residual PPO model (agents.train's run setting ``distill_episodes``; docs/agents.md).

The teacher's episodes use seeds :data:`DISTILL_SEED` + 1000 x the run's seed + i, apart from the
held-out (100000+) and validation (200000+) seeds.
"""
from __future__ import annotations

from typing import Optional

import numpy as np

#: The first teacher episode's seed (plus 1000 x the run's seed).
DISTILL_SEED = 300_000


def teacher_episode(task: str, base_name: str, env_kwargs: Optional[dict], seed: int, knots: int,
                    evaluations: int) -> tuple:
    """One optimised episode: ``(inputs (T, n_in), targets (T, action size), gain)``: the student's
    input at each step, the feed-forward applied there (the target residual) and the optimum's
    return gain over the base."""
    from agents.headroom import Episode, optimise
    from agents.residual import base_policy

    episode = Episode(task, base_policy(base_name, task, env_kwargs), seed, knots, env_kwargs)
    best = optimise(episode, evaluations)
    steps = []
    episode(np.ravel(best["knots"]), record=steps)  # the optimum again, as the student sees it
    inputs = np.array([np.concatenate([obs, features]) for obs, features, _ in steps])
    return inputs, np.array([target for _, _, target in steps]), best["gain"]


def _teacher_job(job: tuple) -> tuple:
    return teacher_episode(*job)


def teach(task: str, base_name: str, env_kwargs: Optional[dict], seeds: list, knots: int, evaluations: int,
          jobs: int = 1, progress: bool = False) -> tuple:
    """:func:`teacher_episode` for each of ``seeds`` (``jobs`` processes): the stacked inputs and
    targets and each episode's gain."""
    from tqdm import tqdm

    work = [(task, base_name, env_kwargs, seed, knots, evaluations) for seed in seeds]
    bar = dict(total=len(work), desc="teacher episodes", unit="episode", disable=not progress)
    if jobs == 1:
        results = [_teacher_job(job) for job in tqdm(work, **bar)]
    else:
        from multiprocessing import get_context

        with get_context("spawn").Pool(jobs) as pool:
            results = list(tqdm(pool.imap(_teacher_job, work), **bar))
    inputs = np.concatenate([r[0] for r in results])
    targets = np.concatenate([r[1] for r in results])
    return inputs, targets, np.array([r[2] for r in results])


def fit_actor(model, normalizer, inputs: np.ndarray, targets: np.ndarray, epochs: int = 300,
              learning_rate: float = 1e-3, batch_size: int = 512, seed: int = 0) -> float:
    """Set ``normalizer``'s observation statistics (SB3 VecNormalize) to ``inputs``' and fit the
    actor mean of ``model`` (an SB3 PPO MlpPolicy) to ``targets`` on the normalised inputs (Adam,
    mean squared error); returns the last epoch's mean loss."""
    import torch

    normalizer.obs_rms.mean = inputs.mean(axis=0)
    normalizer.obs_rms.var = inputs.var(axis=0)
    normalizer.obs_rms.count = float(len(inputs))
    x = torch.as_tensor(normalizer.normalize_obs(inputs.astype(np.float32)), dtype=torch.float32)
    y = torch.as_tensor(targets, dtype=torch.float32)
    policy = model.policy
    actor = list(policy.mlp_extractor.policy_net.parameters()) + list(policy.action_net.parameters())
    optimiser = torch.optim.Adam(actor, lr=learning_rate)
    generator = torch.Generator().manual_seed(seed)
    loss_sum = 0.0
    for _ in range(epochs):
        order = torch.randperm(len(x), generator=generator)
        loss_sum, batches = 0.0, 0
        for start in range(0, len(x), batch_size):
            batch = order[start:start + batch_size]
            mean = policy.action_net(policy.mlp_extractor.forward_actor(policy.extract_features(
                x[batch], policy.pi_features_extractor)))
            loss = ((mean - y[batch]) ** 2).mean()
            optimiser.zero_grad()
            loss.backward()
            optimiser.step()
            loss_sum, batches = loss_sum + loss.item(), batches + 1
        loss_sum /= batches
    return loss_sum
