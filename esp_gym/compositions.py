"""Symmetric compositions of the LGVI: higher-order steppers built from LGVI substeps.

The LGVI is a symmetric one-step map Phi_h of order 2. A composition
``Phi_{gamma_s h} o ... o Phi_{gamma_1 h}`` with palindromic weights (gamma_i = gamma_{s+1-i})
summing to 1 is again symmetric and symplectic; the weights below solve the order conditions
for order 4, 6 or 8 (Hairer, Lubich, Wanner, *Geometric Numerical Integration*, Sec. V.3).
Each substep is a full LGVI step, so the Lie group structure (R_{k+1} = R_k F_k), pi3 and the
energy behaviour carry over.

Two numbers decide what a composition costs: ``stages`` (LGVI substeps per step) and
``largest_substep`` (max |gamma_i|): the explicit string update is stable while
``largest_substep * h`` is below the LGVI's bound, so the stable h is that bound divided by it.
Triple jump has a large negative middle weight (-1.70), hence a small stable h and a large
error constant; Suzuki's five-stage and Kahan-Li's nine- and seventeen-stage schemes keep every
weight below 1.
The measured orders are asserted in tests/test_variants.py.
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

    def weights(self) -> np.ndarray:
        return np.array(self.gammas, dtype=np.float64)


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
