"""The RLlib callback of ``train.py --framework rllib``: driving metrics per episode.

It runs in the env runners (any process of the cluster): at the end of each episode the
env's ``info["summary"]`` becomes the ``driving/`` scalars of
:mod:`sdc_training.driving_metrics`, averaged by RLlib over the last
:data:`EPISODES_WINDOW` episodes (as its ``episode_return_mean``), and so reach the
results (``env_runners/driving/...``), TensorBoard and Tune.
"""

from __future__ import annotations

from typing import Any

from ray.rllib.callbacks.callbacks import RLlibCallback

from sdc_training.driving_metrics import driving_metrics

EPISODES_WINDOW = 100
"""Episodes each driving metric is averaged over (RLlib's ``episode_return_mean`` too)."""


class DrivingMetricsCallback(RLlibCallback):
    """Logs each finished episode's driving summary (``driving/...``)."""

    def on_episode_end(self, *, episode: Any, metrics_logger: Any = None,
                       **kwargs: Any) -> None:
        summary = (episode.get_infos(-1) or {}).get("summary")
        if not summary or metrics_logger is None:
            return
        for name, value in driving_metrics(summary):
            metrics_logger.log_value(name, float(value), reduce="mean",
                                     window=EPISODES_WINDOW)
