"""The per-episode samples the statistics' coverage test draws from (tests/data).

Reads an evaluation run's ``summary.json`` and writes, per agent, each episode's mean
speed (mph) and lap time (s, the first lap), with the seeds and the command that made
them::

    .venv/bin/python evaluate.py --agents fsm_conservative fsm_bold lane_keeping \\
        --seeds $(seq 0 39) --workers 2 --no-plots --output results/samples
    .venv/bin/python benchmarks/episode_samples.py results/samples \\
        > tests/data/episode_samples.json

``tests/test_statistics.py`` resamples these values (with replacement) as the episodes of
simulated runs and checks that the intervals the tables print cover the true mean as
often as they claim.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path


def samples(run: Path) -> dict:
    summary = json.loads((run / "summary.json").read_text(encoding="utf-8"))
    agents: dict[str, dict[str, list]] = {}
    for episode in summary["episodes"]:
        entry = agents.setdefault(episode["agent"], {"seed": [], "mean_speed_mph": [],
                                                     "lap_time": []})
        if not episode["lap_times"]:
            raise SystemExit(f"{episode['agent']} seed {episode['seed']}: no lap completed")
        entry["seed"].append(episode["seed"])
        entry["mean_speed_mph"].append(round(episode["mean_speed_mph"], 4))
        entry["lap_time"].append(round(episode["lap_times"][0], 3))
    return {"made_by": [summary["run"]["command"], "benchmarks/episode_samples.py RUN"],
            "env_id": summary["run"]["env_id"], "laps": summary["run"]["laps"],
            "agents": agents}


def main(argv: list[str]) -> None:
    if len(argv) != 1:
        raise SystemExit("usage: episode_samples.py RUN_FOLDER > tests/data/episode_samples.json")
    data = samples(Path(argv[0]))
    agents = data.pop("agents")
    lines = [json.dumps(data)[:-1] + ', "agents": {']  # one line per list: a small diff
    for i, (agent, fields) in enumerate(agents.items()):
        lines.append(f" {json.dumps(agent)}: {{")
        lines += [f"  {json.dumps(key)}: {json.dumps(values)}"
                  + ("," if j < len(fields) - 1 else "") for j, (key, values)
                  in enumerate(fields.items())]
        lines.append(" }" + ("," if i < len(agents) - 1 else ""))
    print("\n".join(lines) + "\n}}")


if __name__ == "__main__":
    main(sys.argv[1:])
