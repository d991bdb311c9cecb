"""Every packed array of the kernels, by name: the one place that knows what index means what.

Two kinds of structure cross the boundary between the compiled kernels and Python:

* **namedtuples of arrays** (:class:`StateArrays`, :class:`Work`, :class:`LGVIParams`,
  :class:`DiagWork`, :class:`Snapshots`): numba types their fields by name;
* **packed vectors** (the diagnostics, the input balances, the step report, the inputs, the
  observation, the reward terms, the task and action parameters, the targets, a recording
  sample): each is a :class:`Layout` of named fields. Python reads them with
  ``LAYOUT["name"]`` (a slice) or ``LAYOUT.scalar("name")`` (an int); kernels read them
  through the module-level integer offsets below (numba compiles a module global into a
  constant; this file is inside the kernels' hashed cache, see ``jit.py``, so editing a
  layout recompiles every kernel).

Status and termination codes share one table, :data:`STATUS`, with their messages.
"""
from collections import namedtuple


class Layout:
    """Named fields of a packed 1-D array: ``fields`` is a sequence of ``(name, size)``.

    ``layout["name"]`` is the field's slice, ``layout.scalar("name")`` its index (size-1 fields
    only), ``layout.start("name")`` its first index, ``layout.size`` the total length and
    ``layout.names`` the field names in order. ``layout.structure()`` maps name -> slice (as
    Gymnasium's ``observation_structure``)."""

    def __init__(self, *fields):
        self.fields = tuple((str(name), int(size)) for name, size in fields)
        self._slices = {}
        k = 0
        for name, size in self.fields:
            if name in self._slices or size < 1:
                raise ValueError(f"bad layout field {name!r} (size {size})")
            self._slices[name] = slice(k, k + size)
            k += size
        self.size = k
        self.names = tuple(name for name, _ in self.fields)

    def __getitem__(self, name: str) -> slice:
        return self._slices[name]

    def __contains__(self, name: str) -> bool:
        return name in self._slices

    def __len__(self) -> int:
        return self.size

    def start(self, name: str) -> int:
        return self._slices[name].start

    def scalar(self, name: str) -> int:
        s = self._slices[name]
        if s.stop - s.start != 1:
            raise ValueError(f"field {name!r} has {s.stop - s.start} entries, not 1")
        return s.start

    def structure(self) -> dict:
        return dict(self._slices)

    def scalar_names(self) -> tuple:
        """One name per entry: a field of size k > 1 gives ``name_0 .. name_{k-1}``, or
        ``name_x, name_y, name_z`` for k = 3."""
        out = []
        for name, size in self.fields:
            if size == 1:
                out.append(name)
            elif size == 3:
                out.extend(f"{name}_{c}" for c in "xyz")
            else:
                out.extend(f"{name}_{i}" for i in range(size))
        return tuple(out)

    def __repr__(self) -> str:
        return f"Layout({', '.join(f'{n}[{s}]' for n, s in self.fields)})"


# -- arrays of the stepper (kernels/lgvi.py, kernels/loops.py) ------------------------------------

#: Scene constants of the stepper, all SI. ``w`` and the Thomas factors are indexed by node;
#: ``first`` is the first unknown node (1: fixed pivot, 0: free pivot of mass ``Mp``);
#: ``max_len2``: the blow-up guard, the squared element length [m^2] no step may exceed;
#: ``slack``: tension-only string law; ``compensated``: Kahan-compensated state updates (the
#: general path reads it at run time, the specialised kernels compile it in).
#: ``mdiag``: the mass matrix's diagonal on the unknown nodes (0 on a fixed pivot), for the
#: implicit string's residual (kernels/implicit.py). ``settle``: the explicit string settles its
#: slack switches (kernels/switch.py); ``gradient``: the implicit string's energy-momentum form.
LGVIParams = namedtuple("LGVIParams", "h m kappa u g M Mp rho J Jd Jeff inv cp off w first slack tol max_iter gammas "
                                      "max_len2 compensated mdiag settle gradient")

