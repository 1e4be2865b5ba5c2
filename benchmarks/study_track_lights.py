"""What timing the approach to the track's lights could gain, and what the car can know.

    python benchmarks/study_track_lights.py --bound-seeds 1000 1040 --probe-seeds 2000 2010

1. **The schedule bound** (``--bound-seeds``, no driving): the lap of a car that cruises at
   the stack's speed (limit less 0.15 m/s) and, when it would reach a stop line on red,
   crosses it at full speed the instant it turns green (crossing on yellow is legal): the
   fastest lap any behavior could drive past the seed's lights, with knowledge of the
   future. Earliest arrival at each line is optimal (arriving earlier never makes a later
   crossing later), so this is a lower bound of the lap time, up to the start from rest.
2. **The observation** (``--probe-seeds``): ``TrackLoopBehavior-v0`` driven by the
   StopAtRedLights rule (stop for red, for yellow when a comfortable stop is possible,
   keep a committed stop), and at each stop line's visit of the detector's 70 m gate:
   the light state at gate entry and, for a red, whether its onset was seen (then the
   remaining red is known: the phases are fixed, 10 s green, 3 s yellow, 10 s red) or it
   was already red when first reported (then ``state_time`` counts from the first report,
   and the time to green is unknown), with the true elapsed red at that moment.
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import sdc_gym  # noqa: F401
from sdc_gym.lights.traffic_lights import DEFAULT_GREEN_S, DEFAULT_RED_S, DEFAULT_YELLOW_S
from sdc_gym.stack.track.behavior import DEFAULT_SPEED_MARGIN_MPS

GREEN_END = DEFAULT_GREEN_S
YELLOW_END = DEFAULT_GREEN_S + DEFAULT_YELLOW_S
CYCLE = YELLOW_END + DEFAULT_RED_S
GO, STOP = 0, 3
GATE_M = 70.0


def schedule_bound(seeds: range) -> dict[str, float]:
    """Mean free-flow lap, bound lap, unavoidable wait and reds met per lap (section 1)."""
    env = gym.make("sdc_gym/TrackLoop-v0", config={"observe_light_states": True}).unwrapped
    speed = float(env.track.speed_limit_mps) - DEFAULT_SPEED_MARGIN_MPS
    lines = np.asarray(env.track.stop_line_s)
    laps, waits, reds = [], [], []
    for seed in seeds:
        env.reset(seed=seed)
        offsets = env.world.state.light_offsets[0]
        t, s, wait, met = 0.0, 0.0, 0.0, 0
        for line in np.argsort(lines):
            t += (lines[line] - s) / speed
            s = lines[line]
            phase = (t + offsets[line]) % CYCLE
            if phase >= YELLOW_END:  # red: wait for green
                met += 1
                wait += CYCLE - phase
                t += CYCLE - phase
        laps.append(t + (env.track.length - s) / speed)
        waits.append(wait)
        reds.append(met)
    return {"free_flow_s": float(env.track.length / speed), "bound_s": float(np.mean(laps)),
            "wait_s": float(np.mean(waits)), "reds_per_lap": float(np.mean(reds))}


def probe(seeds: range) -> dict[str, float]:
    """The rule's drive: gate visits, reds reported, onsets seen (section 2)."""
    visits = reds = onset_seen = 0
    hidden: list[float] = []
    entry_states = np.zeros(4, dtype=int)
    for seed in seeds:
        env = gym.make("sdc_gym/TrackLoopBehavior-v0").unwrapped
        obs, info = env.reset(seed=seed)
        st = env.batch.world.state
        committed, current, red_seen = -1, None, False
        while True:
            line = int(info.get("next_stop_line", -1))
            state = int(np.argmax(obs[3:7]))  # red, yellow, green, unknown
            in_gate = line >= 0 and obs[1] * 100.0 < GATE_M
            if in_gate and current != line:  # a new visit of the gate
                current, red_seen = line, False
                visits += 1
                entry_states[state] += 1
            if in_gate and state == 0 and not red_seen:
                red_seen = True
                reds += 1
                phase = (float(st.light_clock[0]) + st.light_offsets[0, line]) % CYCLE
                elapsed = phase - YELLOW_END
                if elapsed > 1.5:  # already red at the first report (debounce: ~0.1 s)
                    hidden.append(elapsed)
                else:
                    onset_seen += 1
            action = GO
            if state == 0 or (state == 1 and (obs[10] > 0 or committed == line)):
                action, committed = STOP, line
            obs, _, terminated, truncated, info = env.step(action)
            if terminated or truncated:
                break
    return {"visits": visits, "reds": reds, "onset_seen": onset_seen,
            "already_red": len(hidden), "elapsed_mean": float(np.mean(hidden)),
            "elapsed_min": float(np.min(hidden)), "elapsed_max": float(np.max(hidden)),
            "entry_red": int(entry_states[0]), "entry_yellow": int(entry_states[1]),
            "entry_green": int(entry_states[2]), "entry_unknown": int(entry_states[3])}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--bound-seeds", type=int, nargs=2, default=(1000, 1040),
                        metavar=("FIRST", "END"))
    parser.add_argument("--probe-seeds", type=int, nargs=2, default=(2000, 2010),
                        metavar=("FIRST", "END"))
    args = parser.parse_args()
    b = schedule_bound(range(*args.bound_seeds))
    print(f"seeds {args.bound_seeds[0]}-{args.bound_seeds[1] - 1}: free-flow lap "
          f"{b['free_flow_s']:.1f} s; the schedule bound {b['bound_s']:.1f} s (waits at red "
          f"{b['wait_s']:.1f} s per lap, {b['reds_per_lap']:.2f} reds met per lap)")
    if args.probe_seeds[1] > args.probe_seeds[0]:
        p = probe(range(*args.probe_seeds))
        print(f"seeds {args.probe_seeds[0]}-{args.probe_seeds[1] - 1}, the rule's drive: "
              f"{p['visits']} gate visits (state at entry: red {p['entry_red']}, yellow "
              f"{p['entry_yellow']}, green {p['entry_green']}, unknown {p['entry_unknown']}); "
              f"{p['reds']} reds reported: onset seen {p['onset_seen']}, already red "
              f"{p['already_red']} (elapsed red at the first report: mean "
              f"{p['elapsed_mean']:.1f} s, {p['elapsed_min']:.1f}-{p['elapsed_max']:.1f} s)")


if __name__ == "__main__":
    main()
