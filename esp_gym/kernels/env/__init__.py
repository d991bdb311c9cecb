"""ElasticStringPendulum-v0's compiled control step: its arrays and packed vectors (arrays.py), the
entry points of the point pivot's rigs (step.py), the observation, reward terms and termination
(task_terms.py), the track task's curve (track_curve.py) and a recording sample (recording.py)."""
