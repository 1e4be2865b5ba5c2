"""Issue 27's speed measurements in one run, one report: each part's table, then the targets.

    nice -n 10 python benchmarks/speed_report.py                   # all four, ~15-20 min
    nice -n 10 python benchmarks/speed_report.py --parts track,cold
    nice -n 10 python benchmarks/speed_report.py --quick           # a smoke run of each part

The parts (``--parts``, comma-separated, in this order; :mod:`speed_parts` runs them with
the functions of the scripts that own them):

* ``learners``: PPO samples/s end to end per learner on the batched
  ``HighwayLoopBehavior-v0`` (``bench_learners.py``: the env alone, SB3 and its no-op
  case, RLlib, torchrl and PufferLib when they import), then each learner's wall time to
  a fixed mean mph on validation laps (``learner_time_to_mph.py``);
* ``threads``: batched behavior env steps/s with its kernels on one and two threads, at
  each E, and highway-env's ``highway-fast-v0`` (``bench_kernel_threads.py``);
* ``cold``: the first step's CPU per env in a fresh process on an empty numba cache, and
  again on the cache it filled (``cold_start.py``);
* ``track``: the single ``TrackLoop-v0`` env against the scalar code it replaced
  (``bench_track_batched.py``'s worker, in this tree and in a ``git archive`` of the scalar
  commit, or ``--scalar-tree``).

Every table gives min / median / max over its rounds and, where the script measures a
peer, the ratio of medians to it. The targets table (:mod:`speed_targets`) then says per
target the measured figure, met or not met, and for a target not met the measured reason
(for the learners: the sequential bound ``1 / (1/env + 1/learner)`` from the env-alone and
no-op cases). Other jobs on the machine skew absolute numbers: the load average is printed
at the start and end of each part; compare the figures of one run.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent))

import speed_parts as parts
import speed_targets as targets

PARTS = ("learners", "threads", "cold", "track")


def parse_parts(text: str) -> list[str]:
    """``--parts``: known names, in the order given, each once."""
    names = list(dict.fromkeys(name.strip() for name in text.split(",") if name.strip()))
    unknown = [name for name in names if name not in PARTS]
    if unknown or not names:
        problem = f"unknown part {unknown[0]!r}" if unknown else f"no part in {text!r}"
        raise argparse.ArgumentTypeError(f"{problem}; choices: {', '.join(PARTS)}")
    return names


def judge(results: dict[str, Any]) -> list[targets.Target]:
    """One row per target, in :data:`PARTS`' order; a part that did not run gives a 'not
    measured' row saying so."""
    learners, threads = results.get("learners"), results.get("threads")
    cold, track = results.get("cold"), results.get("track")
    rows = [targets.learner_target(learners.rates if learners else {}),
            targets.threads_target({key: value for key, value in (threads or {}).items()
                                    if isinstance(key, tuple)},
                                   scaling=(threads or {}).get(targets.CORES)),
            targets.cold_target(cold.first_cpu if cold else {},
                                cold.warm_cpu if cold else None,
                                cold.compiles if cold else None),
            targets.track_target(track.now if track else [], track.scalar if track else [])]
    return [row if part in results else replace(row, reason=f"part '{part}' not run")
            for part, row in zip(PARTS, rows, strict=True)]


MEASURE = {"learners": (parts.measure_learners, parts.learner_lines),
           "threads": (parts.measure_threads, parts.thread_lines),
           "cold": (parts.measure_cold, parts.cold_lines),
           "track": (parts.measure_track, parts.track_lines)}


def run(names: list[str], settings: parts.Settings,
        out: Any = sys.stdout) -> tuple[dict[str, Any], list[targets.Target]]:
    """Measure ``names`` in order, printing progress and each table to ``out``; the
    results and the targets judged on them (printed last)."""
    def say(line: str = "") -> None:
        print(line, file=out, flush=True)

    started = time.perf_counter()
    say(f"speed report (issue 27): parts {', '.join(names)}; load average {parts.load()}")
    results: dict[str, Any] = {}
    tables: list[tuple[str, list[str]]] = []
    for name in names:
        measure, lines = MEASURE[name]
        part_started = time.perf_counter()
        say(f"\n== {name}: measuring (load {parts.load()})")
        results[name] = measure(settings, say)
        tables.append((name, lines(results[name])))
        say(f"== {name}: {time.perf_counter() - part_started:.0f} s wall (load {parts.load()})")
    say("\n# Report")
    for name, lines in tables:
        say(f"\n## {name}\n")
        say("\n".join(lines))
    rows = judge(results)
    say("\n## Targets\n")
    say("\n".join(targets.targets_table(rows)))
    say(f"\n{time.perf_counter() - started:.0f} s wall in all; load average at the end "
        f"{parts.load()}")
    return results, rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--parts", type=parse_parts, default=list(PARTS),
                        help=f"comma-separated, of {', '.join(PARTS)} (default: all)")
    parser.add_argument("--quick", action="store_true",
                        help="every part at smoke-run sizes (1 round, tiny budgets)")
    parser.add_argument("--scalar-tree", type=Path, default=None,
                        help=f"a checkout of the scalar track code (default: a git archive "
                             f"of {parts.SCALAR_COMMIT})")
    parser.add_argument("--target-mph", type=float, default=None,
                        help="the races' target mean mph (default "
                             f"{parts.Settings.target_mph})")
    parser.add_argument("--race-budget-s", type=float, default=None,
                        help="each race's wall budget (default "
                             f"{parts.Settings.race_budget_s:g} s; --quick "
                             f"{parts.QUICK.race_budget_s:g} s)")
    args = parser.parse_args(argv)
    if args.scalar_tree is not None and not (args.scalar_tree / "sdc_gym").is_dir():
        parser.error(f"--scalar-tree: {args.scalar_tree} holds no sdc_gym/ (a checkout of "
                     f"{parts.SCALAR_COMMIT} is expected)")
    for flag in ("target_mph", "race_budget_s"):
        value = getattr(args, flag)
        if value is not None and not value > 0:
            parser.error(f"--{flag.replace('_', '-')} must be > 0, got {value}")
    settings = parts.Settings(scalar_tree=args.scalar_tree)
    if args.quick:
        settings = parts.quick(settings)
    if args.target_mph is not None:
        settings = replace(settings, target_mph=args.target_mph)
    if args.race_budget_s is not None:
        settings = replace(settings, race_budget_s=args.race_budget_s)
    run(args.parts, settings)


if __name__ == "__main__":
    main()
