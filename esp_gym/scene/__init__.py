"""A scene, validated before anything runs: its sections (params.py ``Scene``, pivot_params.py,
shapes.py), what it is read from (scene_input.py: YAML files, overrides, numbers), loading one by
name (``load_scene``), the steppers' compositions (compositions.py), the drone's rotor layout
(rotors.py), and the closed-form rules that need no simulator: the string's stability bound
(stability.py) and the step and resolution rules (stepsize.py, ``elements: auto``). Nothing here
imports the physics or the environments."""
