"""The structs the compiled kernels take, made in one place (kernels/layout.py, kernels/drone/quadrotor.py and
kernels/team/arrays.py name their fields): a string's state, work and diagnostics arrays for N
elements, the winch's, drones' arrays, a team's stacked strings, read-out and task, and a batch's
arrays: a struct stacked with a leading axis (zeros, or a template's values in every row) and one
row's views. The constants
computed from a scene are their owners' (esp_gym/physics/state.py ``build_params``, esp_gym/physics/drone.py,
esp_gym/physics/winch.py, esp_gym/team/assembly.py), written into these.
"""
from __future__ import annotations

import numpy as np

from ..kernels.drone.quadrotor import DRONE, DRONE_DIAG, DroneArrays
from ..kernels.env.arrays import TARGET
from ..kernels.layout import BALANCE, DIAG, WINCH, DiagWork, LGVIParams, StateArrays, WinchArrays, Work
from ..kernels.step.loops import state_size
from ..kernels.team.arrays import TeamArrays
from ..kernels.team.env import TEAM_DRIVE, TEAM_ENV, TEAM_STEP, TeamEnvArrays, TeamStructs
from ..kernels.team.readout import TEAM_READ, TeamReadArrays
from ..kernels.team.task import AGENT_REWARD, OBSERVED, TEAM_REWARD, TEAM_TASK, TeamTaskArrays
from ..kernels.team.winch import TeamWinch


def state_arrays(n: int, r=None, p=None, R=None, Pi=None) -> StateArrays:
    """The state of a string of ``n`` elements (kernels/layout.py ``StateArrays``): the positions
    and momenta ``r``, ``p`` (n+1, 3), ``R`` (3, 3) and ``Pi`` (3,) given (taken, not copied) or
    zeros; their remainders, the forces, the balances and the slack switch's debts zero."""
    z = np.zeros
    return StateArrays(r=z((n + 1, 3)) if r is None else r, p=z((n + 1, 3)) if p is None else p,
                       R=z((3, 3)) if R is None else R, Pi=z(3) if Pi is None else Pi, rc=z((n + 1, 3)),
                       pc=z((n + 1, 3)), Rc=z((3, 3)), Pic=z(3), f=z((n + 1, 3)), acc=z(BALANCE.size),
                       accc=z(BALANCE.size), owed=z(n))


def work_arrays(n: int, damped: bool = False) -> Work:
    """The stepper's scratch for a string of ``n`` elements (kernels/layout.py ``Work``), zeros; its
    ``backup`` holds a checkpoint of the state (kernels/step/loops.py ``save_state``). The damper's
    arrays (``dvel`` ... ``dmat``) have their rows only for a ``damped`` string (else none: 20 floats
    per node that an undamped string never reads)."""
    z = np.zeros
    d = n if damped else -1  # the damper's node count less one: its rows are d + 1
    return Work(fn=z((n + 1, 3)), X=z((n + 1, 3)), Y=z((n + 1, 3)), FmI=z((3, 3)), RF=z((3, 3)), Rn=z((3, 3)),
                jac=z((3, 3)), backup=z(state_size(state_arrays(n))), fl=z((n + 1, 3)), fr=z((n + 1, 3)), dy=z((n + 1, 3)),
                elim=z((n + 1, 3, 3)), taut=z(n), ext=z((n + 2, 3)), switch=z(n), dvel=z((d + 1, 3)),
                dinc=z((d + 1, 3)), ddir=z((max(d, 0), 3)), dten=z(max(d, 0)), dset=z(max(d, 0)),
                dfac=z((d + 1, 3, 3)), dmat=z((4, 3, 3)))


def diag_work(n: int) -> DiagWork:
    """The diagnostics' scratch and output for a string of ``n`` elements (kernels/step/diagnostics.py)."""
    z = np.zeros
    return DiagWork(V=z((n + 1, 3)), strain=z(n), omega=z(3), out=z(DIAG.size))


