"""What a scene is read from, checked before it becomes a :class:`~esp_gym.scene.params.Scene`: YAML
files, overrides, and the rules for a single number. Every failure is a :class:`SceneError`
naming the file, the override or the field, never a parser's traceback.

* **Numbers** (:data:`Real`, :data:`Count`): strict. A bool or a string where a number belongs
  is an error (lax validation turned ``EA: yes`` into 1.0 and ``EA: "40"`` into 40.0); an int
  is a float's value. Each kind of number has a range (:data:`BOUNDS`).
* **Files** (:func:`read_scene_file`): PyYAML's safe loader, with numbers as YAML 1.2 reads them
  (an unquoted ``1e-4`` is a number; YAML 1.1 reads it as text), duplicate keys refused with the
  key and both lines, and a size limit (:data:`MAX_SCENE_BYTES`) checked before reading.
  Binary content, bad encodings, syntax errors, nesting too deep for the parser and unreadable
  files (permissions, directories) are errors naming the file.
* **Overrides** (:func:`merge_overrides`): one merge for files and for scenes already built.

docs/scenes.md has the rules and the bounds.
"""
from __future__ import annotations

import copy
import math
import os
import re
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import yaml
from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, Strict, ValidationError

#: Largest scene file read [bytes]: a scene with explicit node rows for 100,000 elements is ~6 MB.
MAX_SCENE_BYTES = 16 * 2**20
#: Suffixes of a scene file, compared without case (``.YAML`` is a YAML file).
YAML_SUFFIXES = (".yaml", ".yml")


class SceneError(ValueError):
    """A scene failed validation or could not be read; the message names each bad field and
    the rule it breaks, or the file and what is wrong with it."""


# -- numbers ----------------------------------------------------------------------------------------

#: The range of each kind of scene number [SI]: wide enough for any tethered load (a 100 km
#: tether, a 1e9 kg ship, a steel bar's EA, 100 g, orbital speeds), narrow enough that the energy
#: at t = 0 and the stepper's constants (element stiffness and mass, the inverse mass matrix,
#: J_eff^-1, the blow-up guard's squared length) are finite: tests/test_params.py builds and
#: steps a scene at the corners. docs/scenes.md lists the fields of each kind.
BOUNDS = {
    "length": (1e-6, 1e5),           # string.length, shape sizes [m]
    "coordinate": (-1e5, 1e5),       # pivot.position, body.rho_c, initial.nodes, per component [m]
    "mass": (1e-9, 1e9),             # body.mass, pivot.mass [kg]
    "mass_per_length": (1e-9, 1e6),  # string.mass_per_length [kg/m]
    "EA": (1e-6, 1e12),              # string.EA [N]
    "inertia": (-1e12, 1e12),        # body.inertia, per entry [kg m^2]
    "gravity": (0.0, 1e3),           # gravity [m/s^2]
    "speed": (-1e4, 1e4),            # pivot.velocity, initial.*velocit*, per component [m/s]
    "angular_speed": (-1e4, 1e4),    # initial.Omega0, per component [rad/s]
    "stretch": (1e-6, 1e6),          # initial.stretch, solver.max_stretch [rest lengths]
    "elements": (1, 10**15),         # string.elements (memory is checked when a Simulator is built)
    "time": (0.0, 1e3),              # string.damping_time [s]
}


def plain_number(value: Any) -> Any:
    """A number stays a number (NumPy scalars become Python's); a bool or text is refused, with
    a clearer message than the strict type's."""
    if isinstance(value, (bool, np.bool_, str, bytes)):
        raise ValueError(f"must be a number, not {type(value).__name__} {value!r}")
    return value.item() if isinstance(value, np.generic) else value


def real_number(name: str, value: Any, positive: bool = False) -> float:
    """``value`` as a float, for arguments outside a scene (a reel speed, an accuracy): ValueError
    naming ``name`` unless it is a real number (not a bool or text) that is finite, and > 0 when
    ``positive``."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name} must be a real number [SI], got {value!r}")
    value = float(value)
    if not math.isfinite(value) or (positive and value <= 0.0):
        raise ValueError(f"{name} must be finite{' and positive' if positive else ''}, got {value!r}")
    return value


def _sequence(value: Any) -> Any:
    """Vectors are ordered: a list, a tuple or an array, not a set, a mapping or text."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"must be a list of numbers, not {type(value).__name__}")
    return value


