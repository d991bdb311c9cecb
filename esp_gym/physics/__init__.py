"""The physics' Python face: the simulator that steps a scene (simulator.py ``Simulator``) and its
state and constants (state.py), a drone at the pivot (drone.py), the winch (winch.py), the energy
watchdog (watchdog.py), choosing h by pilot runs (pilot.py ``choose_h``), a run's snapshots
(trajectory.py), the structs the kernels take (arrays.py), and the rigs: which exist and the
structs each one's entry points take (rig.py, rig_arrays.py). It reads scenes (esp_gym.scene) and
runs the kernels (esp_gym.kernels); it imports no environment."""
