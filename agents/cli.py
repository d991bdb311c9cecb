"""The command line of the agent scripts: one-line errors, and dataclass settings -> argparse.

Light on purpose (argparse only): ``agents.evaluate --policy zero`` should not import torch.
"""
from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path
from typing import Optional

from esp_gym.paths import cannot_write


class ArgumentParser(argparse.ArgumentParser):
    """argparse whose errors are one line on stderr, ``PROG: error: MESSAGE (see --help)``, with
    exit code 2 (argparse's own code for usage errors; the usage block is left to ``--help``)."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {one_line(message)} (see --help)\n")

    def add_episode_options(self, tasks, episodes: int, seed: bool = True, preset: bool = False,
                            default_seed: int = 0) -> None:
        """``--task`` (one of ``tasks``), ``--episodes`` (>= 1, default ``episodes``) and, with
        ``seed``, ``--seed`` (>= 0; episode i uses seed + i), with ``preset`` ``--preset`` (an
        environment preset, esp_gym/pendulum/env_setup.py PRESETS): the options every script that runs
        episodes shares. Their minimums are checked by :meth:`parse_args`."""
        self.add_argument("--task", default="stabilize", choices=sorted(tasks))
        self.add_argument("--episodes", type=int, default=episodes)
        self.minimums = {**getattr(self, "minimums", {}), "episodes": 1}
        if seed:
            self.add_argument("--seed", type=int, default=default_seed, help="episode i uses seed + i (>= 0)")
            self.minimums["seed"] = 0
        if preset:
            from esp_gym.pendulum.env_setup import PRESETS

            self.add_argument("--preset", default=None, choices=sorted(PRESETS),
                              help="environment preset (default: the nominal task)")

    def add_scene_options(self) -> None:
        """``--scene`` and ``--actuation``: the environment the episodes run in (read back, checked,
        by :meth:`environment_options`)."""
        from esp_gym.pendulum.options import ACTUATION_CHOICES

        self.add_argument("--scene", default=None, help="the environment's scene (default: drone_load)")
        self.add_argument("--actuation", default=None, choices=ACTUATION_CHOICES,
                          help="how the action moves the pivot (default: the scene's pivot's)")

    def environment_options(self, args) -> dict:
        """The environment options ``args`` give (``--preset``, ``--scene``, ``--actuation``: those
        set); an error naming --scene/--actuation where they make no environment for ``args.task``."""
        options = {name: getattr(args, name, None) for name in ("preset", "scene", "actuation")}
        options = {name: value for name, value in options.items() if value is not None}
        if "scene" in options or "actuation" in options:
            from esp_gym.pendulum.env_setup import make_setup

            try:
                make_setup(task=args.task, **options)
            except ValueError as err:
                self.error(f"argument --scene/--actuation: {err}")
        return options

    def parse_args(self, args=None, namespace=None):
        parsed = super().parse_args(args, namespace)
        self.check_minimums(vars(parsed), **getattr(self, "minimums", {}))
        return parsed

    def check_minimums(self, values: dict, **minimums) -> None:
        """An error for the first ``values[name]`` below ``minimums[name]`` (names of options)."""
        for name, low in minimums.items():
            if name in values and values[name] < low:
                self.error(f"argument {option_name(name)}: must be >= {low}, got {values[name]}")

    def check_out_dir(self, option: str, path: Optional[str]) -> None:
        """An error unless ``path`` (None: no output) is a directory, or can be made in an
        existing one, that this process can write in."""
        if path and Path(path).exists() and not Path(path).is_dir():
            self.error(f"argument {option}: {path} is not a directory")
        self.check_parent_dir(option, path)
        self.check_writable_dir(option, path)

    def check_file(self, option: str, path: Optional[str]) -> None:
        """An error unless ``path`` (None: not given) is an existing file."""
        if path is not None and not Path(path).is_file():
            self.error(f"argument {option}: {path} is not a file")

    def check_new_file(self, option: str, path: Optional[str]) -> None:
        """An error unless a file can be written at ``path`` (None: no file): its directory
        exists, this process can write in it, and ``path`` is not a directory."""
        if path and Path(path).is_dir():
            self.error(f"argument {option}: {path} is a directory, not a file")
        self.check_parent_dir(option, path)
        self.check_writable_dir(option, path and Path(path).resolve().parent)

    def check_parent_dir(self, option: str, path: Optional[str]) -> None:
        """An error unless the directory a file ``path`` is to be written in exists (None: no file)."""
        if path and not Path(path).resolve().parent.is_dir():
            self.error(f"argument {option}: no directory {Path(path).resolve().parent} for {path}")

    def check_writable_dir(self, option: str, path) -> None:
        """An error unless a directory ``path`` can be made (with its missing parents) and
        written in (:func:`cannot_write`; None or empty: no directory)."""
        problem = cannot_write(path) if path else None
        if problem:
            self.error(f"argument {option}: {problem}")


class SettingsError(ValueError):
    """Bad settings found before anything is written; ``option`` is the argument at fault
    (``--set``, ``--resume``, ...) or None when the fault lies elsewhere (a config file)."""

    def __init__(self, option: Optional[str], message: str):
        super().__init__(f"argument {option}: {message}" if option else message)
        self.option = option


def one_line(text) -> str:
    return " ".join(str(text).split())


def option_name(field_name: str) -> str:
    return "--" + field_name.replace("_", "-")


def settings_parser(cls, prog: Optional[str] = None, description: str = "") -> ArgumentParser:
    """A parser for a dataclass whose fields carry ``metadata={"help": ...}`` (and optionally
    ``type``, ``choices``, ``nargs``, ``action``, ``min``). Arguments left out are absent from the
    namespace (:func:`parse_settings` fills in the dataclass defaults and reports which were given)."""
    ap = ArgumentParser(prog=prog, description=description)
    for f in dataclasses.fields(cls):
        meta = f.metadata
        default = f.default if f.default is not dataclasses.MISSING else f.default_factory()
        help_ = meta.get("help", "") + ("" if default in (None, []) else f" (default: {default})")
        if f.type in ("bool", bool):
            ap.add_argument(option_name(f.name), action=argparse.BooleanOptionalAction, default=argparse.SUPPRESS,
                            help=help_)
        elif meta.get("nargs"):
            ap.add_argument(option_name(f.name), nargs=meta["nargs"], action=meta.get("action", "store"),
                            default=argparse.SUPPRESS, metavar="KEY=VALUE", help=help_)
        else:
            ap.add_argument(option_name(f.name), type=meta.get("type", str), choices=meta.get("choices"),
                            default=argparse.SUPPRESS, help=help_)
    return ap


def parse_settings(ap: ArgumentParser, cls, argv=None):
    """``(settings, given)``: the dataclass from the command line and the names of the fields the
    command line set. Values below a field's ``min`` are errors."""
    given = vars(ap.parse_args(argv))
    ap.check_minimums(given, **{f.name: f.metadata["min"] for f in dataclasses.fields(cls) if "min" in f.metadata})
    return cls(**given), frozenset(given)