#: A real number: int or float (NumPy's too), never a bool or a string
Real = Annotated[float, BeforeValidator(plain_number), Strict()]
#: A whole number: int (NumPy's too), never a bool, a float or a string
Count = Annotated[int, BeforeValidator(plain_number), Strict()]
#: true or false (NumPy's too), never 1, "yes" or "true"
Flag = Annotated[bool, BeforeValidator(lambda v: bool(v) if isinstance(v, np.bool_) else v), Strict()]


class Frozen(BaseModel):
    """A scene section: immutable, no unknown keys, no inf or NaN."""

    model_config = ConfigDict(frozen=True, extra="forbid", allow_inf_nan=False)


def bounded(kind: str, **field: Any) -> Any:
    """A field whose value lies in the range of :data:`BOUNDS` ``kind`` (ends included)."""
    lo, hi = BOUNDS[kind]
    return Field(ge=lo, le=hi, **field)


def vector(kind: str = "", n: int = 3) -> Any:
    """A list of ``n`` reals, each in :data:`BOUNDS` ``kind`` (any finite value without one)."""
    item = Annotated[Real, bounded(kind)] if kind else Real
    return Annotated[tuple[(item,) * n], BeforeValidator(_sequence)]


def matrix(kind: str = "") -> Any:
    """A 3 x 3 matrix: three rows of :func:`vector`."""
    return Annotated[tuple[(vector(kind),) * 3], BeforeValidator(_sequence)]


def is_yaml_path(path: str | os.PathLike) -> bool:
    """True if ``path`` ends in .yaml or .yml, in any case."""
    return Path(path).suffix.lower() in YAML_SUFFIXES


#: pydantic error types of a number outside its range: the message points to the bounds
_RANGE_ERRORS = {"greater_than", "greater_than_equal", "less_than", "less_than_equal"}


def validation_message(err: ValidationError, source: str) -> str:
    """A scene's validation errors, one line each: the field's dotted path and the rule."""
    lines = [f"invalid scene {source}:"]
    for e in err.errors():
        loc = ".".join(str(x) for x in e["loc"])
        msg = e["msg"].removeprefix("Value error, ")
        if e["type"] == "extra_forbidden":
            msg = "unknown key"
        elif e["type"] in _RANGE_ERRORS:
            msg += f", got {e['input']!r} (the bounds of a scene: docs/scenes.md)"
        # scene-level rules (h vs the bound, row counts) name their field in the message
        lines.append(f"  {loc}: {msg}" if loc else f"  {msg}")
    return "\n".join(lines)


def validated(model: type, data: Any, source: str):
    """``model`` (a scene's pydantic class) validated from a plain dict, raising :class:`SceneError`
    with :func:`validation_message` on bad input."""
    try:
        return model.model_validate(data)
    except ValidationError as err:
        raise SceneError(validation_message(err, source)) from None
    except RecursionError:
        raise SceneError(f"invalid scene {source}: nested too deeply to be a scene") from None


# -- files ------------------------------------------------------------------------------------------

#: YAML 1.2 floats that YAML 1.1 reads as text: an exponent without a dot (1e-4) or without a
#: sign (1.0e4). The 1.1 forms (1.0e-4, 0.5, .inf) keep PyYAML's own resolver.
_FLOAT_12 = re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$")


class SceneLoader(yaml.SafeLoader):
    """PyYAML's safe loader, with YAML 1.2 exponent floats and duplicate keys refused."""

    def construct_mapping(self, node, deep=False):
        if isinstance(node, yaml.MappingNode):
            first = {}
            for key_node, _ in node.value:  # the mapping's own keys; merged ones (<<) may be overridden
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=True)
                try:
                    seen = first.setdefault(key, key_node.start_mark)
                except TypeError:  # unhashable: the safe loader reports it
                    continue
                if seen is not key_node.start_mark:
                    raise yaml.constructor.ConstructorError(
                        None, None, f"duplicate key {key!r} (first given on line {seen.line + 1})",
                        key_node.start_mark)
        return super().construct_mapping(node, deep=deep)


SceneLoader.add_implicit_resolver("tag:yaml.org,2002:float", _FLOAT_12, list("-+0123456789."))


def _where(mark) -> str:
    return "" if mark is None else f" at line {mark.line + 1}, column {mark.column + 1}"


