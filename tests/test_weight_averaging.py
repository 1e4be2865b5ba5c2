"""Weight averaging (sdc_training.weight_averaging, train.py's ``averaging`` key): the
average is the known mean of the samples (uniform or exponential), the averaged weights
are lent to the policy and given back, the average survives a checkpoint and a resume,
train.py writes ``averaged_model.zip`` and validates it, and bad settings are clear errors."""

from __future__ import annotations

import csv

import pytest
import torch
import yaml

import train
from sdc_gym.config import ConfigError
from sdc_training.validation_laps import CSV_NAME
from sdc_training.weight_averaging import (
    AVERAGED_NAME,
    WeightAverage,
    averaging_callback,
    load_state,
    save_state,
    state_path,
)

HIGHWAY = "sdc_gym/HighwayLoopBehavior-v0"


def filled(module: torch.nn.Module, value: float) -> torch.nn.Module:
    with torch.no_grad():
        for parameter in module.parameters():
            parameter.fill_(value)
    return module


def test_uniform_and_exponential_means_have_known_answers():
    net = torch.nn.Linear(3, 2)
    uniform, ema = WeightAverage(net), WeightAverage(net, decay=0.5)
    for value in (1.0, 2.0, 6.0):
        filled(net, value)
        uniform.add(net)
        ema.add(net)
    assert uniform.count == ema.count == 3
    # Uniform: (1 + 2 + 6) / 3 = 3. EMA with decay 0.5: 1, then 1.5, then 3.75.
    assert torch.all(uniform.average.module.weight == 3.0)
    assert torch.all(ema.average.module.bias == 3.75)


def test_the_average_is_lent_to_the_policy_and_given_back():
    net = filled(torch.nn.Linear(2, 2), 1.0)
    optimizer = torch.optim.SGD(net.parameters(), lr=0.1)
    average = WeightAverage(net)
    average.add(net)
    filled(net, 5.0)
    average.add(net)
    with average.applied(net):
        assert torch.all(net.weight == 3.0)
    assert torch.all(net.weight == 5.0)
    # The optimizer still holds the module's own parameters (copied in place).
    assert optimizer.param_groups[0]["params"][0] is net.weight
    with pytest.raises(RuntimeError), average.applied(net):
        raise RuntimeError("an error inside the block")
    assert torch.all(net.weight == 5.0)


def test_a_saved_average_loads_back_and_refuses_another_decay(tmp_path):
    net = filled(torch.nn.Linear(2, 1), 2.0)
    average = WeightAverage(net)
    average.add(net)
    filled(net, 4.0)
    average.add(net)
    path = state_path(tmp_path, 1000)
    save_state(average, path)
    assert path.name == "averaged_1000_steps.pt"
    restored = WeightAverage(filled(torch.nn.Linear(2, 1), 0.0))
    load_state(restored, path)
    assert restored.count == 2 and torch.all(restored.average.module.weight == 3.0)
    filled(net, 9.0)
    restored.add(net)  # the mean goes on over 3 samples: (2 + 4 + 9) / 3 = 5
    assert torch.all(restored.average.module.weight == 5.0)
    with pytest.raises(ValueError, match=r"decay None, this run 0\.9"):
        load_state(WeightAverage(net, decay=0.9), path)


def test_a_resumed_callback_goes_on_at_the_next_sample_point(tmp_path):
    class Model:
        policy = filled(torch.nn.Linear(2, 1), 1.0)

    average = WeightAverage(Model.policy)
    for _ in range(3):  # samples at 1000, 1400, 1800
        average.add(Model.policy)
    save_state(average, state_path(tmp_path, 2000))
    callback = averaging_callback(Model(), tmp_path, every=400, start=1000, decay=None,
                                  checkpoint_every=10, resume_steps=2000)
    assert callback.average.count == 3 and callback.next_sample == 2200
    (tmp_path / "fresh").mkdir()  # a checkpoint before the first sample: none saved
    before = averaging_callback(Model(), tmp_path / "fresh", every=400, start=5000,
                                decay=None, checkpoint_every=10, resume_steps=2000)
    assert before.average.count == 0 and before.next_sample == 5000


