"""A team's task, compiled (docs/team.md, "Observations", "Rewards", "Episode end"): every agent's
observation, the reward terms with each agent's share, and the task's terminations, from the
control step's read-out (kernels/team/readout.py) in one call.

The observation is what the agent's layout names (esp_gym/team/spaces.py ``agent_layout``),
copies and differences of the read-out (the sensor noise is drawn in Python, from the env's
generator, and added after). Each tracking term is ``weight`` x :func:`~.tolerance.tolerance` of
its error.
"""
import math
from collections import namedtuple

from ..jit import kernel
from ..layout import Layout
from ..status import TERM_COLLISION, TERM_DRONE_FLIPPED, TERM_NONE, TERM_OVERSTRETCH, TERM_WORKSPACE
from ..tolerance import tolerance
from .readout import TR_LOAD, TR_LOAD_VELOCITY, TR_OMEGA

#: A team task's constants: the terms' weights, their errors' scales (position [m], velocity
#: [m/s], tilt [rad], spin [rad/s]), the longest stretch and the workspace's radius [m] that end an
#: episode, the distance below which pivots are penalised (``separation``) and below which they
#: have collided (``collision``) [m], and the cosine of a drone's flip tilt.
TEAM_TASK = Layout(("w_load_position", 1), ("w_load_velocity", 1), ("w_pivot_position", 1), ("w_tilt", 1),
                   ("w_spin", 1), ("w_control", 1), ("w_separation", 1), ("scale_position", 1),
                   ("scale_velocity", 1), ("scale_tilt", 1), ("scale_spin", 1), ("max_stretch", 1),
                   ("workspace_radius", 1), ("separation", 1), ("collision", 1), ("flip_cosine", 1))
TK_W_LOAD_POSITION = TEAM_TASK.scalar("w_load_position")
TK_W_LOAD_VELOCITY = TEAM_TASK.scalar("w_load_velocity")
TK_W_PIVOT_POSITION = TEAM_TASK.scalar("w_pivot_position")
TK_W_TILT = TEAM_TASK.scalar("w_tilt")
TK_W_SPIN = TEAM_TASK.scalar("w_spin")
TK_W_CONTROL = TEAM_TASK.scalar("w_control")
TK_W_SEPARATION = TEAM_TASK.scalar("w_separation")
TK_SCALE_POSITION = TEAM_TASK.scalar("scale_position")
TK_SCALE_VELOCITY = TEAM_TASK.scalar("scale_velocity")
TK_SCALE_TILT = TEAM_TASK.scalar("scale_tilt")
TK_SCALE_SPIN = TEAM_TASK.scalar("scale_spin")
TK_MAX_STRETCH = TEAM_TASK.scalar("max_stretch")
TK_WORKSPACE = TEAM_TASK.scalar("workspace_radius")
TK_SEPARATION = TEAM_TASK.scalar("separation")
TK_COLLISION = TEAM_TASK.scalar("collision")
TK_FLIP_COSINE = TEAM_TASK.scalar("flip_cosine")

#: The team's reward terms, in order (``info["reward_<term>"]``), and those each agent has its own
#: share of (``info["agent_<term>"]``), in order.
TEAM_REWARD = Layout(("load_position", 1), ("load_velocity", 1), ("tilt", 1), ("spin", 1), ("pivot_position", 1),
                     ("control", 1), ("separation", 1))
AGENT_REWARD = Layout(("pivot_position", 1), ("control", 1), ("separation", 1))
TW_LOAD_POSITION = TEAM_REWARD.scalar("load_position")
TW_LOAD_VELOCITY = TEAM_REWARD.scalar("load_velocity")
TW_TILT = TEAM_REWARD.scalar("tilt")
TW_SPIN = TEAM_REWARD.scalar("spin")
TW_PIVOT_POSITION = TEAM_REWARD.scalar("pivot_position")
TW_CONTROL = TEAM_REWARD.scalar("control")
TW_SEPARATION = TEAM_REWARD.scalar("separation")
AW_PIVOT_POSITION = AGENT_REWARD.scalar("pivot_position")
AW_CONTROL = AGENT_REWARD.scalar("control")
AW_SEPARATION = AGENT_REWARD.scalar("separation")

