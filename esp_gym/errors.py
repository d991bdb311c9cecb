"""What a failed step raises, what to change after it, and what its status codes say
(kernels/status.py, STATUS)."""
from __future__ import annotations

from .kernels.status import BLOW_UP, ENERGY_BALANCE, NEWTON_FAILED, NON_FINITE, PHYSICS_FAILURES, STATUS
from .scene.params import Scene


class SimulationError(RuntimeError):
    """The stepper could not take a step. The simulator keeps the last good state."""

    def __init__(self, status: int, step: int, time: float, newton_iterations: int, advice: str = ""):
        self.status = status
        self.step = step
        self.time = time
        if status == ENERGY_BALANCE:  # the watchdog: the steps were taken, the state is finite
            super().__init__(f"after step {step} (t = {time:.6g} s): {status_message(status)}; the simulator holds "
                             f"the state where it broke. {advice}".rstrip())
            return
        super().__init__(
            f"step {step} (t = {time:.6g} s) failed: {status_message(status)} "
            f"(Newton iterations in the failing step: {newton_iterations}); "
            f"the simulator holds the last good state. {advice}".rstrip())


def failure_advice(scene: Scene, status: int) -> str:
    """What to change after a failed step, from the kind of failure and how h compares with the
    stability bound (a smaller h is the answer only when h is near or past the bound)."""
    bound = scene.stability_bound
    ratio = scene.h / bound
    if status in (BLOW_UP, NON_FINITE) and ratio > 0.7:
        return (f"h = {scene.h:g} s is {ratio:.2g} x the stability bound {bound:.3g} s: use h <= 0.7 x the bound "
                f"(esp_gym.choose_h).")
    if status == NEWTON_FAILED and scene.solver.string == "implicit":
        return ("The implicit string's Newton iteration did not converge (it can cycle where elements switch between "
                "slack and taut, or when the body turns far in one step): use a smaller h, a larger "
                "solver.newton_max_iter, or solver.string: explicit.")
    if status == NEWTON_FAILED:
        return "The body turned too far in one step: use a smaller h or a larger solver.newton_max_iter."
    if status == BLOW_UP:
        return (f"h is {ratio:.2g} x the stability bound, so the step is stable: the inputs or the initial state "
                f"stretched an element past solver.max_stretch; use smaller inputs, or raise max_stretch if "
                f"that stretch is intended.")
    return "The forces or inputs overflowed: check their magnitudes."


def status_message(code: int) -> str:
    """The message of a status code (the code itself if it is unknown)."""
    status = STATUS.get(int(code))
    return str(code) if status is None else status.message


def termination_reason(code: int) -> str:
    """``info["termination_reason"]`` of a termination code ("" for 0)."""
    code = int(code)
    if code in PHYSICS_FAILURES:
        return "physics_failure: " + STATUS[code].message
    return STATUS[code].reason


