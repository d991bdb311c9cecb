"""The environment's arrays across the compiled boundary: one named struct, :class:`EnvArrays`,
beside the physics' (:class:`~.layout.StateArrays`, :class:`~.layout.Work`,
:class:`~.layout.LGVIParams`, :class:`~.layout.DiagWork`, :class:`~.layout.WinchArrays`).

Python builds it once per environment (esp_gym/pendulum/control.py) and hands its fields to the entry
points (kernels/env/step.py) as a plain tuple, which the kernels rebuild by name; a batch of
environments holds the same fields with a leading batch axis, and :func:`~.rows.row_function`
takes sub-environment b's row of it from the fields. The environment's packed vectors are laid
out below (the physics' in kernels/layout.py).
"""
from collections import namedtuple

from ..layout import Layout

#: One environment's arrays (a batch's: each with a leading (B,) axis):
#:
#: * ``ap`` ACTION_PARAMS: the action box and its map to the inputs;
#: * ``inputs`` INPUTS: the held pivot force, body and spatial torques [N, N m];
#: * ``nsub`` (1,) int64: physics steps per control step;
#: * ``target`` TARGET: the references [m, m/s] (spatial frame);
#: * ``tp`` TASK_PARAMS: the reward's weights and scales, the workspace, the watchdog's bound;
#: * ``action`` ACTION or WINCH_ACTION: the applied (clipped) action;
#: * ``obs`` OBSERVATION or WINCH_OBSERVATION; ``terms`` REWARD; ``sensors`` SENSORS;
#: * ``features`` FEATURES: what the tasks read of the state (kernels/env/task_terms.py);
#: * ``result`` REPORT (int64): the control step's status, steps, Newton counts, termination;
#: * ``dp`` DISTURBANCE_PARAMS, ``ds`` DISTURBANCE, ``draws`` (K, DRAWS), ``drawn`` (1,) int64:
#:   the wind's episode constants, its state, the random draws ahead and the next one's row
#:   (read only when disturbed: kernels/step/disturbance.py).
EnvArrays = namedtuple("EnvArrays", "ap inputs nsub target tp action obs terms sensors features result dp ds draws "
                                    "drawn")

#: What the tasks read of the state after each control step and reset, computed once
#: (kernels/env/task_terms.py): the load's centre of mass [m] and its velocity [m/s] (spatial
#: frame), the swing angle of pivot -> load centre from the downward vertical e3 [rad] and the
#: load's spin |Omega| [rad/s].
FEATURES = Layout(("load_position", 3), ("load_velocity", 3), ("swing", 1), ("spin", 1))
F_LOAD_POSITION = FEATURES.start("load_position")
F_LOAD_VELOCITY = FEATURES.start("load_velocity")
F_SWING = FEATURES.scalar("swing")
F_SPIN = FEATURES.scalar("spin")


# -- the environment's packed vectors (kernels/env/step.py, kernels/env/task_terms.py) ----------------

#: The action in [-1, 1]: pivot force (spatial, x force_limit, added to the hover force) and
#: body torque (body frame, x torque_limit).
ACTION = Layout(("pivot_force", 3), ("body_torque", 3))
A_PIVOT_FORCE = ACTION.start("pivot_force")
A_BODY_TORQUE = ACTION.start("body_torque")
ACTION_SIZE = ACTION.size

#: The action of an environment with a winch (``winch=True``): ACTION, then the reel speed
#: (x max_reel_speed [m/s]; > 0 reels out).
WINCH_ACTION = Layout(*ACTION.fields, ("reel_speed", 1))
A_REEL_SPEED = WINCH_ACTION.scalar("reel_speed")

#: The constants of the action path: the box bounds (ACTION.size each; the reel speed's box is
#: [-1, 1]), the hover force [N], force_limit [N], torque_limit [N m] and the winch's largest reel
#: speed [m/s].
ACTION_PARAMS = Layout(("low", ACTION_SIZE), ("high", ACTION_SIZE), ("hover_force", 3), ("force_limit", 1),
                       ("torque_limit", 1), ("max_reel_speed", 1))