#: The fields an agent's observation may hold (esp_gym/team/spaces.py ``agent_layout``): the
#: task's ``fields`` vector gives where each starts in an agent's row, -1 where it has none.
OBSERVED = Layout(("pivot_position_error", 1), ("pivot_velocity", 1), ("drone_attitude_6d", 1), ("drone_rates", 1),
                  ("hook_tension", 1), ("string_length", 1), ("load_offset", 1), ("load_position_error", 1),
                  ("load_velocity", 1), ("load_attitude_6d", 1), ("load_rates", 1), ("load_target_offset", 1),
                  ("neighbours", 1))
OB_PIVOT_POSITION_ERROR = OBSERVED.scalar("pivot_position_error")
OB_PIVOT_VELOCITY = OBSERVED.scalar("pivot_velocity")
OB_DRONE_ATTITUDE = OBSERVED.scalar("drone_attitude_6d")
OB_DRONE_RATES = OBSERVED.scalar("drone_rates")
OB_HOOK_TENSION = OBSERVED.scalar("hook_tension")
OB_STRING_LENGTH = OBSERVED.scalar("string_length")
OB_LOAD_OFFSET = OBSERVED.scalar("load_offset")
OB_LOAD_POSITION_ERROR = OBSERVED.scalar("load_position_error")
OB_LOAD_VELOCITY = OBSERVED.scalar("load_velocity")
OB_LOAD_ATTITUDE = OBSERVED.scalar("load_attitude_6d")
OB_LOAD_RATES = OBSERVED.scalar("load_rates")
OB_LOAD_TARGET_OFFSET = OBSERVED.scalar("load_target_offset")
OB_NEIGHBOURS = OBSERVED.scalar("neighbours")

#: A team task's arrays: its constants ``params`` (:data:`TEAM_TASK`) and observed ``fields``
#: (:data:`OBSERVED`, int64); the targets of the load ``load_target`` (3,) [m] and of its
#: velocity ``target_velocity`` (3,) [m/s] and each pivot's ``pivot_targets`` (K, 3) [m]
#: (spatial); the outputs: every agent's observation ``obs`` (K, n), the team's reward terms
#: ``terms`` (:data:`TEAM_REWARD`), each agent's shares ``agent`` (K, :data:`AGENT_REWARD`) and
#: the distance between each pair of pivots ``distances`` (K (K - 1) / 2,) [m], pairs (i < j) in
#: order.
TeamTaskArrays = namedtuple("TeamTaskArrays", "params fields load_target target_velocity pivot_targets obs terms agent "
                                              "distances")


@kernel(entry=True)
def team_task(RD, drone_R, drone_rates, action, TK, code):
    """Fill ``TK``'s observation, reward terms and distances from the read-out ``RD``
    (:data:`~esp_gym.kernels.team.readout.TeamReadArrays`) of a state whose drones (a drone team's, else none)
    have the attitudes ``drone_R`` (K, 3, 3) and body rates ``drone_rates`` (K, 3) [rad/s], after
    the applied ``action`` (K, n_a) in [-1, 1]. Returns ``(reward, the smallest distance between
    two pivots [m] (inf with one), code)``: the physics' ``code``, or where it is TERM_NONE the
    task's termination, if any."""
    observe(RD, drone_R, drone_rates, TK)
    smallest = separations(RD, TK)
    reward = score(RD, action, TK)
    if code == TERM_NONE:
        code = task_termination(RD, drone_R, TK, smallest)
    return reward, smallest, code


@kernel(inline="always")
def put3(o, start, x0, x1, x2):
    """``o[start:start + 3] = (x0, x1, x2)``, nothing where ``start`` is -1 (no such field)."""
    if start >= 0:
        o[start] = x0
        o[start + 1] = x1
        o[start + 2] = x2


