"""``python -m sdc_gym.precompile``: after it, an env's first use compiles nothing."""

from __future__ import annotations

import io

import gymnasium as gym
import numpy as np
from numba.core import event
from rich.console import Console

import sdc_gym  # noqa: F401  (registers the envs)
from sdc_gym.kernel_compiler import _CompileCounter
from sdc_gym.precompile import FAMILIES, precompile


def test_every_env_is_precompiled_by_default() -> None:
    assert sorted(env for family in FAMILIES for env in family) == sorted(
        env for env in gym.registry if env.startswith("sdc_gym/"))


def test_after_precompiling_an_env_its_first_use_here_compiles_nothing() -> None:
    out = io.StringIO()
    [done] = precompile([("sdc_gym/TrackLoop-v0",)], workers=1,
                        console=Console(file=out, force_terminal=False, width=200))
    assert done.env_id == "sdc_gym/TrackLoop-v0" and done.kernels >= 0
    assert done.cpu_seconds > 0
    text = out.getvalue()
    assert "precompiling sdc-gym's kernels for 1 envs" in text
    assert f"sdc_gym/TrackLoop-v0: {done.kernels} kernels compiled" in text
    # This process loads what the worker cached: numba emits no compile event.
    counter = _CompileCounter(lambda name, count: None)
    event.register("numba:compile", counter)
    try:
        env = gym.make("sdc_gym/TrackLoop-v0")
        env.reset(seed=0)
        env.step(np.zeros(env.action_space.shape, dtype=env.action_space.dtype))
        env.close()
    finally:
        event.unregister("numba:compile", counter)
    assert counter.count == 0


def test_a_worker_count_below_one_is_refused_naming_the_argument(capsys) -> None:
    import pytest

    from sdc_gym.precompile import main

    with pytest.raises(SystemExit) as exit_info:
        main(["--workers", "0"])
    assert exit_info.value.code == 2
    assert "--workers 0: a number of processes, 1 or more" in capsys.readouterr().err
