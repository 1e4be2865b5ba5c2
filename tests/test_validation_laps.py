"""Validation laps (sdc_training.validation_laps): the batch drives each seed's episode as
the single env does, scores rank models the way issue 28 asks (mph without collision; lap
time without a red light), and train.py's ``validation`` key keeps every result and the
best model across a resume, with clear errors for bad values."""

from __future__ import annotations

import argparse
import csv

import gymnasium as gym
import numpy as np
import pytest
import yaml

import sdc_gym  # noqa: F401
import train
from sdc_gym.stack.highway.decisions import ACTION_NAMES
from sdc_training.validation_laps import (
    BEST_NAME,
    CSV_NAME,
    LapScore,
    drive_laps,
    lap_config,
    make_lap_envs,
    read_best,
    score_laps,
)

HIGHWAY = "sdc_gym/HighwayLoopBehavior-v0"
KEEP_CRUISE = ACTION_NAMES.index("keep/cruise")
LEFT_CRUISE = ACTION_NAMES.index("left/cruise")


def highway_summary(mph: float, collisions: int = 0, laps: int = 1, jerk: int = 0) -> dict:
    incidents = {name: count for name, count in (("collision", collisions), ("jerk", jerk))
                 if count}
    return {"mean_speed_mph": mph, "incidents": incidents,
            "incident_total": collisions + jerk, "laps": laps}


def track_summary(lap: float | None, red: int = 0) -> dict:
    return {"lap_times": [] if lap is None else [lap], "red_light_violations": red,
            "incidents": {"red_light": red} if red else {}, "incident_total": red,
            "stops": [{}] * 2}


def test_scores_have_known_answers_and_rank_by_eligibility():
    # mean 46, sample sd 2 over 4 laps: t(0.975, 3) = 3.1824 -> +-3.1824.
    fast = score_laps(HIGHWAY, [highway_summary(x) for x in (44.0, 46.0, 46.0, 48.0)])
    sd = np.std([44.0, 46.0, 46.0, 48.0], ddof=1)
    assert fast.value == 46.0 and fast.eligible and fast.higher_is_better
    assert fast.high - fast.value == pytest.approx(3.182446 * sd / 2.0, rel=1e-5)
    assert fast.counts == {"laps": 4, "collisions": 0, "incidents": 0}
    crashed = score_laps(HIGHWAY, [highway_summary(50.0, collisions=1),
                                   highway_summary(50.0, laps=0)])
    assert crashed.value == 50.0 and not crashed.eligible and crashed.counts["laps"] == 1
    assert fast.beats(None) and fast.beats(crashed) and not crashed.beats(fast)
    jerky = score_laps(HIGHWAY, [highway_summary(50.0, jerk=1), highway_summary(50.0)])
    assert not jerky.eligible and jerky.counts == {"laps": 2, "collisions": 0, "incidents": 1}
    slower = score_laps(HIGHWAY, [highway_summary(45.0), highway_summary(45.5)])
    assert not slower.beats(fast) and fast.beats(slower)
    # The track: shorter laps win; a red light or an unfinished lap makes a result ineligible.
    quick = score_laps("sdc_gym/TrackLoopBehavior-v0", [track_summary(650.0),
                                                        track_summary(660.0)])
    assert quick.value == 655.0 and quick.eligible and not quick.higher_is_better
    assert quick.counts == {"unfinished": 0, "red_lights": 0, "collisions": 0,
                            "incidents": 0, "stops": 4}
    ran_red = score_laps("sdc_gym/TrackLoopBehavior-v0", [track_summary(600.0, red=1),
                                                          track_summary(610.0)])
    unfinished = score_laps("sdc_gym/TrackLoopBehavior-v0", [track_summary(600.0),
                                                             track_summary(None)])
    assert not ran_red.eligible and not unfinished.eligible
    assert unfinished.counts["unfinished"] == 1 and np.isnan(unfinished.low)
    assert quick.beats(ran_red) and not ran_red.beats(quick)
    with pytest.raises(ValueError, match="HighwayLoop-v0"):
        lap_config("sdc_gym/HighwayLoop-v0", {})