#: The state the kernels advance: positions r and momenta p (N+1, 3), R (3, 3), Pi (3,), the
#: compensated-summation remainders rc, pc, Rc, Pic of each, the forces f at r (N+1, 3), the
#: input balances acc (:data:`BALANCE`) with their remainders accc, and per element the energy
#: the explicit string's slack switch still owes, ``owed`` (N,) [J] (kernels/switch.py).
StateArrays = namedtuple("StateArrays", "r p R Pi rc pc Rc Pic f acc accc owed")

#: Scratch arrays of one simulator; ``backup`` holds a checkpoint of the state during composed
#: steps (kernels/loops.py), so a failure can go back to it. The implicit string's Newton
#: (kernels/implicit.py) uses ``fl``, ``fr`` (N+1, 3), the string's forces of the step along
#: the elements at its start and at its end [N], ``dy``
#: (N+1, 3), its right-hand sides and corrections [m], ``elim`` (N+1, 3, 3), the factors of
#: its block elimination, and ``taut`` (N,), 1 for the elements it holds to the taut branch of
#: the slack law until it has converged (docs/physics.md, "The taut-branch start").
#: ``ext`` (N+2, 3): the external forces held over a control step (kernels/disturbance.py), on
#: the nodes (rows 0..N) and on the load's centre of mass (row N+1) [N], spatial frame.
#: ``switch`` (N,): the explicit string's energy errors of a step's slack switches [J]
#: (kernels/switch.py), which also uses ``dy`` and ``fr`` as scratch (the explicit string's
#: step does not: the winch's loop reads ``Y``, the step's increments, after it).
Work = namedtuple("Work", "fn X Y FmI RF Rn jac backup fl fr dy elim taut ext switch")

#: The winch's arrays (kernels/winch.py): ``state`` (:data:`WINCH`), per element the weights
#: ``coef`` (N, 3) of its convective kinetic energy (alpha, beta, gamma: docs/physics.md, "The
#: winch"), the Thomas factors of the step's matrix (``lower``, ``upper``, ``inv``, ``cp``, and
#: its attachment column ``w``, (N+1,)) with ``jeff`` (3, 3), the shifted momenta ``pshift``
#: (N+1, 3) and the mass matrix at the current length for the diagnostics (``dinv``, ``dcp``,
#: ``dw``, ``djeff``), a checkpoint of ``state`` (``backup``), and for the implicit string
#: (kernels/winch_implicit.py) the step matrix's diagonal ``diag`` (N+1,) and the constant part
#: ``rhs`` (N+1, 3) of its residual.
WinchArrays = namedtuple("WinchArrays", "state coef lower upper inv cp w jeff pshift dinv dcp dw djeff backup diag rhs")

#: Scratch and outputs of the diagnostics: node velocities V (N+1, 3) [m/s], per-element strain
#: energy (N,) [J], body angular velocity omega (3,, body frame) [rad/s], and ``out``
#: (:data:`DIAG`).
DiagWork = namedtuple("DiagWork", "V strain omega out")

#: Recording buffers of a run: per snapshot j the node positions, R, Omega, attachment
#: velocity, :data:`DIAG`, strain energies and :data:`BALANCE`; ``step_diag`` (per step,
#: possibly 0 rows) receives :data:`STEP_DIAG`.
Snapshots = namedtuple("Snapshots", "r R omega v diag strain acc step_diag")

# -- packed vectors -------------------------------------------------------------------------------

#: Diagnostics of a state (kernels/diagnostics.py) [J, kg m^2/s, -, m, kg m/s].
DIAG = Layout(("kinetic_string", 1), ("kinetic_body", 1), ("potential_gravity", 1), ("potential_elastic", 1),
              ("energy", 1), ("pi3", 1), ("orthogonality", 1), ("stretched_length", 1), ("kinetic_pivot", 1),
              ("linear_momentum", 3))
