"""A team's arrays (docs/physics.md, "A team: several strings on one body"): the constants and the
state of strings 1..K-1, stacked by rows, and the small stages that walk those rows. Shared by the
team's step (kernels/team/step.py), its winches' (kernels/team/winch.py) and its slack switch
(kernels/team/switch.py).
"""
from collections import namedtuple

from ..jit import kernel

#: Constants of a team's strings 1..K-1 (per string j: ``first`` its first unknown row, 0 for a
#: free pivot of mass ``Mp``; ``kappa`` [N/m], ``u`` [m], ``m`` [kg] its elements'; ``off`` its
#: mass matrix's off-diagonal [kg]; ``slack`` tension only; ``max_len2`` its blow-up guard [m^2];
#: ``rho`` (K-1, 3) its attachment point from string 0's, body frame [m]) and per stacked row the
#: Thomas factors ``inv``, ``cp`` of the rows before the end and ``w_end`` = M_II^-1 e_last, that
#: block's last column. The body's inertia with the strings' end masses: ``mass`` M' [kg],
#: ``rho_inertial`` rho' [m], ``jeff`` (3, 3), and string 0's Thomas factors ``inv0``, ``cp0`` and
#: attachment column ``w0`` with M' on its last row. ``settle``: the slack strings 1..K-1 settle
#: their switches (``solver.slack_switch: settled``; string 0's is the lead's ``P.settle``).
TeamParams = namedtuple("TeamParams", "start first kappa u m Mp off slack max_len2 rho inv cp w_end "
                                      "mass rho_inertial jeff inv0 cp0 w0 settle")

#: The state and scratch of strings 1..K-1, stacked by rows (rows, 3): positions ``r``, momenta
#: ``p`` (0 on the ends), their remainders ``rc``, ``pc``, the forces ``f`` at r and ``fn`` at the
#: step's new positions ``X`` (increments ``Y``) [N, m]; per string the coupling momentum ``c``
#: (K-1, 3) = M_eI M_II^-1 b_I [kg m/s], the pivot's displacement ``dr0`` over the step [m] and
#: the pivot force ``force`` (K-1, 2, 3) at the step's start u_k and its end u_{k+1} (spatial) [N]
#: (equal for a held force; a drone's thrust turns with it: kernels/team/drones.py); per row
#: (string j's element a at row start[j] + a) its slack switch's error of the step ``switch`` and
#: what it still owes ``owed`` [J] (kernels/team/switch.py).
TeamArrays = namedtuple("TeamArrays", "r p rc pc f fn X Y c dr0 force switch owed")


@kernel(inline="always")
def pivot_rows(T, j):
    """String j's rows that do not move by the solve: 0 below a free pivot, 1 below a fixed one.
    The select of two constants lets the compiler prove every row index from it non-negative, so
    the loops over a string's rows drop the negative-index wraparound that ``T.first[j]`` (read
    from memory) would cost on each access."""
    return 0 if T.first[j] == 0 else 1


@kernel(inline="always")
def add_end_loads(X, w0, E, first, others):
    """X += w0 E on rows ``first..N``: the other strings' left loads ``E`` on string 0's
    attachment row, through its solve's last column w0, by linearity (nothing when ``others`` is 0)."""
    if others > 0:
        E0, E1, E2 = E
        for a in range(first, X.shape[0]):
            X[a, 0] += w0[a] * E0
            X[a, 1] += w0[a] * E1
            X[a, 2] += w0[a] * E2
