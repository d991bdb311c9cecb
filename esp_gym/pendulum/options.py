"""The environments' arguments, validated in one place (pydantic): the single env, both vector
envs and the recording wrapper build their setup from :class:`EnvOptions`, the team's envs from
:class:`TeamOptions`; what both take is :class:`CommonOptions`, checked alike. The batch size goes
through :func:`check_count`, the physics steps a control step needs through :func:`check_substeps`.

Numbers are checked, not coerced: a bool or a string where a number belongs is an error (lax
validation would turn ``True`` into 1.0 and ``"0.02"`` into 0.02), as are NaN, infinities and a
fractional count. Every error names the argument.
"""
from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, ValidationError, ValidationInfo, field_validator

from .. import ENV_ID, TEAM_ENV_ID
from ..scene.params import Scene
from ..scene.scene_input import Flag, Real, plain_number

#: Physics steps per control step above which the environment refuses to start: past this a
#: single ``step`` costs tens of milliseconds or more (0.33 us per physics step at N = 20).
MAX_SUBSTEPS = 100_000
#: The longest action latency [control steps] (a second at the default 50 Hz).
MAX_LATENCY = 50
#: The largest pivot force at action 1, in hover forces (the weight a pivot holds up): far past
#: any crane or drone (a racing drone lifts 5-10 times its weight); 1e300 overflowed the first step.
MAX_FORCE_SHARE = 1000.0


#: A count: a whole number (an integral float such as 2.0 counts), never a bool or text. Real
#: numbers are the scenes' (scene_input.Real).
Count = Annotated[int, BeforeValidator(plain_number)]


#: The ``actuation`` names: a point pivot's force, a drone's thrust and torque, thrust and rates, motors.
ACTUATION_CHOICES = ("force", "thrust_torque", "thrust_rates", "motors")


class CommonOptions(BaseModel):
    """The arguments both ElasticStringPendulum-v0 (:class:`EnvOptions`) and ElasticStringTeam-v0
    (:class:`TeamOptions`) take, with the same meaning and the same checks."""

    model_config = ConfigDict(extra="forbid", frozen=True, arbitrary_types_allowed=True)

    control_period: Real = Field(0.02, gt=0, allow_inf_nan=False, description="seconds per step")
    #: False, True or name -> (low, high): checked by esp_gym/pendulum/randomize.py (no coercion here)
    randomize: Any = False
    observation: Literal["full", "hook"] = "full"
    #: a level or field -> standard deviation: checked by esp_gym/pendulum/observe.py
    sensor_noise: Any = 0.0
    action_latency: Count = Field(0, ge=0, le=MAX_LATENCY, description="control steps")
    #: a speed or a mapping: checked by esp_gym/pendulum/wind.py
    wind: Any = 0.0
    preset: Optional[Literal["hard"]] = None
    #: None: as the task needs (lift, lower)
    winch: Optional[Flag] = None
    #: None: the pivot's ("force" for a free point mass, "thrust_rates" for a drone)
    actuation: Optional[Literal[ACTUATION_CHOICES]] = None
    #: the automatic h's margin under the stability bound (a fraction); None: each env's default
    safety: Optional[Real] = Field(None, gt=0, le=1, allow_inf_nan=False)


class EnvOptions(CommonOptions):
    """Arguments of ElasticStringPendulum-v0 (see :class:`~esp_gym.pendulum.env.ElasticStringPendulumEnv`)."""

    scene: Union[Scene, Path, str] = "drone_load"
    task: str = "stabilize"
    h: Optional[Real] = Field(None, gt=0, allow_inf_nan=False, description="physics step [s]")
    force_limit: Optional[Real] = Field(None, gt=0, allow_inf_nan=False, description="[N] at action 1")
    torque_limit: Real = Field(0.02, ge=0, allow_inf_nan=False, description="[N m] at action 1")
    scene_overrides: Optional[dict] = None
    #: True: the targets move along a track reference (lift); None: the task's own, or its preset's
    moving_target: Optional[Flag] = None
    #: a drone's: each rotor's thrust times 1 + this x N(0, 1), drawn per control step
    thrust_noise: Real = Field(0.0, ge=0, le=0.5, allow_inf_nan=False, description="relative")


