"""Fuzzed scenes (issue 12): whatever a scene dict, an override or a scene file holds, loading it
gives a valid Scene or a SceneError with a message, never another exception.

Examples are few (each test a few seconds at most) and, under `make test`, derandomized
(tests/conftest.py), so CI sees the same ones on every run; `make fuzz` draws fresh ones.
"""
import math

import numpy as np
import yaml
from hypothesis import HealthCheck, given, settings, strategies as st

from esp_gym.scene.params import ALIASES, SCENES_DIR, Scene, SceneError, load_scene, override_scene, scene_from_dict

FUZZ = settings(deadline=None, max_examples=300,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

BASE = load_scene("paper_example").model_dump(mode="json")
FIELDS = [(section, key) for section, value in BASE.items() if isinstance(value, dict) for key in value]
PATHS = [(key,) for key in BASE] + FIELDS + [("colour",), ("string", "colour"), ("body", "shape", "kind"),
                                             ("body", "shape", "radius"), ("pivot", "mass")]

#: Plausible numbers, the edges of float64 and values of the wrong type.
numbers = st.one_of(st.floats(-3, 3), st.floats(), st.integers(-5, 30), st.integers(), st.sampled_from(
    [0, 1e-300, 5e-324, 1e300, -1e300, 1.7976931348623157e308, 10**400, 1e-6, 1e5, 1e12, 1e3 + 1e-9]))
wrong = st.one_of(st.none(), st.booleans(), st.text(max_size=6), st.binary(max_size=4), st.sampled_from(
    ["40", "1e-4", "yes", "nan", "elastic", "slack", "free", "fixed", "box", "sphere", "lumped", "triple_jump"]))
scalars = st.one_of(numbers, wrong, st.builds(np.float64, st.floats()), st.builds(np.int64, st.integers(-9, 9)))
keys = st.one_of(st.sampled_from(["kind", "size", "radius", "mass", "EA", "position", "velocity", "x"]),
                 st.text(max_size=4))
values = st.recursive(scalars, lambda inner: st.one_of(
    st.lists(inner, max_size=4), st.tuples(inner, inner, inner), st.dictionaries(keys, inner, max_size=3)),
    max_leaves=10)


def _outcome(load):
    """Run ``load``: a Scene, or a SceneError with a message that says something."""
    try:
        scene = load()
    except SceneError as err:
        assert str(err).strip(), "an empty SceneError"
        return err
    assert isinstance(scene, Scene)
    return scene


def _set(data: dict, path: tuple, value) -> None:
    node = data
    for key in path[:-1]:
        if not isinstance(node.get(key), dict):
            node[key] = {}
        node = node[key]
    node[path[-1]] = value


@FUZZ
@given(changes=st.lists(st.tuples(st.sampled_from(PATHS), values), min_size=1, max_size=4))
def test_a_fuzzed_scene_dict_is_a_scene_or_a_scene_error(changes):
    data = yaml.safe_load(yaml.safe_dump(BASE))  # a deep copy
    for path, value in changes:
        _set(data, path, value)
    _outcome(lambda: scene_from_dict(data, source="fuzz"))


@FUZZ
@given(scale=st.sampled_from(PATHS), factor=st.sampled_from([0.0, -1.0, 1e-300, 1e-9, 1e9, 1e300, math.inf]))
def test_a_scaled_field_is_a_scene_or_a_scene_error(scale, factor):
    """Plausible values pushed to implausible sizes, keeping their types (lists stay lists)."""
    data = yaml.safe_load(yaml.safe_dump(BASE))
    node = data
    for key in scale[:-1]:
        node = node.get(key) if isinstance(node.get(key), dict) else {}
    old = node.get(scale[-1])
    if isinstance(old, (int, float, list)) and not isinstance(old, bool):
        with np.errstate(invalid="ignore"):  # inf * 0 is a NaN: one of the values to try
            node[scale[-1]] = (np.asarray(old, dtype=float) * factor).tolist()
    scene = _outcome(lambda: scene_from_dict(data, source="fuzz"))
    if isinstance(scene, Scene):  # an accepted scene has finite derived constants
        assert math.isfinite(scene.stability_bound) and np.all(np.isfinite(scene.initial_nodes()))


override_keys = st.one_of(st.sampled_from(sorted(ALIASES)), st.sampled_from([".".join(p) for p in PATHS]),
                          st.sampled_from(["", ".", "string.", "h.x", "initial.nodes.0", "body..mass"]),
                          st.text(max_size=6))


@FUZZ
@given(overrides=st.dictionaries(override_keys, values, min_size=1, max_size=3), scene_object=st.booleans())
def test_fuzzed_overrides_are_a_scene_or_a_scene_error(overrides, scene_object):
    """The same for overrides, of a file by name and of a Scene object (one merge for both)."""
    if scene_object:
        _outcome(lambda: override_scene(load_scene("paper_example"), overrides))
    else:
        _outcome(lambda: load_scene("paper_example", **overrides))


PAPER_TEXT = (SCENES_DIR / "paper_example.yaml").read_bytes()


@FUZZ
@given(edit=st.one_of(
    st.binary(max_size=64),
    st.text(alphabet=st.characters(codec="utf-8"), max_size=64).map(str.encode),
    st.tuples(st.integers(0, len(PAPER_TEXT)), st.integers(0, 40), st.binary(max_size=8)).map(
        lambda t: PAPER_TEXT[:t[0]] + t[2] + PAPER_TEXT[t[0] + t[1]:]),
    st.lists(st.sampled_from(["[", "{", "a: ", "- ", "&x ", "*x ", "!!binary ", "<<: ", "? ", "\t", "'", '"',
                              "\n", "h: 1e-4", "h: 1", "1", ","]), max_size=30).map(lambda t: "".join(t).encode()),
))
def test_a_fuzzed_scene_file_is_a_scene_or_a_scene_error_naming_it(tmp_path_factory, edit):
    """Random bytes, random text, the paper's file with random bytes spliced in and YAML syntax
    soup: every file loads or raises a SceneError, and a file that cannot be parsed is named."""
    path = tmp_path_factory.mktemp("fuzz") / "scene.yaml"
    path.write_bytes(edit)
    outcome = _outcome(lambda: load_scene(path))
    if isinstance(outcome, SceneError) and not str(outcome).startswith("invalid scene '"):
        assert str(path) in str(outcome)