AP_LOW = ACTION_PARAMS.start("low")
AP_HIGH = ACTION_PARAMS.start("high")
AP_HOVER_FORCE = ACTION_PARAMS.start("hover_force")
AP_FORCE_LIMIT = ACTION_PARAMS.scalar("force_limit")
AP_TORQUE_LIMIT = ACTION_PARAMS.scalar("torque_limit")
AP_MAX_REEL_SPEED = ACTION_PARAMS.scalar("max_reel_speed")

#: The episode's targets, spatial frame: the pivot's and the load's [m], their velocity [m/s]
#: (0 but in ``track``), and the moving reference that ``track`` follows (kernels/env/track_curve.py):
#: its clock [s], the curve's centre [m], the load's depth below the pivot target [m], the
#: curve's amplitudes [m], harmonic, phases [rad], start angle [rad], rate omega [rad/s] (0: a
#: fixed target) and orientation about e3 [rad].
TARGET = Layout(("pivot", 3), ("load", 3), ("velocity", 3), ("clock", 1), ("centre", 3), ("depth", 1),
                ("amplitude", 2), ("harmonic", 1), ("phase", 2), ("start", 1), ("rate", 1), ("orientation", 1))
T_PIVOT = TARGET.start("pivot")
T_LOAD = TARGET.start("load")
T_VELOCITY = TARGET.start("velocity")
T_CLOCK = TARGET.scalar("clock")
T_CENTRE = TARGET.start("centre")
T_DEPTH = TARGET.scalar("depth")
T_AMPLITUDE = TARGET.start("amplitude")
T_HARMONIC = TARGET.scalar("harmonic")
T_PHASE = TARGET.start("phase")
T_START = TARGET.scalar("start")
T_RATE = TARGET.scalar("rate")
T_ORIENTATION = TARGET.scalar("orientation")

#: The observation (spatial frame unless stated): pivot position - target [m], pivot velocity
#: [m/s], load centre of mass - target [m], its velocity [m/s] (both velocities less the
#: target's, which is 0 but in ``track``), the first two columns of R
#: (body x and y axes), the body angular velocity (body frame) [rad/s], and the string stretch
#: (stretched length / l - 1, l the current unstretched length).
OBSERVATION = Layout(("pivot_position_error", 3), ("pivot_velocity", 3), ("load_position_error", 3),
                     ("load_velocity", 3), ("attitude_6d", 6), ("angular_velocity", 3), ("string_stretch", 1))
O_PIVOT_POSITION_ERROR = OBSERVATION.start("pivot_position_error")
O_PIVOT_VELOCITY = OBSERVATION.start("pivot_velocity")
O_LOAD_POSITION_ERROR = OBSERVATION.start("load_position_error")
O_LOAD_VELOCITY = OBSERVATION.start("load_velocity")
O_ATTITUDE_6D = OBSERVATION.start("attitude_6d")
O_ANGULAR_VELOCITY = OBSERVATION.start("angular_velocity")
O_STRING_STRETCH = OBSERVATION.scalar("string_stretch")
OBS_SIZE = OBSERVATION.size
#: The observation of an environment with a winch: OBSERVATION, then the unstretched length [m].
WINCH_OBSERVATION = Layout(*OBSERVATION.fields, ("unstretched_length", 1))
O_UNSTRETCHED_LENGTH = WINCH_OBSERVATION.scalar("unstretched_length")

#: What the compiled step measures besides the full observation: the string's pull on the
#: pivot, the first element's force c x_0 (a load cell at the hook) [N], and the load target
#: relative to the pivot [m], both spatial frame.
SENSORS = Layout(("hook_tension", 3), ("load_target_offset", 3))
SN_HOOK_TENSION = SENSORS.start("hook_tension")
SN_LOAD_TARGET_OFFSET = SENSORS.start("load_target_offset")

#: The ``hook`` observation: what a drone or a crane hook measures, no load state. Its fields
#: are taken from OBSERVATION and SENSORS by name (esp_gym/pendulum/observe.py).
HOOK_OBSERVATION = Layout(("pivot_position_error", 3), ("pivot_velocity", 3), ("hook_tension", 3),
                          ("load_target_offset", 3))

