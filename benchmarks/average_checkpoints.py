"""Average the weights of several checkpoints of one run into one model (weight averaging).

    python benchmarks/average_checkpoints.py \
        runs/dqn_n3/checkpoints/dqn_{12,14,16,18,20}00000_steps.zip \
        --algo dqn --output runs/dqn_n3/averaged.zip
    python benchmarks/validate_policies.py runs/dqn_n3/averaged.zip --algo dqn --episodes 40

Stochastic weight averaging (Izmailov et al. 2018) on saved snapshots: the element-wise mean
of every policy parameter over the checkpoints (the same network shape; e.g. the late
checkpoints of a DQN run, whose greedy policy shifts by 1-3 mph between neighbours,
docs/rl.md) in one model, written atomically with the last checkpoint's other state
(timesteps, hyperparameters). The run's ``config.yaml`` is copied beside the output when
the output is in another folder, so the averaged model is an agent ``dqn:PATH`` and a
``validate_policies.py`` model like any checkpoint.
"""

from __future__ import annotations

import argparse
import shutil
from pathlib import Path
from typing import Any

from sdc_agents.checkpoints import save_model
from sdc_agents.policy_agent import SB3_KINDS, algorithm_class


def average_models(models: list[Any]) -> Any:
    """The last of ``models`` with every policy parameter set to the mean over all of them
    (ValueError if their parameter names or shapes differ)."""
    import torch

    if not models:
        raise ValueError("no checkpoints to average")
    target = models[-1]
    named = [dict(model.policy.named_parameters()) for model in models]
    for other in named[:-1]:
        if {k: v.shape for k, v in other.items()} != {k: v.shape for k, v in named[-1].items()}:
            raise ValueError("the checkpoints hold different networks: cannot average them")
    with torch.no_grad():
        for name, parameter in named[-1].items():
            parameter.copy_(torch.stack([weights[name] for weights in named]).mean(dim=0))
    return target


def run_config_of(checkpoint: Path) -> Path | None:
    """The run folder's ``config.yaml`` of a checkpoint (``RUN/checkpoints/x.zip``)."""
    for folder in (checkpoint.parent, checkpoint.parent.parent):
        if (folder / "config.yaml").is_file():
            return folder / "config.yaml"
    return None


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("checkpoints", nargs="+", type=Path)
    parser.add_argument("--algo", required=True, choices=SB3_KINDS)
    parser.add_argument("--output", type=Path, required=True, help="the averaged model .zip")
    args = parser.parse_args(argv)
    if args.output.suffix != ".zip":
        parser.error(f"--output must be a .zip path, got {args.output}")
    missing = [str(path) for path in args.checkpoints if not path.is_file()]
    if missing:
        parser.error(f"no such checkpoint: {', '.join(missing)}")
    algorithm = algorithm_class(args.algo)
    try:
        model = average_models([algorithm.load(path) for path in args.checkpoints])
    except ValueError as error:
        parser.error(str(error))
    args.output.parent.mkdir(parents=True, exist_ok=True)
    save_model(model, args.output)
    config = run_config_of(args.checkpoints[-1])
    beside = args.output.parent / "config.yaml"
    if config is not None and not beside.exists():
        shutil.copyfile(config, beside)
    print(f"averaged {len(args.checkpoints)} checkpoints into {args.output}")


if __name__ == "__main__":
    main()
