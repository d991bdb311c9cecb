"""Every validation rule of a scene raises a SceneError that names the field and the rule."""
import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

import esp_gym
from esp_gym.scene.params import BOUNDS, SCENES_DIR, SceneError, load_scene, override_scene, scene_from_dict
from esp_gym.scene.pivot_params import DRONE_REACH, MAX_RATE_GAIN


@pytest.mark.parametrize("overrides, needle", [
    ({"string": {"length": 0.0}}, "string.length"),
    ({"string": {"mass_per_length": -1.0}}, "string.mass_per_length"),
    ({"EA": 0.0}, "string.EA"),
    ({"N": 0}, "string.elements"),
    ({"N": 2.5}, "string.elements"),
    ({"M": 0.0}, "body.mass"),
    ({"h": 0.0}, "h"),
    ({"h": -1e-4}, "h"),
    ({"g": -9.81}, "gravity"),
    ({"g": float("nan")}, "gravity"),
    ({"J": [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]}, "symmetric"),
    ({"J": [[1, 0, 0], [0, -1, 0], [0, 0, 1]]}, "positive definite"),
    ({"J": [[1, 0, 0], [0, 1, 0], [0, 0, 3]]}, "triangle inequality"),
    ({"J": [[1, 0, 0], [0, 1, 0]]}, "body.inertia"),
    ({"rho_c": [0.1, 0.2]}, "body.rho_c"),
    ({"string": {"colour": "red"}}, "string.colour: unknown key"),
    ({"wind": 3.0}, "unknown override 'wind'"),
    ({"initial": {"R0": [[1, 0, 0], [0, 1, 0], [0, 0, -1]]}}, "initial.R0"),
    ({"initial": {"nodes": [[0, 0, 0], [1, 0, 0]]}}, "initial.nodes needs N+1 = 21 rows"),
    ({"initial": {"direction": [0, 0, 0]}}, "initial.direction"),
    ({"pivot": {"kind": "floating"}}, "pivot.kind"),
    ({"solver": {"newton_tol": 1e-3}}, "solver.newton_tol"),
    ({"pivot": {"kind": "free"}}, "pivot.mass > 0"),
    ({"pivot": {"kind": "free", "mass": -1.0}}, "pivot.mass"),
    ({"pivot": {"mass": 0.5}}, "belong to a free pivot"),
    ({"string": {"law": "rubber"}}, "string.law"),
])
def test_bad_field_is_named(overrides, needle):
    with pytest.raises(SceneError) as err:
        load_scene("paper_example", **overrides)
    assert needle in str(err.value)


def test_h_above_stability_bound_states_the_bound():
    scene = load_scene("paper_example")
    assert scene.string.element_bound == pytest.approx(7.2169e-4, rel=1e-4)  # docs/physics.md: 7.22e-4 s
    assert scene.stability_bound == pytest.approx(7.2836e-4, rel=1e-4)  # the assembled string's: 7.28e-4 s
    with pytest.raises(SceneError, match=r"h = 0\.001 s exceeds the stability bound h_max = 0\.00072836 s "
                                         r"\(2/omega_max of the assembled string, N = 20\)"):
        load_scene("paper_example", h=1e-3)
    assert load_scene("paper_example", h=1e-3, allow_unstable_h=True).h == 1e-3


def test_unknown_scene_lists_the_known_ones():
    with pytest.raises(SceneError, match="paper_example"):
        load_scene("no_such_scene")


def test_scene_is_immutable_and_matches_the_paper():
    s = load_scene("paper_example")
    with pytest.raises(Exception):
        s.h = 1.0
    assert (s.string.length, s.string.mass_per_length, s.string.EA, s.string.elements) == (1.0, 0.025, 40.0, 20)
    assert s.body.mass == 0.1 and s.body.rho_c == (0.04, 0.01, 0.05)
    assert s.body.inertia[0] == (0.38, -0.04, -0.20) and s.h == 1e-4
    assert s.initial.attach_velocity == (0.0, 0.2, -0.5)
    np.testing.assert_array_equal(s.initial_nodes()[:, 0], np.linspace(0, 1, 21))


