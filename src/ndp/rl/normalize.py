"""Running observation and return normalisation (numpy, float64, checkpointable)."""

from __future__ import annotations

import warnings
from typing import TypedDict

import numpy as np
import numpy.typing as npt


class RunningStats(TypedDict):
    """The state of a :class:`RunningMeanStd` (a checkpoint's, or an export's ``obs_norm``
    read back from JSON, where the arrays are lists)."""

    mean: npt.ArrayLike
    """Mean per entry."""
    var: npt.ArrayLike
    """Variance per entry."""
    count: float
    """Samples merged (with the initial pseudo-count)."""


class RunningMeanStd:
    """Running mean and variance over batches (parallel-variance merge).

    Args:
        shape: shape of one sample.
        epsilon: initial pseudo-count (keeps the first normalisations finite).
    """

    def __init__(self, shape: tuple[int, ...] = (), epsilon: float = 1e-4) -> None:
        self.mean = np.zeros(shape, dtype=np.float64)
        self.var = np.ones(shape, dtype=np.float64)
        self.count = float(epsilon)

    def update(self, x: np.ndarray) -> None:
        """Merge a batch ``x`` [n, *shape] into the statistics."""
        x = np.asarray(x, dtype=np.float64)
        if x.shape[0] == 0:
            return
        b_mean, b_var, b_count = x.mean(0), x.var(0), x.shape[0]
        delta = b_mean - self.mean
        tot = self.count + b_count
        self.mean = self.mean + delta * b_count / tot
        m2 = self.var * self.count + b_var * b_count + delta**2 * self.count * b_count / tot
        self.var = m2 / tot
        self.count = tot

    def state_dict(self) -> RunningStats:
        """Statistics as plain arrays."""
        return {"mean": self.mean.copy(), "var": self.var.copy(), "count": self.count}

    def load_state_dict(self, d: RunningStats) -> None:
        """Restore from :meth:`state_dict`."""
        self.mean = np.asarray(d["mean"], dtype=np.float64).copy()
        self.var = np.asarray(d["var"], dtype=np.float64).copy()
        self.count = float(d["count"])


class ObsNormalizer:
    """``clip((obs - mean) / sqrt(var + eps), -clip, clip)`` with running statistics.

    Args:
        obs_dim: observation size.
        clip: clip of the normalised values.
        enabled: when False, observations pass through unchanged (as float32).
    """

    def __init__(self, obs_dim: int, clip: float = 10.0, enabled: bool = True) -> None:
        self.rms = RunningMeanStd((obs_dim,))
        self.clip = float(clip)
        self.enabled = bool(enabled)
        self.warn_clip = False
        """Say once (a warning) when an observation is clipped: set for a loaded policy, whose
        statistics are frozen, so that inputs far outside what it was trained on are not
        silently cut to the bound; a training run clips quietly (its statistics move)."""

    def __call__(self, obs: np.ndarray, update: bool = False) -> np.ndarray:
        """Normalise ``obs`` [n, O] (updating the statistics first if ``update``) -> float32."""
        obs = np.asarray(obs, dtype=np.float64)
        if not self.enabled:
            return obs.astype(np.float32)
        if update:
            self.rms.update(obs)
        z = (obs - self.rms.mean) / np.sqrt(self.rms.var + 1e-8)
        if self.warn_clip and not update and np.abs(z).max(initial=0.0) > self.clip:
            self.warn_clip = False  # once per policy
            idx = np.unravel_index(int(np.argmax(np.abs(z))), z.shape)
            warnings.warn(
                f"obs: entry {list(map(int, idx))} is {float(obs[idx]):.3g}, "
                f"{float(abs(z[idx])):.3g} std from the training mean: clipped to the "
                f"normaliser's bound (+-{self.clip:g} std); the policy has not seen such inputs "
                "(said once per policy)",
                RuntimeWarning,
                stacklevel=3,
            )
        return np.clip(z, -self.clip, self.clip).astype(np.float32)

    def state_dict(self) -> RunningStats:
        """Running statistics."""
        return self.rms.state_dict()

    def load_state_dict(self, d: RunningStats) -> None:
        """Restore the running statistics."""
        self.rms.load_state_dict(d)


class ReturnNormalizer:
    """Scale rewards by the running std of each env's discounted return (per sub-step).

    For each executed sub-step: ``G <- gamma * G + r``; the statistics are updated with the G
    values; the reward becomes ``clip(r / sqrt(var + eps), -clip, clip)``. G restarts at 0 when
    an episode ends.

    Args:
        num_envs: E.
        gamma: discount per sub-step.
        clip: clip of the scaled rewards.
        enabled: when False, rewards pass through unchanged.
    """

    def __init__(
        self, num_envs: int, gamma: float, clip: float = 10.0, enabled: bool = True
    ) -> None:
        self.rms = RunningMeanStd(())
        self.ret = np.zeros(num_envs, dtype=np.float64)
        self.gamma = float(gamma)
        self.clip = float(clip)
        self.enabled = bool(enabled)

    def __call__(self, rewards: np.ndarray, masks: np.ndarray, ends: np.ndarray) -> np.ndarray:
        """Scale one decision's rewards.

        Args:
            rewards: [E, k] raw sub-step rewards.
            masks: [E, k] executed sub-steps.
            ends: [E] episode ended during this decision.

        Returns:
            [E, k] scaled rewards (float64), 0 where not executed.
        """
        r: npt.NDArray[np.float64] = np.asarray(rewards, dtype=np.float64) * masks
        if not self.enabled:
            return r
        k = r.shape[1]
        rets = np.empty_like(r)
        for j in range(k):
            self.ret = np.where(masks[:, j] > 0, self.gamma * self.ret + r[:, j], self.ret)
            rets[:, j] = self.ret
        self.rms.update(rets[masks > 0])
        self.ret[np.asarray(ends, dtype=bool)] = 0.0
        scaled = r / np.sqrt(self.rms.var + 1e-8)
        out: npt.NDArray[np.float64] = np.clip(scaled, -self.clip, self.clip) * masks
        return out

    def scale(self, x: np.ndarray | float) -> np.ndarray | float:
        """Divide by the current return std (no update, no clip)."""
        if not self.enabled:
            return x
        return x / np.sqrt(self.rms.var + 1e-8)

    def state_dict(self) -> RunningStats:
        """Running statistics (the per-env running returns are episode state, not saved)."""
        return self.rms.state_dict()

    def load_state_dict(self, d: RunningStats) -> None:
        """Restore the running statistics."""
        self.rms.load_state_dict(d)
