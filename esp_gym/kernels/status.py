"""Status and termination codes: what a kernel returns (``REPORT["status"]``) or an environment
step ends with (``REPORT["termination"]``; a team's too), with their messages (esp_gym/errors.py)
and the environments' ``info["termination_reason"]``."""
from collections import namedtuple

Status = namedtuple("Status", "name message reason")

#: Codes a kernel returns (``REPORT["status"]``) or an environment step ends with
#: (``REPORT["termination"]``): name, message, and the env's ``info["termination_reason"]``.
STATUS = {
    0: Status("ok", "", ""),
    1: Status("newton_failed", "Newton's method on the Cayley vector did not converge", None),
    2: Status("non_finite", "the state became non-finite (inf or NaN)", None),
    3: Status("overstretched", "the string stretched past the task's limit", "string_overstretched"),
    4: Status("left_workspace", "the pivot or the load left the workspace", "left_workspace"),
    5: Status("blow_up", "an element stretched beyond solver.max_stretch times its rest length "
                         "(the step is blowing up)", None),
    6: Status("energy_balance", "the energy balance |E - E0 - W| passed the watchdog's bound (the step is "
                                "gaining energy)", "energy_balance"),
    7: Status("drone_flipped", "the drone tilted past the flip limit", "drone_flipped"),
    8: Status("hit_ground", "the pivot or the load reached the scene's ground plane", "hit_ground"),
    9: Status("collision", "two pivots of a team came closer than its collision distance", "collision"),
}
OK = 0
#: A control step that does not end the episode.
TERM_NONE = OK
NEWTON_FAILED = 1
NON_FINITE = 2
TERM_OVERSTRETCH = 3
TERM_WORKSPACE = 4
#: An element grew past solver.max_stretch times its rest length: an unstable step blowing up
#: (typically h above the stability bound) caught while the state is still finite.
BLOW_UP = 5
#: The energy watchdog (esp_gym/physics/watchdog.py) ended a finite state that gains energy.
ENERGY_BALANCE = 6
#: A drone's body axis b3 tilted from the vertical past the environment's limit
#: (kernels/drone/env.py).
TERM_DRONE_FLIPPED = 7
#: The pivot (the drone's centre) or the load's centre of mass reached the scene's ``ground`` plane
#: (kernels/env/task_terms.py).
TERM_GROUND = 8
#: Two pivots of a team came closer than its collision distance (esp_gym/team/tasks.py COLLISION).
TERM_COLLISION = 9
#: Codes of the physics (failures of a step); the others are the environment's terminations.
PHYSICS_FAILURES = (NEWTON_FAILED, NON_FINITE, BLOW_UP)