def winch_arrays(state: np.ndarray, coef: np.ndarray) -> WinchArrays:
    """The winch's arrays (kernels/layout.py ``WinchArrays``) for a string of ``coef.shape[0]``
    elements: its ``state`` (WINCH, taken, not copied) and convective weights ``coef`` (N, 3)
    (esp_gym/physics/winch.py ``convective_weights``), the step's factors and scratch zeros."""
    n, z = coef.shape[0], np.zeros
    return WinchArrays(state=state, coef=coef, lower=z(n + 1), upper=z(n + 1), inv=z(n + 1), cp=z(n + 1),
                       w=z(n + 1), jeff=z((3, 3)), pshift=z((n + 1, 3)), dinv=z(n + 1), dcp=z(n + 1), dw=z(n + 1),
                       djeff=z((3, 3)), backup=z(WINCH.size), diag=z(n + 1), rhs=z((n + 1, 3)))


def team_winch_arrays(lead: WinchArrays, state: np.ndarray, coef: np.ndarray) -> TeamWinch:
    """A team's winches (kernels/team/winch.py ``TeamWinch``): string 0's :func:`winch_arrays`
    ``lead``, every string's WINCH ``state`` (K, WINCH) and the other strings' stacked convective
    weights ``coef`` (rows, 3) (taken, not copied); the step's factors and scratch zeros."""
    z = np.zeros
    rows, K = coef.shape[0], state.shape[0]
    return TeamWinch(lead=lead, state=state, coef=coef, lower=z(rows), upper=z(rows), diag=z(rows), inv=z(rows),
                     cp=z(rows), w=z(rows), fl=z((rows, 3)), fr=z((rows, 3)), mu=z(K - 1), off=z(K - 1),
                     kappa=z(K - 1), u=z(K - 1), m=z(K - 1), max_len2=z(K - 1), body=z(4), J=z((3, 3)), target=z(K))


def stacked_drone_arrays(count: int) -> DroneArrays:
    """:class:`~esp_gym.kernels.drone.quadrotor.DroneArrays` of ``count`` drones, zeros but ``thrust_scale`` 1,
    every field's first index the drone (one drone's: its :func:`row` 0; a team's:
    kernels/team/drones.py)."""
    z = np.zeros
    return DroneArrays(R=z((count, 3, 3)), Rc=z((count, 3, 3)), Pi=z((count, 3)), Pic=z((count, 3)),
                       speed=z((count, 4)), command=z((count, 4)), setpoint=z((count, 4)),
                       thrust_scale=np.ones((count, 4)), consts=z((count, DRONE.size)), inertia=z((count, 3, 3)),
                       inertia_inv=z((count, 3, 3)), mixer=z((count, 4, 4)), allocation=z((count, 4, 4)),
                       next_speed=z((count, 4)), wrench=z((count, 2, 4)), scratch=z((count, 4, 3, 3)),
                       diag=z((count, DRONE_DIAG.size)))


def team_arrays(rows: int, others: int) -> TeamArrays:
    """A team's stacked strings 1..K-1 (kernels/team/arrays.py ``TeamArrays``): ``rows`` node rows in
    all, ``others`` = K - 1 strings; zeros."""
    z = np.zeros
    return TeamArrays(r=z((rows, 3)), p=z((rows, 3)), rc=z((rows, 3)), pc=z((rows, 3)), f=z((rows, 3)),
                      fn=z((rows, 3)), X=z((rows, 3)), Y=z((rows, 3)), c=z((others, 3)), dr0=z((others, 3)),
                      force=z((others, 2, 3)), switch=z(rows), owed=z(rows))


