"""Input shaping of the pivot's path for ``transport``, tracked by the LQR with its preview
feed-forward (docs/agents.md, "Input shaping").

A lightly damped mode (natural frequency w [rad/s], damping ratio zeta) driven by a path p(t)
rings on after the move unless the path's spectrum vanishes at the mode. Convolving any path
with a *shaper*, impulses A_i at times t_i (sum A_i = 1), multiplies the residual vibration by

    V(w) = exp(-zeta w t_n) |sum_i A_i exp(zeta w t_i) exp(i w_d t_i)|,   w_d = w sqrt(1 - zeta^2),

which is 0 at the design frequency for ZV (two impulses, half a damped period apart) and also
flat there (dV/dw = 0) for ZVD (three impulses), at the price of half a period more delay. The
mode is the pendulum's: the slowest oscillatory eigenvalue pair of the linearised control step
(agents/baselines/lqr.py) with the pivot held, so it is the scene's own, string stretch and body rocking
included (:func:`pendulum_mode`).

The path: the pivot and the load move from where the episode starts to their targets along a
cosine ramp of ``move_time`` seconds convolved with the shaper; the LQR acts on the error to
that path and adds the affine LQR's preview feed-forward of the path (as LQRTracker does for
``track``).
"""
from __future__ import annotations

import cmath
import math
from dataclasses import dataclass

import numpy as np

from agents.baselines import libm
from agents.baselines.lqr import LQR, REDUCED, preview_feedforward, preview_terms, reduced_state

#: Shaper names -> builders.
SHAPERS = ("none", "zv", "zvd")


@dataclass(frozen=True)
class Shaper:
    """Impulses of amplitudes ``amplitudes`` (sum 1) at ``times`` [s] (the first at 0)."""

    amplitudes: np.ndarray
    times: np.ndarray

    @classmethod
    def design(cls, kind: str, omega: float, zeta: float = 0.0) -> "Shaper":
        """``kind`` none, zv or zvd for the mode (``omega`` [rad/s], damping ratio ``zeta``)."""
        if kind not in SHAPERS:
            raise ValueError(f"shaper must be one of {SHAPERS}, got {kind!r}")
        if not (omega > 0 and 0 <= zeta < 1):
            raise ValueError(f"need omega > 0 and 0 <= zeta < 1, got omega = {omega}, zeta = {zeta}")
        if kind == "none":
            return cls(np.ones(1), np.zeros(1))
        K = math.exp(-zeta * math.pi / math.sqrt(1.0 - zeta ** 2))
        half = math.pi / (omega * math.sqrt(1.0 - zeta ** 2))  # half a damped period
        if kind == "zv":
            return cls(np.array([1.0, K]) / (1.0 + K), np.array([0.0, half]))
        return cls(np.array([1.0, 2.0 * K, K ** 2]) / (1.0 + K) ** 2, np.array([0.0, half, 2.0 * half]))

    @property
    def duration(self) -> float:
        return float(self.times[-1])

    def residual(self, omega: float, zeta: float = 0.0) -> float:
        """V(omega): the residual vibration of a mode (omega, zeta) after the shaped move, as a
        share of the unshaped one's (module docstring)."""
        wd = omega * math.sqrt(1.0 - zeta ** 2)
        growth = libm.exp(zeta * omega * self.times)
        c = np.sum(self.amplitudes * growth * libm.cos(wd * self.times))
        s = np.sum(self.amplitudes * growth * libm.sin(wd * self.times))
        return float(math.exp(-zeta * omega * self.duration) * math.hypot(c, s))

    def progress(self, t, move_time: float) -> tuple:
        """``(s, ds/dt)``: the share of the move done at times ``t`` [s], a cosine ramp of
        ``move_time`` [s] convolved with the impulses."""
        t = np.asarray(t, dtype=float)
        s = np.zeros_like(t)
        v = np.zeros_like(t)
        for a, t0 in zip(self.amplitudes, self.times):
            u = np.clip((t - t0) / move_time, 0.0, 1.0)
            s += a * 0.5 * (1.0 - libm.cos(math.pi * u))
            inside = (t - t0 > 0.0) & (t - t0 < move_time)
            v += a * np.where(inside, 0.5 * math.pi / move_time * libm.sin(math.pi * u), 0.0)
        return s, v


def pendulum_mode(A: np.ndarray, period: float) -> tuple:
    """``(omega [rad/s], zeta)`` of the slowest oscillatory mode of the linearised control step
    ``A`` (REDUCED) with the pivot held (its rows and columns dropped); ``period`` [s]."""
    free = np.ones(REDUCED.size, dtype=bool)
    free[REDUCED["pivot_error"]] = False
    free[REDUCED["pivot_velocity"]] = False
    eig = np.linalg.eigvals(A[np.ix_(free, free)])
    s = np.array([cmath.log(e) for e in eig.astype(complex)]) / period  # the C library's, as libm.py says
    oscillatory = s[s.imag > 1e-9]
    slowest = oscillatory[np.argmin(np.abs(oscillatory))]
    omega = float(abs(slowest))
    # the variational step conserves energy: the mode is undamped but for the differences' error
    return omega, max(0.0, float(-slowest.real / omega))


