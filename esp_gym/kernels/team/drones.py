"""Drones at a team's pivots (docs/physics.md, "Drones at a team's pivots").

Each drone carries its string at its centre of mass, so its rotation is a free rigid body under
its rotors' torque and its translation is its pivot's, pushed by the thrust pair
u_k = -f_k R_{q,k} e3, u_{k+1} = -f_{k+1} R_{q,k+1} e3 (kernels/drone/quadrotor.py). A step: every drone's
rotors over the step and its rotation solved (nothing committed), the thrust pairs into the
pivots' forces, the team's step (kernels/team/step.py), then every drone committed; a failure anywhere
leaves all of it untouched (the run of steps: kernels/team/loops.py).
"""
from collections import namedtuple

from ..drone.quadrotor import THRUST_RATES, actuate, drone_at, drone_finish, drone_solve, rate_loop_due
from ..jit import kernel
from ..layout import IN_PIVOT_FORCE
from ..status import OK

#: A team's drones: ``arrays`` their :class:`~esp_gym.kernels.drone.quadrotor.DroneArrays` stacked (every field's first
#: index the drone), ``pivot`` (n,) int64 the pivot each flies (0: string 0's; j >= 1: string j's),
#: and ``pending`` (n, 2, 3): each rotation's momentum increment dPi_q [kg m^2/s] and Cayley
#: vector c between its solve and its commit.
TeamDrones = namedtuple("TeamDrones", "arrays pivot pending")


@kernel(inline="always")
def drones_solve(TD, P, A, inputs, h, rates, compensated, step):
    """Every drone's half of a step before the team's (kernels/drone/quadrotor.py ``drone_solve``), the rate
    controller first when ``rates`` and its loop samples before the control step's ``step``-th step; each
    thrust pair into its pivot's force: ``inputs``' pivot force pair for string 0, ``A.force[j - 1]`` for
    string j. Returns ``(status, iterations)``."""
    total = 0
    for d in range(TD.pivot.shape[0]):
        DR = drone_at(TD.arrays, d)
        if rates and rate_loop_due(DR, step):
            actuate(DR, THRUST_RATES)
        k = TD.pivot[d]
        pair = A.force[k - 1] if k > 0 else inputs[IN_PIVOT_FORCE:IN_PIVOT_FORCE + 6].reshape((2, 3))
        status, iters, dP, c = drone_solve(DR, P, h, compensated, pair)
        total += iters
        if status != OK:
            return status, total
        for i in range(3):
            TD.pending[d, 0, i] = dP[i]
            TD.pending[d, 1, i] = c[i]
    return OK, total


@kernel(inline="always")
def drones_finish(S, TD, h, compensated):
    """Every drone's half after the team's step succeeded (kernels/drone/quadrotor.py ``drone_finish``)."""
    for d in range(TD.pivot.shape[0]):
        q = TD.pending[d]
        drone_finish(S, drone_at(TD.arrays, d), h, (q[0, 0], q[0, 1], q[0, 2]), (q[1, 0], q[1, 1], q[1, 2]),
                     compensated)