def yaml_problem(err: yaml.YAMLError) -> str:
    """One line saying what is wrong with a YAML text and where."""
    if isinstance(err, yaml.reader.ReaderError):
        decoding = err.encoding not in (None, "unicode")  # the reader says "unicode" once the text is decoded
        what = (f"not {err.encoding} text (byte #x{err.character:02x}" if decoding
                else f"a character YAML does not allow (#x{err.character:04x}")
        return f"{what} at offset {err.position}: {err.reason}); a scene is a YAML text file"
    if isinstance(err, yaml.MarkedYAMLError):
        context = f" (while {err.context.removeprefix('while ')}{_where(err.context_mark)})" if err.context else ""
        return f"YAML error: {err.problem}{_where(err.problem_mark)}{context}"
    return f"YAML error: {err}"


def read_scene_file(path: str | os.PathLike) -> dict:
    """The mapping a scene file holds (a new dict), or :class:`SceneError` naming the file and
    the problem: unreadable, too large, not UTF-8 text, not YAML, duplicate keys, nested too
    deeply, or not a mapping."""
    path = Path(path)
    try:
        size = os.stat(path).st_size
        if size > MAX_SCENE_BYTES:
            raise SceneError(f"scene file {path}: {size:,} bytes, more than a scene needs "
                             f"(at most {MAX_SCENE_BYTES:,})")
        with open(path, "rb") as fh:
            text = fh.read(MAX_SCENE_BYTES + 1)
    except OSError as err:
        raise SceneError(f"cannot read scene file {path}: {err.strerror or err}") from None
    try:
        data = yaml.load(text, Loader=SceneLoader)
    except yaml.YAMLError as err:
        raise SceneError(f"invalid scene file {path}: {yaml_problem(err)}") from None
    except UnicodeDecodeError as err:  # the reader reports bad encodings itself; kept as a net
        raise SceneError(f"invalid scene file {path}: not UTF-8 text ({err.reason})") from None
    except RecursionError:
        raise SceneError(f"invalid scene file {path}: nested too deeply to be a scene") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise SceneError(f"invalid scene file {path}: it must hold a mapping of scene fields, "
                         f"not a {type(data).__name__}")
    return data


# -- overrides --------------------------------------------------------------------------------------

#: Short names of overrides (:func:`merge_overrides`).
ALIASES = {
    "N": "string.elements",
    "EA": "string.EA",
    "length": "string.length",
    "M": "body.mass",
    "J": "body.inertia",
    "rho_c": "body.rho_c",
    "g": "gravity",
}


def _set_dotted(data: dict, dotted: str, value: Any, replaced: Collection[str], prefix: str = "") -> None:
    keys = dotted.split(".")
    node = data
    for key in keys[:-1]:
        child = node.get(key)
        if child is None:
            child = node[key] = {}
        if not isinstance(child, dict):
            raise SceneError(f"override {prefix + dotted!r}: {key!r} is not a section")
        node = child
    old, path = node.get(keys[-1]), prefix + dotted
    if isinstance(value, Mapping) and isinstance(old, dict) and not (
            path in replaced and value.get("kind", old.get("kind")) != old.get("kind")):
        merged = dict(old)
        for k, v in value.items():
            if not isinstance(k, str):
                raise SceneError(f"override {path!r}: its keys must be strings, got {k!r}")
            _set_dotted(merged, k, v, replaced, path + ".")
        node[keys[-1]] = merged
    else:
        node[keys[-1]] = value


def merge_overrides(data: Mapping, overrides: Mapping[str, Any], fields: Collection[str],
                    replaced: Collection[str] = ()) -> dict:
    """A new dict: the scene ``data`` with ``overrides`` applied. An override is a top-level
    field (``h``), a section merged key by key (``string={"EA": 80}``), a dotted path
    (``"body.mass"``) or an alias (:data:`ALIASES`); its first part must be one of ``fields``
    (the scene's). A section in ``replaced`` (a choice of kinds with different fields, such as
    the body's shape) is replaced, not merged, by a mapping of another ``kind``. Nothing is
    validated here but the override names."""
    try:
        data = copy.deepcopy(dict(data))
    except RecursionError:
        raise SceneError("the scene is nested too deeply to be a scene") from None
    for key, value in overrides.items():
        dotted = ALIASES.get(key, key) if isinstance(key, str) else ""
        if dotted.split(".")[0] not in fields:
            raise SceneError(f"unknown override {key!r}: use a scene field {sorted(fields)}, a dotted path "
                             f"or one of {sorted(ALIASES)}")
        _set_dotted(data, dotted, value, replaced)
    return data
