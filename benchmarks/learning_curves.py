"""Learning curves of train.py runs: samples against the periodic evaluation's mean mph.

    python benchmarks/learning_curves.py --group dqn=runs/dqn_s0,runs/dqn_s1 \
        --group ppo=runs/ppo_s0 --reference fsm_bold=46.33 --output docs/images/curves.png

Each ``--group LABEL=RUN[,RUN...]`` is one curve: the runs of one config with different
training seeds. A run's curve is its TensorBoard scalar ``eval/mean_speed_mph`` (train.py's
periodic evaluation on the held-out evaluation seeds of its run config, the same episodes
at every point). With two or more runs the curve is their mean at each evaluation step with
a 95 % Student t interval over the runs (the project's interval, sdc_evaluation.statistics);
a single run is drawn alone. ``--reference NAME=MPH`` draws a rule-based agent's mean
speed on the same evaluation episodes as a horizontal line. Prints the table it plots.

``--source validation`` draws the validation laps instead (one lap per validation seed,
40 by default: ``validations.csv`` of the run, written by train.py's ``validation`` key or
``benchmarks/validate_policies.py --record RUN``), which rank checkpoints far better than
the periodic 4-episode evaluation. ``--averaged-group LABEL=RUNS`` draws the validation
laps of the same runs' averaged weights (train.py's ``averaging`` key, the rows
``weights=averaged`` of ``validations.csv``) as one more curve.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

from sdc_evaluation.statistics import t_intervals

EVAL_TAG = "eval/mean_speed_mph"


def eval_curve(run: Path, tag: str = EVAL_TAG) -> dict[int, float]:
    """``{samples: mean mph}`` of one run folder's TensorBoard events (the newest value per
    step when a resumed run logged a step twice)."""
    from tensorboard.backend.event_processing.event_accumulator import EventAccumulator

    curve: dict[int, float] = {}
    event_folders = sorted({path.parent for path in run.glob("tensorboard/**/events.out.*")})
    if not event_folders:
        raise SystemExit(f"{run}: no TensorBoard events under {run / 'tensorboard'}")
    for folder in event_folders:
        events = EventAccumulator(str(folder), size_guidance={"scalars": 0})
        events.Reload()
        if tag in events.Tags()["scalars"]:
            curve.update({int(event.step): float(event.value) for event in events.Scalars(tag)})
    if not curve:
        raise SystemExit(f"{run}: no {tag!r} scalars (was it trained with --eval-every?)")
    return curve


def validation_curve(run: Path, weights: str = "online") -> dict[int, float]:
    """``{samples: mean mph}`` of one run folder's ``validations.csv`` for its ``weights``
    (``online`` or ``averaged``; the last row per step when a step was validated twice,
    e.g. after a resume)."""
    from sdc_training.validation_laps import CSV_NAME, read_rows

    path = run / CSV_NAME
    if not path.is_file():
        raise SystemExit(f"{run}: no {CSV_NAME} (train with --validate-every, or run "
                         f"benchmarks/validate_policies.py --record {run} on its checkpoints)")
    curve = {int(row["timesteps"]): float(row["value"]) for row in read_rows(run, weights)}
    if not curve:
        raise SystemExit(f"{run}: {CSV_NAME} has no rows of the {weights} weights")
    return curve


CURVES = {"eval": eval_curve, "validation": validation_curve}


def group_curve(runs: list[Path], source: str = "eval", weights: str = "online"
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``(steps, mean, low, high)`` over the steps every run evaluated at (``weights``:
    which weights' validation laps, for ``source="validation"``)."""
    curves = [validation_curve(run, weights) if source == "validation"
              else CURVES[source](run) for run in runs]
    steps = sorted(set.intersection(*(set(curve) for curve in curves)))
    if not steps:
        raise SystemExit(f"runs {[str(run) for run in runs]} share no evaluation step")
    values = np.array([[curve[step] for curve in curves] for step in steps])
    mean = values.mean(axis=1)
    if len(runs) < 2:
        return np.array(steps), mean, mean, mean
    low, high = t_intervals(values)
    return np.array(steps), mean, low, high


