"""The string's step family: the elastic string's forces (string.py), the explicit LGVI substep
(lgvi.py) and what every scheme's step ends with (step_shared.py), the implicit string
(implicit*.py), the winch (winch*.py), the slack switch's settlement (switch.py), the run loops
with their checkpoints (loops.py, step.py), the held forces of wind and pushes (disturbance.py),
the diagnostics (diagnostics.py) and the step kernels specialised per scene (specialise.py)."""