D_KINETIC_STRING = DIAG.scalar("kinetic_string")
D_KINETIC_BODY = DIAG.scalar("kinetic_body")
D_POTENTIAL_GRAVITY = DIAG.scalar("potential_gravity")
D_POTENTIAL_ELASTIC = DIAG.scalar("potential_elastic")
D_ENERGY = DIAG.scalar("energy")
D_PI3 = DIAG.scalar("pi3")
D_ORTHOGONALITY = DIAG.scalar("orthogonality")
D_STRETCHED_LENGTH = DIAG.scalar("stretched_length")
D_KINETIC_PIVOT = DIAG.scalar("kinetic_pivot")
D_LINEAR_MOMENTUM = DIAG.start("linear_momentum")
#: One name per diagnostics entry (linear_momentum_x, _y, _z).
DIAG_NAMES = DIAG.scalar_names()

#: Input balances accumulated by the step since the last reset: input work [J], angular
#: impulse about e3 [kg m^2/s], gravity impulse, pivot-force impulse and the impulse of the
#: external forces (wind and pushes, kernels/disturbance.py) (3 each) [kg m/s], and the
#: winch's work [J] (kernels/winch.py).
BALANCE = Layout(("work", 1), ("angular_impulse_z", 1), ("gravity_impulse", 3), ("pivot_impulse", 3),
                 ("external_impulse", 3), ("winch_work", 1))
B_WORK = BALANCE.scalar("work")
B_ANGULAR_IMPULSE_Z = BALANCE.scalar("angular_impulse_z")
B_GRAVITY_IMPULSE = BALANCE.start("gravity_impulse")
B_PIVOT_IMPULSE = BALANCE.start("pivot_impulse")
B_EXTERNAL_IMPULSE = BALANCE.start("external_impulse")
B_WINCH_WORK = BALANCE.scalar("winch_work")

#: The winch (kernels/winch.py): the unstretched length l [m] and the reel speed dl/dt [m/s]
#: of the state (the speed its momenta were made with), the string's constants mass per length
#: [kg/m], EA [N], solver.max_stretch, the
#: consistent or lumped mass model's shares of an element's mass on its end nodes' diagonal
#: and off the diagonal, and the winch's range [m].
WINCH = Layout(("length", 1), ("reel_speed", 1), ("mass_per_length", 1), ("EA", 1),
               ("max_stretch", 1), ("end_share", 1), ("off_share", 1), ("min_length", 1), ("max_length", 1))
WN_LENGTH = WINCH.scalar("length")
WN_SPEED = WINCH.scalar("reel_speed")
WN_MASS_PER_LENGTH = WINCH.scalar("mass_per_length")
WN_EA = WINCH.scalar("EA")
WN_MAX_STRETCH = WINCH.scalar("max_stretch")
WN_END_SHARE = WINCH.scalar("end_share")
WN_OFF_SHARE = WINCH.scalar("off_share")
WN_MIN_LENGTH = WINCH.scalar("min_length")
WN_MAX_LENGTH = WINCH.scalar("max_length")

#: Energy, pi3 and orthogonality after every step of a recorded run.
STEP_DIAG = Layout(("energy", 1), ("pi3", 1), ("orthogonality", 1))
SD_ENERGY = STEP_DIAG.scalar("energy")
SD_PI3 = STEP_DIAG.scalar("pi3")
SD_ORTHOGONALITY = STEP_DIAG.scalar("orthogonality")

#: Inputs held over a step: pivot force (spatial) [N], body torque (body frame) [N m], spatial
#: torque [N m].
INPUTS = Layout(("pivot_force", 3), ("body_torque", 3), ("spatial_torque", 3))
IN_PIVOT_FORCE = INPUTS.start("pivot_force")
IN_BODY_TORQUE = INPUTS.start("body_torque")
IN_SPATIAL_TORQUE = INPUTS.start("spatial_torque")

