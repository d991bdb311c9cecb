"""Rerun recordings (``.rrd``) of esp_gym runs: the 3-D scene and the energy and momentum
diagnostics, for free simulations (:func:`record_simulation`, ``esp-gym record``) and for
rollouts of ElasticStringPendulum-v0 (the Gymnasium wrapper :class:`RecordRerun`).

Open a recording with ``rerun FILE.rrd``; it carries its default blueprint (the 3-D view
beside the time-series panels). Read it back with ``rerun.chunk.RrdReader(FILE).stream()``.

Timelines
    ``step`` (sequence): the physics step for free simulations; for env rollouts the control
    step, counted across episodes (a reset takes the index after the previous episode's last
    step). ``time`` (duration [s]): the simulated time for free simulations, ``step`` x the
    control period for env rollouts.

Entities (SI units; spatial frame unless stated; gravity along +z, the 3-D view is z-down)

==============================  =====================================================================
``/world``                      static: view coordinates (right-handed, z down)
``/world/string``               N two-point line strips, one per element (Rerun colours per strip),
                                coloured by the element's strain energy: the rgb_array renderer's
                                ramp at ``sqrt(E / strain_scale)``
``/world/body``                 Transform3D, translation = attachment node, mat3x3 = R (body to
                                spatial): everything below is drawn in the body frame
``/world/body/shape``           the body's shape centred on rho_c (box, sphere, a mesh for the
                                cylinders; without a shape the box of the same mass and inertia
                                about the centre of mass): static for free simulations; for env
                                rollouts each episode's (randomised sizes, rho_c), at its reset
``/world/body/center_of_mass``  a point at rho_c (static, or each episode's at its reset)
``/world/body/torque``          arrow from the centre of mass (origin as the point above):
                                ``torque_scale`` x body torque [m per N m]
``/world/pivot``                node 0
``/world/pivot_force``          arrow from the pivot: ``force_scale`` x (pivot force -
                                ``force_offset``) [m per N] (env rollouts: minus the hover force)
``/world/load_trail``           the load's centre of mass over the last ``trail_seconds``
``/world/targets/{pivot,load}`` env rollouts: the episode's targets, at its reset
``/world/wind``                 env rollouts: arrow from the load's centre of mass, ``wind_scale``
                                x wind (mean + gust) [m per m/s]
``/world/push``                 env rollouts: arrow from the load's centre of mass, ``force_scale``
                                x the push on the load [m per N]
``/world/hook_tension``         env rollouts: arrow from the pivot, ``force_scale`` x the hook
                                tension (the string's pull on the pivot) [m per N]
``/diag/energy/total``          E [J]
``/diag/energy/parts``          kinetic_string, kinetic_body, kinetic_pivot, potential_gravity,
                                potential_elastic and the input work W [J] (named series)
``/diag/energy_residual``       E - E0 - W [J] (the input work balance, the winch's work included;
                                E0 at the episode's start)
``/diag/pi3``                   pi3 [kg m^2/s]
``/diag/pi3_residual``          pi3 - pi3_0 - angular impulse [kg m^2/s]
``/diag/orthogonality``         ||I - R^T R||_F
``/diag/stretched_length``      [m]
``/diag/newton_iterations``     mean Newton iterations per physics step since the previous sample
``/rl/reward/total``            env rollouts: the reward ...
``/rl/reward/terms``            ... and its terms (``info["reward_*"]``, named series)
``/rl/return``                  the episode's return so far
``/rl/action``                  the applied (clipped) action, force_x .. torque_z (named series)
``/env/wind``                   env rollouts: the wind (mean + gust) wind_x, _y, _z [m/s]
``/env/hook_tension``           env rollouts: the hook tension hook_tension_x, _y, _z [N]
``/env/push``                   env rollouts: the push on the load push_x, _y [N] (horizontal)
``/env/drag``                   env rollouts: the drag on the load load_drag_x, _y, _z and on the
                                line (summed over its nodes) line_drag_x, _y, _z [N]
``/winch/unstretched_length``   with a winch (``winch=True``): the string's unstretched length [m]
``/winch/reel_speed``           ... the reel speed of the last step [m/s] (the reel action times
                                ``winch.max_speed``, 0 once the winch stops at its range)
``/winch/work``                 ... and the winch's work since the episode's start [J]
``/world/drone``                with a drone at the pivot: Transform3D, translation = the pivot,
                                mat3x3 = R_q (the drone's body to spatial)
``/world/drone/frame``          static: its arms and rotor rings in its body frame
``/drone/rates``                its body rates Omega_q [rad/s]
``/drone/rotor_speeds``         its four rotor speeds [rad/s]
==============================  =====================================================================

With a drone the ``/rl/action`` series are its four entries, named for its actuation
(``thrust, rate_x, ...``), and the pivot-force arrow is the inputs' thrust at the last physics
step's start less the hover force (drone_track.py keeps the drone's samples).

A sample holds the state after a step (or a reset, or the start of a free simulation) and its
diagnostics; for env rollouts also what that ``env.step`` returned and applied (reward, terms,
action) and the sensors and disturbance of that step (at a reset: of the episode's start; in still
air zeros). Reset samples have no Newton, reward or action values (nulls: no data at that row).

Bulk logging: each sample is copied into a preallocated row (``kernels.recording.sample_layout``)
by one compiled call (~1 us, ``kernels.recording.capture_sample``); the rows are written
``flush_every`` at a time (also after ``flush_seconds`` of wall time, on
:meth:`Recorder.close`, at exit and on signals; :class:`RecordRerun` optionally at each
episode's end) as ONE ``send_record_batch`` per flush: a column per (entity, component), each
field described by the ``rerun:*`` metadata that ``rerun.chunk.Chunk.from_record_batch`` reads,
with the component's own Rerun descriptor and Arrow type. That is ``send_columns`` for all
entities at once: one ``send_columns`` call costs ~0.1-0.5 ms, and ~20 of them per flush cost
more than the rollout. Scalars are stored as float64 (the simulator's bits); 3-D geometry as
float32 (Rerun's types). Related scalar series share an entity (named series): every entity
costs a row id and two time values per sample.

Interruption (lifecycle.py): SIGTERM closes every open recording (the file gets its footer) and
then ends the process as SIGTERM would have (or calls the previously installed Python handler);
a second SIGTERM, or 30 s, ends it even if closing hangs. SIGINT writes the buffers and raises
KeyboardInterrupt as usual; ``atexit`` closes the recordings. A signal arriving during a flush
is handled when it is done. Only SIGKILL (or a crash) loses data: the samples buffered since the
last flush (at most ``flush_seconds`` of wall time, or ``flush_every`` samples); the file is then
still readable with ``RrdReader(path).stream()`` (without its footer ``.store()`` refuses it).

Write errors (lifecycle.py): Rerun writes into a pipe and a thread of ours writes the file,
checking each write. A failed write (disk full, file-size limit) raises :class:`RecordingError`
(an ``OSError`` naming the file) from the next sample, flush or ``close()``; the recording stops
and the file, cut back to the end of its last complete flush, stays readable. A wait for the
file ends when it has not grown for ``write_timeout`` (a failure, ``errno.ETIMEDOUT``).

Modules: entities.py (the entity paths and series, the blueprint, the body's shape), recorder.py
(:class:`Recorder`), drone_track.py (a drone's samples), record_env.py (:class:`RecordRerun`, :func:`record_simulation`), arrow.py
(the record batches), lifecycle.py (exit and signals), geometry.py and palette.py (shared with
the rgb_array renderer), esp_gym/kernels/env/recording.py (the compiled sample, geometry and trail
kernels). This module is their public face: it asks for the ``record`` extra (Rerun) before they
import it.
"""
from ..extras import require