def test_train_writes_and_validates_the_averaged_model_and_resumes_it(tmp_path, capsys):
    from stable_baselines3 import DQN

    config = tmp_path / "run.yaml"
    config.write_text(yaml.safe_dump({
        "env": HIGHWAY, "config": {"highway": {"max_duration": 20.0}}, "algo": "dqn",
        "eval": {"every": 0}, "validation": {"every": 200, "episodes": 2, "seed": 2000},
        "averaging": {"every": 50, "start": 100}}))
    output = tmp_path / "run"
    args = ["--config", str(config), "--output", str(output), "--n-envs", "2",
            "--timesteps", "400", "--checkpoint-every", "200", "--hp", "learning_starts=50",
            "--hp", "buffer_size=1000", "--hp", "policy_kwargs.net_arch=[16]",
            "--no-progress"]
    train.main(args)
    checkpoints = output / "checkpoints"
    # Samples at 100, 150, ..., 400 env steps: 7; the 200-step checkpoint holds 3.
    saved = torch.load(state_path(checkpoints, 200), weights_only=True)
    assert saved["count"] == 3
    final = torch.load(state_path(checkpoints, 400), weights_only=True)
    assert final["count"] == 7
    averaged = DQN.load(output / AVERAGED_NAME)
    online = DQN.load(output / "model.zip")
    for name, tensor in averaged.policy.state_dict().items():
        assert torch.equal(tensor, final["weights"][name])
    assert not all(torch.equal(tensor, online.policy.state_dict()[name])
                   for name, tensor in averaged.policy.state_dict().items())
    with (output / CSV_NAME).open() as handle:
        rows = [(int(row["timesteps"]), row["weights"]) for row in csv.DictReader(handle)]
    assert rows == [(200, "online"), (200, "averaged"), (400, "online"), (400, "averaged")]
    assert "weight average of 7 samples" in capsys.readouterr().out
    # Resumed from the 200-step checkpoint: the average goes on from its 3 samples to 7
    # again, and is the same as the uninterrupted run's (the same samples).
    for name in ("dqn_400_steps.zip", "dqn_replay_buffer_400_steps.pkl",
                 "averaged_400_steps.pt"):
        (checkpoints / name).unlink()
    train.main(["--output", str(output), "--resume", "--no-progress"])
    out = capsys.readouterr().out
    assert "weight average from" in out and "(3 samples)" in out
    assert "weight average of 7 samples" in out


@pytest.mark.parametrize(("averaging", "message"), [
    ({"every": -1}, r"'averaging\.every' must be an int in \[0, "),
    ({"every": 100, "decay": 1.0}, "'averaging.decay' must be None or a finite number"),
    ({"every": 100, "start": 1.5}, "'averaging.start' must be an int"),
    ({"every": 100, "from": 3}, "'averaging' must be a mapping with keys of "
                                "\\['decay', 'every', 'start'\\]"),
])
def test_bad_averaging_settings_are_clear_errors(tmp_path, averaging, message):
    config = tmp_path / "run.yaml"
    config.write_text(yaml.safe_dump({"env": HIGHWAY, "config": {}, "averaging": averaging}))
    with pytest.raises(SystemExit, match=message):
        train.run_config(train.parse_args(["--config", str(config), "--output",
                                           str(tmp_path / "run")]))


def test_averaging_is_refused_with_rllib_and_on_resume(tmp_path):
    with pytest.raises(ConfigError, match=r"'averaging\.every' must be 0 with framework rllib"):
        train.check_averaging({"averaging": {"every": 10}, "framework": "rllib"}, "run.yaml")
    with pytest.raises(SystemExit):
        train.parse_args(["--output", str(tmp_path), "--resume", "--average-every", "10"])