def test_yaml_path_and_dotted_overrides(tmp_path):
    src = load_scene("paper_example").model_dump()
    import yaml

    path = tmp_path / "mine.yaml"
    path.write_text(yaml.safe_dump(src))
    s = load_scene(path, **{"body.mass": 0.2, "string": {"EA": 80.0}})
    assert s.body.mass == 0.2 and s.string.EA == 80.0 and s.string.length == 1.0


def _is_inertia(A, rel=1e-9):
    """Eigenvalue test of an inertia: positive, and the principal moments obey the triangle
    inequality. Returns None within ``rel`` of either boundary (left to the validator)."""
    lam = np.linalg.eigvalsh(A)
    tol = rel * max(1.0, np.abs(A).max())
    margin = min(lam[0], lam[0] + lam[1] - lam[2])
    return None if abs(margin) <= tol else margin > 0


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1, 1, allow_nan=False), min_size=6, max_size=6))
def test_random_inertia_is_accepted_or_named(vals):
    """A symmetric matrix is either a valid inertia about the attachment point, whose
    centre-of-mass part J - M (|rho|^2 I - rho rho^T) is an inertia too, or it is rejected as
    body.inertia: nothing else."""
    a, b, c, d, e, f = vals
    J = np.array([[a, d, e], [d, b, f], [e, f, c]])
    base = load_scene("paper_example").body
    rho = np.array(base.rho_c)
    J_cm = J - base.mass * (rho @ rho * np.eye(3) - np.outer(rho, rho))
    verdicts = (_is_inertia(J), _is_inertia(J_cm))
    assume(None not in verdicts)
    if all(verdicts):
        assert load_scene("paper_example", J=J.tolist()).body.inertia == tuple(map(tuple, J.tolist()))
    else:
        with pytest.raises(SceneError, match="body.inertia"):
            load_scene("paper_example", J=J.tolist())


def test_inertia_valid_alone_but_not_about_the_centre_of_mass_is_rejected():
    """The case hypothesis found: diag(1, 1, ~0) obeys the triangle inequality, but with the
    paper's offset its centre-of-mass part has a negative eigenvalue."""
    with pytest.raises(SceneError, match="centre of mass"):
        load_scene("paper_example", J=[[1, 0, 0], [0, 1, 0], [0, 0, 2.5e-203]])


# -- issue 12, item 10: strict numbers, bounded magnitudes, duplicate keys, one override path ----------------
@pytest.mark.parametrize("overrides, needle", [
    ({"EA": True}, "string.EA: must be a number, not bool"),      # lax: 1.0
    ({"N": True}, "string.elements: must be a number, not bool"),  # lax: 1
    ({"EA": "40"}, "string.EA: must be a number, not str"),        # lax: 40.0
    ({"h": "1e-4"}, "h: must be a number, not str"),
    ({"N": "20"}, "string.elements"),
    ({"N": 20.0}, "string.elements"),
    ({"g": np.bool_(True)}, "gravity: must be a number"),
    ({"rho_c": [0.04, "0.01", 0.05]}, "body.rho_c.1"),
    ({"rho_c": {0.04, 0.01, 0.05}}, "body.rho_c: must be a list"),  # a set has no order
    ({"solver.compensated": 1}, "solver.compensated"),
    ({"allow_unstable_h": "yes"}, "allow_unstable_h"),
    ({"solver.order": True}, "solver.order"),
])
def test_numbers_are_strict(overrides, needle):
    with pytest.raises(SceneError) as err:
        load_scene("paper_example", **overrides)
    assert needle in str(err.value)


def test_numbers_that_are_numbers_pass():
    """Negative control: ints where floats belong, and NumPy scalars, are numbers."""
    s = load_scene("paper_example", EA=40, N=np.int64(10), g=np.float32(9.5), rho_c=np.array([0.04, 0.01, 0.05]),
                   **{"solver.compensated": np.bool_(False)})
    assert (s.string.EA, s.string.elements, s.gravity, s.solver.compensated) == (40.0, 10, 9.5, False)
    assert type(s.string.EA) is float and type(s.string.elements) is int


def _write(tmp_path, text, name="scene.yaml"):
    path = tmp_path / name
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    return path


PAPER_YAML = (SCENES_DIR / "paper_example.yaml").read_text()


