"""The team as a PettingZoo ``ParallelEnv`` (docs/team.md): agents ``pivot_0 .. pivot_{K-1}``, each
pushing its own pivot or flying its drone and observing what :func:`~esp_gym.team.spaces.agent_layout`
names; the reward is the team's, given to every agent, with each agent's own terms in its
``infos`` entry. Every agent's info holds the same numbers at reset and at every step
(:func:`agent_info`), so that libraries that turn infos into tensors (TorchRL, skrl) read them."""
from __future__ import annotations

from typing import Optional

import gymnasium as gym
import numpy as np

from .. import MAX_EPISODE_STEPS
from ..extras import require
from ..pendulum.control import raw_actions
from .core import TeamCore
from .spaces import agent_layout
from .tasks import AGENT_TERMS, REWARD_TERMS


def agent_info(k: int, core: TeamCore, info: dict) -> dict:
    """Agent ``k``'s info from the team's step ``info`` (TeamCore.step's): its index, the load's and
    its own target [m], the team's reward terms (``reward_<term>``), its own shares
    (``agent_<term>``), the smallest distance between two pivots [m], its string's pull at its hook
    (the first element's, (3,)) [N], the action applied to it (after the latency) and the
    episode's ``termination`` code (0 while it goes on; the single env's codes,
    esp_gym/kernels/status.py ``STATUS``, whose words ``esp_gym.errors.termination_reason``
    gives); numbers only, the same keys always."""
    return {"agent": k, "load_target": core.load_target.copy(), "pivot_target": core.pivot_targets[k].copy(),
            **{f"reward_{name}": float(info[f"reward_{name}"]) for name in REWARD_TERMS},
            **{f"agent_{name}": float(info[f"agent_{name}"][k]) for name in AGENT_TERMS},
            "min_separation": float(info["min_separation"]), "tension": info["tension"][k].copy(),
            "applied_action": info["applied_action"][k].copy(), "termination": int(info["termination"])}


ParallelEnv = require("pettingzoo", "esp_gym.team.parallel_env").ParallelEnv