require("rerun", "esp_gym.viz.recording")
from ..kernels.env.arrays import REWARD_TERMS
from .geometry import equivalent_box, prism_triangles, quaternion_xyzw
from .lifecycle import RecordingError
from .entities import (BODY, BODY_COM, BODY_SHAPE, BODY_TORQUE, DRONE, DRONE_FRAME, DRONE_RATES, DRONE_ROTORS,
                       ENV_DRAG, ENV_HOOK_TENSION, ENV_PUSH, ENV_WIND, HOOK_TENSION, LOAD_TRAIL, NEWTON, PIVOT, PIVOT_FORCE, PUSH, RETURN, SCALARS, STRING,
                       TARGET_LOAD, TARGET_PIVOT, WIND, WINCH_LENGTH, WINCH_SPEED, WINCH_WORK, WORLD, default_blueprint,
                       default_strain_scale)
from .record_env import RecordRerun, default_record_every, record_simulation
from .recorder import Recorder

__all__ = [
    "Recorder", "RecordRerun", "RecordingError", "record_simulation", "default_record_every",
    "default_strain_scale", "default_blueprint", "quaternion_xyzw", "prism_triangles", "equivalent_box",
    "REWARD_TERMS", "SCALARS", "WORLD", "STRING", "BODY", "BODY_SHAPE", "BODY_COM", "BODY_TORQUE", "PIVOT",
    "PIVOT_FORCE", "LOAD_TRAIL", "TARGET_PIVOT", "TARGET_LOAD", "NEWTON", "RETURN", "WIND", "PUSH", "HOOK_TENSION",
    "ENV_WIND", "ENV_HOOK_TENSION", "ENV_PUSH", "ENV_DRAG", "WINCH_LENGTH", "WINCH_SPEED", "WINCH_WORK",
    "DRONE", "DRONE_FRAME", "DRONE_RATES", "DRONE_ROTORS",
]