@kernel(inline="always")
def put_attitude(o, start, R):
    """A rotation's first two columns, column by column (its '6d' form), from ``start`` (-1: none)."""
    if start >= 0:
        for c in range(2):
            for i in range(3):
                o[start + 3 * c + i] = R[i, c]


@kernel(inline="always")
def observe(RD, drone_R, drone_rates, TK):
    """Every agent's observation (module docstring) into ``TK.obs``."""
    f = TK.fields
    R = RD.R
    out = RD.out
    K = RD.pivot.shape[0]
    target = TK.load_target
    for k in range(K):
        o = TK.obs[k]
        x = RD.pivot[k]
        t = TK.pivot_targets[k]
        put3(o, f[OB_PIVOT_POSITION_ERROR], x[0] - t[0], x[1] - t[1], x[2] - t[2])
        v = RD.pivot_velocity[k]
        put3(o, f[OB_PIVOT_VELOCITY], v[0], v[1], v[2])
        if f[OB_DRONE_ATTITUDE] >= 0:
            put_attitude(o, f[OB_DRONE_ATTITUDE], drone_R[k])
            w = drone_rates[k]
            put3(o, f[OB_DRONE_RATES], w[0], w[1], w[2])
        put3(o, f[OB_HOOK_TENSION], RD.tension[k, 0], RD.tension[k, 1], RD.tension[k, 2])
        if f[OB_STRING_LENGTH] >= 0:
            o[f[OB_STRING_LENGTH]] = RD.length[k]
        load = (out[TR_LOAD], out[TR_LOAD + 1], out[TR_LOAD + 2])
        put3(o, f[OB_LOAD_OFFSET], load[0] - x[0], load[1] - x[1], load[2] - x[2])
        put3(o, f[OB_LOAD_POSITION_ERROR], load[0] - target[0], load[1] - target[1], load[2] - target[2])
        put3(o, f[OB_LOAD_VELOCITY], out[TR_LOAD_VELOCITY], out[TR_LOAD_VELOCITY + 1], out[TR_LOAD_VELOCITY + 2])
        put_attitude(o, f[OB_LOAD_ATTITUDE], R)
        put3(o, f[OB_LOAD_RATES], out[TR_OMEGA], out[TR_OMEGA + 1], out[TR_OMEGA + 2])
        put3(o, f[OB_LOAD_TARGET_OFFSET], target[0] - x[0], target[1] - x[1], target[2] - x[2])
        if f[OB_NEIGHBOURS] >= 0:  # the others relative to it, the next one first
            for i in range(1, K):
                y = RD.pivot[(k + i) % K]
                put3(o, f[OB_NEIGHBOURS] + 3 * (i - 1), y[0] - x[0], y[1] - x[1], y[2] - x[2])


@kernel(inline="always")
def distance(a, b):
    """|a - b| of two 3-vectors."""
    d0 = a[0] - b[0]
    d1 = a[1] - b[1]
    d2 = a[2] - b[2]
    return math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)


@kernel(inline="always")
def separations(RD, TK):
    """Each pair's distance (i < j) into ``TK.distances`` [m]; returns the smallest (inf: one pivot)."""
    K = RD.pivot.shape[0]
    smallest = math.inf
    n = 0
    for i in range(K):
        for j in range(i + 1, K):
            d = distance(RD.pivot[i], RD.pivot[j])
            TK.distances[n] = d
            smallest = min(smallest, d)
            n += 1
    return smallest


