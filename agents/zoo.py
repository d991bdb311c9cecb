"""The model zoo: every shipped policy from one recipe (configs/agents/zoo.yaml) and one command.

    python -m agents.zoo --list
    python -m agents.zoo --train --compare                 # every configuration
    python -m agents.zoo --train --only track lift --jobs 2
    python -m agents.zoo --compare --episodes 100          # docs/compare/* and the README's table

``--train`` runs ``python -m agents.train`` per configuration with the recipe's settings and the
configuration's own (its residual base, privileged critic, environment options and ``set``),
``--jobs`` at a time (at most the CPUs; each with one thread per library; comparisons too), into
``--runs`` (run directories ``zoo_NAME``, their output in ``zoo_NAME.log``), and ships each finished run to
``--models``/NAME_ppo: the model, its normalisation statistics, the resolved config, the
command, the training statistics and the learning curve (with the base controller's return
drawn as a line). ``--compare`` runs agents.compare on every configuration's shipped model over
``--episodes`` held-out episodes from ``--seed`` into ``--out`` (compare_NAME.md/.json), then
rewrites the docs' and the README's quotes of them (benchmarks.quote) when ``--out`` is the
docs' own directory. The paths, the models to compare and every training's settings are
checked before the first training or comparison starts.
"""
from __future__ import annotations

import os
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path
from typing import Literal, Optional

import yaml
from pydantic import BaseModel, ConfigDict, Field

from agents.artifacts import ModelFileError, model_algorithm
from agents.cli import ArgumentParser, SettingsError
from agents import INSTALLED, MODELS, ROOT, ZOO_FILE
from esp_gym.workers import jobs_argument, worker_count

#: The docs' comparisons in a checkout (rewritten with their quotes); installed, out/compare.
COMPARE_DIR = ROOT / "out" / "compare" if INSTALLED else ROOT / "docs" / "compare"
#: What a shipped model directory holds of its run (the rest, checkpoints and logs, stays in runs/).
SHIPPED_FILES = ("model.zip", "vecnormalize.npz", "config.yaml", "args.json", "command.txt", "residual.json",
                 "training.json", "evaluations.npz", "learning_curve.png", "references.json")
#: Each training process's libraries on one thread: ``--jobs`` processes share the cores.
ONE_THREAD = {name: "1" for name in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "NUMBA_NUM_THREADS")}


class Recipe(BaseModel):
    """The settings every configuration trains with (configs/agents/zoo.yaml ``recipe``)."""

    model_config = ConfigDict(extra="forbid")
    algo: Literal["ppo", "sac"] = "ppo"
    seed: int = Field(default=1, ge=0)
    time_limit: float = Field(default=30.0, gt=0)  #: [min]
    set: dict = {}  #: agents.train --set KEY=VALUE, in order


class Configuration(BaseModel):
    """One configuration of the zoo: the environment it is trained and compared in, and the
    recipe's additions for it."""

    model_config = ConfigDict(extra="forbid")
    task: str
    preset: Optional[str] = None
    scene: Optional[str] = None
    actuation: Optional[str] = None
    residual: Optional[Literal["pd", "lqr", "lqg", "geometric"]] = None
    privileged_critic: bool = False
    seed: Optional[int] = Field(default=None, ge=0)  #: the recipe's seed unless given (chosen on validation seeds)
    set: dict = {}

    @property
    def env_kwargs(self) -> dict:
        return {k: v for k, v in (("preset", self.preset), ("scene", self.scene), ("actuation", self.actuation))
                if v is not None}


class Zoo(BaseModel):
    model_config = ConfigDict(extra="forbid")
    recipe: Recipe
    configurations: dict[str, Configuration]


def load_zoo(path: Path = ZOO_FILE) -> Zoo:
    """The zoo file, checked: every name is its configuration's (agents.compare
    configuration_name), so models, compare files and the README agree on it."""
    from agents.compare import configuration_name

    zoo = Zoo.model_validate(yaml.safe_load(Path(path).read_text()))
    for name, c in zoo.configurations.items():
        expected = configuration_name(c.task, c.preset, c.scene, c.actuation)
        if name != expected:
            raise ValueError(f"{path}: configuration {name!r} is named {expected!r} by its task, preset, scene and "
                             f"actuation (agents.compare configuration_name)")
    return zoo


def settings(zoo: Zoo, name: str) -> dict:
    """The ``--set`` items of configuration ``name``: the recipe's, its base and critic, its
    environment options, then its own (a later item overrides an earlier one)."""
    c = zoo.configurations[name]
    items = dict(zoo.recipe.set)
    if c.residual:
        items["residual"] = c.residual
    if c.privileged_critic:
        items["privileged_critic"] = True
    if c.env_kwargs:
        items["env_kwargs"] = c.env_kwargs
    items.update(c.set)
    return items


def yaml_value(value) -> str:
    """``value`` as one line of YAML flow, as agents.train --set reads it."""
    return yaml.safe_dump(value, default_flow_style=True, width=10_000).strip().removesuffix("\n...")