class ElasticStringTeamParallelEnv(ParallelEnv):
    """
    ## Description
    The episode of ``ElasticStringTeam-v0`` (esp_gym/team/env.py, whose docstring gives each
    section in full) with one agent per pivot, ``pivot_0`` ... ``pivot_{K-1}``: K point pivots or
    K quadrotors carry one rigid load, each on its own extensible, tension-only elastic string.

    ## Action Space
    Agent k's ``Box(-1, 1, (3,), float32)``: its pivot's force (spatial) on top of its hover
    force, ``force_limit`` times it at 1; with drones ``Box(-1, 1, (4,))``, its drone's four
    numbers (esp_gym/team/spaces.py ``DroneDrive``); with ``winch=True`` one more, its string's
    reel speed. ``action_spaces`` holds them by name.

    ## Observation Space
    Agent k's ``Box(-inf, inf, (n,), float32)``, named by :attr:`observation_structure`
    (esp_gym/team/spaces.py ``agent_layout``): ``pivot_position_error``, ``pivot_velocity``,
    ``drone_attitude_6d`` and ``drone_rates`` (drones), ``hook_tension``, ``string_length``
    (winch), then ``load_offset``, ``load_position_error``, ``load_velocity``,
    ``load_attitude_6d``, ``load_rates`` (``full``) or ``load_target_offset`` (``hook``), then
    ``neighbours``; n = 27 + 3(K - 1) (``full``) or 12 + 3(K - 1) (``hook``, the hard preset's),
    9 more with drones, 1 more with a winch. ``observation_spaces`` holds them by name;
    :meth:`state` (``state_space``) is the ``full`` observation of every agent without noise.

    ## Rewards
    Every agent gets the team's reward, the sum of the terms ``load_position``,
    ``load_velocity``, ``tilt``, ``spin``, ``pivot_position``, ``control`` and ``separation``
    (esp_gym/team/tasks.py ``REWARD_TERMS``); ``infos[agent]`` holds its own share of
    ``pivot_position``, ``control`` and ``separation`` and the team's terms, every key a number,
    the same keys at reset and at every step (what tensorising clients read).

    ## Starting State
    As ``ElasticStringTeam-v0``'s: the team hanging at rest, the load knocked into a small
    motion, the task's targets drawn; :attr:`episode_info` is the reset's info (the targets and
    the episode's draws).

    ## Episode End
    Terminated for every agent at once (``infos[agent]["termination"]``, the single
    environment's code, and :attr:`termination_reason`): ``collision``, ``drone_flipped``,
    ``string_overstretched``, ``left_workspace``, ``energy_balance`` or ``physics_failure: ...``.
    Truncated after ``max_cycles`` steps (500: 10 s).

    ## Arguments
    ``team``, ``task``, ``max_cycles`` (500), ``render_mode`` and the options of
    :class:`~esp_gym.team.core.TeamCore` (control_period, force_limit, preset, randomize,
    observation, sensor_noise, action_latency, wind, actuation, winch, safety), checked alike.
    """

    metadata = {"name": "elastic_string_team_v0", "render_modes": ["rgb_array"], "render_fps": 50,
                "is_parallelizable": True}

    def __init__(self, team=3, task: str = "transport", max_cycles: int = MAX_EPISODE_STEPS,
                 render_mode: Optional[str] = None, **options):
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        if isinstance(max_cycles, bool) or not isinstance(max_cycles, (int, np.integer)) or max_cycles < 1:
            raise ValueError(f"max_cycles must be a whole number >= 1, got {max_cycles!r}")
        self.core = TeamCore(team, task, **options)
        self.metadata = {**self.metadata, "render_fps": 1.0 / self.core.control_period}  # a frame per step
        self.max_cycles = int(max_cycles)
        self.render_mode = render_mode
        self.possible_agents = [f"pivot_{k}" for k in range(self.core.size)]
        self.agents = []
        #: name -> slice of one agent's observation
        self.observation_structure = self.core.layout.structure()
        core = self.core
        self.observation_spaces = {a: gym.spaces.Box(-np.inf, np.inf, (core.layout.size,), np.float32)
                                   for a in self.possible_agents}
        self.action_spaces = {a: gym.spaces.Box(-1.0, 1.0, (core.action_size,), np.float32)
                              for a in self.possible_agents}
        full = agent_layout(core.size, "full", core.drones, core.winch).size
        #: :meth:`state`'s space: every agent's ``full`` observation without noise
        self.state_space = gym.spaces.Box(-np.inf, np.inf, (core.size * full,), np.float32)
        #: the core's reset info of the episode (its draws with ``randomize``, its wind), and why it
        #: ended, in the single env's words ("" while it goes on; a failed step's error is ``core.failure``)
        self.episode_info, self.termination_reason = {}, ""

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    def reset(self, seed: Optional[int] = None, options: Optional[dict] = None):
        core = self.core
        obs, self.episode_info = core.reset(seed=seed)
        self.agents, self.termination_reason = list(self.possible_agents), ""
        # the step's info of the state it starts from: its terms with no action, nothing ended
        task, _, smallest, _ = core.evaluate(np.zeros((core.size, core.action_size)))
        info = {**core.task_info(task, smallest), "applied_action": core.last_action, "termination": 0}
        return ({a: obs[k] for k, a in enumerate(self.agents)},
                {a: agent_info(k, core, info) for k, a in enumerate(self.agents)})

    def step(self, actions: dict):
        if not self.agents:
            raise RuntimeError("step: the episode has ended; call reset()")
        missing = [a for a in self.agents if a not in actions]
        if missing:
            raise ValueError(f"actions: every agent acts in a team, missing {missing}")
        unknown = [a for a in actions if a not in self.possible_agents]
        if unknown:
            raise ValueError(f"actions: unknown agents {unknown}")
        shape = (self.core.action_size,)
        action = np.stack([raw_actions(actions[a], shape, f"actions[{a!r}]") for a in self.possible_agents])
        obs, reward, terminated, _, info = self.core.step(action)
        truncated = not terminated and self.core.steps >= self.max_cycles
        agents = list(self.agents)
        self.termination_reason = info.get("termination_reason", "")
        infos = {a: agent_info(k, self.core, info) for k, a in enumerate(agents)}
        out = ({a: obs[k] for k, a in enumerate(agents)}, {a: reward for a in agents},
               {a: terminated for a in agents}, {a: truncated for a in agents}, infos)
        if terminated or truncated:
            self.agents = []
        return out

    def render(self):
        """The team's frame (:meth:`~esp_gym.team.core.TeamCore.frame`) with ``render_mode="rgb_array"``, else None."""
        return self.core.frame() if self.render_mode == "rgb_array" else None

    def state(self) -> np.ndarray:
        """The team's true state as every agent's ``full`` observation without noise, one after the
        other (a centralised critic's input)."""
        return self.core.true_observations().ravel()


def parallel_env(team=3, task: str = "transport", **kwargs) -> ElasticStringTeamParallelEnv:
    """A team of ``team`` point pivots (or drones: ``actuation="thrust_rates"``) as a PettingZoo
    ParallelEnv (:class:`ElasticStringTeamParallelEnv`)."""
    return ElasticStringTeamParallelEnv(team=team, task=task, **kwargs)
