"""Callbacks for training: the task metrics of finished episodes, logged like SB3's episode return; checkpoints."""

from __future__ import annotations

from collections import deque

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

__all__ = ["CheckpointCallback", "EpisodeMetricsCallback"]


class CheckpointCallback(BaseCallback):
    """Call ``save()`` each time ``every`` more timesteps have passed since the last call (or the start of
    ``learn``): what lets a killed run resume from its last checkpoint."""

    def __init__(self, every: int, save, verbose: int = 0):
        super().__init__(verbose)
        self.every, self.save, self.last = int(every), save, 0

    def _on_training_start(self) -> None:
        self.last = self.num_timesteps

    def _on_step(self) -> bool:
        if self.num_timesteps - self.last >= self.every:
            self.save()
            self.last = self.num_timesteps
        return True


class EpisodeMetricsCallback(BaseCallback):
    """Log ``episode_metrics/<name>``: the mean of each task metric over the last ``window`` finished episodes.

    Reads ``infos[i]["episode_metrics"]`` on the rows whose ``dones[i]`` is set (both
    :class:`~polyenvs.training.vec_adapter.NativeVecEnvAdapter` and ``DummyVecEnv`` put the finished episode's
    metrics there) and records the means at the end of every rollout, so they reach TensorBoard with SB3's own
    ``rollout/ep_rew_mean`` (a window of 100 episodes, like ``stats_window_size``).
    """

    def __init__(self, window: int = 100, prefix: str = "episode_metrics", verbose: int = 0):
        super().__init__(verbose)
        self.window = window
        self.prefix = prefix
        self.buffers: dict[str, deque[float]] = {}
        self.episodes = 0

    def _on_step(self) -> bool:
        dones = self.locals.get("dones")
        infos = self.locals.get("infos")
        if dones is None or infos is None:
            return True
        for row in np.flatnonzero(dones).tolist():
            metrics = infos[row].get("episode_metrics")
            if not metrics:
                continue
            self.episodes += 1
            for name, value in metrics.items():
                if name.startswith("_"):
                    continue
                buffer = self.buffers.get(name)
                if buffer is None:
                    buffer = self.buffers[name] = deque(maxlen=self.window)
                buffer.append(float(value))
        return True

    def means(self) -> dict[str, float]:
        """The current window means, by metric name."""
        return {name: float(np.mean(buffer)) for name, buffer in self.buffers.items() if buffer}

    def _on_rollout_end(self) -> None:
        for name, value in self.means().items():
            self.logger.record(f"{self.prefix}/{name}", value)