#: Reward terms, in the order they are summed (env info keys are "reward_" + name).
REWARD_TERMS = ("load_position", "load_velocity", "pivot_position", "swing", "spin", "control")
REWARD = Layout(*((name, 1) for name in REWARD_TERMS))
RW_LOAD_POSITION = REWARD.scalar("load_position")
RW_LOAD_VELOCITY = REWARD.scalar("load_velocity")
RW_PIVOT_POSITION = REWARD.scalar("pivot_position")
RW_SWING = REWARD.scalar("swing")
RW_SPIN = REWARD.scalar("spin")
RW_CONTROL = REWARD.scalar("control")

#: The task's constants (esp_gym/pendulum/tasks.py): reward weights, shaping scales [m, m/s, rad,
#: rad/s], termination limits [m] (the ground plane's depth z [m], e3 down; inf without one), the
#: string's rest length [m], and the energy watchdog's fraction, bound [J] and the episode's E0 [J]
#: (esp_gym/physics/watchdog.py; the reset writes E0).
TASK_PARAMS = Layout(*((name, 1) for name in (
    "w_load_position", "w_load_velocity", "w_pivot_position", "w_swing", "w_spin", "w_control",
    "scale_position", "scale_velocity", "scale_swing", "scale_spin",
    "max_stretched_length", "workspace_radius", "ground_depth", "string_length", "energy_watchdog", "energy_bound",
    "energy_origin")))
TASK_PARAM_NAMES = TASK_PARAMS.names
TP_W_LOAD_POSITION = TASK_PARAMS.scalar("w_load_position")
TP_W_LOAD_VELOCITY = TASK_PARAMS.scalar("w_load_velocity")
TP_W_PIVOT_POSITION = TASK_PARAMS.scalar("w_pivot_position")
TP_W_SWING = TASK_PARAMS.scalar("w_swing")
TP_W_SPIN = TASK_PARAMS.scalar("w_spin")
TP_W_CONTROL = TASK_PARAMS.scalar("w_control")
TP_SCALE_POSITION = TASK_PARAMS.scalar("scale_position")
TP_SCALE_VELOCITY = TASK_PARAMS.scalar("scale_velocity")
TP_SCALE_SWING = TASK_PARAMS.scalar("scale_swing")
TP_SCALE_SPIN = TASK_PARAMS.scalar("scale_spin")
TP_MAX_STRETCHED_LENGTH = TASK_PARAMS.scalar("max_stretched_length")
TP_WORKSPACE_RADIUS = TASK_PARAMS.scalar("workspace_radius")
TP_GROUND_DEPTH = TASK_PARAMS.scalar("ground_depth")
TP_STRING_LENGTH = TASK_PARAMS.scalar("string_length")
TP_ENERGY_WATCHDOG = TASK_PARAMS.scalar("energy_watchdog")
TP_ENERGY_BOUND = TASK_PARAMS.scalar("energy_bound")
TP_ENERGY_ORIGIN = TASK_PARAMS.scalar("energy_origin")

#: An episode's physical parameters (esp_gym/pendulum/randomize.py; the env's ``reset`` info
#: ``"scene_params"``): string rest length [m], axial stiffness [N], mass per length [kg/m], load
#: mass [kg], load box edges [m], attachment offsets (rho_c x, y, body frame) [m], pivot mass [kg].
SCENE_PARAMS = Layout(*((name, 1) for name in (
    "string_length", "EA", "mass_per_length", "load_mass", "load_size_x", "load_size_y", "load_size_z",
    "attachment_offset_x", "attachment_offset_y", "pivot_mass")))

#: A drone's episode parameters, after SCENE_PARAMS with a drone at the pivot (esp_gym/pendulum/randomize.py):
#: scales of its inertia, of its rotors' thrust and drag coefficients (together: the mixer's
#: ratio stays), and of its motors' time constants (1: the scene's).
DRONE_SCENE_PARAMS = Layout(("drone_inertia_scale", 1), ("rotor_coefficient_scale", 1), ("motor_lag_scale", 1))

#: The environment step's ``scheme`` (kernels/env/step.py): a bit for wind and pushes (an int, so that
#: a later run-time option is a bit, not an argument: each costs numba's dispatcher about 0.09 us
#: per call).
SCHEME_DISTURBED = 2