def test_yaml_booleans_and_quoted_numbers_are_not_numbers(tmp_path):
    for old, new, needle in [("EA: 40.0", "EA: yes", "string.EA: must be a number, not bool"),
                             ("elements: 20", "elements: true", "string.elements: must be a number, not bool"),
                             ("EA: 40.0", 'EA: "40"', "string.EA: must be a number, not str")]:
        with pytest.raises(SceneError, match=needle):
            load_scene(_write(tmp_path, PAPER_YAML.replace(old, new)))


def test_yaml_exponents_are_numbers(tmp_path):
    """YAML 1.1 (PyYAML's default) reads 1e-4 and 4.0e1 as text; a scene reads them as YAML 1.2 does."""
    s = load_scene(_write(tmp_path, PAPER_YAML.replace("h: 1.0e-4", "h: 1e-4").replace("EA: 40.0", "EA: 4.0e1")))
    assert (s.h, s.string.EA) == (1e-4, 40.0)


@pytest.mark.parametrize("overrides, needle", [
    ({"J": (1e300 * np.eye(3)).tolist()}, "body.inertia.0.0"),   # was accepted: NaN energy at t = 0
    ({"initial.attach_velocity": [1e300, 0, 0]}, "initial.attach_velocity.0"),
    ({"initial.Omega0": [0, -1e300, 0]}, "initial.Omega0.1"),
    ({"g": 1e300}, "gravity"),
    ({"solver.max_stretch": 1e300}, "solver.max_stretch"),       # was an OverflowError
    ({"length": 1e300}, "string.length"),                         # was a ZeroDivisionError
    ({"EA": 1e300, "allow_unstable_h": True}, "string.EA"),
    ({"M": 1e300}, "body.mass"),
    ({"pivot.position": [1e300, 0, 0]}, "pivot.position.0"),
    ({"N": 10**400}, "string.elements"),
    ({"initial.stretch": 1e300}, "initial.stretch"),
    ({"initial.stretch": 10.0}, "initial.stretch = 10 must be below solver.max_stretch = 10"),
    ({"initial.R0": (1e200 * np.eye(3)).tolist()}, "initial.R0"),
    ({"body.inertia": None, "body.rho_c": [1.0, 0, 0],
      "body.shape": {"kind": "sphere", "radius": 1e-6}}, "body.shape: the smallest principal inertia"),
])
def test_magnitudes_are_bounded_and_named(overrides, needle):
    with pytest.raises(SceneError) as err:
        load_scene("paper_example", **overrides)
    assert needle in str(err.value)


def test_initial_nodes_beyond_the_blow_up_guard_are_refused():
    nodes = load_scene("paper_example", N=2).initial_nodes()
    nodes[2] = nodes[1] + [20.0, 0, 0]  # an element 40 rest lengths long: the guard would stop step 1
    with pytest.raises(SceneError, match="40 rest lengths long, not below solver.max_stretch = 10"):
        load_scene("paper_example", N=2, initial={"nodes": nodes.tolist()})


def _corner(rng, hi):
    """A scene with each kind of number at one end of its bounds (see esp_gym/scene/scene_input.py)."""
    end = {k: BOUNDS[k][1] if hi[k] else BOUNDS[k][0] for k in hi}
    size = end["length"]
    rho = [rng.uniform(-1, 1) * size for _ in range(3)]
    free = rng.random() < 0.5
    return {
        "name": "corner",
        "string": {"length": end["length"], "mass_per_length": end["mass_per_length"], "EA": end["EA"],
                   "elements": rng.choice([1, 4, 20])},
        "body": {"mass": end["mass"], "rho_c": rho, "shape": {"kind": "box", "size": [size] * 3}},
        "pivot": ({"kind": "free", "mass": end["mass"], "position": [end["coordinate"]] * 3,
                   "velocity": [end["speed"], 0, -end["speed"]]} if free else
                  {"kind": "fixed", "position": [0, 0, end["coordinate"]]}),
        "gravity": end["gravity"], "h": 1e-3, "allow_unstable_h": True,
        "solver": {"max_stretch": BOUNDS["stretch"][1]},
        "initial": {"stretch": 0.999 * BOUNDS["stretch"][1] if hi["stretch"] else BOUNDS["stretch"][0],
                    "attach_velocity": [end["speed"], -end["speed"], end["speed"]],
                    "Omega0": [end["angular_speed"], 0, -end["angular_speed"]],
                    "direction": [rng.uniform(-1, 1) for _ in range(3)]},
    }


