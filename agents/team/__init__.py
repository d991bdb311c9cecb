"""Agents for the team environments (ElasticStringTeam-v0, esp_gym.team.parallel_env): RLlib
training of one shared policy (train.py; ``python -m agents.team.train``, the ``ray`` extra) and
its Tune sweep (sweep.py; ``python -m agents.team.sweep``), a residual on a baseline (residual.py),
a centralised critic (critic.py, critic_module.py), and the episodes that score a team's policy
against its baselines (evaluate.py). The team's classical baselines are agents.baselines.team."""
