"""Weight averaging in train.py: a running mean of the policy's weights (SWA or EMA).

A greedy value-based policy is hypersensitive to its last gradient steps: on the highway
behavior env, four more gradient steps (the largest weight change 0.005) moved a DQN's
validation laps from 44.61 to 46.76 mph, and neighbouring 200k checkpoints differ by
1-3 mph (docs/rl.md). Averaging the weights over the end of training (stochastic weight
averaging, Izmailov et al. 2018) removes most of that noise: the mean of five checkpoints
drove 1.2 mph faster than those checkpoints did on average. This module does it during
training, densely, with :class:`torch.optim.swa_utils.AveragedModel`:

* from ``start`` env steps on, every ``every`` env steps, the policy's weights (and
  buffers) are added to the average: a uniform mean of every sample (``decay: null``,
  SWA), or an exponential one (``decay`` in (0, 1), per sample);
* at each checkpoint the average is saved beside it (``checkpoints/averaged_<steps>_steps
  .pt``: the averaged weights and how many samples they hold), so ``--resume`` goes on
  with the same average;
* at the end it is written as ``averaged_model.zip``, an SB3 model like ``model.zip``
  (``evaluate.py`` and ``validate_policies.py`` load it as any other), and the validation
  laps (run config ``validation``) score it beside the online weights.

Run config key ``averaging``: ``{every: 0 (off), start: 0, decay: null}``
(:data:`sdc_gym.validation.run_config.AVERAGING_DEFAULTS`).
"""

from __future__ import annotations

import contextlib
import copy
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

AVERAGED_NAME = "averaged_model.zip"


def state_path(checkpoints: Path, steps: int) -> Path:
    """Where the average is saved with the checkpoint of ``steps`` env steps."""
    return checkpoints / f"averaged_{steps}_steps.pt"


class WeightAverage:
    """The running average of one torch module's weights and buffers.

    ``decay`` None: the uniform mean of every sample added (SWA); a number in (0, 1): an
    exponential moving average, ``avg = decay * avg + (1 - decay) * sample`` (the first
    sample is taken as it is).
    """

    def __init__(self, module: Any, decay: float | None = None) -> None:
        from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

        self.decay = decay
        self.average = AveragedModel(
            module, use_buffers=True,
            multi_avg_fn=None if decay is None else get_ema_multi_avg_fn(decay))

    @property
    def count(self) -> int:
        """How many samples the average holds."""
        return int(self.average.n_averaged.item())

    def add(self, module: Any) -> None:
        """Add ``module``'s current weights to the average."""
        self.average.update_parameters(module)

    def state(self) -> dict[str, Any]:
        """What :meth:`load` takes back: the averaged weights and the sample count."""
        return {"weights": copy.deepcopy(self.average.module.state_dict()),
                "count": self.count, "decay": self.decay}

    def load(self, state: Mapping[str, Any]) -> None:
        """Go on from a :meth:`state` (a resumed run); ValueError when it does not fit."""
        if state.get("decay") != self.decay:
            raise ValueError(f"the saved average has decay {state.get('decay')!r}, this run "
                             f"{self.decay!r}")
        self.average.module.load_state_dict(state["weights"])
        self.average.n_averaged.fill_(int(state["count"]))

    @contextlib.contextmanager
    def applied(self, module: Any) -> Iterator[None]:
        """``module`` holds the averaged weights inside the block, its own ones after it
        (copied in place: an optimizer's references to the parameters stay valid)."""
        own = copy.deepcopy(module.state_dict())
        module.load_state_dict(self.average.module.state_dict())
        try:
            yield
        finally:
            module.load_state_dict(own)


def save_state(average: WeightAverage, path: Path) -> None:
    """Write ``average``'s state to ``path`` atomically (torch.save)."""
    import torch

    from sdc_agents.checkpoints import atomic_file

    with atomic_file(path) as handle:
        torch.save(average.state(), handle)


def load_state(average: WeightAverage, path: Path) -> None:
    """Load a state written by :func:`save_state` into ``average``."""
    import torch

    average.load(torch.load(path, map_location="cpu", weights_only=True))


def save_averaged_model(model: Any, average: WeightAverage, path: Path) -> None:
    """``model`` saved with the averaged weights (an SB3 zip, written atomically)."""
    from sdc_agents.checkpoints import save_model

    with average.applied(model.policy):
        save_model(model, path)


def averaging_callback(model: Any, checkpoints: Path, *, every: int, start: int,
                       decay: float | None, checkpoint_every: int,
                       resume_steps: int | None = None) -> Any:
    """An SB3 callback keeping a :class:`WeightAverage` of ``model.policy``.

    A sample is taken at the first batch step at or past each of ``start``,
    ``start + every``, ... env steps; the state is saved every ``checkpoint_every``
    callback calls (the checkpoint callback's schedule: put this one after it). With
    ``resume_steps`` the state saved with that checkpoint is loaded (a run that reaches no
    sample before it has none saved, and starts the average afresh).
    """
    from stable_baselines3.common.callbacks import BaseCallback

    average = WeightAverage(model.policy, decay)
    next_sample = start
    if resume_steps is not None:
        saved = state_path(checkpoints, resume_steps)
        if saved.is_file():
            load_state(average, saved)
            print(f"--resume: weight average from {saved} ({average.count} samples)")
        elif resume_steps > start:
            print(f"--resume: no weight average saved at {resume_steps} steps ({saved}); "
                  "the average starts afresh")
        if resume_steps >= start:  # the next sample point after the checkpoint's
            next_sample = start + ((resume_steps - start) // every + 1) * every

    class WeightAveragingCallback(BaseCallback):
        def __init__(self) -> None:
            super().__init__()
            self.average = average
            self.next_sample = next_sample

        def _on_step(self) -> bool:
            if self.num_timesteps >= self.next_sample:
                self.average.add(self.model.policy)
                while self.next_sample <= self.num_timesteps:
                    self.next_sample += every
            if self.n_calls % checkpoint_every == 0 and self.average.count:
                save_state(self.average, state_path(checkpoints, self.num_timesteps))
            return True

    return WeightAveragingCallback()