def test_scenes_at_the_bounds_have_a_finite_energy_at_t0():
    """The bounds are what keeps the stepper's constants and the energy at t = 0 finite: 24 scenes,
    each kind of number at a random end of its range (1e300 in J, speeds or g gave NaN here)."""
    import random

    rng = random.Random(12)
    kinds = ["length", "mass", "mass_per_length", "EA", "gravity", "speed", "angular_speed", "stretch",
             "coordinate"]
    for _ in range(24):
        hi = {k: rng.random() < 0.5 for k in kinds}
        sim = esp_gym.Simulator(scene_from_dict(_corner(rng, hi)))
        d = sim.diagnostics()
        assert np.isfinite(d["energy"]) and np.all(np.isfinite(sim.state.p)), hi


def test_duplicate_keys_are_refused_with_the_key_and_lines(tmp_path):
    text = PAPER_YAML.replace("  EA: 40.0               # [N]\n", "  EA: 40.0\n  EA: 80.0\n")
    path = _write(tmp_path, text)
    first = text.splitlines().index("  EA: 40.0") + 1
    with pytest.raises(SceneError) as err:
        load_scene(path)
    assert f"duplicate key 'EA' (first given on line {first}) at line {first + 1}" in str(err.value)
    assert str(path) in str(err.value)
    with pytest.raises(SceneError, match="duplicate key 'h'"):
        load_scene(_write(tmp_path, PAPER_YAML + "h: 2.0e-4\n"))
    # negative control: a merge key's entries may be overridden (that is what merging is)
    merged = PAPER_YAML.replace("pivot:\n  kind: fixed\n", "pivot:\n  <<: {kind: free, mass: 1.0}\n  kind: fixed\n")
    with pytest.raises(SceneError, match="pivot.mass and pivot.velocity belong to a free pivot"):
        load_scene(_write(tmp_path, merged))


@pytest.mark.parametrize("content, needle", [
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "not utf-8 text"),         # binary
    (PAPER_YAML.encode() + b"\x00", "a character YAML does not allow (#x0000"),
    ("name: caf\u00e9\n".encode("latin-1"), "not utf-8 text"),
    (b"string: {length: 1.0\nh: 1.0e-4\n", "YAML error"),                # a ParserError
    (b"string:\n  EA: 1\n    bad: 2\n", "YAML error: mapping values are not allowed here at line 3"),
    (b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),             # a RecursionError
    (b"- 1\n- 2\n", "it must hold a mapping of scene fields, not a list"),
    (b"h: !!python/object:os.system x\n", "could not determine a constructor"),
])
def test_malformed_files_raise_scene_error_naming_the_file(tmp_path, content, needle):
    path = _write(tmp_path, content)
    with pytest.raises(SceneError) as err:
        load_scene(path)
    message = str(err.value)
    assert str(path) in message and needle in message and "\n" not in message, message


def test_unreadable_files_raise_scene_error_naming_the_file(tmp_path, monkeypatch):
    from esp_gym.scene import scene_input

    (tmp_path / "dir.yaml").mkdir()
    with pytest.raises(SceneError, match="dir.yaml'?: a directory"):
        load_scene(tmp_path / "dir.yaml")
    path = _write(tmp_path, PAPER_YAML)

    def denied(*args, **kwargs):  # chmod 000 does not stop root, so the refusal is simulated
        raise PermissionError(13, "Permission denied", str(path))

    monkeypatch.setattr(scene_input, "open", denied, raising=False)
    with pytest.raises(SceneError, match=f"cannot read scene file {path}: Permission denied"):
        load_scene(path)
    monkeypatch.undo()
    monkeypatch.setattr(scene_input, "MAX_SCENE_BYTES", 100)
    with pytest.raises(SceneError, match=r"bytes, more than a scene needs \(at most 100\)"):
        load_scene(path)


