"""The environment's arrays across the compiled boundary: one named struct, :class:`EnvArrays`,
beside the physics' (:class:`~.layout.StateArrays`, :class:`~.layout.Work`,
:class:`~.layout.LGVIParams`, :class:`~.layout.DiagWork`, :class:`~.layout.WinchArrays`).

Python builds it once per environment (esp_gym/control.py) and hands its fields to the entry
points (kernels/env_step.py) as a plain tuple, which the kernels rebuild by name; a batch of
environments holds the same fields with a leading batch axis, and :func:`~.rows.row_function`
takes sub-environment b's row of it from the fields. Every vector is laid out in
kernels/layout.py.
"""
from collections import namedtuple

from .layout import Layout

#: One environment's arrays (a batch's: each with a leading (B,) axis):
#:
#: * ``ap`` ACTION_PARAMS: the action box and its map to the inputs;
#: * ``inputs`` INPUTS: the held pivot force, body and spatial torques [N, N m];
#: * ``nsub`` (1,) int64: physics steps per control step;
#: * ``target`` TARGET: the references [m, m/s] (spatial frame);
#: * ``tp`` TASK_PARAMS: the reward's weights and scales, the workspace, the watchdog's bound;
#: * ``action`` ACTION or WINCH_ACTION: the applied (clipped) action;
#: * ``obs`` OBSERVATION or WINCH_OBSERVATION; ``terms`` REWARD; ``sensors`` SENSORS;
#: * ``features`` FEATURES: what the tasks read of the state (kernels/task_terms.py);
#: * ``result`` REPORT (int64): the control step's status, steps, Newton counts, termination;
#: * ``dp`` DISTURBANCE_PARAMS, ``ds`` DISTURBANCE, ``draws`` (K, DRAWS), ``drawn`` (1,) int64:
#:   the wind's episode constants, its state, the random draws ahead and the next one's row
#:   (read only when disturbed: kernels/disturbance.py).
EnvArrays = namedtuple("EnvArrays", "ap inputs nsub target tp action obs terms sensors features result dp ds draws "
                                    "drawn")

#: What the tasks read of the state after each control step and reset, computed once
#: (kernels/task_terms.py): the load's centre of mass [m] and its velocity [m/s] (spatial
#: frame), the swing angle of pivot -> load centre from the downward vertical e3 [rad] and the
#: load's spin |Omega| [rad/s].
FEATURES = Layout(("load_position", 3), ("load_velocity", 3), ("swing", 1), ("spin", 1))
F_LOAD_POSITION = FEATURES.start("load_position")
F_LOAD_VELOCITY = FEATURES.start("load_velocity")
F_SWING = FEATURES.scalar("swing")
F_SPIN = FEATURES.scalar("spin")