def team_read_arrays(n: int, rows: int, lengths: np.ndarray) -> TeamReadArrays:
    """A team's read-out (kernels/team/readout.py ``TeamReadArrays``): string 0 of ``n`` elements,
    the others' ``rows`` stacked rows, each string's unstretched ``lengths`` (K,) [m] (copied); zeros."""
    z = np.zeros
    K = len(lengths)
    return TeamReadArrays(V0=z((n + 1, 3)), Vo=z((rows, 3)), pivot=z((K, 3)), pivot_velocity=z((K, 3)),
                          tension=z((K, 3)), stretch=z(K), length=np.array(lengths, dtype=float), R=z((3, 3)),
                          out=z(TEAM_READ.size), strain=z(max(n, rows)))


def team_task_arrays(size: int, observation_size: int) -> TeamTaskArrays:
    """A team task's arrays (kernels/team/task.py ``TeamTaskArrays``) for ``size`` agents each
    observing ``observation_size`` numbers; zeros (its ``params`` and ``fields`` are its task's:
    esp_gym/team/tasks.py ``task_arrays``)."""
    z = np.zeros
    return TeamTaskArrays(params=z(TEAM_TASK.size), fields=np.full(OBSERVED.size, -1, dtype=np.int64),
                          load_target=z(3), target_velocity=z(3), pivot_targets=z((size, 3)),
                          obs=z((size, observation_size)), terms=z(TEAM_REWARD.size),
                          agent=z((size, AGENT_REWARD.size)), distances=z(size * (size - 1) // 2))


def team_env_arrays(size: int, drones: int, action_size: int) -> TeamEnvArrays:
    """A team environment's arrays (kernels/team/env.py ``TeamEnvArrays``) for ``size`` agents, of
    which ``drones`` fly drones, each acting with ``action_size`` numbers; zeros."""
    z = np.zeros
    return TeamEnvArrays(params=z(TEAM_ENV.size), drive=z((drones, TEAM_DRIVE.size)), action=z((size, action_size)),
                         formation=z((size, 3)), reference=z(TARGET.size), load_force=z(3),
                         drone_rates=z((drones, 3)), report=z(TEAM_STEP.size))


def plain_structs(structs: TeamStructs) -> TeamStructs:
    """A team's ``structs`` (kernels/team/env.py ``TeamStructs``) as its entry points take them:
    each struct a plain tuple (numba's dispatcher types those about twice as fast)."""
    drones = structs.drones
    drones = None if drones is None else (tuple(drones.arrays), drones.pivot, drones.pending)
    return structs._replace(**{name: tuple(getattr(structs, name)) for name in ("state", "work", "params", "team",
                                                                                 "arrays", "read")}, drones=drones)


def stacked(struct, batch: tuple):
    """A struct of the same type whose every field is zeros of shape ``batch`` + the field's."""
    return type(struct)(*(np.zeros(batch + np.shape(a)) for a in struct))


def repeated(struct, count: int):
    """A struct of the same type whose every field holds ``struct``'s in each of ``count`` rows
    (a scalar field becomes a (count,) array of its type)."""
    return type(struct)(*(np.repeat(np.asarray(a)[None], count, axis=0) for a in struct))


def copy_into(source, target) -> None:
    """Every field of the struct ``source`` copied into ``target``'s (views of another struct of
    its type, such as a batch's :func:`row`)."""
    for a, b in zip(source, target):
        if np.shape(a) != np.shape(b):  # numpy would broadcast a smaller one silently
            raise ValueError(f"cannot copy a field of shape {np.shape(a)} into one of {np.shape(b)}")
        b[...] = a


def put_row(stacked_struct, i: int, struct) -> None:
    """Row ``i`` of a :func:`repeated` struct set to ``struct``'s values (its scalars too)."""
    for a, b in zip(stacked_struct, struct):
        a[i] = b


def row(struct, i: int):
    """Row ``i`` of a :func:`stacked` or :func:`repeated` struct, its fields views."""
    return type(struct)(*(a[i] for a in struct))


def params_row(params: LGVIParams, i: int) -> LGVIParams:
    """Row ``i`` of :func:`repeated` stepper constants, their scalars Python scalars again."""
    return LGVIParams(*(a[i] if a.ndim > 1 else a[i].item() for a in params))