def train_argv(zoo: Zoo, name: str, runs: Path, extra: tuple = ()) -> list:
    """agents.train's command line for configuration ``name`` (``extra``: more ``--set`` items)."""
    c, r = zoo.configurations[name], zoo.recipe
    items = [f"{key}={yaml_value(value)}" for key, value in settings(zoo, name).items()] + list(extra)
    seed = r.seed if c.seed is None else c.seed
    return ["--algo", r.algo, "--task", c.task, "--seed", str(seed), "--runs", str(runs), "--run-name",
            f"zoo_{name}", "--time-limit", str(r.time_limit), "--no-progress", "--set", *items]


def check_trainings(zoo: Zoo, names: list, runs: Path, extra: tuple = ()) -> None:
    """What agents.train checks first (its config with every ``--set`` item, its environment
    options), for each of ``names``, before any training starts: SettingsError naming the
    configuration that would not train."""
    from agents.train import parse_args, run_config

    for name in names:
        s, _, _ = parse_args(train_argv(zoo, name, runs, extra))
        try:
            run_config(s)
        except SettingsError as err:
            raise SettingsError(None, f"configuration {name!r} would not train: {err}") from None


def ship(run_dir: Path, target: Path) -> Path:
    """Copy the finished run ``run_dir``'s SHIPPED_FILES (those it has) into ``target``, which
    is replaced; returns ``target``."""
    run_dir = Path(run_dir)
    if not (run_dir / "model.zip").is_file():
        raise FileNotFoundError(f"run {run_dir} has no model.zip: it did not finish (see its status.json)")
    staging = target.with_name(target.name + ".new")
    shutil.rmtree(staging, ignore_errors=True)
    staging.mkdir(parents=True)
    for name in SHIPPED_FILES:
        if (run_dir / name).is_file():
            shutil.copy2(run_dir / name, staging / name)
    shutil.rmtree(target, ignore_errors=True)
    staging.rename(target)
    return target


def train(zoo: Zoo, names: list, runs: Path, models: Path, jobs: int = 1, extra: tuple = (),
          progress: bool = True) -> dict:
    """Train ``names`` (``jobs`` at a time, at most the CPUs) and ship each finished one; returns
    {name: model directory} for those shipped. A failed training is reported with its log and ships
    nothing."""
    from tqdm import tqdm

    jobs = worker_count("jobs", jobs, len(names))
    runs.mkdir(parents=True, exist_ok=True)
    waiting, running, shipped, failed = list(names), {}, {}, {}
    checkout = None if INSTALLED else str(ROOT)  # installed, agents imports from site-packages
    env = {**os.environ, **ONE_THREAD, "PYTHONPATH": os.pathsep.join(filter(None, (checkout,
                                                                                  os.environ.get("PYTHONPATH"))))}
    with tqdm(total=len(names), desc="zoo training", unit="model", disable=not progress) as bar:
        while waiting or running:
            while waiting and len(running) < jobs:
                name = waiting.pop(0)
                argv = [sys.executable, "-m", "agents.train", *train_argv(zoo, name, runs, extra)]
                log = open(runs / f"zoo_{name}.log", "w")
                log.write(shlex.join(argv) + "\n")
                log.flush()
                running[name] = (subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, cwd=ROOT, env=env), log)
            time.sleep(0.5)
            for name, (process, log) in list(running.items()):
                if process.poll() is None:
                    continue
                log.close()
                del running[name]
                if process.returncode == 0:
                    shipped[name] = ship(runs / f"zoo_{name}", models / f"{name}_ppo")
                else:
                    failed[name] = runs / f"zoo_{name}.log"
                bar.update(1)
    if failed:
        raise RuntimeError("training failed for " + ", ".join(f"{n} (see {log})" for n, log in failed.items()))
    return shipped


def shipped_model(models: Path, name: str) -> Path:
    """Configuration ``name``'s model under ``models``, checked to be a PPO or SAC archive (its
    metadata read, nothing unpickled); ModelFileError naming the file otherwise."""
    model = models / f"{name}_ppo" / "model.zip"
    model_algorithm(model)
    return model


def compare_one(zoo: Zoo, name: str, models: Path, out: Path, episodes: int, seed: int, progress: bool) -> dict:
    """agents.compare on configuration ``name``'s model under ``models``, written to ``out``."""
    from agents.compare import compare, write_comparison

    c = zoo.configurations[name]
    model = shipped_model(models, name)
    result = compare(c.task, c.preset, episodes, seed, str(model), progress, c.scene, c.actuation)
    write_comparison(result, out)
    return result


def compare_all(zoo: Zoo, names: list, models: Path, out: Path, episodes: int, seed: int, jobs: int = 1,
                progress: bool = True) -> dict:
    """:func:`compare_one` for each of ``names``, ``jobs`` at a time (each in a process of its own
    when more than one, at most one per configuration and the CPUs); returns {name: comparison} in
    ``names``' order. Every model is checked before the first comparison."""
    jobs = worker_count("jobs", jobs, len(names))
    for name in names:
        shipped_model(models, name)
    if jobs == 1:
        return {name: compare_one(zoo, name, models, out, episodes, seed, progress) for name in names}
    from concurrent.futures import ProcessPoolExecutor, as_completed

    from tqdm import tqdm

    with ProcessPoolExecutor(max_workers=jobs) as pool:
        futures = {name: pool.submit(compare_one, zoo, name, models, out, episodes, seed, False) for name in names}
        for _ in tqdm(as_completed(futures.values()), total=len(futures), desc="zoo comparisons", unit="configuration",
                      disable=not progress):
            pass
        return {name: future.result() for name, future in futures.items()}


