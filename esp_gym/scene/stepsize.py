"""The closed-form rules of the step and the resolution: the stability bound at a string's length
(:func:`at_length`, :func:`shortest`), the environment's choice of string scheme and steps per
control step (:func:`choose_scheme`, docs/physics.md, "The environment's choice"), and the
resolution rule, the elements and the step for an accuracy (:func:`choose_resolution`,
``elements: auto``). None of them runs the integrator, so the scene's validation can use them;
:func:`~esp_gym.physics.pilot.choose_h`, which runs a pilot pair, is esp_gym/physics/pilot.py.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Optional

from ..kernels.step.implicit import TRANSVERSE_LIMIT
from .scene_input import real_number, validated
from .stability import explicit_bound, transverse_bound

if TYPE_CHECKING:  # the rules read a scene; params.py calls them to resolve ``elements: auto``
    from .params import Scene


def at_length(scene: Scene, length: float) -> Scene:
    """``scene`` with its string's unstretched length ``length`` [m] (where a winch has taken it).
    A copy, not validated again: the winch's range may reach below the bounds a scene file must
    keep (a 1 um string's default ``min_length`` is 0.5 um)."""
    return scene.model_copy(update={"string": scene.string.model_copy(update={"length": float(length)}),
                                    "allow_unstable_h": True})


def shortest(scene: Scene) -> Scene:
    """``scene`` with the shortest string its winch reaches: the one whose explicit step bound is
    smallest (its elements are shortest); see :func:`at_length`."""
    return at_length(scene, scene.winch_range[0])


def longest(scene: Scene) -> Scene:
    """``scene`` with the longest string its winch reaches: the one whose load-path error at N
    elements is largest (:func:`spatial_error` grows as l^(5/2)); see :func:`at_length`."""
    return at_length(scene, scene.winch_range[1])


#: The smallest accuracy [m] choose_h takes: the positions' rounding (1e-16 of a metre-sized scene
#: per step, compensated) accumulated over a pilot run's 1e4-1e6 steps is of this order; a target of
#: 1e-20 m asked for pilot runs that did not end in 20 minutes.
MIN_ACCURACY = 1e-12
#: The longest horizon [s] choose_h and choose_resolution take: an hour. The error models are fitted
#: over PROTOCOL_HORIZON and extrapolated linearly, which says nothing about hours of drift, and
#: choose_h's pilot runs step through the whole horizon (1e300 s overflowed the element count).
MAX_HORIZON = 3600.0
#: The smallest safety [fraction of the stability bound] they take: the rules use 0.35-0.7, and a
#: step 1000 times under the bound is already stable with room; below, the only effect is the cost
#: (1e-300 gave h = 2e-303 s).
MIN_SAFETY = 1e-3

def checked_targets(accuracy, horizon, divides, safety) -> tuple:
    """``(accuracy, horizon, divides, safety)`` of :func:`choose_h` and :func:`choose_resolution` as
    floats (None stays None): ValueError naming the first that is not a finite positive real number,
    an accuracy below MIN_ACCURACY [m], a horizon above MAX_HORIZON [s], a period ``divides``
    longer than the horizon or a safety outside [MIN_SAFETY, 1]."""
    accuracy, divides, safety = (None if v is None else real_number(name, v, positive=True)
                                 for name, v in (("accuracy", accuracy), ("divides", divides), ("safety", safety)))
    horizon = real_number("horizon", horizon, positive=True)
    if accuracy is not None and accuracy < MIN_ACCURACY:
        raise ValueError(f"accuracy must be at least {MIN_ACCURACY:g} m, got {accuracy:g}: below it the pilot "
                         "runs' own rounding decides, and their length grows without bound")
    if horizon > MAX_HORIZON:
        raise ValueError(f"horizon must be at most {MAX_HORIZON:g} s, got {horizon:g}: the error models grow "
                         f"linearly from their {PROTOCOL_HORIZON:g}-s fit, and past an hour they predict nothing")
    if divides is not None and divides > horizon:
        raise ValueError(f"divides must be at most the horizon ({horizon:g} s), got {divides:g}: it is a period "
                         "(a control step) of the run the accuracy is asked over")
    if safety is not None and not MIN_SAFETY <= safety <= 1.0:
        raise ValueError(f"safety must be in [{MIN_SAFETY:g}, 1], got {safety:g}: it is the fraction of the "
                         "stability bound a step may take, and below the least the step only multiplies the cost")
    return accuracy, horizon, divides, safety


def divided(h: float, divides: Optional[float]) -> tuple:
    """``(h, substeps)``: the largest step at most ``h`` [s] that divides ``divides`` [s] a whole
    number of times, and that number (``(h, None)`` without ``divides``)."""
    if divides is None:
        return h, None
    substeps = math.ceil(divides / h - 1e-9)
    return divides / substeps, substeps


# -- the environment's choice of string scheme and step (docs/physics.md, "The environment's
# choice") -------------------------------------------------------------------------------------

#: The implicit string's step costs about this many explicit steps in the environment
#: (drone_load, N = 8, random actions: about 21 us with 13 Newton iterations per step, cut-backs
#: included, against 0.62 us; in hover 4.2 us with 3 iterations: docs/physics.md).
IMPLICIT_COST = 34.0
#: The tension the implicit step is sized for, in units of the weight below the pivot (random
#: actions of the environment reach 3.6x on drone_load); steps with more are cut back in the
#: variational form.
DESIGN_TENSION = 4.0
#: The implicit step stays this far under the transverse bound 2/omega_t at that tension: the
#: transverse limit h omega_t <= TRANSVERSE_LIMIT (kernels/step/implicit.py), which the variational
#: form needs under its parametric resonances, and which resolves the transverse waves for the
#: energy-momentum form (docs/physics.md, "The environment's choice").
TRANSVERSE_SAFETY = TRANSVERSE_LIMIT / 2.0


@dataclass(frozen=True)
class SchemeChoice:
    """The result of :func:`choose_scheme`."""

    string: str  #: "explicit" or "implicit"
    substeps: int  #: physics steps per control period
    explicit_substeps: int  #: what the explicit string would need (safety x its bound)
    implicit_substeps: int  #: what the implicit string needs (its transverse bound)
    reason: str  #: one line for logs and errors


def explicit_substeps(scene: Scene, control_period: float, safety: float) -> int:
    """Steps of the explicit string per control period: ``ceil(period / (safety x its bound))``,
    the assembled string's bound (esp_gym/scene/stability.py) with the scene's composition, whatever
    its ``solver.string``."""
    return math.ceil(control_period / (safety * explicit_bound(scene)) - 1e-9)


def implicit_substeps(scene: Scene, control_period: float) -> int:
    """Steps of the implicit string per control period: ``ceil(period / h_i)``, h_i =
    TRANSVERSE_SAFETY x the transverse bound at DESIGN_TENSION x the weight below the pivot (one
    step without weight: the cut-backs bound it)."""
    below = scene.gravity * (scene.body.mass + scene.string.length * scene.string.mass_per_length)
    h_implicit = (TRANSVERSE_SAFETY * transverse_bound(scene, DESIGN_TENSION * below) if below > 0.0
                  else control_period)
    return math.ceil(control_period / h_implicit - 1e-9)


def scheme_substeps(scene: Scene, control_period: float, safety: float) -> int:
    """Steps per control period of the scene's own scheme (``solver.string``); for a string whose
    resolution is chosen (``string.auto``) also no fewer than :func:`accurate_step` and
    :func:`accurate_drone_step` need; a whole number per drone's rate-loop period
    (:func:`rate_loop_substeps`)."""
    if scene.solver.string == "implicit":
        return rate_loop_substeps(scene, control_period, implicit_substeps(scene, control_period))
    steps = explicit_substeps(scene, control_period, safety)
    if scene.string.auto:
        h_accurate = min(accurate_step(scene), accurate_drone_step(scene))
        steps = max(steps, math.ceil(control_period / h_accurate - 1e-9))
    return rate_loop_substeps(scene, control_period, steps)


def rate_loop_period(scene: Scene) -> Optional[float]:
    """The drone's rate-loop period T_r [s] (``pivot.drone.rate_loop_period``), or None: no drone,
    or its rate controller runs at every physics step."""
    return scene.pivot.drone.rate_loop_period if scene.pivot.is_drone else None


def rate_loop_substeps(scene: Scene, control_period: float, substeps: int) -> int:
    """The fewest steps per ``control_period`` [s], at least ``substeps``, whose step divides the
    drone's rate-loop period (:func:`rate_loop_period`; ``substeps`` itself without one)."""
    loops = rate_loops(scene, control_period)
    return loops * math.ceil(substeps / loops - 1e-9)


def rate_loops(scene: Scene, control_period: float) -> int:
    """The drone's rate-loop periods per ``control_period`` [s] (1 without a sampled loop). The
    loop samples from each control step's start, so its period must divide the control period:
    ValueError naming both otherwise."""
    period = rate_loop_period(scene)
    if period is None:
        return 1
    loops = int(round(control_period / period))
    if loops < 1 or abs(loops * period - control_period) > 1e-9 * control_period:
        raise ValueError(f"control_period {control_period:g} s is not a whole number of the drone's rate-loop "
                         f"periods (pivot.drone.rate_loop_period {period:g} s): the loop samples from each control "
                         "step's start; take a control period that it divides")
    return loops


def choose_scheme(scene: Scene, control_period: float, safety: float) -> SchemeChoice:
    """The string scheme and the number of steps per control period that cost least, in units of
    an explicit step: :func:`explicit_substeps` against :func:`implicit_substeps`, each implicit
    step IMPLICIT_COST explicit ones."""
    n_explicit = explicit_substeps(scene, control_period, safety)
    n_implicit = implicit_substeps(scene, control_period)
    if scene.solver.order != 2:
        return SchemeChoice("explicit", n_explicit, n_explicit, n_implicit,
                            f"explicit: the implicit string is of order 2 only (order {scene.solver.order})")
    implicit = IMPLICIT_COST * n_implicit < n_explicit
    reason = (f"{'implicit' if implicit else 'explicit'}: {n_explicit} explicit steps per control period against "
              f"{n_implicit} implicit ones at {IMPLICIT_COST} each")
    return SchemeChoice("implicit" if implicit else "explicit", n_implicit if implicit else n_explicit, n_explicit,
                        n_implicit, reason)


# -- the string's resolution: elements, scheme and step chosen by accuracy (docs/physics.md,
# "The string's resolution") -------------------------------------------------------------------

#: The load-path error of an N-element string, e_N = SPATIAL_ERROR l beta^(3/2) N^(-1/2) (horizon/4 s)
#: with beta = mu l / M the string's mass over the load's: fitted to the protocol's measurements
#: (benchmarks/resolution.py; 1.0 mm at beta = 0.1 and 7.4 mm at beta = 0.4 with N = 1, 0.3 and 3.2 mm with
#: N = 8, on drone_load at EA = 200 N against N = 32 at h/8, over 4 s).
SPATIAL_ERROR = 0.032
#: The protocol's horizon the errors were measured over [s].
PROTOCOL_HORIZON = 4.0
#: Margin under the assembled string's bound (esp_gym/scene/stability.py) where the tension-only law keeps
#: its energy (each slack-to-taut crossing at h omega near 1 pumps energy into the element): over
#: 100 s of the PD law with action noise and of random actions at N = 1, EA = 2e5 to 1e7 N, 0.35 kept
#: the residual at 0.01-0.07 J, 0.5 let it grow to 0.1-0.5 J (benchmarks/resolution.py).
SLACK_SAFETY = 0.35
#: The same margin for the two-sided elastic law (no kink): the environment's.
ELASTIC_SAFETY = 0.5
#: A damped tension-only string whose fastest mode (omega_max = 2/bound) its damper holds at a
#: damping ratio tau omega_max/2 = tau/bound of at least FLICKER_DAMPING takes DAMPED_SAFETY: the
#: flicker that SLACK_SAFETY guards against dies out. Measured over 100 s of the protocol (PD law
#: with noise, random actions) at 0.7 of the bound, EA = 2e5 ... 1e7 N, tau = 0.77 ms (ratios 0.4 to
#: 2.8): within 0.006 J; tau = 0.1 ms at 2e6 N (0.16): 0.001 J; tau = 0.1 ms at 2e5 N (0.05): 0.031 J
#: under random actions, and 0.01 ms (0.005): 0.21 J, as undamped (0.36 J).
FLICKER_DAMPING = 0.15
DAMPED_SAFETY = 0.7
#: A damped string's balance drift (docs/physics.md, "Material damping"): a mode of frequency
#: omega stepped at h keeps its plain step's modified energy, in which the work done on it counts
#: (1 - r) times, r = (h omega)^2/4 <= (h/bound)^2; the damper takes the energy the mode carries
#: through, so E - E0 - W + D drifts by r times the work the mode is fed. The protocol feeds the
#: bounce mode (omega_b^2 = k/m, k = EA/l, m the load's least effective mass) a force held per
#: control period dt of rms DISSIPATION_FORCING m g: a power (F m g)^2 min((omega_b dt)^2/2, 2)/(k dt).
#: F fitted to 100 s of the PD law with noise on drone_load (benchmarks/resolution.py): 0.233 gives
#: the measured drift at EA = 2e4 ... 1e7 N within 5 %, and over-predicts 2e3 N 1.3x and 2e2 N 6x.
DISSIPATION_FORCING = 0.233
#: The drift a damped string may reach over DISSIPATION_HORIZON [s], as a share of the load's weight
#: times the string's length (0.025 J on drone_load, half the protocol's 0.05 J).
DISSIPATION_BUDGET = 0.005
DISSIPATION_HORIZON = 100.0
#: The control period the rule assumes when it is not told one [s] (the environment's default).
PROTOCOL_CONTROL_PERIOD = 0.02
#: A drone's own step error under its sampled rate loop (``pivot.drone.rate_loop_period``: the
#: closed loop is then h's only through the integrator, of order 2), e_q = DRONE_STEP_ERROR g h^2
#: (horizon/PROTOCOL_HORIZON): fitted to the worst of 10 seeds of quadrotor_load's protocol (the
#: geometric cascade with thrust_rates and +-0.5 action noise, 4 s, N = 1, its 800 Hz loop) against
#: 512 steps per 20 ms: 2.50, 0.64, 0.16, 0.04 mm at 16, 32, 64, 128 steps, C_q = 163-167
#: (benchmarks/resolution.py --drone).
DRONE_STEP_ERROR = 170.0
#: The largest N the rule considers; beyond it the accuracy is reported as not met.
MAX_AUTO_ELEMENTS = 256


@dataclass(frozen=True)
class ResolutionChoice:
    """The result of :func:`choose_resolution` (lengths in m, times in s)."""

    elements: int  #: N, the fewest elements whose predicted load error meets the accuracy
    string: str  #: the string's scheme: "explicit"
    h: float  #: the step (dividing ``divides`` when given)
    substeps: Optional[int]  #: steps per ``divides`` (None without it)
    spatial_error: float  #: predicted load-path error of N elements over the horizon
    step_error: float  #: predicted load-path error of the step h over the horizon
    limited_by: str  #: what set h: "stability" (the energy margin under the bound), "dissipation", "accuracy" or "drone"
    reason: str  #: one line for logs
    met: bool = True  #: False when even MAX_AUTO_ELEMENTS elements miss the accuracy

    def scene(self, scene: Scene) -> Scene:
        """``scene`` with this resolution: N, h and the scheme (the string stays marked ``auto``)."""
        data = scene.model_dump()
        data["string"] = {**data["string"], "elements": self.elements, "auto": True}
        data["solver"] = {**data["solver"], "string": self.string}
        return validated(type(scene), {**data, "h": self.h}, repr(scene.name))


def spatial_error(scene: Scene, elements: int, horizon: float) -> float:
    """The predicted load-path error [m] of ``elements`` elements over ``horizon`` [s]:
    SPATIAL_ERROR l beta^(3/2) N^(-1/2) horizon/PROTOCOL_HORIZON, beta = mu l / M."""
    s = scene.string
    beta = s.mass_per_length * s.length / scene.body.mass
    return SPATIAL_ERROR * s.length * beta ** 1.5 / math.sqrt(elements) * horizon / PROTOCOL_HORIZON


def step_error(scene: Scene, h: float, horizon: float) -> float:
    """The predicted load-path error [m] of the step h over ``horizon`` [s]: the phase error of the
    load bouncing on the string, (W/m) h^2/8 per the protocol's horizon, W the weight below the pivot
    and m the load's least effective mass (esp_gym/scene/stability.py): the bounce's amplitude W l/EA times
    (h omega_b)^2/8, omega_b^2 = EA/(l m)."""
    from .stability import attachment_mass
    weight = scene.gravity * (scene.body.mass + scene.string.length * scene.string.mass_per_length)
    return weight / attachment_mass(scene.body) * h * h / 8.0 * horizon / PROTOCOL_HORIZON


def drone_step_error(scene: Scene, h: float, horizon: float) -> float:
    """The predicted error [m] of a drone's own motion stepped at h [s] over ``horizon`` [s],
    DRONE_STEP_ERROR g h^2 horizon/PROTOCOL_HORIZON; 0 without a sampled rate loop
    (:func:`rate_loop_period`), whose error is then the loop's sampling at h, not the step's."""
    if rate_loop_period(scene) is None:
        return 0.0
    return DRONE_STEP_ERROR * scene.gravity * h * h * horizon / PROTOCOL_HORIZON


def accurate_drone_step(scene: Scene, accuracy: float = 5e-3, horizon: float = PROTOCOL_HORIZON) -> float:
    """The largest h [s] whose :func:`drone_step_error` is at most half of ``accuracy`` [m] (inf
    without a drone's sampled rate loop)."""
    unit = drone_step_error(scene, 1.0, horizon)
    return math.inf if unit == 0.0 else math.sqrt(0.5 * accuracy / unit)


def dissipation_power(scene: Scene, control_period: float = PROTOCOL_CONTROL_PERIOD) -> float:
    """The power [W] the protocol's forcing, held per ``control_period`` [s], feeds a damped
    string's bounce mode: (F m g)^2 min((omega_b dt)^2/2, 2)/(k dt) (0 for an undamped string)."""
    from .stability import attachment_mass
    s = scene.string
    if not s.damped:
        return 0.0
    m, stiffness = attachment_mass(scene.body), s.EA / s.length
    swing = stiffness / m * control_period * control_period  # (omega_b dt)^2
    return (DISSIPATION_FORCING * m * scene.gravity) ** 2 * min(swing / 2.0, 2.0) / (stiffness * control_period)


def dissipation_drift(scene: Scene, h: float, control_period: float = PROTOCOL_CONTROL_PERIOD) -> float:
    """The predicted |E - E0 - W + D| [J] of a damped string stepped at h [s] over
    DISSIPATION_HORIZON: (h/bound)^2 times the work :func:`dissipation_power` feeds it."""
    return (h / scene.stability_bound) ** 2 * dissipation_power(scene, control_period) * DISSIPATION_HORIZON


def dissipation_safety(scene: Scene, control_period: float = PROTOCOL_CONTROL_PERIOD) -> float:
    """The largest h/bound whose :func:`dissipation_drift` is within DISSIPATION_BUDGET of the
    load's weight times the string's length (inf for an undamped string)."""
    fed = dissipation_power(scene, control_period) * DISSIPATION_HORIZON
    if fed == 0.0:
        return math.inf
    return math.sqrt(DISSIPATION_BUDGET * scene.body.mass * scene.gravity * scene.string.length / fed)


def law_safety(scene: Scene) -> float:
    """The margin under the stability bound where the string's law keeps its energy: SLACK_SAFETY
    (tension-only), DAMPED_SAFETY (tension-only, its fastest mode damped at a ratio of at least
    FLICKER_DAMPING) or ELASTIC_SAFETY."""
    s = scene.string
    if s.law != "slack":
        return ELASTIC_SAFETY
    return DAMPED_SAFETY if s.damping_time >= FLICKER_DAMPING * scene.stability_bound else SLACK_SAFETY


def resolution_safety(scene: Scene, control_period: float = PROTOCOL_CONTROL_PERIOD) -> float:
    """The rule's margin under the stability bound: :func:`law_safety`, and for a damped string at
    most :func:`dissipation_safety` (its balance drift)."""
    return min(law_safety(scene), dissipation_safety(scene, control_period))


def rate_loop_divided(scene: Scene, h: float, divides: Optional[float]) -> tuple:
    """:func:`divided` with a drone's rate loop: ``(h, substeps)``, the largest step at most ``h`` [s]
    that divides the rate-loop period (:func:`rate_loop_period`) and ``divides`` [s]."""
    period = rate_loop_period(scene)
    if period is None:
        return divided(h, divides)
    h, _ = divided(h, period)
    return h, None if divides is None else rate_loop_substeps(scene, divides, int(round(divides / h)))


def auto_elements(scene: Scene, accuracy: float = 5e-3, horizon: float = PROTOCOL_HORIZON) -> int:
    """The fewest elements whose predicted error (:func:`spatial_error`, falling as N^(-1/2)) is at
    most half of ``accuracy`` [m] over ``horizon`` [s], at most MAX_AUTO_ELEMENTS."""
    wanted = (spatial_error(scene, 1, horizon) / (0.5 * accuracy)) ** 2
    return min(MAX_AUTO_ELEMENTS, max(1, math.ceil(wanted - 1e-9)))


def accurate_step(scene: Scene, accuracy: float = 5e-3, horizon: float = PROTOCOL_HORIZON) -> float:
    """The largest h [s] whose predicted error (:func:`step_error`) is at most half of ``accuracy``."""
    return math.sqrt(0.5 * accuracy / step_error(scene, 1.0, horizon))


def choose_resolution(scene: Scene, accuracy: float = 5e-3, horizon: float = PROTOCOL_HORIZON,
                      divides: Optional[float] = None, safety: Optional[float] = None) -> ResolutionChoice:
    """The string's resolution for a load-path ``accuracy`` [m] over ``horizon`` [s]: the fewest
    elements N whose predicted error (:func:`spatial_error`) is at most half of it, then the
    largest h under ``safety`` x the assembled string's bound at that N (default
    :func:`resolution_safety`: the law's energy, and a damped string's balance drift with
    ``divides`` its control period) whose
    predicted error (:func:`step_error`, and a drone's own, :func:`drone_step_error`) is at most the
    other half, rounded down to divide a drone's rate-loop period and ``divides`` [s] (a control
    period) when given. The explicit string (docs/physics.md, "The
    string's resolution", for why not the implicit one). Deterministic, and monotone: a tighter
    accuracy never gets fewer elements or a longer step.

    >>> scene = load_scene("drone_load", EA=2e5, allow_unstable_h=True)
    >>> sim = Simulator(choose_resolution(scene, divides=0.02).scene(scene))
    """
    accuracy, horizon, divides, safety = checked_targets(accuracy, horizon, divides, safety)
    period = PROTOCOL_CONTROL_PERIOD if divides is None else divides
    base = scene.model_copy(update={"solver": scene.solver.model_copy(update={"string": "explicit"}),
                                    "allow_unstable_h": True})
    elements = auto_elements(base, accuracy, horizon)
    at_n = base.model_copy(update={"string": base.string.model_copy(update={"elements": elements})})
    margin = "stability"
    if safety is None:  # a damped string's drift may set the margin, not the law's energy
        safety = resolution_safety(at_n, period)
        margin = "dissipation" if safety < law_safety(at_n) else margin
    h_stable = safety * at_n.stability_bound
    h_accurate = accurate_step(at_n, accuracy, horizon)
    h_drone = accurate_drone_step(at_n, accuracy, horizon)
    h, limited = min((h_stable, margin), (h_accurate, "accuracy"), (h_drone, "drone"))
    h, substeps = rate_loop_divided(at_n, h, divides)
    e_space, e_step = spatial_error(at_n, elements, horizon), step_error(at_n, h, horizon)
    met = e_space <= 0.5 * accuracy * (1 + 1e-12)
    reason = (f"N = {elements}, explicit, h = {h:.4g} s ({limited}): predicted load error {e_space:.2g} m "
              f"(elements) + {e_step:.2g} m (step) over {horizon:g} s"
              + ("" if met else f" (accuracy {accuracy:g} m not met: N is capped at {MAX_AUTO_ELEMENTS})"))
    return ResolutionChoice(elements, "explicit", h, substeps, e_space, e_step, limited, reason, met)
