"""Verification rigs for the tests and the benchmarks, not part of the environment.

* :mod:`esp_gym.verify.reference`: a plain-NumPy LGVI step (the paper's formulas, dense Newton),
  independent of :mod:`esp_gym.kernels`; the compiled stepper is checked against it.
* :mod:`esp_gym.verify.ode`: the same finite-element model as a first-order ODE, for
  general-purpose integrators (SciPy, a compiled RK4).
* :mod:`esp_gym.verify.mujoco_chain`: the lumped-mass scene as a MuJoCo model (needs the
  optional ``mujoco``).

Nothing here is imported by ``esp_gym`` itself, and this file imports none of them: import the
module you need.
"""
