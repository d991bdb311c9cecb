"""Every validation rule of a scene raises a SceneError that names the field and the rule."""
import numpy as np
import pytest
from hypothesis import assume, given, settings, strategies as st

import esp_gym
from esp_gym.params import SceneError, load_scene


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
    bound = load_scene("paper_example").string.stability_bound
    assert bound == pytest.approx(7.2169e-4, rel=1e-4)  # docs/physics.md: 7.2e-4 s
    with pytest.raises(SceneError, match=r"h = 0\.001 s exceeds the stability bound h_max = 0\.000721688 s"):
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
