"""The :class:`Layout` of a packed vector, and the physics' arrays by name: the stepper's
structs and packed vectors. Every other owner keeps its own next to its code: the environment's
(the action, targets, observation, reward terms, task parameters: kernels/env/arrays.py), the
wind's (kernels/step/disturbance.py), a recording sample's (kernels/env/recording.py), a drone's
(DroneArrays, its constants and diagnostics: kernels/drone/quadrotor.py); the status and termination codes
are kernels/status.py's.

Two kinds of structure cross the boundary between the compiled kernels and Python:

* **namedtuples of arrays** (:class:`StateArrays`, :class:`Work`, :class:`LGVIParams`,
  :class:`DiagWork`, :class:`WinchArrays`, :class:`Snapshots`; the environment's EnvArrays, a
  drone's DroneArrays):
  numba types their fields by name;
* **packed vectors** (here the diagnostics, the input balances, the winch's state, the inputs
  and the step report): each is a :class:`Layout` of named fields. Python reads them with
  ``LAYOUT["name"]`` (a slice) or ``LAYOUT.scalar("name")`` (an int); kernels read them
  through module-level integer offsets (numba compiles a module global into a constant; these
  files are inside the kernels' hashed cache, see ``jit.py``, so editing a layout recompiles
  every kernel).
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


# -- arrays of the stepper (kernels/step/lgvi.py, kernels/step/loops.py) ------------------------------------

#: Scene constants of the stepper, all SI. ``w`` and the Thomas factors are indexed by node;
#: ``first`` is the first unknown node (1: fixed pivot, 0: free pivot of mass ``Mp``);
#: ``max_len2``: the blow-up guard, the squared element length [m^2] no step may exceed;
#: ``slack``: tension-only string law; ``compensated``: Kahan-compensated state updates (the
#: general path reads it at run time, the specialised kernels compile it in).
#: ``mdiag``: the mass matrix's diagonal on the unknown nodes (0 on a fixed pivot), for the
#: implicit string's residual (kernels/step/implicit.py). ``settle``: the explicit string settles its
#: slack switches (kernels/step/switch.py); ``gradient``: the implicit string's energy-momentum form.
#: ``damping``: an element's damper coefficient c = EA tau / u [N s/m] (0: no damper, the step
#: untouched); ``turn_mass`` (3, 3): M^2 rho^ J^-1 rho^T, body frame [kg], the share of the load's
#: mass its rotation takes from a push at the attachment point with Pi held (kernels/step/damper.py).
LGVIParams = namedtuple("LGVIParams", "h m kappa u g M Mp rho J Jd Jeff inv cp off w first slack tol max_iter gammas "
                                      "max_len2 compensated mdiag settle gradient damping turn_mass")

#: The state the kernels advance: positions r and momenta p (N+1, 3), R (3, 3), Pi (3,), the
#: compensated-summation remainders rc, pc, Rc, Pic of each, the forces f at r (N+1, 3), the
#: input balances acc (:data:`BALANCE`) with their remainders accc, and per element the energy
#: the explicit string's slack switch still owes, ``owed`` (N,) [J] (kernels/step/switch.py).
StateArrays = namedtuple("StateArrays", "r p R Pi rc pc Rc Pic f acc accc owed")

#: Scratch arrays of one simulator; ``backup`` holds a checkpoint of the state during composed
#: steps (kernels/step/loops.py), so a failure can go back to it. The implicit string's Newton
#: (kernels/step/implicit.py) uses ``fl``, ``fr`` (N+1, 3), the string's forces of the step along
#: the elements at its start and at its end [N], ``dy``
#: (N+1, 3), its right-hand sides and corrections [m], ``elim`` (N+1, 3, 3), the factors of
#: its block elimination, and ``taut`` (N,), 1 for the elements it holds to the taut branch of
#: the slack law until it has converged (docs/physics.md, "The taut-branch start").
#: ``ext`` (N+2, 3): the external forces held over a control step (kernels/step/disturbance.py), on
#: the nodes (rows 0..N) and on the load's centre of mass (row N+1) [N], spatial frame.
#: ``switch`` (N,): the explicit string's energy errors of a step's slack switches [J]
#: (kernels/step/switch.py), which also uses ``dy`` and ``fr`` as scratch (the explicit string's
#: step does not: the winch's loop reads ``Y``, the step's increments, after it).
#: The damper's half step (kernels/step/damper.py): ``dvel`` (N+1, 3) the node velocities of the
#: state [m/s], ``dinc`` (N+1, 3) their increments, ``ddir`` (N, 3) the elements' directions,
#: ``dten`` (N,) their elastic tensions [N], ``dset`` (N,) the damper's state of each (slack,
#: active, held), ``dfac`` (N+1, 3, 3) the eliminated blocks, ``dmat`` (4, 3, 3) scratch of a row's blocks.
Work = namedtuple("Work", "fn X Y FmI RF Rn jac backup fl fr dy elim taut ext switch dvel dinc ddir dten dset dfac "
                          "dmat")

#: The winch's arrays (kernels/step/winch.py): ``state`` (:data:`WINCH`), per element the weights
#: ``coef`` (N, 3) of its convective kinetic energy (alpha, beta, gamma: docs/physics.md, "The
#: winch"), the Thomas factors of the step's matrix (``lower``, ``upper``, ``inv``, ``cp``, and
#: its attachment column ``w``, (N+1,)) with ``jeff`` (3, 3), the shifted momenta ``pshift``
#: (N+1, 3) and the mass matrix at the current length for the diagnostics (``dinv``, ``dcp``,
#: ``dw``, ``djeff``), a checkpoint of ``state`` (``backup``), and for the implicit string
#: (kernels/step/winch_implicit.py) the step matrix's diagonal ``diag`` (N+1,) and the constant part
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

#: Diagnostics of a state (kernels/step/diagnostics.py) [J, kg m^2/s, -, m, kg m/s].
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
#: external forces (wind and pushes, kernels/step/disturbance.py) (3 each) [kg m/s], the
#: winch's work [J] (kernels/step/winch.py) and the energy the string's dampers took [J], >= 0
#: (kernels/step/damper.py): the energy balance is E - E0 - W - W_winch + D.
BALANCE = Layout(("work", 1), ("angular_impulse_z", 1), ("gravity_impulse", 3), ("pivot_impulse", 3),
                 ("external_impulse", 3), ("winch_work", 1), ("dissipation", 1))
B_WORK = BALANCE.scalar("work")
B_ANGULAR_IMPULSE_Z = BALANCE.scalar("angular_impulse_z")
B_GRAVITY_IMPULSE = BALANCE.start("gravity_impulse")
B_PIVOT_IMPULSE = BALANCE.start("pivot_impulse")
B_EXTERNAL_IMPULSE = BALANCE.start("external_impulse")
B_WINCH_WORK = BALANCE.scalar("winch_work")
B_DISSIPATION = BALANCE.scalar("dissipation")

#: The winch (kernels/step/winch.py): the unstretched length l [m] and the reel speed dl/dt [m/s]
#: of the state (the speed its momenta were made with), the string's constants mass per length
#: [kg/m], EA [N], solver.max_stretch, the
#: consistent or lumped mass model's shares of an element's mass on its end nodes' diagonal
#: and off the diagonal, and the winch's range [m].
WINCH = Layout(("length", 1), ("reel_speed", 1), ("mass_per_length", 1), ("EA", 1),
               ("max_stretch", 1), ("end_share", 1), ("off_share", 1), ("min_length", 1), ("max_length", 1))
WN_LENGTH = WINCH.scalar("length")
WN_REEL_SPEED = WINCH.scalar("reel_speed")
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

#: Inputs of a step: the pivot force at the step's start and at its end (spatial) [N] (equal
#: for a force held over the step; a drone's thrust turns with it: kernels/drone/quadrotor.py), body
#: torque (body frame) [N m], spatial torque [N m], held over the step.
INPUTS = Layout(("pivot_force", 3), ("pivot_force_end", 3), ("body_torque", 3), ("spatial_torque", 3))
IN_PIVOT_FORCE = INPUTS.start("pivot_force")
IN_PIVOT_FORCE_END = INPUTS.start("pivot_force_end")
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