@kernel(inline="always")
def score(RD, action, TK):
    """The reward terms into ``TK.terms`` and each agent's shares into ``TK.agent`` (TeamTask's
    docstring, esp_gym/team/tasks.py); returns their sum, the reward."""
    P = TK.params
    out = RD.out
    K = RD.pivot.shape[0]
    terms = TK.terms
    load = (out[TR_LOAD], out[TR_LOAD + 1], out[TR_LOAD + 2])
    velocity_error = (out[TR_LOAD_VELOCITY] - TK.target_velocity[0], out[TR_LOAD_VELOCITY + 1] - TK.target_velocity[1],
                      out[TR_LOAD_VELOCITY + 2] - TK.target_velocity[2])
    omega = (out[TR_OMEGA], out[TR_OMEGA + 1], out[TR_OMEGA + 2])
    terms[TW_LOAD_POSITION] = P[TK_W_LOAD_POSITION] * tolerance(distance(load, TK.load_target), P[TK_SCALE_POSITION])
    terms[TW_LOAD_VELOCITY] = P[TK_W_LOAD_VELOCITY] * tolerance(distance(velocity_error, (0.0, 0.0, 0.0)),
                                                                 P[TK_SCALE_VELOCITY])
    tilt = math.acos(min(1.0, max(-1.0, RD.R[2, 2])))
    terms[TW_TILT] = P[TK_W_TILT] * tolerance(tilt, P[TK_SCALE_TILT])
    terms[TW_SPIN] = P[TK_W_SPIN] * tolerance(distance(omega, (0.0, 0.0, 0.0)), P[TK_SCALE_SPIN])
    agent = TK.agent
    n_a = action.shape[1]
    for k in range(K):
        error = distance(RD.pivot[k], TK.pivot_targets[k])
        agent[k, AW_PIVOT_POSITION] = P[TK_W_PIVOT_POSITION] * tolerance(error, P[TK_SCALE_POSITION]) / K
        effort = 0.0
        for i in range(n_a):
            effort += action[k, i] * action[k, i]
        agent[k, AW_CONTROL] = -P[TK_W_CONTROL] * effort / (n_a * K)
        agent[k, AW_SEPARATION] = 0.0
    n = 0
    for i in range(K):  # each pair's crowding, half to each of its two agents
        for j in range(i + 1, K):
            crowding = max(0.0, 1.0 - TK.distances[n] / P[TK_SEPARATION]) ** 2
            agent[i, AW_SEPARATION] -= 0.5 * P[TK_W_SEPARATION] * crowding
            agent[j, AW_SEPARATION] -= 0.5 * P[TK_W_SEPARATION] * crowding
            n += 1
    terms[TW_PIVOT_POSITION] = agents_total(agent, AW_PIVOT_POSITION)
    terms[TW_CONTROL] = agents_total(agent, AW_CONTROL)
    terms[TW_SEPARATION] = agents_total(agent, AW_SEPARATION)
    reward = 0.0
    for i in range(terms.shape[0]):
        reward += terms[i]
    return reward


@kernel(inline="always")
def agents_total(agent, term):
    """The sum over agents of their shares of ``term`` (an :data:`AGENT_REWARD` index)."""
    total = 0.0
    for k in range(agent.shape[0]):
        total += agent[k, term]
    return total


@kernel(inline="always")
def task_termination(RD, drone_R, TK, smallest):
    """The task's termination code, TERM_NONE if none (in this order: two pivots collided, a drone
    flipped, a string overstretched, the load or a pivot left the workspace)."""
    P = TK.params
    if smallest < P[TK_COLLISION]:
        return TERM_COLLISION
    for k in range(drone_R.shape[0]):
        if drone_R[k, 2, 2] < P[TK_FLIP_COSINE]:
            return TERM_DRONE_FLIPPED
    for k in range(RD.stretch.shape[0]):
        if RD.stretch[k] > P[TK_MAX_STRETCH]:
            return TERM_OVERSTRETCH
    out = RD.out
    load = (out[TR_LOAD], out[TR_LOAD + 1], out[TR_LOAD + 2])
    if distance(load, TK.load_target) > P[TK_WORKSPACE]:
        return TERM_WORKSPACE
    for k in range(RD.pivot.shape[0]):
        if distance(RD.pivot[k], TK.pivot_targets[k]) > P[TK_WORKSPACE]:
            return TERM_WORKSPACE
    return TERM_NONE
