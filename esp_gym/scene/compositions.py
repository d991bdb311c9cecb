"""Symmetric compositions of the LGVI: higher-order steppers built from LGVI substeps.

The LGVI is a symmetric one-step map Phi_h of order 2. A composition
``Phi_{gamma_s h} o ... o Phi_{gamma_1 h}`` with palindromic weights (gamma_i = gamma_{s+1-i})
summing to 1 is again symmetric and symplectic; the weights below solve the order conditions
for order 4, 6 or 8 (Hairer, Lubich, Wanner, *Geometric Numerical Integration*, Sec. V.3).
Each substep is a full LGVI step, so the Lie group structure (R_{k+1} = R_k F_k), pi3 and the
energy behaviour carry over.

Two numbers decide what a composition costs: ``stages`` (LGVI substeps per step) and its
stability interval. The explicit string update limits the LGVI to h omega < 2 on its stiffest
mode; a composition is stable up to h omega < ``stability_interval``, computed here exactly for
the linear test equation q'' = -omega^2 q, on which each LGVI substep acts like velocity
Verlet. It is *not* 2 / max|gamma_i| (every substep stable): the substeps' maps are rotations in
different metrics, so their product can be unstable although each factor is stable (Suzuki's
scheme: 2.72 instead of 3.04) or stable although one factor is not (triple jump: 1.57 instead of
1.17). The paper example confirms both (largest 2-s stable h: 0.90 and >= 1.2 times
2 / (max|gamma| omega_max)). Triple jump's large negative middle weight (-1.70) also gives it a
large error constant. The measured orders are asserted in tests/test_variants.py.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Composition:
    """Palindromic weights ``gammas`` (sum 1) of a symmetric composition of order ``order``."""

    name: str
    order: int
    gammas: tuple
    reference: str

    @property
    def stages(self) -> int:
        return len(self.gammas)

    @property
    def largest_substep(self) -> float:
        return float(max(abs(g) for g in self.gammas))

    @property
    def stability_interval(self) -> float:
        """Largest x such that the composition is stable for every h omega < x (2 for the
        plain LGVI)."""
        return _stability_interval(self.gammas)

    @property
    def bound_factor(self) -> float:
        """Stable h of the composition / stable h of one LGVI step: stability_interval / 2
        (exactly 1 for the LGVI itself)."""
        return 1.0 if self.stages == 1 else self.stability_interval / 2.0

    def weights(self) -> np.ndarray:
        return np.array(self.gammas, dtype=np.float64)


_INTERVALS: dict = {}


def _trace(gammas, x: np.ndarray) -> np.ndarray:
    """Trace of the composition's one-step matrix on q'' = -omega^2 q at h omega = x (in the
    coordinates (q, p / omega), each substep of angle t = gamma x is velocity Verlet:
    [[1 - t^2/2, t], [-t (1 - t^2/4), 1 - t^2/2]]; the product has determinant 1, so it is
    stable iff |trace| <= 2)."""
    a, b, c, d = np.ones_like(x), np.zeros_like(x), np.zeros_like(x), np.ones_like(x)
    for g in gammas:
        t = g * x
        e = 1.0 - 0.5 * t * t
        f = -t * (1.0 - 0.25 * t * t)
        a, b, c, d = e * a + t * c, e * b + t * d, f * a + e * c, f * b + e * d
    return a + d


def _stability_interval(gammas) -> float:
    key = tuple(gammas)
    if key not in _INTERVALS:
        x = np.linspace(1e-4, 8.0, 80_001)
        bad = np.nonzero(np.abs(_trace(gammas, x)) > 2.0 + 1e-12)[0]
        lo, hi = (x[bad[0] - 1], x[bad[0]]) if bad.size else (x[-1], x[-1])
        for _ in range(40):  # refine the first crossing by bisection
            mid = np.array([0.5 * (lo + hi)])
            lo, hi = (mid[0], hi) if abs(_trace(gammas, mid)[0]) <= 2.0 + 1e-12 else (lo, mid[0])
        _INTERVALS[key] = float(lo)
    return _INTERVALS[key]


def _palindrome(half) -> tuple:
    return tuple(half) + tuple(reversed(half[:-1]))


_CBRT2 = 2.0 ** (1.0 / 3.0)
_SUZUKI_P = 1.0 / (4.0 - 4.0 ** (1.0 / 3.0))

COMPOSITIONS = {
    c.name: c
    for c in (
        Composition("lgvi", 2, (1.0,), "the paper's LGVI itself"),
        Composition("triple_jump", 4, (1.0 / (2.0 - _CBRT2), -_CBRT2 / (2.0 - _CBRT2), 1.0 / (2.0 - _CBRT2)),
                    "Yoshida 1990; Creutz & Gocksch 1989; Suzuki 1990"),
        Composition("suzuki5", 4, (_SUZUKI_P, _SUZUKI_P, 1.0 - 4.0 * _SUZUKI_P, _SUZUKI_P, _SUZUKI_P),
                    "Suzuki 1990 (fractal decomposition, 5 stages)"),
        # the 5-stage order-4 family (a, b, 1 - 2a - 2b, b, a) with 2a^3 + 2b^3 + (1-2a-2b)^3 = 0
        # trades error constant for stability: Suzuki's member (a = b) has the smallest phase
        # error, a = 1/5 a 22 % wider interval (3.319 vs 2.721, 0.664 per stage, within 7 % of
        # the family's widest) at 6x the leading phase-error constant. For stability-limited
        # runs: where the fastest steps Suzuki can take are already more accurate than needed.
        Composition("wide5", 4, (0.2, 0.81748462964498403636, -1.03496925928996807272,
                                 0.81748462964498403636, 0.2),
                    "5-stage symmetric family (Suzuki 1990), outer weight 1/5 (this project)"),
        Composition("kahan_li9", 6, _palindrome((0.39216144400731413927925056, 0.33259913678935943859974864,
                                                 -0.70624617255763935980996482, 0.08221359629355080023149045,
                                                 0.79854399093482996339895035)),
                    "Kahan & Li 1997, s9odr6a"),
        Composition("kahan_li17", 8, _palindrome((0.13020248308889008087881763, 0.56116298177510838456196441,
                                                  -0.38947496264484728640807860, 0.15884190655515560089621075,
                                                  -0.39590389413323757733623154, 0.18453964097831570709183254,
                                                  0.25837438768632204729397911, 0.29501172360931029887096624,
                                                  -0.60550853383003451169892108)),
                    "Kahan & Li 1997, s17odr8a"),
    )
}

#: The composition each order uses unless the scene names one (the cheapest per accuracy in
#: benchmarks/work_precision.py).
DEFAULT_FOR_ORDER = {2: "lgvi", 4: "suzuki5", 6: "kahan_li9", 8: "kahan_li17"}
