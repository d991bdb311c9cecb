"""Choosing the time step h from the stability bound and an accuracy target (:func:`choose_h`).

Two limits decide h:

* stability: the string update is explicit, so h omega_max must stay inside the scheme's
  stability interval (2 for the LGVI; ``Scene.stability_bound`` already scales by a
  composition's interval, esp_gym/scene/compositions.py). Long runs need a margin: ``safety`` (default 0.7; benchmarks/stability.py measured
  one blow-up in twelve 100-s runs at 0.8 of the bound and none at 0.7);
* accuracy: the global error of an order-p scheme behaves like ``C h^p`` while h is in the
  asymptotic range. A pilot pair of runs at ``h1`` and ``h1/2`` over ``horizon`` seconds from
  the scene's initial state (no inputs) estimates the error of the ``h1`` run by Richardson's
  formula ``|x_h1 - x_h1/2| 2^p / (2^p - 1)`` (x the load position, max over the common
  samples); then ``h_acc = h1 (accuracy / e1)^(1/p)``, times 0.9 for margin. If that is
  smaller than h1, the pilot is repeated at h_acc (h1 may lie outside the asymptotic range).

The accuracy is an error in the load (attachment node) position [m] over the pilot horizon,
the same measure as benchmarks/work_precision.py. The motion can be chaotic (the paper's example
is after ~2 s), so a pointwise target only means something over a short horizon; for longer
runs the LGVI's bounded energy error is the guarantee, not a pointwise one.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional

import numpy as np

from ..scene.params import Scene, scene_from_dict
from ..scene.stepsize import checked_targets, divided, shortest
from .simulator import Simulator


@dataclass(frozen=True)
class StepChoice:
    """The result of :func:`choose_h` (times in s, errors in m)."""

    h: float  #: the chosen step
    h_stable: float  #: safety x stability bound
    h_accurate: Optional[float]  #: step meeting the accuracy target by the pilot estimate (None: no target)
    error_estimate: Optional[float]  #: predicted load-position error at h over the horizon
    limited_by: str  #: "stability" or "accuracy"
    pilot_h: Optional[float] = None  #: h1 of the pilot pair
    pilot_error: Optional[float] = None  #: Richardson estimate of the pilot run's error

    def scene(self, scene: Scene) -> Scene:
        """``scene`` with this h."""
        return scene_from_dict({**scene.model_dump(), "h": self.h}, source=repr(scene.name))


#: Load positions held at once while comparing the pilot pair (bounds its memory, whatever the
#: horizon: the runs go in chunks of at most this many coarse steps' samples of the whole string).
PILOT_CHUNK_FLOATS = 1 << 22


def pilot_error(scene: Scene, h: float, horizon: float) -> float:
    """max over the coarse steps of |x_h - x_h/2|, x the load (attachment node) position, of
    two runs from the scene's initial state over ``horizon`` [s]; memory independent of the
    horizon (the runs advance side by side in chunks)."""
    def sim(step: float) -> Simulator:
        return Simulator(scene_from_dict({**scene.model_dump(), "h": step, "allow_unstable_h": True},
                                         source=repr(scene.name)))

    coarse, fine = sim(h), sim(h / 2)
    steps = int(round(horizon / h))
    chunk = max(1, PILOT_CHUNK_FLOATS // (3 * (scene.string.elements + 1)))
    worst = 0.0
    done = 0
    while done < steps:
        k = min(chunk, steps - done)
        a = coarse.run(k * coarse.h, record_every=1).nodes[1:, -1]
        b = fine.run(2 * k * fine.h, record_every=2).nodes[1:, -1]
        worst = max(worst, float(np.linalg.norm(a - b, axis=1).max()))
        done += k
    return worst


def choose_h(scene: Scene, accuracy: Optional[float] = None, horizon: float = 0.1, safety: float = 0.7,
             divides: Optional[float] = None, reeling: bool = False) -> StepChoice:
    """The largest h [s] that is stable with margin ``safety`` and, if ``accuracy`` [m] is given,
    keeps the load-position error over ``horizon`` [s] below it (estimated by a pilot pair of
    runs at the scene's length; see the module docstring). With ``divides`` [s] (e.g. a control
    period) h is rounded down so that it divides that time. ``reeling``: stable for the shortest
    string the scene's winch reaches too (the bound scales with the element length). Uses the
    scene's integrator (its order and composition).

    >>> choice = choose_h(load_scene("paper_example"), accuracy=1e-6)
    >>> sim = Simulator(choice.scene(load_scene("paper_example")))
    """
    accuracy, horizon, divides, safety = checked_targets(accuracy, horizon, divides, safety)
    h_stable = safety * (shortest(scene) if reeling else scene).stability_bound
    h, limited, h_acc, estimate, pilot_h, pilot_err = h_stable, "stability", None, None, None, None
    if accuracy is not None:
        p = scene.solver.scheme.order
        # the pilot step: stable, and at least 40 steps over the horizon. Far from the target the
        # pilot h may be outside the asymptotic range: repeat the pilot at the predicted step
        # (up to 3 times) until the predicted step is no smaller than the pilot's.
        pilot_h = min(h_stable, horizon / 40)
        for _ in range(3):
            pilot_h = horizon / math.ceil(horizon / pilot_h - 1e-9)
            pilot_err = pilot_error(scene, pilot_h, horizon) * 2 ** p / (2 ** p - 1)
            h_acc = math.inf if pilot_err == 0.0 else 0.9 * pilot_h * (accuracy / pilot_err) ** (1.0 / p)
            if h_acc >= pilot_h:
                break
            pilot_h = h_acc
        if h_acc < h_stable:
            h, limited = h_acc, "accuracy"
    h, _ = divided(h, divides)
    if pilot_err is not None:
        estimate = pilot_err * (h / pilot_h) ** scene.solver.scheme.order
    return StepChoice(h=h, h_stable=h_stable, h_accurate=h_acc, error_estimate=estimate, limited_by=limited,
                      pilot_h=pilot_h, pilot_error=pilot_err)
