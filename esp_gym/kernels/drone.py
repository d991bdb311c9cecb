"""A drone's rotation at the default hook (docs/physics.md, "A drone at the pivot"): with the
hook at the centre of mass the string exerts no torque on the drone, and its rotation is a free
rigid body under the rotors' torque, stepped by the LGVI's own stages (the Cayley Newton of
kernels/so3.py, the attitude and momentum updates of kernels/step_shared.py). The translation is
the free pivot's, pushed by the thrust's impulses; this module is the rotation's half.
"""
from .jit import kernel
from .so3 import cayley_minus_identity, cayley_newton
from .status import NEWTON_FAILED, OK
from .step_shared import commit_rotation, free_body_increment, next_attitude


@kernel(forceinline=True)
def attitude_step(body, inertia, h, torques, scratch, solver, compensated):
    """One step of length ``h`` [s] of the drone's rotation: ``body`` = (R_q (3, 3), its
    remainder Rc, Pi_q (3) [kg m^2/s], its remainder Pic), updated in place; ``inertia`` J_q
    (3, 3) about the hook [kg m^2]; ``torques`` = (tau^-, tau^+), the left and right body torques
    of the step (3 each, body frame [N m]: the rotors' torque from their speeds at k and at k+1,
    docs/physics.md); ``scratch`` = (jac, FmI, RF, Rn), four 3x3 arrays; ``solver`` = (Newton's
    relative tolerance, its iteration cap). Solves (F K - K F^T)^vee = h Pi_k + h^2/2 tau^-
    (K = J_d, so J_eff = J_q) for F = cay(f), then R_{k+1} = R_k F and Pi_{k+1} by (4) in
    increment form, compensated or plain. Returns ``(status, newton_iterations)``; a failed
    Newton leaves the body untouched."""
    R, Rc, Pi, Pic = body
    left, right = torques
    jac, FmI, RF, Rn = scratch
    tol, max_iter = solver
    hh = 0.5 * h
    f0, f1, f2, iterations, converged = cayley_newton(h * (Pi[0] + hh * left[0]), h * (Pi[1] + hh * left[1]),
                                                      h * (Pi[2] + hh * left[2]), inertia, tol, max_iter, jac)
    if not converged:
        return NEWTON_FAILED, iterations
    cayley_minus_identity(f0, f1, f2, FmI)
    next_attitude(R, Rc, FmI, RF, Rn, compensated)
    dP = free_body_increment(Pi, FmI, h, left, right, True)
    commit_rotation(R, Rc, Pi, Pic, Rn, RF, dP, compensated)
    return OK, iterations