def test_a_batch_of_laps_is_each_seeds_single_env_episode():
    """The batch (seed + i) ends each env once, with the single env's own summary; the
    action counts cover only the decisions of episodes still running."""
    config = {"highway": {"max_duration": 12.0}}
    envs = make_lap_envs(HIGHWAY, config, episodes=3, max_duration=12.0)
    assert lap_config(HIGHWAY, config, 12.0)["highway"] == {"max_duration": 12.0, "laps": 1}

    def policy(observations: np.ndarray) -> np.ndarray:  # a move left now and then
        return np.where(np.arange(len(observations)) == 1, LEFT_CRUISE, KEEP_CRUISE)

    batch = drive_laps(envs, policy, seed=2000)
    again = drive_laps(envs, policy, seed=2000)  # reusable: reset by the seed again
    envs.close()
    assert batch.summaries == again.summaries
    decisions = 0
    for index in range(3):
        env = gym.make(HIGHWAY, config=lap_config(HIGHWAY, config, 12.0))
        env.reset(seed=2000 + index)
        done = False
        while not done:
            action = LEFT_CRUISE if index == 1 else KEEP_CRUISE
            _, _, terminated, truncated, info = env.step(action)
            done = terminated or truncated
            decisions += 1
        env.close()
        assert batch.summaries[index] == info["summary"]
    assert batch.action_counts.sum() == decisions == 3 * 50  # 12 s / 0.24 s per decision
    assert batch.action_counts[LEFT_CRUISE] == 50


def test_train_validates_on_laps_keeps_the_best_and_resumes(tmp_path, capsys):
    from stable_baselines3 import DQN

    config = tmp_path / "run.yaml"
    config.write_text(yaml.safe_dump({
        "env": HIGHWAY, "config": {"highway": {"max_duration": 20.0}}, "algo": "dqn",
        "eval": {"every": 0}, "validation": {"every": 100, "episodes": 2, "seed": 2000}}))
    output = tmp_path / "run"
    args = ["--config", str(config), "--output", str(output), "--n-envs", "2",
            "--timesteps", "200", "--checkpoint-every", "100", "--hp", "learning_starts=50",
            "--hp", "buffer_size=1000", "--hp", "policy_kwargs.net_arch=[16]",
            "--no-progress"]
    train.main(args)
    with (output / CSV_NAME).open() as handle:
        rows = list(csv.DictReader(handle))
    assert [int(row["timesteps"]) for row in rows] == [100, 200]
    assert {"value", "low", "high", "eligible", "laps", "collisions"} <= set(rows[0])
    printed = [line for line in capsys.readouterr().out.splitlines()
               if line.startswith("Validation num_timesteps=")]
    assert len(printed) == 2 and "2 laps from seed 2000" in printed[0]
    best = read_best(output)
    eligible = [float(row["value"]) for row in rows if row["eligible"] == "True"]
    if eligible:  # an untrained DQN may collide; then no best model is written
        assert best is not None and best.value == max(eligible)
        model = DQN.load(output / BEST_NAME)
        assert model.num_timesteps in {int(r["timesteps"]) for r in rows
                                       if float(r["value"]) == best.value}
    else:
        assert best is None and not (output / BEST_NAME).exists()
    # Resumed from the 100-step checkpoint: the best so far is carried over, a row added.
    (output / "checkpoints" / "dqn_200_steps.zip").unlink()
    (output / "checkpoints" / "dqn_replay_buffer_200_steps.pkl").unlink()
    train.main(["--output", str(output), "--resume", "--no-progress"])
    with (output / CSV_NAME).open() as handle:
        assert [int(r["timesteps"]) for r in csv.DictReader(handle)] == [100, 200, 200]


def test_read_best_ignores_ineligible_rows(tmp_path):
    from sdc_training.validation_laps import append_row

    append_row(tmp_path, 100, LapScore(47.0, 46.0, 48.0, True, False, {"collisions": 1}))
    assert read_best(tmp_path) is None
    append_row(tmp_path, 200, LapScore(45.0, 44.0, 46.0, True, True, {"collisions": 0}))
    append_row(tmp_path, 300, LapScore(44.0, 43.0, 45.0, True, True, {"collisions": 0}))
    assert read_best(tmp_path).value == 45.0
    assert (tmp_path / CSV_NAME).read_text().count("\n") == 4  # header + 3 rows