def parse_pair(text: str, what: str) -> tuple[str, str]:
    label, separator, value = text.partition("=")
    if not separator or not label or not value:
        raise SystemExit(f"--{what} {text!r}: expected LABEL=VALUE")
    return label, value


def parse_ylim(text: str) -> tuple[float, float]:
    """``--ylim LOW,HIGH``: two finite numbers, LOW below HIGH."""
    parts = text.split(",")
    try:
        low, high = (float(part) for part in parts)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"--ylim takes LOW,HIGH (two numbers, mph), not {text!r}") from None
    if not (math.isfinite(low) and math.isfinite(high) and low < high):
        raise argparse.ArgumentTypeError(
            f"--ylim {text!r}: LOW and HIGH must be finite with LOW < HIGH")
    return low, high


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--group", action="append", required=True, metavar="LABEL=RUNS",
                        help="a curve: comma-separated run folders of one config")
    parser.add_argument("--averaged-group", action="append", default=[], metavar="LABEL=RUNS",
                        help="a curve of the runs' averaged weights (--source validation)")
    parser.add_argument("--reference", action="append", default=[], metavar="NAME=MPH",
                        help="a rule-based agent's mean mph on the same evaluation episodes")
    parser.add_argument("--output", type=Path, default=Path("learning_curves.png"))
    parser.add_argument("--title", default=None,
                        help="default: the env and the source of the curves")
    parser.add_argument("--source", choices=sorted(CURVES), default="eval",
                        help="eval: train.py's periodic evaluation (TensorBoard); validation: "
                             "the validation laps (validations.csv)")
    parser.add_argument("--ylim", type=parse_ylim, default=None, metavar="LOW,HIGH",
                        help="the mph axis' range (default: matplotlib's, which a wide "
                             "interval over two seeds stretches)")
    args = parser.parse_args(argv)
    if args.averaged_group and args.source != "validation":
        raise SystemExit(f"--averaged-group needs --source validation, not "
                         f"{args.source!r}: only the validation laps score the averaged weights")
    title = args.title or ("HighwayLoopBehavior-v0: " + (
        "periodic evaluation" if args.source == "eval" else "validation laps"))

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(7.5, 4.2))
    groups = ([(group, "online") for group in args.group]
              + [(group, "averaged") for group in args.averaged_group])
    for group, weights in groups:
        label, folders = parse_pair(group, "group")
        runs = [Path(folder) for folder in folders.split(",")]
        steps, mean, low, high = group_curve(runs, args.source, weights)
        line, = axes.plot(steps / 1e6, mean, marker="o", markersize=3,
                          label=f"{label} ({len(runs)} seed{'s' * (len(runs) > 1)})")
        if len(runs) > 1:
            axes.fill_between(steps / 1e6, low, high, color=line.get_color(), alpha=0.2)
        print(f"{label}: " + ", ".join(f"{step / 1e6:.2f}M {value:.2f} [{lo:.2f}, {hi:.2f}]"
                                       for step, value, lo, hi in zip(steps, mean, low, high,
                                                                      strict=True)))
    for reference in args.reference:
        name, mph = parse_pair(reference, "reference")
        axes.axhline(float(mph), linestyle="--", color="black", linewidth=1,
                     label=f"{name} on the same episodes ({float(mph):.2f})")
    axes.set_xlabel("samples (millions of decisions)")
    axes.set_ylabel("mean mph, " + ("evaluation episodes" if args.source == "eval"
                                    else "validation laps"))
    axes.set_title(title)
    if args.ylim:
        axes.set_ylim(*args.ylim)
    axes.grid(alpha=0.3)
    axes.legend(loc="lower right", fontsize=8)
    figure.tight_layout()
    args.output.parent.mkdir(parents=True, exist_ok=True)
    figure.savefig(args.output, dpi=110)
    print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
