"""ElasticStringPendulum-v0, the single string's environment: the env (env.py), its arguments
(options.py) and what they resolve to (env_setup.py ``make_setup``), its control step around the
rig's compiled entry points (control.py), the tasks (tasks.py), observations and their noise
(observe.py), per-episode randomisation (randomize.py), wind and pushes (wind.py), and the
batched environments, Gymnasium's (vector.py) and Stable-Baselines3's (sb3_vector.py)."""