#: ElasticStringPendulum-v0's arguments that a team does not take, and why (the message after the name).
TEAM_LACKS = {
    "scene": "a team's rig is its team argument: a number of strings or a TeamScene",
    "scene_overrides": "a team's rig is its team argument: build a TeamScene with the values wanted",
    "h": "a team chooses its own physics step: the largest within safety (default 0.5) x every string's stability "
         "bound that divides control_period",
    "torque_limit": "a team's point pivots push without turning the load (a drone team's torques are its actuation's)",
    "thrust_noise": "a team's drones fly on noiseless rotors for now",
    "moving_target": "a team's lift holds its target for now; task 'track' moves the target",
}


class TeamOptions(CommonOptions):
    """Arguments of ElasticStringTeam-v0 but the team and the task (see
    :class:`~esp_gym.team.core.TeamCore`); the names of :data:`TEAM_LACKS` are refused with the reason."""

    force_limit: Real = Field(0.6, gt=0, le=MAX_FORCE_SHARE, allow_inf_nan=False,
                              description="each pivot's force at action 1, in its hover forces")
    scene: Any = None
    scene_overrides: Any = None
    h: Any = None
    torque_limit: Any = None
    thrust_noise: Any = None
    moving_target: Any = None

    @field_validator(*TEAM_LACKS)
    @classmethod
    def _not_for_a_team(cls, value: Any, info: ValidationInfo) -> Any:
        if value is not None:
            raise ValueError(TEAM_LACKS[info.field_name])
        return value


def validation_message(error: ValidationError, what: str) -> str:
    """One line per bad argument: ``what: name: problem (got value)``."""
    lines = []
    for e in error.errors():
        name = ".".join(str(p) for p in e["loc"]) or "arguments"
        got = e.get("input")
        detail = e["msg"].replace("Value error, ", "")
        lines.append(f"{what}: {name}: {detail} (got {got!r})" if e["type"] != "extra_forbidden"
                     else f"{what}: unknown argument {name!r}")
    return "\n".join(lines)


def env_options(**kwargs: Any) -> EnvOptions:
    """:class:`EnvOptions` from keyword arguments; ValueError naming each bad one."""
    try:
        return EnvOptions(**kwargs)
    except ValidationError as e:
        raise ValueError(validation_message(e, ENV_ID)) from None


def team_options(**kwargs: Any) -> TeamOptions:
    """:class:`TeamOptions` from keyword arguments; ValueError naming each bad one."""
    try:
        return TeamOptions(**kwargs)
    except ValidationError as e:
        raise ValueError(validation_message(e, TEAM_ENV_ID)) from None


def check_substeps(env_id: str, control_period: float, how: str, substeps: float, remedy: str) -> None:
    """ValueError unless ``substeps`` physics steps per control step (``how`` they were chosen)
    stay within :data:`MAX_SUBSTEPS`; ``remedy``: what the user can change."""
    if substeps > MAX_SUBSTEPS:
        raise ValueError(f"{env_id}: control_period = {control_period} s with {how} needs {substeps:.3g} physics "
                         f"steps per step (at most {MAX_SUBSTEPS:,}): {remedy}")


class _Count(BaseModel):
    value: Count = Field(ge=1)


def check_count(name: str, value: Any) -> int:
    """``value`` as an int >= 1 (a number of environments, steps, ...): ValueError naming
    ``name`` for a fraction, a bool, a string or anything below 1."""
    try:
        return _Count(value=value).value
    except ValidationError as e:
        detail = e.errors()[0]["msg"].replace("Value error, ", "")
        raise ValueError(f"{name} must be a whole number >= 1: {detail} (got {value!r})") from None
