"""Callbacks for training: the task metrics of finished episodes, logged like SB3's episode return; the learning
curve; checkpoints."""

from __future__ import annotations

from collections import deque

import numpy as np
from stable_baselines3.common.callbacks import BaseCallback

__all__ = ["CheckpointCallback", "EpisodeMetricsCallback", "LearningCurveCallback", "curve_document"]


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
    :class:`~polyenvs.training.vec_adapter.NativeVecEnvAdapter` and the project's ``DummyVecEnv``, whose envs
    :class:`~polyenvs.core.episode_metrics.RecordEpisodeMetrics` wraps, put the finished episode's metrics there,
    time-limit truncations included; a ``DummyVecEnv`` of bare ``gym.make`` envs lacks them on those) and records
    the means at the end of every rollout, so they reach TensorBoard with SB3's own ``rollout/ep_rew_mean`` (a
    window of 100 episodes, like ``stats_window_size``).
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


class LearningCurveCallback(BaseCallback):
    """Write the learning curve to ``path`` at the end of a rollout (the first, then one at least ``every``
    timesteps after the last written: an off-policy algorithm's rollout can be one step): the timesteps, the mean
    return of SB3's episode window (``rollout/ep_rew_mean``) and the task metrics' window means of ``metrics``.

    The file (``curve.json``: ``{"timesteps": [...], "return": [...], "metrics": {name: [...]}}``, ``None`` where no
    episode had finished yet) is rewritten atomically each time; ``resume_from`` is what an interrupted run wrote,
    cut to the timesteps its saved model reached, so a resumed run's curve continues without a gap or a repeat.
    """

    def __init__(self, metrics: EpisodeMetricsCallback, path, resume_from: dict | None = None, every: int = 1000):
        super().__init__()
        self.metrics, self.path, self.every = metrics, path, every
        self.rows: list[dict] = _curve_rows(resume_from) if resume_from else []

    def _on_training_start(self) -> None:
        self.rows = [row for row in self.rows if row["timesteps"] <= self.num_timesteps]

    def _on_step(self) -> bool:
        return True

    def _on_rollout_end(self) -> None:
        from polyenvs.files import write_json_atomic

        if self.rows and self.num_timesteps - self.rows[-1]["timesteps"] < self.every:
            return
        episodes = self.model.ep_info_buffer
        mean_return = float(np.mean([info["r"] for info in episodes])) if episodes else None
        self.rows.append({"timesteps": int(self.num_timesteps), "return": mean_return, **self.metrics.means()})
        write_json_atomic(self.path, curve_document(self.rows))


def curve_document(rows: list[dict]) -> dict:
    """The columns of ``curve.json`` from its rows (one per rollout)."""
    names = sorted({name for row in rows for name in row} - {"timesteps", "return"})
    return {
        "timesteps": [row["timesteps"] for row in rows],
        "return": [row["return"] for row in rows],
        "metrics": {name: [row.get(name) for row in rows] for name in names},
    }


def _curve_rows(document: dict) -> list[dict]:
    """The rows of a ``curve.json`` document (the inverse of :func:`curve_document`)."""
    rows = [{"timesteps": t, "return": r} for t, r in zip(document["timesteps"], document["return"], strict=True)]
    for name, values in document["metrics"].items():
        for row, value in zip(rows, values, strict=True):
            if value is not None:
                row[name] = value
    return rows