#: The report of a run of steps (int64): status (:data:`STATUS`), steps taken, Newton
#: iterations in all and at most in one step; for a control step also its termination code.
REPORT = Layout(("status", 1), ("steps", 1), ("newton_total", 1), ("newton_max", 1), ("termination", 1))
R_STATUS = REPORT.scalar("status")
R_STEPS = REPORT.scalar("steps")
R_NEWTON_TOTAL = REPORT.scalar("newton_total")
R_NEWTON_MAX = REPORT.scalar("newton_max")
R_TERMINATION = REPORT.scalar("termination")
#: A run of steps fills the first four entries only.
LOOP_REPORT_SIZE = R_TERMINATION

# -- the environment (kernels/env_step.py) ------------------------------------------------------------

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
AP_HOVER = ACTION_PARAMS.start("hover_force")
AP_FORCE_LIMIT = ACTION_PARAMS.scalar("force_limit")
AP_TORQUE_LIMIT = ACTION_PARAMS.scalar("torque_limit")
AP_MAX_REEL_SPEED = ACTION_PARAMS.scalar("max_reel_speed")

#: The episode's targets, spatial frame: the pivot's and the load's [m], their velocity [m/s]
#: (0 but in ``track``), and the moving reference that ``track`` follows (kernels/reference.py):
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
O_PIVOT_ERROR = OBSERVATION.start("pivot_position_error")
O_PIVOT_VELOCITY = OBSERVATION.start("pivot_velocity")
O_LOAD_ERROR = OBSERVATION.start("load_position_error")
O_LOAD_VELOCITY = OBSERVATION.start("load_velocity")
O_ATTITUDE = OBSERVATION.start("attitude_6d")
O_ANGULAR_VELOCITY = OBSERVATION.start("angular_velocity")
O_STRETCH = OBSERVATION.scalar("string_stretch")
OBS_SIZE = OBSERVATION.size
#: The observation of an environment with a winch: OBSERVATION, then the unstretched length [m].
WINCH_OBSERVATION = Layout(*OBSERVATION.fields, ("unstretched_length", 1))
O_LENGTH = WINCH_OBSERVATION.scalar("unstretched_length")

#: What the compiled step measures besides the full observation: the string's pull on the
#: pivot, the first element's force c x_0 (a load cell at the hook) [N], and the load target
#: relative to the pivot [m], both spatial frame.
SENSORS = Layout(("hook_tension", 3), ("load_target_offset", 3))
SN_HOOK_TENSION = SENSORS.start("hook_tension")
SN_LOAD_TARGET_OFFSET = SENSORS.start("load_target_offset")

#: The ``hook`` observation: what a drone or a crane hook measures, no load state. Its fields
#: are taken from OBSERVATION and SENSORS by name (esp_gym/observe.py).
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