class ShapedLQR(LQR):
    """:class:`LQR` tracking the shaped path from the episode's start to its target (module
    docstring): a = -K (z - z_ref(t)) - G^-1 B' sum_j (A - BK)'^j P d_k+j with
    d_k = A z_ref(t_k) - z_ref(t_k+1), cut after ``preview`` steps. Stateful: the path starts
    at the first observation after :meth:`reset`."""

    def __init__(self, base: LQR, period: float, shaper: Shaper, move_time: float, preview: int = 150):
        super().__init__(base.K, base.axis, base.A, base.B, base.P, base.R, base.k_spin)
        self._preview = preview_terms(self.A, self.B, self.K, self.P, self.R, preview)
        self.period = float(period)
        self.shaper = shaper
        self.move_time = float(move_time)
        self._start = None
        self._step = 0

    @classmethod
    def design(cls, setup, episode=None, control_weight: float = 100.0, shaper: str = "zvd",
               move_time: float = 3.0, preview: int = 150) -> "ShapedLQR":
        """The LQR of ``setup`` (``episode``: default nominal) and the ``shaper`` for its
        pendulum mode."""
        base = LQR.design(setup, episode, control_weight)
        omega, zeta = pendulum_mode(base.A, setup.control_period)
        return cls(base, setup.control_period, Shaper.design(shaper, omega, zeta), move_time, preview)

    def reset(self, env=None) -> None:
        self._start = None
        self._step = 0

    def path(self, times) -> np.ndarray:
        """z_ref at ``times`` [s] from the start, (T, 16): pivot and load on the shaped path
        from the start's pivot error to 0, at its velocity, the body hanging straight."""
        s, v = self.shaper.progress(times, self.move_time)
        out = np.zeros((len(s), REDUCED.size))
        for name in ("pivot_error", "load_error"):
            out[:, REDUCED[name]] = self._start[None, :] * (1.0 - s[:, None])
        for name in ("pivot_velocity", "load_velocity"):
            out[:, REDUCED[name]] = -self._start[None, :] * v[:, None]
        return out

    def act(self, obs: np.ndarray, setup) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float64)
        z = reduced_state(obs, self.axis)
        if self._start is None:
            self._start = z[REDUCED["pivot_error"]].copy()
        ref = self.path(self.period * (self._step + np.arange(len(self._preview[1]) + 1)))
        drift = ref[:-1] @ self.A.T - ref[1:]
        self._step += 1
        force = -self.K @ (z - ref[0]) + preview_feedforward(self._preview, drift)
        return self.action(force, obs, setup)


def frequency_spread(setup, draws: int = 100, seed: int = 0) -> np.ndarray:
    """The pendulum frequency [rad/s] of ``draws`` episodes drawn by ``setup``'s randomiser
    (each linearised on its own scene)."""
    from agents.baselines.lqr import linearize

    rng = np.random.default_rng(seed)
    return np.array([pendulum_mode(linearize(setup, setup.draw_episode(rng))[0], setup.control_period)[0]
                     for _ in range(draws)])


def main(argv=None) -> dict:
    """Print the nominal mode and its spread under the default randomisation; plot V(w) of the
    shapers against the spread (docs/img/shaping.png)."""
    from pathlib import Path

    from agents.cli import ArgumentParser
    from agents.baselines.lqr import linearize
    from esp_gym.pendulum.env_setup import make_setup
    from esp_gym.viz.figures import new_figure, save_figure

    ap = ArgumentParser(prog="python -m agents.baselines.shaping", description=main.__doc__.split(";")[0])
    ap.add_argument("--draws", type=int, default=100, help="randomised episodes for the spread")
    ap.add_argument("--out", default="docs/img", help="directory for shaping.png")
    a = ap.parse_args(argv)
    ap.check_minimums(vars(a), draws=2)
    setup = make_setup(task="transport", randomize=True)
    omega, zeta = pendulum_mode(linearize(setup)[0], setup.control_period)
    spread = frequency_spread(setup, a.draws)
    ratio = np.linspace(0.5, 1.5, 401)
    fig = new_figure((6.4, 3.8))
    ax = fig.subplots()
    for kind in SHAPERS[1:]:
        shaper = Shaper.design(kind, omega, zeta)
        ax.plot(ratio, [shaper.residual(r * omega, zeta) for r in ratio], label=kind.upper())
    counts = ax.twinx()  # the spread on its own axis: episodes per bin
    counts.hist(spread / omega, bins=20, alpha=0.3, color="0.4", label=f"randomised episodes ({a.draws})")
    counts.set_ylabel("episodes")
    counts.legend(loc="upper center", fontsize=8)
    ax.set_xlabel("pendulum frequency / design frequency")
    ax.set_ylabel("residual swing / unshaped")
    ax.set_title(f"transport shapers, design w = {omega:.3f} rad/s")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    save_figure(fig, Path(a.out) / "shaping.png")
    q = np.percentile(spread, [0, 5, 50, 95, 100])
    result = {"omega": omega, "zeta": zeta, "spread_percentiles_0_5_50_95_100": q.tolist(),
              "zv_worst_in_5_95": max(Shaper.design("zv", omega).residual(w) for w in q[1:4]),
              "zvd_worst_in_5_95": max(Shaper.design("zvd", omega).residual(w) for w in q[1:4])}
    print(result)
    return result


if __name__ == "__main__":
    main()
