"""``train.py --tune SWEEP.yaml``: a Ray Tune sweep of RLlib runs, a table of its trials
and its best checkpoint.

    python train.py --tune configs/tune/highway_ppo.yaml \
        --config configs/train_highway_behavior.yaml --output runs/sweep
    python train.py --output runs/sweep --resume     # unfinished and errored trials go on
    python evaluate.py --agents rllib:runs/sweep/best_model fsm_bold

The sweep file (YAML; every key checked, an unknown one named with the valid ones)::

    algo: ppo                      # optional: the run config's / --algo otherwise
    num_samples: 8                 # trials (each grid point this many times)
    max_concurrent_trials: 2       # default: as many as the cluster's CPUs allow
    metric: env_runners/episode_return_mean
    mode: max
    timesteps: 200000              # env steps per trial (default: the run's)
    n_envs: 1                      # env processes per trial (default: the run's)
    checkpoint_frequency: 1        # iterations between checkpoints (the best one is kept)
    scheduler:                     # optional: asha, or none (every trial runs to the end)
      type: asha
      grace_period: 20000          # env steps before ASHA may stop a trial
      reduction_factor: 3
    search_space:                  # hyperparameter (dotted into sections) -> distribution
      lr: {loguniform: [1.0e-5, 1.0e-3]}
      entropy_coeff: {choice: [0.0, 0.01]}
      model.fcnet_hiddens: {grid_search: [[64, 64], [128, 128]]}

Distributions: ``uniform``, ``loguniform``, ``quniform``, ``randint``, ``qrandint``
(Tune's functions, their arguments as a list), ``choice`` and ``grid_search`` (a list of
values). Every other hyperparameter is the run's (``configs/hyperparams/rllib_<algo>.yaml``
by env id, with ``--hp`` overrides). ASHA stops the trials that lag behind at each rung,
measured in env steps (``num_env_steps_sampled_lifetime``).

The run folder: ``config.yaml`` (the run config, with the sweep under ``tune``),
``command.txt``, ``tune/sweep/`` (Tune's experiment: per trial its results, TensorBoard
events and its best checkpoint), ``trials.csv`` (one row per trial: its id, hyperparameters,
env steps, iterations, the metric's last and best value, whether ASHA stopped it, its
error) also printed as a
table, and ``best_model/`` (the best checkpoint of the best trial) with ``best_model.yaml``
(that trial's resolved run config, which ``rllib:`` agents read).
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path
from typing import Any

import yaml

from sdc_evaluation.files import atomic_write_text, csv_text
from sdc_gym.config import ConfigError
from sdc_gym.ray import LOCAL, ray_session
from sdc_gym.validation.rules import (
    Choice,
    Number,
    Rule,
    check_finite,
    check_value,
    fail,
    lookup,
)
from sdc_gym.validation.run_config import MAX_N_ENVS, MAX_TIMESTEPS
from sdc_training.rllib_config import ALGORITHMS, algorithm_config, config_class, with_keys
from sdc_training.rllib_trainer import BEST_FOLDER, STEPS_KEY, replace_folder
from sdc_training.yaml_files import read_yaml

SWEEP_KEYS = {"algo", "num_samples", "max_concurrent_trials", "metric", "mode", "timesteps",
              "n_envs", "checkpoint_frequency", "scheduler", "search_space"}
SCHEDULER_KEYS = {"type", "grace_period", "reduction_factor"}
SCHEDULERS = ("asha", "none")
DISTRIBUTIONS = ("uniform", "loguniform", "quniform", "randint", "qrandint", "choice",
                 "grid_search")
MODES = ("max", "min")
DEFAULTS = {"num_samples": 1, "metric": "env_runners/episode_return_mean", "mode": "max",
            "checkpoint_frequency": 1, "scheduler": {"type": "none"}}
EXPERIMENT = "sweep"
TRIALS_FILE = "trials.csv"


SWEEP_RULES: dict[str, Rule] = {
    "num_samples": Number(1, 10**6, integer=True, unit="trials per grid point"),
    "max_concurrent_trials": Number(1, 10**6, integer=True, optional=True),
    "mode": Choice(MODES),
    "timesteps": Number(1, MAX_TIMESTEPS, integer=True, optional=True,
                        unit="env steps per trial"),
    "n_envs": Number(1, MAX_N_ENVS, integer=True, optional=True),
    "checkpoint_frequency": Number(1, integer=True, unit="iterations"),
    "scheduler.type": Choice(SCHEDULERS),
    "scheduler.grace_period": Number(1, MAX_TIMESTEPS, integer=True, optional=True,
                                     unit="env steps"),
    "scheduler.reduction_factor": Number(1.0, low_open=True, optional=True),
}


def read_sweep(path: Path) -> dict[str, Any]:
    """The sweep file at ``path``, checked and with its defaults (``SystemExit`` naming
    the file, the key, the value and the valid choices for anything wrong)."""
    owner = f"--tune {path}"
    data = read_yaml(path, "--tune sweep file")
    unknown = set(data) - SWEEP_KEYS
    if unknown:
        raise SystemExit(f"{owner}: unknown keys {sorted(unknown)}; valid: "
                         f"{sorted(SWEEP_KEYS)}")
    sweep = {**DEFAULTS, **data}
    scheduler = sweep["scheduler"]
    if not isinstance(scheduler, dict) or set(scheduler) - SCHEDULER_KEYS:
        raise SystemExit(f"{owner}: config key 'scheduler' must be a mapping with keys of "
                         f"{sorted(SCHEDULER_KEYS)}, got {scheduler!r}")
    sweep["scheduler"] = {"type": "none", **scheduler}
    space = sweep.get("search_space")
    if not isinstance(space, dict) or not space:
        raise SystemExit(f"{owner}: config key 'search_space' must map hyperparameters to "
                         f"distributions, e.g. lr: {{loguniform: [1.0e-5, 1.0e-3]}}, "
                         f"got {space!r}")
    if not isinstance(sweep["metric"], str) or not sweep["metric"]:
        raise SystemExit(f"{owner}: config key 'metric' must be the name of a result, e.g. "
                         f"{DEFAULTS['metric']}, got {sweep['metric']!r}")
    try:
        for key, rule in SWEEP_RULES.items():
            found, value = lookup(sweep, key)
            check_value(rule, value if found else None, owner, key)
        if "algo" in sweep:
            check_value(Choice(ALGORITHMS), sweep["algo"], owner, "algo")
        for key, distribution in space.items():
            if (not isinstance(distribution, dict) or len(distribution) != 1
                    or next(iter(distribution)) not in DISTRIBUTIONS
                    or not isinstance(next(iter(distribution.values())), list)):
                raise fail(owner, f"search_space.{key}", f"one of {list(DISTRIBUTIONS)} "
                           "with a list of its arguments", distribution)
            check_finite(distribution, owner, prefix=f"search_space.{key}")
            try:
                tune_domain(distribution)  # Tune's own checks of the arguments
            except (TypeError, ValueError, AssertionError) as error:
                raise fail(owner, f"search_space.{key}", "arguments Tune takes "
                           f"({type(error).__name__}: {error})", distribution) from None
    except ConfigError as error:
        raise SystemExit(str(error)) from None
    return sweep


def tune_domain(distribution: dict[str, list[Any]]) -> Any:
    """A Tune search domain from ``{"loguniform": [1e-5, 1e-3]}`` and the like."""
    from ray import tune

    (name, arguments), = distribution.items()
    if name in ("choice", "grid_search"):
        return getattr(tune, name)(arguments)
    return getattr(tune, name)(*arguments)


def _get_dotted(params: dict[str, Any] | None, key: str) -> Any:
    """``params["a"]["b"]`` for ``"a.b"``; None where a part is missing."""
    node: Any = params
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return None
        node = node[part]
    return node


def trial_config(config: dict[str, Any], sweep: dict[str, Any]) -> dict[str, Any]:
    """The run config of each trial: the run's, with the sweep's n_envs and timesteps."""
    trial = {**config, "hyperparams": dict(config["hyperparams"])}
    for key in ("n_envs", "timesteps"):
        if sweep.get(key) is not None:
            trial[key] = sweep[key]
    return trial


def sweep(config: dict[str, Any], args: argparse.Namespace) -> Path:
    """Run (or resume) the sweep ``config["tune"]`` in ``args.output``; the best
    checkpoint's folder (see the module doc)."""
    from ray import tune
    from ray.tune.schedulers import ASHAScheduler

    spec = config["tune"]
    trial = trial_config(config, spec)
    space = spec["search_space"]
    hyper = with_keys(trial["hyperparams"], space, lambda key: tune_domain(space[key]))
    output = args.output.resolve()
    storage = output / "tune"
    timesteps = int(trial["timesteps"])
    trainable = config_class(trial["algo"])().algo_class
    with ray_session(args.ray or LOCAL):
        param_space = algorithm_config(trial, hyper)
        experiment = storage / EXPERIMENT
        if args.resume and tune.Tuner.can_restore(str(experiment)):
            tuner = tune.Tuner.restore(str(experiment), trainable=trainable,
                                       resume_unfinished=True, resume_errored=True,
                                       param_space=param_space)
        else:
            scheduler = None
            settings = spec["scheduler"]
            if settings.get("type", "none") == "asha":
                scheduler = ASHAScheduler(
                    time_attr=STEPS_KEY, max_t=timesteps,
                    grace_period=int(settings.get("grace_period") or max(timesteps // 10, 1)),
                    reduction_factor=float(settings.get("reduction_factor") or 3))
            tuner = tune.Tuner(
                trainable, param_space=param_space,
                tune_config=tune.TuneConfig(
                    metric=spec["metric"], mode=spec["mode"], scheduler=scheduler,
                    num_samples=int(spec["num_samples"]),
                    max_concurrent_trials=spec.get("max_concurrent_trials")),
                run_config=tune.RunConfig(
                    name=EXPERIMENT, storage_path=str(storage),
                    stop={STEPS_KEY: timesteps}, verbose=0 if args.no_progress else 1,
                    checkpoint_config=tune.CheckpointConfig(
                        num_to_keep=1, checkpoint_score_attribute=spec["metric"],
                        checkpoint_score_order=spec["mode"],
                        checkpoint_frequency=int(spec["checkpoint_frequency"]),
                        checkpoint_at_end=True)))
        grid = tuner.fit()
        rows = trial_rows(grid, spec, timesteps)
        atomic_write_text(output / TRIALS_FILE, _csv(rows))
        _print_table(rows, spec["metric"])
        if all(row["error"] for row in rows):
            raise SystemExit(f"every trial of the sweep failed (see {output / TRIALS_FILE} "
                             f"and {experiment})")
        best = grid.get_best_result(metric=spec["metric"], mode=spec["mode"], scope="all")
        checkpoint = best.get_best_checkpoint(spec["metric"], spec["mode"]) or best.checkpoint
        if checkpoint is None:
            raise SystemExit(f"no trial of the sweep left a checkpoint (see {TRIALS_FILE})")
        temporary = output / f".{BEST_FOLDER}.tmp"
        if temporary.exists():
            shutil.rmtree(temporary)
        shutil.copytree(checkpoint.path, temporary)
        replace_folder(temporary, output / BEST_FOLDER)
        resolved = {**trial, "hyperparams": with_keys(
            trial["hyperparams"], space,
            lambda key: _plain(_get_dotted(best.config, _config_key(key))))}
        resolved.pop("tune", None)
        atomic_write_text(output / f"{BEST_FOLDER}.yaml",
                          yaml.safe_dump(resolved, sort_keys=False))
    [row] = [row for row in rows if row["trial"] == trial_id(best)]
    print(f"best trial {row['trial']} ({', '.join(f'{k} {row[k]}' for k in spec['search_space'])}"
          f"): best {spec['metric']} {row['best']:.4g}; model: {output / BEST_FOLDER}")
    return output / BEST_FOLDER


def _config_key(key: str) -> str:
    """Where a hyperparameter sits in the trial's config dict: ``model.x`` is in the
    RLModule's model config (``AlgorithmConfig.to_dict``'s ``_model_config``), the rest are
    top-level keys."""
    head, _, rest = key.partition(".")
    if head == "model":
        return f"_model_config.{rest}"
    if head == "env_runners":
        return rest
    return key


def _plain(value: Any) -> Any:
    """A config value as plain YAML data (tuples to lists, numpy scalars to numbers)."""
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if hasattr(value, "item"):
        return value.item()
    return value


def trial_rows(grid: Any, spec: dict[str, Any], timesteps: int) -> list[dict[str, Any]]:
    """One row per trial: its hyperparameters, env steps, iterations, last and best metric,
    whether it was stopped before ``timesteps`` (ASHA), its error."""
    metric, mode = spec["metric"], spec["mode"]
    rows = []
    for result in grid:
        metrics = result.metrics or {}
        frame = result.metrics_dataframe
        history = (frame[metric].dropna() if frame is not None and metric in frame
                   else None)
        best = None if history is None or history.empty else (
            float(history.max() if mode == "max" else history.min()))
        steps = int(metrics.get(STEPS_KEY, 0) or 0)
        row = {"trial": trial_id(result),
               **{key: _plain(_get_dotted(result.config, _config_key(key)))
                  for key in spec["search_space"]},
               "env_steps": steps, "iterations": int(metrics.get("training_iteration", 0)),
               "last": _metric(metrics, metric), "best": best,
               "stopped_early": result.error is None and steps < timesteps,
               "error": "" if result.error is None else str(result.error).splitlines()[0]}
        rows.append(row)
    return rows


def trial_id(result: Any) -> str:
    """Tune's id of a trial (``4e75b_00001``), or its folder's name without metrics."""
    reported = (result.metrics or {}).get("trial_id")
    return str(reported) if reported else (Path(result.path).name if result.path else "")


def _metric(metrics: dict[str, Any], metric: str) -> float | None:
    node: Any = metrics
    for part in metric.split("/"):
        if not isinstance(node, dict) or part not in node:
            return metrics.get(metric)
        node = node[part]
    return None if node is None else float(node)


def _csv(rows: list[dict[str, Any]]) -> str:
    """The trials table as CSV (a list value, e.g. a layer size choice, as its text)."""
    flat = [{key: (str(value) if isinstance(value, list) else value)
             for key, value in row.items()} for row in rows]
    return csv_text(flat, list(rows[0]) if rows else ["trial"])


def _print_table(rows: list[dict[str, Any]], metric: str) -> None:
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"trials: last and best {metric}")
    for key in rows[0] if rows else ():
        table.add_column(key, overflow="fold")
    for row in rows:
        table.add_row(*("" if value is None else
                        f"{value:.4g}" if isinstance(value, float) else str(value)
                        for value in row.values()))
    Console().print(table)
