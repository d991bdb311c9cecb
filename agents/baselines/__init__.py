"""The classical baselines: the PD laws and the hoist (pd.py), the LQR on the linearised control
step (lqr.py), input shaping of the pivot's path (shaping.py), the LQG for hook observations
(lqg.py), every baseline of a configuration by name with its tuned constants (registry.py), and
the grid search of the PD laws' gains (gain_search.py; ``python -m agents.baselines.gain_search``)."""
