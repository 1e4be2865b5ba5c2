"""The seed's further work against the seed's FSM (issue 29): every variant beside Bold.

    python benchmarks/study_fsm_variants.py                      # held-out seeds 1000-1039
    python benchmarks/study_fsm_variants.py --seeds $(seq 1000 1009) --workers 2

Each variant is Bold with one optional mode or option from its packaged rule file
(``agents/highway/rules/<name>.yaml``: ``fsm_alert``, ``fsm_caution``, ``fsm_reverse``,
``fsm_hyper``, ``fsm_straight_braking``, ``fsm_reroute``, ``fsm_easing``). Two runs of the
project's own evaluation (``evaluate.py``, so the intervals and verdicts are its: Student's
t over seeds for the mean speed, Garwood's exact interval for incidents per 100 miles, a
paired difference of mean mph per variant against ``fsm_bold`` on the same seeds):

1. one lap per seed, every agent on the same seeds (``--output``/laps);
2. every scenario of the library (``sdc_gym/scenarios/library``, seed 0), pass or fail.

Prints two Markdown tables (for ``docs/studies.md``): per agent the mean mph with its
interval, the difference to Bold with its interval, incidents per 100 miles with its
interval, and the library scenarios it passes; and per library scenario the verdicts, with
the ones that newly pass or fail against Bold marked.
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # evaluate.py beside it

import evaluate  # the project's evaluation entry point

SEED_AGENT = "fsm_bold"
VARIANTS = ("fsm_alert", "fsm_caution", "fsm_reverse", "fsm_hyper", "fsm_straight_braking",
            "fsm_reroute", "fsm_easing")
LIBRARY = Path(__file__).resolve().parents[1] / "sdc_gym" / "scenarios" / "library"


def read_rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8", newline="") as handle:
        return list(csv.DictReader(handle))


def interval(row: dict[str, str], key: str, digits: int = 2) -> str:
    low, high = row.get(f"{key}_ci_low", ""), row.get(f"{key}_ci_high", "")
    value = f"{float(row[key]):.{digits}f}"
    return f"{value} [{float(low):.{digits}f}, {float(high):.{digits}f}]" if low and high \
        else value


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", nargs="+", type=int, default=list(range(1000, 1040)))
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--output", type=Path, default=Path("results/study_fsm_variants"))
    parser.add_argument("--tables-only", action="store_true",
                        help="print the tables of the runs already in --output")
    args = parser.parse_args(argv)
    agents = [SEED_AGENT, *VARIANTS]
    laps, library = args.output / "laps", args.output / "library"
    common = ["--agents", *agents, "--workers", str(args.workers), "--overwrite",
              "--no-progress"]
    if not args.tables_only:
        evaluate.main([*common, "--seeds", *map(str, args.seeds), "--output", str(laps),
                       "--no-plots"])
        evaluate.main([*common, "--scenario", str(LIBRARY), "--output", str(library)])
    # Episodes the same as the seed's (distance, time and max jerk to the last digit): the
    # variant's rule never fired on that seed.
    episodes = {(row["agent"], row["seed"]): (row["distance"], row["time"], row["max_jerk"])
                for row in read_rows(laps / "episodes.csv")}
    seeds = sorted({seed for _, seed in episodes}, key=int)
    same = {agent: sum(episodes[agent, seed] == episodes[SEED_AGENT, seed] for seed in seeds)
            for agent in agents}

    rows = {row["agent"]: row for row in read_rows(laps / "agents.csv")}
    pairs = {(row["a"], row["b"]): row for row in read_rows(laps / "comparisons.csv")}
    verdicts: dict[str, dict[str, tuple[bool, str]]] = {}
    for row in read_rows(library / "scenarios.csv"):
        verdicts.setdefault(row["scenario"], {})[row["agent"]] = (row["passed"] == "True",
                                                                  row["reason"])
    passed = {agent: sum(v[agent][0] for v in verdicts.values()) for agent in agents}

    print(f"\nseeds {seeds[0]}-{seeds[-1]} ({len(seeds)}), one lap each; "
          f"library: {len(verdicts)} scenarios, seed 0\n")
    print("| agent | mean mph [95% CI] | vs fsm_bold mph [95% CI] | incidents / 100 mi "
          "[95% CI] | max jerk m/s^3 | laps as fsm_bold's | library passed |")
    print("|---|---:|---:|---:|---:|---:|---:|")
    for agent in agents:
        row = rows[agent]
        if agent == SEED_AGENT:
            difference = "-"
        else:
            pair = pairs.get((SEED_AGENT, agent))
            sign = -1.0
            if pair is None:
                pair, sign = pairs[(agent, SEED_AGENT)], 1.0
            value = sign * float(pair["speed_difference_mph"]) + 0.0  # no "-0.00"
            low, high = pair["speed_difference_mph_ci_low"], pair["speed_difference_mph_ci_high"]
            difference = f"{value:+.2f}"
            if low and high:
                ends = sorted((sign * float(low) + 0.0, sign * float(high) + 0.0))
                difference += f" [{ends[0]:+.2f}, {ends[1]:+.2f}]"
        print(f"| {agent} | {interval(row, 'mean_speed_mph')} | {difference} | "
              f"{interval(row, 'incidents_per_100_miles', 1)} | {float(row['max_jerk']):.2f} | "
              f"{same[agent]} / {len(seeds)} | {passed[agent]} / {len(verdicts)} |")

    print("\n| scenario | " + " | ".join(agents) + " |")
    print("|---|" + "---|" * len(agents))
    for scenario, by_agent in sorted(verdicts.items()):
        seed_pass = by_agent[SEED_AGENT][0]
        cells = []
        for agent in agents:
            ok, _ = by_agent[agent]
            text = "PASS" if ok else "FAIL"
            if agent != SEED_AGENT and ok != seed_pass:
                text = f"**{'newly passes' if ok else 'newly fails'}**"
            cells.append(text)
        print(f"| `{scenario}` | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
