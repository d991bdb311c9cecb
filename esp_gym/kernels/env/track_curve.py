"""The moving reference of the ``track`` task (esp_gym/pendulum/tasks.py): a closed curve in a
horizontal plane, its parameters and its clock held in the episode's TARGET vector.

With theta = theta_0 + omega t, the curve in its own frame is

    x = A_x sin(theta + psi_x),   y = A_y sin(m theta + psi_y)

(a circle: A_x = A_y = a, m = 1, psi_x = pi/2, psi_y = 0; a figure-eight, Gerono's lemniscate:
A_x = a, A_y = a/2, m = 2, psi = 0), turned by the orientation alpha about e3 and put at the
centre: the pivot target is centre + (x, y, 0) turned, the load target ``depth`` below it, and
both move at the curve's velocity. A TARGET with omega = 0 is a fixed target (stabilize,
transport) and never changes.
"""
import math

from ..jit import kernel
from .arrays import (T_AMPLITUDE, T_CENTRE, T_CLOCK, T_DEPTH, T_HARMONIC, T_LOAD, T_ORIENTATION, T_PHASE, T_PIVOT,
                     T_RATE, T_START, T_VELOCITY)


@kernel(entry=True)
def reference_at(target, t):
    """Put the reference at time ``t`` [s] into ``target`` (TARGET): the clock, the pivot and the
    load targets [m] and their velocity [m/s], spatial frame."""
    w = target[T_RATE]
    m = target[T_HARMONIC]
    theta = target[T_START] + w * t
    ax = target[T_AMPLITUDE]
    ay = target[T_AMPLITUDE + 1]
    u = theta + target[T_PHASE]
    v = m * theta + target[T_PHASE + 1]
    x = ax * math.sin(u)
    y = ay * math.sin(v)
    vx = ax * w * math.cos(u)
    vy = ay * m * w * math.cos(v)
    c = math.cos(target[T_ORIENTATION])
    s = math.sin(target[T_ORIENTATION])
    target[T_CLOCK] = t
    target[T_PIVOT] = target[T_CENTRE] + (c * x - s * y)
    target[T_PIVOT + 1] = target[T_CENTRE + 1] + (s * x + c * y)
    target[T_PIVOT + 2] = target[T_CENTRE + 2]
    target[T_LOAD] = target[T_PIVOT]
    target[T_LOAD + 1] = target[T_PIVOT + 1]
    target[T_LOAD + 2] = target[T_PIVOT + 2] + target[T_DEPTH]
    target[T_VELOCITY] = c * vx - s * vy
    target[T_VELOCITY + 1] = s * vx + c * vy
    target[T_VELOCITY + 2] = 0.0


@kernel(inline="always")
def advance_reference(target, dt):
    """Move a moving reference (omega != 0) on by ``dt`` [s]; a fixed target stays as it is."""
    if target[T_RATE] != 0.0:
        reference_at(target, target[T_CLOCK] + dt)


@kernel(entry=True)
def reference_path(scratch, times, offset, velocity):
    """The reference at each of ``times`` [s]: the pivot target's offset from the centre [m] into
    ``offset`` and its velocity [m/s] into ``velocity`` (both (len(times), 3), spatial frame);
    ``scratch``, a copy of the TARGET, is moved along (the kernels do not allocate)."""
    for k in range(times.shape[0]):
        reference_at(scratch, times[k])
        for i in range(3):
            offset[k, i] = scratch[T_PIVOT + i] - scratch[T_CENTRE + i]
            velocity[k, i] = scratch[T_VELOCITY + i]
