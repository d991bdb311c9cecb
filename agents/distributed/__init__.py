"""Training on a Ray cluster (the ``ray`` extra): a local cluster on loopback (cluster.py), RLlib's
PPO on the environment (rllib.py: its configuration and policy; train.py: the command), and Ray
Tune sweeps over the SB3 recipe (sweep.py; sweep_results.py gathers their trials). Nothing here
is imported by the rest of agents/ (docs/ray.md)."""