def zoo_parser() -> ArgumentParser:
    """The command line of ``python -m agents.zoo``."""
    from agents.compare import HELD_OUT_SEED

    ap = ArgumentParser(prog="python -m agents.zoo", description=__doc__.split("\n\n")[0])
    ap.add_argument("--list", action="store_true", help="print each configuration's agents.train command")
    ap.add_argument("--train", action="store_true", help="train every configuration (or --only's) and ship it")
    ap.add_argument("--compare", action="store_true", help="compare every configuration's model with its baselines")
    ap.add_argument("--only", nargs="+", default=None, metavar="NAME", help="these configurations (default: all)")
    ap.add_argument("--jobs", type=jobs_argument, default=1, help="trainings, or comparisons, at once, each a "
                    "process: at most the CPUs (default: 1)")
    ap.add_argument("--set", nargs="+", default=[], action="extend", metavar="KEY=VALUE",
                    help="more agents.train --set items for every training (e.g. a smaller total_timesteps)")
    ap.add_argument("--zoo", default=str(ZOO_FILE), help="the zoo file (default: configs/agents/zoo.yaml)")
    ap.add_argument("--runs", default=str(ROOT / "runs"), help="where run directories go (default: runs/)")
    ap.add_argument("--models", default=None, help="where models are shipped and read (default: the shipped models; "
                    "installed, models/ with --train)")
    ap.add_argument("--out", default=str(COMPARE_DIR), help="where the comparisons go (default: docs/compare; "
                    "installed, out/compare)")
    ap.add_argument("--episodes", type=int, default=100, help="held-out episodes per comparison (default: 100)")
    ap.add_argument("--seed", type=int, default=HELD_OUT_SEED, help=f"first held-out seed (default: {HELD_OUT_SEED})")
    ap.add_argument("--no-progress", dest="progress", action="store_false", help="no progress bars")
    return ap


def check_zoo_arguments(ap: ArgumentParser, a) -> tuple:
    """``(zoo, configuration names, models directory)`` of the parsed arguments ``a``, everything a
    training or a comparison would fail on refused first (one line, exit code 2)."""
    ap.check_minimums(vars(a), episodes=2, seed=0)
    ap.check_file("--zoo", a.zoo)
    if not (a.list or a.train or a.compare):
        ap.error("nothing to do: give --list, --train and/or --compare")
    try:
        zoo = load_zoo(Path(a.zoo))
    except ValueError as err:  # pydantic's ValidationError is one
        ap.error(f"argument --zoo: {err}")
    # --train writes under ROOT: in a checkout that is MODELS, an install's shipped models stay as they are
    models = Path(a.models or (ROOT / "models" if a.train else MODELS))
    names = a.only or list(zoo.configurations)
    unknown = [n for n in names if n not in zoo.configurations]
    if unknown:
        ap.error(f"argument --only: unknown configuration(s) {unknown}; the zoo has {list(zoo.configurations)}")
    if a.train:  # what a training would fail on, before the first starts
        ap.check_writable_dir("--runs", a.runs)
        ap.check_writable_dir("--models", models)
        try:
            check_trainings(zoo, names, Path(a.runs), tuple(a.set))
        except SettingsError as err:
            ap.error(str(err))
    if a.compare:
        ap.check_out_dir("--out", a.out)
    if a.compare and not a.train:  # with --train, the models are shipped before the comparisons
        for name in names:
            try:
                shipped_model(models, name)
            except ModelFileError as err:
                ap.error(f"argument --models: configuration {name!r}: {err}; train it with --train")
    return zoo, names, models


def main(argv=None) -> dict:
    from agents.compare import markdown

    ap = zoo_parser()
    a = ap.parse_args(argv)
    zoo, names, models = check_zoo_arguments(ap, a)
    out = {}
    if a.list:
        for name in names:
            print(f"{name}: python -m agents.train {shlex.join(train_argv(zoo, name, Path(a.runs), tuple(a.set)))}")
    if a.train:
        out["shipped"] = {n: str(p) for n, p in train(zoo, names, Path(a.runs), models, a.jobs,
                                                      tuple(a.set), a.progress).items()}
    if a.compare:
        out["compared"] = compare_all(zoo, names, models, Path(a.out), a.episodes, a.seed, a.jobs,
                                      a.progress)
        for c in out["compared"].values():
            print(markdown(c) + "\n")
        if not INSTALLED and Path(a.out).resolve() == COMPARE_DIR.resolve():
            from benchmarks.quote import main as quote_main

            quote_main(["--write"])
    return out


if __name__ == "__main__":
    main()
