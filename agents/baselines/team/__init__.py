"""A team's classical baselines: the LQR on the team's linearised control step (lqr.py), the LQG
for hook observations (lqg.py), the drones' cascade around them (cascade.py) and the hoist of
``lift`` (hoist.py)."""
