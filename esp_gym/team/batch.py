"""Many teams' control steps in one compiled call (their rig's batch entry point, esp_gym/physics/rig.py:
kernels/team/env.py ``team_points_batch`` or ``team_drones_batch``; docs/team.md, "Speed"): :class:`TeamBatch` stacks the live arrays of B
teams' episodes (:class:`~esp_gym.team.core.TeamCore`, without winches, all alike) along a leading
axis and lets each team step in its rows, so that a team stepped in the batch is the team stepped
alone, bit for bit, and its Python face (its state, diagnostics, resets) reads the same arrays.
"""
from __future__ import annotations

import numpy as np

from ..kernels.jit import bound_entry
from ..kernels.team.drones import TeamDrones
from ..physics.arrays import plain_structs, put_row, repeated, row


class TeamBatch:
    """B teams (``cores``, :class:`~esp_gym.team.core.TeamCore` s of one configuration: the same
    K, strings' elements, pivots, observation and actuation, without winches) stepped in one
    compiled call. Their live arrays become rows of stacked ones (:meth:`adopt`); a team whose
    episode builds a new team (``randomize``) is adopted again after its reset (:meth:`reset`)."""

    def __init__(self, cores):
        self.cores = list(cores)
        first = self.cores[0]
        for k, core in enumerate(self.cores):
            if core.control is None:
                raise ValueError(f"team {k} steps in Python (its rig {core.rig.name} has no compiled entry points, "
                                 "esp_gym.rigs()): a batch of teams steps compiled teams")
            if core.rig is not first.rig:
                raise ValueError(f"team {k}'s rig is {core.rig.name}, team 0's {first.rig.name}: a batch's teams "
                                 "share one rig")
        B = len(self.cores)
        S = first.sim.structs()
        drones = None if S.drones is None else TeamDrones(repeated(S.drones.arrays, B), *(
            np.repeat(a[None], B, axis=0) for a in (S.drones.pivot, S.drones.pending)))
        #: the stacked structs (kernels/team/env.py TeamStructs), the task's and the env's arrays
        self.structs = S._replace(**{name: repeated(getattr(S, name), B) for name in ("state", "work", "params",
                                                                                       "team", "arrays", "read")},
                                  drones=drones, **{name: np.repeat(getattr(S, name)[None], B, axis=0)
                                                    for name in ("inputs", "stats", "balance")})
        self.task = repeated(first.compiled_task(), B)
        self.env = repeated(first.control.arrays, B)
        self._sims = [None] * B  # the simulator each row holds
        for b in range(B):
            self.adopt(b)
        self.steps = np.array([core.steps for core in self.cores], dtype=np.int64)
        self.nsteps = np.array([core.control.substeps for core in self.cores], dtype=np.int64)
        self.period = first.control_period
        self.disturbed, self.rates = first.control.disturbed, first.control.rates
        #: teams whose actions need Python before the step (latency, wind, motor commands)
        self.prepared = bool(first.action_latency or first.wind is not None or first.drive_held)
        self._args = (plain_structs(self.structs), (tuple(self.task), tuple(self.env)))
        self._entry = None

    def adopt(self, b: int) -> None:
        """Team b's arrays into row b (its constants copied, its live arrays copied and then used
        in place: TeamCore.use_rows)."""
        core = self.cores[b]
        own = core.sim.structs()
        put_row(self.structs.params, b, own.params)
        put_row(self.structs.team, b, own.team)
        S = self.structs
        drones = None if S.drones is None else TeamDrones(row(S.drones.arrays, b), S.drones.pivot[b],
                                                          S.drones.pending[b])
        rows = S._replace(state=row(S.state, b), work=row(S.work, b), params=None, team=None,
                          arrays=row(S.arrays, b), drones=drones, read=row(S.read, b), inputs=S.inputs[b],
                          stats=S.stats[b], balance=S.balance[b])
        core.use_rows(rows, row(self.task, b), row(self.env, b))
        self._sims[b] = core.sim

    def reset(self, b: int) -> None:
        """After team b's reset: adopted again if its episode built a new team; its counters."""
        core = self.cores[b]
        if core.sim is not self._sims[b]:
            self.adopt(b)
        self.steps[b] = core.steps
        self.nsteps[b] = core.control.substeps

    def step(self, raw: np.ndarray, active: np.ndarray) -> list:
        """One control step of every team b with ``active[b]`` from the raw actions ``raw`` (B, K,
        n_a), float64, C-contiguous, finite, this batch's own (overwritten with the applied actions
        where a team delays or clips them in Python). Returns each active team's ``(observations
        (K, n) with its sensor noise drawn, float32; reward; the smallest distance between two
        pivots [m]; termination code)`` (None for the others), as its own step gives them."""
        teams = np.flatnonzero(active)
        if self.prepared:
            for b in teams:
                core = self.cores[b]
                raw[b] = a = core.applied_action(raw[b])
                core.prepare_step(a)
        times = (self.steps + 1) * self.period
        if self._entry is None:
            self._entry = self._bind(raw, active, times)
        self._entry(*self._args, raw, active, self.nsteps, self.disturbed, self.rates, times)
        self.steps[teams] += 1
        out = [None] * len(self.cores)
        obs = self.task.obs
        for b in teams:
            core = self.cores[b]
            out[b] = (core.noisy(obs[b]),) + core.counted()
        return out

    def _bind(self, raw, active, times):
        """The batch entry point's machine code for these arrays (kernels/jit.py ``bound_entry``)."""
        if not (raw.dtype == np.float64 and raw.flags.c_contiguous and raw.flags.writeable and raw.ndim == 3):
            raise TypeError("the raw actions must be a writeable, C-contiguous float64 array (B, K, n_a)")
        return bound_entry(self.cores[0].rig.entries.batch, *self._args, raw, active, self.nsteps, self.disturbed,
                           self.rates, times)