def test_upper_case_yaml_suffix_is_a_yaml_file(tmp_path):
    assert load_scene(_write(tmp_path, PAPER_YAML, "MINE.YAML")).name == "paper_example"
    assert load_scene(_write(tmp_path, PAPER_YAML.replace("name: paper_example\n", ""), "Other.Yml")).name == "Other"


OVERRIDES = {"N": 10, "string": {"EA": 80.0}, "body.mass": 0.2, "solver": {"order": 4}, "initial.Omega0": [0, 0, 1]}


def test_overrides_of_a_scene_object_merge_like_load_scene():
    """One override path: a Scene object takes the aliases, dotted paths and section merges
    that load_scene takes (it rejected N and string.EA, and replaced whole sections)."""
    base = load_scene("paper_example")
    from_file = load_scene("paper_example", **OVERRIDES)
    assert override_scene(base, OVERRIDES) == from_file == load_scene(base, **OVERRIDES)
    assert from_file.string.length == 1.0 and from_file.solver.newton_tol == 1e-14  # merged, not replaced
    assert override_scene(base, {}) is base
    for bad, needle in [({"wind": 1}, "unknown override 'wind'"), ({1: 2}, "unknown override 1"),
                        ({"h.x": 1}, "override 'h.x': 'h' is not a section"), ({"EA": True}, "string.EA")]:
        with pytest.raises(SceneError, match=needle):
            override_scene(base, bad)


def _drone_limits(scene_name):
    """(the largest principal moment [kg m^2], the largest |rho_q| [m]) of a shipped drone scene:
    its mass within DRONE_REACH arm lengths of its centre (esp_gym/scene/pivot_params.py)."""
    scene = load_scene(scene_name)
    reach = DRONE_REACH * scene.pivot.drone.arm_length
    return scene.pivot.mass * reach ** 2, reach


@pytest.mark.parametrize("scene_name", ["quadrotor_load", "crazyflie_load"])
@pytest.mark.parametrize("field, value, needle", [
    # each was accepted: inertia 1e300 ended every episode at step 1 (the Cayley Newton failed),
    # rho_q 1e5 m within 160 steps (energy_balance); rate_gain 1e300 ran as if it were sane
    ("pivot.drone.inertia", [1e300] * 3, "pivot.drone.inertia"),
    ("pivot.drone.inertia", "just above", "pivot.drone.inertia"),
    ("pivot.drone.rate_gain", [1e300] * 3, "pivot.drone.rate_gain must be at most 1000 1/s"),
    ("pivot.drone.rate_gain", [20.0, 20.0, 1.001 * MAX_RATE_GAIN], "pivot.drone.rate_gain must be at most"),
    ("pivot.drone.rho_q", [0.0, 0.0, 1e5], "pivot.drone.rho_q"),
    ("pivot.drone.rho_q", "just above", "pivot.drone.rho_q"),
])
def test_drone_magnitudes_are_bounded_and_named(scene_name, field, value, needle):
    largest, reach = _drone_limits(scene_name)
    if value == "just above":
        value = [1.001 * largest] * 3 if field.endswith("inertia") else [0.0, 0.6 * reach, 0.8 * reach * 1.001]
    with pytest.raises(SceneError, match=needle) as err:
        load_scene(scene_name, **{field: value})
    assert len(str(err.value).splitlines()) == 2  # the header and one line for the field


@pytest.mark.parametrize("scene_name", ["quadrotor_load", "crazyflie_load"])
def test_drone_values_just_inside_the_bounds_load(scene_name):
    """Negative control: the shipped drones load, and so does each value just inside its bound."""
    largest, reach = _drone_limits(scene_name)
    for field, value in (("pivot.drone.inertia", [0.999 * largest] * 3),
                         ("pivot.drone.rate_gain", [MAX_RATE_GAIN] * 3),
                         ("pivot.drone.rho_q", [0.0, 0.6 * reach * 0.999, 0.8 * reach * 0.999])):
        # the fastest rate gain needs a rate loop of at most 1/K (MAX_RATE_LOOP_GAIN): 1 kHz
        loop = {"pivot.drone.rate_loop_period": 1.0 / MAX_RATE_GAIN} if field.endswith("rate_gain") else {}
        scene = load_scene(scene_name, **{field: value}, **loop)
        assert getattr(scene.pivot.drone, field.split(".")[-1]) == tuple(value)