@pytest.mark.parametrize(("validation", "env", "message"), [
    ({"every": 100, "episodes": 1}, HIGHWAY, "'validation.episodes' must be"),
    ({"every": -5}, HIGHWAY, "'validation.every' must be"),
    ({"every": 100, "laps": 3}, HIGHWAY, "'validation' must be a mapping with keys of "
                                         "\\['episodes', 'every', 'seed'\\]"),
    ({"every": 100}, "sdc_gym/HighwayLoop-v0",
     "'validation.every' must be 0 for env sdc_gym/HighwayLoop-v0: validation laps run on"),
])
def test_bad_validation_settings_are_clear_errors(tmp_path, validation, env, message):
    config = tmp_path / "run.yaml"
    config.write_text(yaml.safe_dump({"env": env, "config": {}, "validation": validation}))
    with pytest.raises(SystemExit, match=message):
        train.run_config(train.parse_args(["--config", str(config), "--output",
                                           str(tmp_path / "run")]))


def test_learning_curves_read_validation_laps_with_an_interval_over_training_seeds(tmp_path):
    """benchmarks/learning_curves.py --source validation: each run's validations.csv (the
    last row of a step validated twice), then the mean and 95 % t interval over the runs."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import learning_curves

    from sdc_training.validation_laps import append_row

    runs = [tmp_path / "seed1", tmp_path / "seed2"]
    for run, values in zip(runs, ([44.0, 46.0], [45.0, 47.0]), strict=True):
        run.mkdir()
        for steps, value in zip((200_000, 400_000), values, strict=True):
            append_row(run, steps, LapScore(value, value - 1, value + 1, True, True, {}))
    append_row(runs[1], 400_000, LapScore(48.0, 47.0, 49.0, True, True, {}))  # a resume
    assert learning_curves.validation_curve(runs[1]) == {200_000: 45.0, 400_000: 48.0}
    steps, mean, low, high = learning_curves.group_curve(runs, "validation")
    assert list(steps) == [200_000, 400_000] and list(mean) == [44.5, 47.0]
    # Two runs 1 apart (44, 45): sd 0.7071, t(0.975, 1) = 12.706 -> +-6.353.
    assert high[0] - mean[0] == pytest.approx(12.7062 * 0.70711 / 2 ** 0.5, rel=1e-4)
    assert mean[0] - low[0] == pytest.approx(high[0] - mean[0])
    with pytest.raises(SystemExit, match=r"no validations\.csv"):
        learning_curves.validation_curve(tmp_path)


def test_learning_curves_draw_the_averaged_weights_apart_from_the_online_ones(tmp_path):
    """``--averaged-group``: the rows ``weights=averaged`` of the same validations.csv make
    their own curve; a run without them is refused naming the weights."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import learning_curves

    from sdc_training.validation_laps import append_row

    run = tmp_path / "run"
    run.mkdir()
    append_row(run, 500_000, LapScore(45.0, 44.0, 46.0, True, True, {}))
    append_row(run, 500_000, LapScore(46.5, 46.0, 47.0, True, True, {}), weights="averaged")
    append_row(run, 1_000_000, LapScore(44.0, 43.0, 45.0, True, True, {}))
    assert learning_curves.validation_curve(run) == {500_000: 45.0, 1_000_000: 44.0}
    assert learning_curves.validation_curve(run, "averaged") == {500_000: 46.5}
    steps, mean, _, _ = learning_curves.group_curve([run], "validation", "averaged")
    assert list(steps) == [500_000] and list(mean) == [46.5]
    online_only = tmp_path / "online_only"
    online_only.mkdir()
    append_row(online_only, 500_000, LapScore(45.0, 44.0, 46.0, True, True, {}))
    with pytest.raises(SystemExit, match="no rows of the averaged weights"):
        learning_curves.validation_curve(online_only, "averaged")
    with pytest.raises(SystemExit, match="--averaged-group needs --source validation"):
        learning_curves.main(["--group", f"a={run}", "--averaged-group", f"b={run}"])


def test_learning_curves_ylim_takes_two_ordered_numbers():
    """``--ylim LOW,HIGH`` fixes the mph axis; anything else is refused naming the flag."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import learning_curves

    assert learning_curves.parse_ylim("43,48.5") == (43.0, 48.5)
    for bad in ("43", "48,43", "a,b", "43,inf", "1,2,3"):
        with pytest.raises(argparse.ArgumentTypeError, match="--ylim"):
            learning_curves.parse_ylim(bad)
