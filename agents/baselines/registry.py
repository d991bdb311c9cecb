"""Every classical baseline of a configuration, by name, with the constants the designs were tuned
to: the PD law (agents/baselines/pd.py), the LQR (lqr.py; with a ZV-shaped path for transport,
shaping.py) and, with hook observations, the scheduled LQG (lqg.py). agents.evaluate, compare
and robustness take their baselines from here."""
from __future__ import annotations

from typing import Optional

from agents.baselines.pd import PD_LAWS, Hoist


#: The model-based designs' tuning (docs/agents.md: grids on 10 episodes, seeds 1000+). LQR:
#: control weight over {1, 10, 100, 1e3, 1e4} per nominal task. Shaping (transport): shaper in
#: {none, zv, zvd} x ramp in {0.1, 0.5, 1, 2, 3, 4} s. LQG (hard preset): control weight in
#: {100, 1e3, 1e4} x state noise in {1e-4, 1e-3, 1e-2, 0.1} x force noise in {1e-4, 1e-3, 1e-2}
#: x model error in {1, 3, 10}; one setting is among the best on every task (stabilize 268.8,
#: transport 226.4, track 237.4).
LQR_WEIGHT = {"stabilize": 100.0, "transport": 100.0, "track": 300.0}
SHAPING = {"shaper": "zv", "move_time": 0.1}
LQG_TUNING = {"control_weight": 100.0, "state_noise": 1e-3, "force_noise": 1e-4, "model_error": 3.0}


def baseline(task: str, winch: bool = False, drone: bool = False):
    """The PD law of ``task`` (the simplest reference); with a winch, :class:`Hoist` around it;
    with a drone at the pivot, the same gains flying the drone (agents/baselines/geometric.py
    DronePD)."""
    if task not in PD_LAWS:
        raise ValueError(f"no baseline for task {task!r}; known: {sorted(PD_LAWS)}")
    law = PD_LAWS[task]
    if drone:
        from agents.baselines.geometric import DronePD

        pd = law.pd if isinstance(law, Hoist) else law
        drone_pd = DronePD(kp=pd.kp, kd=pd.kd, kp_z=pd.kp_z, kd_z=pd.kd_z, k_sway=pd.k_sway)
        if winch:
            return Hoist(drone_pd, law.k_length if isinstance(law, Hoist) else 1.0)
        return drone_pd
    return Hoist(law) if winch and not isinstance(law, Hoist) else law


def baseline_factories(task: str, env_kwargs: Optional[dict] = None) -> dict:
    """Every classical baseline of ``task`` with the environment options ``env_kwargs``, by name,
    as a function that builds it (some designs linearise the environment's step, which compiles
    it on a cold cache: a name can be checked without that). With the full observation ``pd``,
    ``lqr`` (each episode's own design: agents/baselines/lqr.py EpisodeLQR; ``track``: with the reference's
    preview) and for ``transport`` ``lqr_zv`` (the ZV-shaped path, agents/baselines/shaping.py); with the
    hook observation ``pd`` (pivot terms only) and ``lqg`` (a Kalman filter and LQR designed for
    the nominal scene but for the load's mass, scheduled on the hook tension: the hook does not
    reveal the episode's other parameters, agents/baselines/lqg.py). Stateful ones are reset per episode by
    evaluate_policy."""
    from agents.baselines.lqg import ScheduledLQG
    from agents.baselines.lqr import EpisodeLQR, LQR, LQRTracker
    from agents.baselines.shaping import ShapedLQR
    from esp_gym.pendulum.env_setup import make_setup

    setup = make_setup(task=task, **(env_kwargs or {}))
    out = {"pd": lambda: baseline(task, setup.winch, setup.drone)}
    if setup.drone:  # the drone's cascades (agents/baselines/geometric.py)
        from agents.baselines.geometric import (GEOMETRIC_HOIST_GAIN, HOOK_ESTIMATOR, HookGeometricController,
                                                geometric_controller, hook_geometric_controller)

        if setup.winch:  # the cascade at the pivot, the PD law's hoist reeling
            if setup.observer.mode == "full":
                out["geometric"] = lambda: Hoist(geometric_controller(task, setup.actuation), GEOMETRIC_HOIST_GAIN)
            else:
                out["geometric"] = lambda: Hoist(HookGeometricController.for_setup(
                    setup, hook_geometric_controller(task, setup.actuation), **HOOK_ESTIMATOR), GEOMETRIC_HOIST_GAIN)
            return out
        if setup.observer.mode == "full":
            out["geometric"] = lambda: geometric_controller(task, setup.actuation)
        else:  # on the load's state as the hook's pull tells it (agents/baselines/load_estimate.py)
            out["geometric"] = lambda: HookGeometricController.for_setup(
                setup, hook_geometric_controller(task, setup.actuation), **HOOK_ESTIMATOR)
        return out
    if setup.winch:  # the model-based designs are for a fixed length
        return out
    if setup.observer.mode == "hook":
        out["lqg"] = lambda: ScheduledLQG(setup, **LQG_TUNING)
        return out
    weight = LQR_WEIGHT[task]
    design = LQRTracker.design if task == "track" else LQR.design
    out["lqr"] = lambda: EpisodeLQR(lambda s, episode: design(s, episode, weight))
    if task == "transport":
        out["lqr_zv"] = lambda: EpisodeLQR(lambda s, episode: ShapedLQR.design(s, episode, weight, **SHAPING))
    return out


def baselines(task: str, env_kwargs: Optional[dict] = None) -> dict:
    """Every classical baseline of ``task`` with the environment options ``env_kwargs``, built, by
    name (:func:`baseline_factories`)."""
    return {name: build() for name, build in baseline_factories(task, env_kwargs).items()}
