"""The environment's arrays across the compiled boundary: one named struct, :class:`EnvArrays`,
beside the physics' (:class:`~.layout.StateArrays`, :class:`~.layout.Work`,
:class:`~.layout.LGVIParams`, :class:`~.layout.DiagWork`, :class:`~.layout.WinchArrays`).

Python builds it once per environment (esp_gym/control.py) and hands its fields to the entry
points (kernels/task.py) as a plain tuple, which the kernels rebuild by name; a batch of
environments holds the same fields with a leading batch axis, and :func:`~.rows.row_function`
takes sub-environment b's row of it from the fields. Every vector is laid out in
kernels/layout.py.
"""
from collections import namedtuple

#: One environment's arrays (a batch's: each with a leading (B,) axis):
#:
#: * ``ap`` ACTION_PARAMS: the action box and its map to the inputs;
#: * ``inputs`` INPUTS: the held pivot force, body and spatial torques [N, N m];
#: * ``nsub`` (1,) int64: physics steps per control step;
#: * ``target`` TARGET: the references [m, m/s] (spatial frame);
#: * ``tp`` TASK_PARAMS: the reward's weights and scales, the workspace, the watchdog's bound;
#: * ``action`` ACTION or WINCH_ACTION: the applied (clipped) action;
#: * ``obs`` OBSERVATION or WINCH_OBSERVATION; ``terms`` REWARD; ``sensors`` SENSORS;
#: * ``result`` REPORT (int64): the control step's status, steps, Newton counts, termination;
#: * ``dp`` DISTURBANCE_PARAMS, ``ds`` DISTURBANCE, ``draws`` (K, DRAWS), ``drawn`` (1,) int64:
#:   the wind's episode constants, its state, the random draws ahead and the next one's row
#:   (read only when disturbed: kernels/disturbance.py).
EnvArrays = namedtuple("EnvArrays", "ap inputs nsub target tp action obs terms sensors result dp ds draws drawn")
