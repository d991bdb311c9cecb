"""VecNormalize statistics as data: saved as ``.npz`` (numpy arrays, read with
``allow_pickle=False``), never as a pickle, so loading them cannot run code.

Runs written by ``agents.train`` hold ``vecnormalize.npz`` beside ``model.zip`` and
``checkpoints/model_vecnormalize_N_steps.npz`` beside ``checkpoints/model_N_steps.zip``. Older runs
hold SB3's pickled ``vecnormalize.pkl`` instead; :func:`read_legacy_pickle`
reads those with an unpickler that knows only numpy's array constructors and a plain record type
standing in for VecNormalize, RunningMeanStd and the spaces, and refuses every other global: a
crafted pickle fails with an error naming the global instead of running it.
"""
from __future__ import annotations

import io
import math
import pickle
from dataclasses import dataclass, fields
from pathlib import Path

import numpy as np

try:
    from numpy._core import multiarray as _multiarray  # numpy >= 2
except ImportError:  # pragma: no cover - numpy 1
    from numpy.core import multiarray as _multiarray


class NormalizationFileError(ValueError):
    """A normalisation statistics file that is missing, malformed or refused; names the file."""


@dataclass(frozen=True)
class NormStats:
    """What VecNormalize needs to normalise observations and rewards (its settings and the
    running mean / variance / count of the observations and of the discounted returns)."""

    norm_obs: bool
    norm_reward: bool
    clip_obs: float
    clip_reward: float
    gamma: float
    epsilon: float
    obs_mean: np.ndarray
    obs_var: np.ndarray
    obs_count: float
    ret_mean: np.ndarray
    ret_var: np.ndarray
    ret_count: float

    @classmethod
    def from_vecnormalize(cls, vn) -> "NormStats":
        if isinstance(vn.obs_rms, dict):
            raise ValueError("dict observation spaces are not supported")
        return cls(norm_obs=bool(vn.norm_obs), norm_reward=bool(vn.norm_reward), clip_obs=float(vn.clip_obs),
                   clip_reward=float(vn.clip_reward), gamma=float(vn.gamma), epsilon=float(vn.epsilon),
                   obs_mean=np.array(vn.obs_rms.mean, dtype=np.float64), obs_var=np.array(vn.obs_rms.var, dtype=np.float64),
                   obs_count=float(vn.obs_rms.count), ret_mean=np.array(vn.ret_rms.mean, dtype=np.float64),
                   ret_var=np.array(vn.ret_rms.var, dtype=np.float64), ret_count=float(vn.ret_rms.count))

    def save(self, path: str | Path) -> Path:
        path = Path(path)
        if path.suffix != ".npz":
            raise ValueError(f"{path}: normalisation statistics are saved as .npz")
        np.savez(path, **{f.name: np.asarray(getattr(self, f.name)) for f in fields(self)})
        return path

    @classmethod
    def load(cls, path: str | Path) -> "NormStats":
        """Read ``.npz`` statistics, or a legacy ``.pkl`` through :func:`read_legacy_pickle`."""
        path = Path(path)
        if path.suffix == ".pkl":
            return read_legacy_pickle(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                values = {f.name: data[f.name] for f in fields(cls)}
        except (OSError, ValueError, KeyError, EOFError) as err:
            raise NormalizationFileError(f"{path}: not a normalisation statistics file ({_reason(err)})") from None
        return cls._checked(path, values)

    @classmethod
    def _checked(cls, path: Path, values: dict) -> "NormStats":
        try:
            out = {}
            for f in fields(cls):
                v = np.asarray(values[f.name])
                if f.name in ("norm_obs", "norm_reward"):
                    out[f.name] = bool(v)
                elif f.name in ("obs_mean", "obs_var", "ret_mean", "ret_var"):
                    out[f.name] = np.array(v, dtype=np.float64)
                else:
                    out[f.name] = float(v)
        except (KeyError, TypeError, ValueError) as err:
            raise NormalizationFileError(f"{path}: malformed normalisation statistics ({_reason(err)})") from None
        stats = cls(**out)
        if stats.obs_mean.shape != stats.obs_var.shape or stats.obs_mean.ndim != 1:
            raise NormalizationFileError(f"{path}: observation mean {stats.obs_mean.shape} and variance "
                                         f"{stats.obs_var.shape} are not vectors of one length")
        numbers = [stats.obs_mean, stats.obs_var, stats.ret_mean, stats.ret_var]
        if not all(np.all(np.isfinite(a)) for a in numbers) or (stats.obs_var < 0).any() \
                or not all(math.isfinite(getattr(stats, k)) for k in ("clip_obs", "clip_reward", "gamma", "epsilon")):
            raise NormalizationFileError(f"{path}: normalisation statistics are not finite (or a variance is negative)")
        return stats

    def normalize_obs(self, obs: np.ndarray) -> np.ndarray:
        """VecNormalize's observation transform (identity if ``norm_obs`` is off)."""
        obs = np.asarray(obs, dtype=np.float32)
        if not self.norm_obs:
            return obs
        return np.clip((obs - self.obs_mean) / np.sqrt(self.obs_var + self.epsilon),
                       -self.clip_obs, self.clip_obs).astype(np.float32)

    def to_vecnormalize(self, venv, training: bool = True):
        """A VecNormalize around ``venv`` in this state (how a resumed run continues)."""
        from stable_baselines3.common.vec_env import VecNormalize

        if venv.observation_space.shape != self.obs_mean.shape:
            raise ValueError(f"statistics for observations of shape {self.obs_mean.shape}, the environment has "
                             f"{venv.observation_space.shape}")
        vn = VecNormalize(venv, training=training, norm_obs=self.norm_obs, norm_reward=self.norm_reward,
                          clip_obs=self.clip_obs, clip_reward=self.clip_reward, gamma=self.gamma, epsilon=self.epsilon)
        vn.obs_rms.mean, vn.obs_rms.var, vn.obs_rms.count = self.obs_mean.copy(), self.obs_var.copy(), self.obs_count
        vn.ret_rms.mean, vn.ret_rms.var, vn.ret_rms.count = self.ret_mean.copy(), self.ret_var.copy(), self.ret_count
        return vn


class _Record:
    """Stands in for every non-numpy object of a legacy pickle: keeps the state it is given."""

    def __init__(self, *args, **kwargs):
        self.args = args

    def __setstate__(self, state):
        self.state = state


class _DataOnlyUnpickler(pickle.Unpickler):
    """Rebuilds numpy arrays, dtypes and scalars; maps the few SB3 / gymnasium / numpy.random
    classes a VecNormalize pickle names to :class:`_Record`; refuses everything else."""

    RECORDS = {
        ("stable_baselines3.common.vec_env.vec_normalize", "VecNormalize"),
        ("stable_baselines3.common.running_mean_std", "RunningMeanStd"),
        ("gymnasium.spaces.box", "Box"),
        ("numpy.random._pickle", "__generator_ctor"),
        ("numpy.random._pickle", "__bit_generator_ctor"),
        ("numpy.random._pcg64", "PCG64"),
        ("numpy.random.bit_generator", "SeedSequence"),
        ("numpy.random.bit_generator", "__pyx_unpickle_SeedSequence"),
    }

    def find_class(self, module, name):
        if (module, name) in self.RECORDS:
            return _Record  # called (a reduce) or instantiated (a class), it only keeps its arguments
        if module in ("numpy.core.multiarray", "numpy._core.multiarray") and name in ("_reconstruct", "scalar"):
            return getattr(_multiarray, name)
        if module == "numpy" and name in ("ndarray", "dtype"):
            return getattr(np, name)
        if (module, name) == ("_codecs", "encode"):  # bytes in protocol-2 pickles
            import codecs

            return codecs.encode
        raise pickle.UnpicklingError(f"refusing to load the global {module}.{name}")


def read_legacy_pickle(path: str | Path) -> NormStats:
    """The statistics of an SB3 ``VecNormalize.save`` pickle, read as data (see the module doc)."""
    path = Path(path)
    try:
        raw = path.read_bytes()
        vn = _DataOnlyUnpickler(io.BytesIO(raw)).load()
        state = vn.state
        obs_rms, ret_rms = state["obs_rms"].state, state["ret_rms"].state
        values = {k: state[k] for k in ("norm_obs", "norm_reward", "clip_obs", "clip_reward", "gamma", "epsilon")}
        values.update(obs_mean=obs_rms["mean"], obs_var=obs_rms["var"], obs_count=obs_rms["count"],
                      ret_mean=ret_rms["mean"], ret_var=ret_rms["var"], ret_count=ret_rms["count"])
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, KeyError, TypeError, ValueError,
            IndexError) as err:
        raise NormalizationFileError(f"{path}: not a VecNormalize pickle that can be read as data ({_reason(err)})") from None
    return NormStats._checked(path, values)


def _reason(err: BaseException) -> str:
    return " ".join(f"{type(err).__name__}: {err}".split())