#: The task's constants (esp_gym/tasks.py): reward weights, shaping scales [m, m/s, rad,
#: rad/s], termination limits [m], the string's rest length [m], and the energy watchdog's
#: fraction, bound [J] and the episode's E0 [J] (esp_gym/watchdog.py; the reset writes E0).
TASK_PARAMS = Layout(*((name, 1) for name in (
    "w_load_position", "w_load_velocity", "w_pivot_position", "w_swing", "w_spin", "w_control",
    "scale_position", "scale_velocity", "scale_swing", "scale_spin",
    "max_stretched_length", "workspace_radius", "string_length", "energy_watchdog", "energy_bound",
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
TP_STRING_LENGTH = TASK_PARAMS.scalar("string_length")
TP_ENERGY_WATCHDOG = TASK_PARAMS.scalar("energy_watchdog")
TP_ENERGY_BOUND = TASK_PARAMS.scalar("energy_bound")
TP_ENERGY_ORIGIN = TASK_PARAMS.scalar("energy_origin")

#: An episode's physical parameters (esp_gym/randomize.py; the env's ``reset`` info
#: ``"scene_params"``): string rest length [m], axial stiffness [N], mass per length [kg/m], load
#: mass [kg], load box edges [m], attachment offsets (rho_c x, y, body frame) [m], pivot mass [kg].
SCENE_PARAMS = Layout(*((name, 1) for name in (
    "string_length", "EA", "mass_per_length", "load_mass", "load_size_x", "load_size_y", "load_size_z",
    "attachment_offset_x", "attachment_offset_y", "pivot_mass")))

#: An episode's wind and pushes (esp_gym/wind.py; kernels/disturbance.py): the mean wind [m/s]
#: (spatial), the gusts' decay a = exp(-T/tau) per control step T and innovation sigma sqrt(1 -
#: a^2) [m/s] per axis; the line's drag per length and speed^2, rho_air C_d d / 2 [kg/m^2];
#: the load's drag area law c(n) = faces . |n| + side sqrt(a^2 n_y^2 + b^2 n_x^2) + round
#: (n the unit relative wind, body frame), each coefficient x rho_air C_d / 2 [kg/m] but the
#: semi-axes (a, b) [m]; the chance of a push per control step and its mean force [N].
DISTURBANCE_PARAMS = Layout(("mean_wind", 3), ("gust_decay", 1), ("gust_innovation", 3), ("line_drag", 1),
                            ("load_faces", 3), ("load_side", 1), ("load_semi_axes", 2), ("load_round", 1),
                            ("push_chance", 1), ("push_force", 1))
DP_MEAN_WIND = DISTURBANCE_PARAMS.start("mean_wind")
DP_GUST_DECAY = DISTURBANCE_PARAMS.scalar("gust_decay")
DP_GUST_INNOVATION = DISTURBANCE_PARAMS.start("gust_innovation")
DP_LINE_DRAG = DISTURBANCE_PARAMS.scalar("line_drag")
DP_LOAD_FACES = DISTURBANCE_PARAMS.start("load_faces")
DP_LOAD_SIDE = DISTURBANCE_PARAMS.scalar("load_side")
DP_LOAD_SEMI_AXES = DISTURBANCE_PARAMS.start("load_semi_axes")
DP_LOAD_ROUND = DISTURBANCE_PARAMS.scalar("load_round")
DP_PUSH_CHANCE = DISTURBANCE_PARAMS.scalar("push_chance")
DP_PUSH_FORCE = DISTURBANCE_PARAMS.scalar("push_force")

#: The wind and the external forces of the current control step, spatial frame: the gust and
#: the wind (mean + gust) [m/s], the drag on the load and the push on it, and the line's drag
#: summed over its nodes [N].
DISTURBANCE = Layout(("gust", 3), ("wind", 3), ("load_drag", 3), ("push", 3), ("line_drag", 3))
DS_GUST = DISTURBANCE.start("gust")
DS_WIND = DISTURBANCE.start("wind")
DS_LOAD_DRAG = DISTURBANCE.start("load_drag")
DS_PUSH = DISTURBANCE.start("push")
DS_LINE_DRAG = DISTURBANCE.start("line_drag")

#: The random numbers of one control step's disturbance, drawn ahead from np_random: standard
#: normal gust innovations, and uniforms on [0, 1) for a push's occurrence, azimuth and size.
DRAWS = Layout(("gust", 3), ("push_chance", 1), ("push_azimuth", 1), ("push_scale", 1))
DR_GUST = DRAWS.start("gust")
DR_PUSH_CHANCE = DRAWS.scalar("push_chance")
DR_PUSH_AZIMUTH = DRAWS.scalar("push_azimuth")
DR_PUSH_SCALE = DRAWS.scalar("push_scale")

#: The environment step's ``scheme`` (kernels/env_step.py): a bit for wind and pushes (an int, so that
#: a later run-time option is a bit, not an argument: each costs numba's dispatcher about 0.09 us
#: per call).
SCHEME_DISTURBED = 2


# -- a recording sample (kernels/recording.py, esp_gym/viz/recorder.py) ---------------------------

#: The fixed head of a recording sample row; then the nodes r (N+1, 3), the per-element strain
#: energies (N) and the diagnostics (:data:`DIAG`): see :func:`sample_columns`. ``stepped`` is
#: 1 for a sample after a step, 0 after a reset; ``newton`` the mean Newton iterations per
#: physics step; ``inputs`` pivot force [N] (spatial) and body torque [N m] (body frame);
#: ``balances`` work, E - E0 - W, angular impulse, pi3 - pi3_0 - impulse; ``target`` NaN but at
#: an episode's reset; ``R`` row-major; ``sensors`` (:data:`SENSORS`: hook tension [N], load
#: target offset [m]) and ``disturbance`` (:data:`DISTURBANCE`: gust and wind [m/s], load drag,
#: push, line drag [N]), spatial frame, zeros for free simulations; ``rho`` the episode's
#: attachment -> centre of mass offset rho_c (body frame) [m]; ``winch`` (:data:`SAMPLE_WINCH`)
#: the unstretched length [m], the reel speed [m/s] and the winch's work [J] (E - E0 - W then
#: subtracts it too).
SAMPLE_WINCH = Layout(("unstretched_length", 1), ("reel_speed", 1), ("winch_work", 1))
SAMPLE_HEAD = Layout(("step", 1), ("time", 1), ("episode", 1), ("stepped", 1), ("newton", 1), ("reward", 1),
                     ("action", ACTION_SIZE), ("terms", len(REWARD_TERMS)), ("inputs", 6), ("balances", 4),
                     ("target", TARGET.size), ("R", 9), ("sensors", SENSORS.size),
                     ("disturbance", DISTURBANCE.size), ("rho", 3), ("winch", SAMPLE_WINCH.size))
S_STEP = SAMPLE_HEAD.scalar("step")
S_TIME = SAMPLE_HEAD.scalar("time")
S_EPISODE = SAMPLE_HEAD.scalar("episode")
S_STEPPED = SAMPLE_HEAD.scalar("stepped")
S_NEWTON = SAMPLE_HEAD.scalar("newton")
S_REWARD = SAMPLE_HEAD.scalar("reward")
S_ACTION = SAMPLE_HEAD.start("action")
S_TERMS = SAMPLE_HEAD.start("terms")
S_INPUTS = SAMPLE_HEAD.start("inputs")
S_BALANCES = SAMPLE_HEAD.start("balances")
S_TARGET = SAMPLE_HEAD.start("target")
S_ROT = SAMPLE_HEAD.start("R")
S_SENSORS = SAMPLE_HEAD.start("sensors")
S_DISTURBANCE = SAMPLE_HEAD.start("disturbance")
S_RHO = SAMPLE_HEAD.start("rho")
S_WINCH = SAMPLE_HEAD.start("winch")
SW_LENGTH = SAMPLE_WINCH.scalar("unstretched_length")
SW_SPEED = SAMPLE_WINCH.scalar("reel_speed")
SW_WORK = SAMPLE_WINCH.scalar("winch_work")
S_NODES = SAMPLE_HEAD.size
#: Offsets inside the ``balances`` field.
SB_WORK, SB_ENERGY_RESIDUAL, SB_ANGULAR_IMPULSE, SB_PI3_RESIDUAL = range(4)


def sample_layout(n_elements: int) -> Layout:
    """The whole sample row for a string of ``n_elements`` elements."""
    return Layout(*SAMPLE_HEAD.fields, ("nodes", 3 * (n_elements + 1)), ("strain", n_elements), ("diag", DIAG.size))


# -- status and termination codes -----------------------------------------------------------------

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
#: The energy watchdog (esp_gym/watchdog.py) ended a finite state that gains energy.
ENERGY_BALANCE = 6
#: Codes of the physics (failures of a step); the others are the environment's terminations.
PHYSICS_FAILURES = (NEWTON_FAILED, NON_FINITE, BLOW_UP)

