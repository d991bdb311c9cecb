"""The comparison table of docs/agents.md: zero action, classical baseline and a trained policy on the same seeded
episodes.

    python -m agents.compare --model models/stabilize_ppo/model.zip --task stabilize --episodes 50

Prints a Markdown table (mean +- std of the return, success rate, swing measures) and writes it
with the raw numbers to ``--out`` (JSON).
"""
from __future__ import annotations

import json
from pathlib import Path

from agents.cli import ArgumentParser
from agents.controllers import ZeroPolicy
from agents.evaluate import SB3Policy, evaluate_policy
from esp_gym.tasks import TASKS


def main(argv=None) -> dict:
    ap = ArgumentParser(prog="python -m agents.compare", description=__doc__.split("\n\n")[0])
    ap.add_argument("--model", required=True, help="trained model .zip")
    ap.add_episode_options(TASKS, episodes=50)
    ap.add_argument("--out", default=None, help="JSON file for the results")
    a = ap.parse_args(argv)
    ap.check_parent_dir("--out", a.out)
    try:
        model = SB3Policy(a.model)
    except ValueError as err:  # ModelFileError, NormalizationFileError
        ap.error(f"argument --model: {err}")
    rows = {
        "zero action": evaluate_policy(ZeroPolicy(), a.task, a.episodes, a.seed),
        "classical baseline (anti-sway PD)": evaluate_policy(None, a.task, a.episodes, a.seed),
        f"trained ({Path(a.model).parent.name})": evaluate_policy(model, a.task, a.episodes, a.seed),
    }
    print(f"| policy ({a.task}, {a.episodes} episodes, seeds {a.seed}..{a.seed + a.episodes - 1}) "
          "| return (mean ± std) | success rate | final swing [deg] | mean swing [deg] |")
    print("|---|---|---|---|---|")
    for name, s in rows.items():
        print(f"| {name} | {s['mean_return']:.1f} ± {s['std_return']:.1f} | {100 * s['success_rate']:.0f} % "
              f"| {s['mean_final_swing_deg']:.2f} | {s['mean_swing_deg']:.2f} |")
    if a.out:
        Path(a.out).write_text(json.dumps(rows, indent=2))
    return rows


if __name__ == "__main__":
    main()
