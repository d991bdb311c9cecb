"""What a team's step costs against K single strings' (docs/physics.md, "A team: several strings on
one body"): microseconds per step of a symmetric team of K = 1..6 equal strings (N elements each,
fixed pivots, h at 0.7 of the stability bound; esp_gym.team.symmetric_team) and of one of its strings alone with the body
(the lead scene, through the single string's general kernel, which the team's step extends, and
its specialised kernel), medians of interleaved repeats. The bound: a team's step costs at most
K x the single string's step plus the body's share, the body's share taken as the whole step of
one string of one element with the body (the step's fixed cost, an upper estimate of the body's).

Prints the table and writes ``OUT/team_step.json`` and ``OUT/team_step.png``.
Usage: ``python -m benchmarks.team_step [--quick] [--elements N|auto ...] [--out DIR]`` (default
10, 40 and auto: each string's N by the resolution rule, docs/physics.md "The string's resolution").
"""
from __future__ import annotations

import time

import numpy as np

from benchmarks.common import arg_parser, figure, finish, interleaved_wall_times, machine


def costs(elements, sizes, steps: int, repeats: int) -> list:
    """Rows ``{K, N, elements, team_us, single_us, single_specialised_us, body_us, ratio, bound_ratio}``:
    us per step, the team's against K x the single string's general step (``ratio``) and against
    the bound K x that + the body's share ``body_us`` (``bound_ratio``, <= 1 within it);
    ``elements`` a count or ``"auto"`` (each string's N by the resolution rule, ``N`` the one
    chosen)."""
    from esp_gym.physics.simulator import Simulator
    from esp_gym.team import TeamSimulator, symmetric_team

    rows = []
    for K in sizes:
        team = symmetric_team(K, elements=elements, stretch=1.01, allow_unstable_h=True)
        if elements != "auto":  # h at 0.7 of the stability bound (auto: the rule's own h)
            team = symmetric_team(K, elements=elements, stretch=1.01, h=0.7 * team.scene.stability_bound)
        N = team.scene.string.elements
        body = symmetric_team(1, elements=1, stretch=1.01, h=team.scene.h, allow_unstable_h=True)
        sims = {"team": TeamSimulator(team), "single": Simulator(team.scene, specialise=False),
                "single_specialised": Simulator(team.scene), "body": Simulator(body.scene, specialise=False)}
        for sim in sims.values():
            sim.step(10)  # compiled
        walls = interleaved_wall_times({key: (None, lambda s=sim: s.step(steps)) for key, sim in sims.items()},
                                       repeats)
        us = {key: 1e6 * float(np.median(w)) / steps for key, w in walls.items()}
        rows.append({"K": K, "N": N, "elements": elements, "team_us": us["team"], "single_us": us["single"],
                     "single_specialised_us": us["single_specialised"], "body_us": us["body"],
                     "ratio": us["team"] / (K * us["single"]),
                     "bound_ratio": us["team"] / (K * us["single"] + us["body"])})
    return rows


def plot(rows: list):
    def draw(path):
        fig = figure((6.0, 3.6))
        ax = fig.add_subplot()
        for elements in dict.fromkeys(r["elements"] for r in rows):
            sub = [r for r in rows if r["elements"] == elements]
            K = [r["K"] for r in sub]
            name = f"N = {elements}" if elements != "auto" else f"elements: auto (N = {sub[0]['N']})"
            line, = ax.plot(K, [r["team_us"] for r in sub], "o-", label=f"team, {name}")
            ax.plot(K, [r["K"] * r["single_us"] for r in sub], "--", color=line.get_color(),
                    label=f"K x one string's step, {name}")
        ax.set_xlabel("strings K")
        ax.set_ylabel("us per step")
        ax.set_title("a team's step against K single strings'")
        ax.legend(fontsize=8)
        fig.savefig(path)
    return draw


def main(argv=None) -> None:
    parser = arg_parser(__doc__)
    parser.add_argument("--elements", nargs="+", default=["10", "40", "auto"],
                        help="elements per string: counts, or auto (the resolution rule's)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    sizes = (1, 3) if args.quick else (1, 2, 3, 4, 5, 6)
    steps, repeats = (200, 2) if args.quick else (5000, 7)
    rows = []
    for elements in (["10"] if args.quick else args.elements):
        if elements != "auto" and not elements.isdigit():
            parser.error(f"argument --elements: a count or auto, got {elements!r}")
        rows += costs(elements if elements == "auto" else int(elements), sizes, steps, repeats)
    print(f"{'K':>3} {'elements':>9} {'N':>4} {'team us':>9} {'single us':>10} {'specialised':>12} {'body us':>8} "
          f"{'team / (K x single)':>20} {'team / bound':>13}")
    for r in rows:
        print(f"{r['K']:>3} {str(r['elements']):>9} {r['N']:>4} {r['team_us']:>9.2f} {r['single_us']:>10.2f} "
              f"{r['single_specialised_us']:>12.2f} {r['body_us']:>8.2f} {r['ratio']:>20.2f} {r['bound_ratio']:>13.2f}")
    finish(args.out, "team_step", {"rows": rows, "steps": steps, "repeats": repeats, "machine": machine()},
           {"team_step.png": plot(rows)}, start)


if __name__ == "__main__":
    main()
