"""A team's constants: each string's mass matrix reduced to its end, and the body's inertia with
the strings' end masses (docs/physics.md, "One string reduced to its end", "The assembled
body"), for :class:`~esp_gym.team.simulator.TeamSimulator`."""
import numpy as np

from ..kernels.step.string import tridiag_factor
from ..kernels.team.arrays import TeamParams
from ..physics.state import attachment_column, mass_matrix
from ..scene.stability import hat


def string_mass(string, pivot):
    """``(diagonal (N+1,), off-diagonal, end share)`` of one string's mass matrix without a body
    (a free pivot's mass on its first row, a fixed pivot's row 0)."""
    m = string.m
    off, end = (m / 6.0, 2.0 * m / 6.0) if string.mass_model == "consistent" else (0.0, 0.5 * m)
    diag = np.full(string.elements + 1, 2.0 * end)
    diag[0] = end + pivot.mass if pivot.is_free else 0.0
    diag[-1] = end
    return diag, off, end


def end_reduction(diag, off, first):
    """The rows before a string's end, and its end mass: ``(inv, cp, w_end, mu)``, the Thomas
    factors of M_II, its last column M_II^-1 e_last and mu = M_ee - off^2 (M_II^-1)_last,last
    (docs/physics.md, "One string reduced to its end")."""
    n = diag.shape[0] - 1
    block = diag[:n]
    if n - 1 < first:  # one element from a fixed pivot: nothing moves but the end
        return np.zeros(n), np.zeros(n), np.zeros(n), float(diag[n])
    inv, cp = tridiag_factor(block, off)
    w_end = attachment_column(block, off, cp, first)
    return inv, cp, w_end, float(diag[n] - off * off * w_end[n - 1])


def build_team(team, lead_params):
    """The team's constants (:data:`~esp_gym.kernels.team.step.TeamParams`) of ``team`` (a
    :class:`~esp_gym.team.scene.TeamScene`) from the lead scene's
    ``lead_params``, and the other strings' per-string data for the diagnostics."""
    rho = team.offsets()[1:]
    rows, first, mus, data = [0], [], [], []
    inv, cp, w_end = [], [], []
    for k, s in enumerate(team.strings, start=1):
        diag, off, end = string_mass(s.string, s.pivot)
        f = 0 if s.pivot.is_free else 1
        i, c, w, mu = end_reduction(diag, off, f)
        inv += [i, [0.0]]
        cp += [c, [0.0]]
        w_end += [w, [0.0]]
        rows.append(rows[-1] + s.string.elements + 1)
        first.append(f)
        mus.append(mu)
        data.append((diag, off, end, f))
    P = lead_params
    n = P.inv.shape[0] - 1
    if team.strings:
        mu = np.array(mus)
        mass = P.M + float(mu.sum())
        rho_inertial = P.rho + (mu[:, None] * (rho - P.rho)).sum(0) / mass
        J = P.J + sum(m * (r @ r * np.eye(3) - np.outer(r, r)) for m, r in zip(mu, rho))
        diag0, off0, _ = mass_matrix(team.scene)
        diag0[n] += float(mu.sum())
        inv0, cp0 = tridiag_factor(diag0, off0)
        w0 = attachment_column(diag0, off0, cp0, P.first)
        jeff = J + mass * mass * inv0[n] * hat(rho_inertial) @ hat(rho_inertial)
    else:  # one string: the lead scene's own constants
        mass, rho_inertial, jeff, inv0, cp0, w0 = P.M, P.rho, P.Jeff, P.inv, P.cp, P.w
    strings = team.strings
    cat = (lambda parts: np.concatenate(parts)) if strings else (lambda parts: np.zeros(0))
    T = TeamParams(
        start=np.array(rows, dtype=np.int64), first=np.array(first, dtype=np.int64),
        kappa=np.array([s.string.kappa for s in strings], dtype=float),
        u=np.array([s.string.u for s in strings], dtype=float),
        m=np.array([s.string.m for s in strings], dtype=float),
        Mp=np.array([s.pivot.mass or 0.0 for s in strings], dtype=float),
        off=np.array([d[1] for d in data], dtype=float),
        slack=np.array([s.string.law == "slack" for s in strings], dtype=np.bool_),
        max_len2=np.array([(team.scene.solver.max_stretch * s.string.u) ** 2 for s in strings], dtype=float),
        rho=np.ascontiguousarray(rho.reshape(-1, 3)), inv=cat(inv), cp=cat(cp), w_end=cat(w_end),
        mass=float(mass), rho_inertial=np.ascontiguousarray(rho_inertial, dtype=float), jeff=jeff,
        inv0=inv0, cp0=cp0, w0=w0, settle=team.scene.solver.slack_switch == "settled")
    return T, data

def banded(diag, off):
    """The (3, n) banded form of a symmetric tridiagonal matrix with constant ``off``."""
    ab = np.zeros((3, diag.shape[0]))
    ab[0, 1:] = off
    ab[1] = diag
    ab[2, :-1] = off
    return ab
