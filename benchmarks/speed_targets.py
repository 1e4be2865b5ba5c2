"""Issue 27's four targets judged on measured numbers, each met or not with the reason.

``speed_report.py`` measures; this module only does arithmetic and text, so the judgement
is tested on constructed numbers (``tests/test_speed_report.py``). Every rate is given as
the list of its rounds' values; a target is judged on medians (a round is one sample of a
shared machine's load, the median the figure least moved by a burst of other jobs).

The targets (issue 27's "Done when"):

* PPO end to end >= 40,000 samples/s: the best learner's median. A learner that
  alternates collection and update pays the env's and its own time per sample, so it is
  bounded by the *sequential bound* ``1 / (1/env + 1/learner)`` (the env alone, and the
  learner on a no-op env); when that bound is below the goal, the goal is out of reach of
  that learner whatever it tunes, and that is the measured reason given.
* Batched behavior env >= 100,000 env steps/s at E >= 256 on two cores: the best median
  at any E >= 256 of the two ways to use them, two kernel threads in one process or the
  batch split over two worker processes (:data:`SPLIT`); the reason compares it with one
  thread's and with what a perfect split of one thread's rate over 2 cores would be.
* The first step of every env on a fresh clone <= 10 s of CPU: the worst env's cold
  first step (make + reset + step on an empty numba cache); the reason names the
  kernels compiled and the first step on the filled cache (what ``python -m
  sdc_gym.precompile`` at set-up leaves).
* The single track env at least as fast as the scalar code it replaced: the ratio of the
  medians ``now / scalar`` >= 1; below it, whether the rounds overlap (within noise) or not.
"""

from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

PPO_GOAL = 40_000.0
ENV_GOAL = 100_000.0
ENV_GOAL_MIN_ENVS = 256
COLD_GOAL_S = 10.0
SPLIT = "2 processes"
"""The key (with E) of the batch split over two worker processes in the threads' rates."""
TWO_CORES = {2: "2 kernel threads", SPLIT: "2 processes"}
CORES = "core scaling"
"""The key of the machine's two-core scaling rounds (``bench_kernel_threads.core_scaling``:
two independent CPU-bound processes at once against one alone, 2.0 for two full cores)."""


@dataclass(frozen=True)
class Target:
    """One row of the targets table; ``met`` None: not measured (its part did not run)."""

    target: str
    measured: str
    met: bool | None
    reason: str = ""


def median(values: Sequence[float]) -> float:
    """The median of a round list; ValueError naming the problem when there is none."""
    if not values:
        raise ValueError("no rounds measured")
    return float(statistics.median(values))


def spread(values: Sequence[float], digits: int = 0) -> str:
    """``min / median / max`` (one value alone when there is one round)."""
    if len(values) == 1:
        return f"{values[0]:,.{digits}f}"
    return " / ".join(f"{value:,.{digits}f}" for value in (min(values), median(values),
                                                           max(values)))


def sequential_bound(env_rate: float, learner_rate: float) -> float:
    """Samples/s of a learner that alternates collection and update: each sample costs
    the env's time plus the learner's, ``1 / (1/env + 1/learner)``."""
    return 1.0 / (1.0 / env_rate + 1.0 / learner_rate)


def bound_cases(rates: Mapping[str, Sequence[float]], learner: str,
                env_case: str = "env") -> tuple[str, str]:
    """The env case and the no-op case that bound learner case ``learner``: a case
    ``X-suffix`` (its env split, or other settings) is bounded by ``env-suffix`` when that
    was measured (else ``env``) and by ``X-suffix-noop`` when measured (else ``X-noop``)."""
    base, _, suffix = learner.partition("-")
    if suffix and rates.get(f"{env_case}-{suffix}"):
        env_case = f"{env_case}-{suffix}"
    noop_case = f"{learner}-noop" if rates.get(f"{learner}-noop") else f"{base}-noop"
    return env_case, noop_case


def learner_target(rates: Mapping[str, Sequence[float]], goal: float = PPO_GOAL,
                   env_case: str = "env") -> Target:
    """The PPO target from ``bench_learners``-style cases: learners ``X`` with their no-op
    cases ``X-noop`` and the env alone ``env_case``; the best learner's median counts."""
    learners = {case: median(values) for case, values in rates.items()
                if not case.endswith("-noop") and not case.startswith("env") and values}
    if not learners:
        return Target(f"PPO >= {goal:,.0f} samples/s end to end", "not measured", None,
                      "no learner case measured")
    best = max(learners, key=learners.get)
    measured = f"{learners[best]:,.0f} ({best}, median)"
    name = f"PPO >= {goal:,.0f} samples/s end to end"
    if learners[best] >= goal:
        return Target(name, measured, True)
    env_case, noop_case = bound_cases(rates, best, env_case)
    env, noop = rates.get(env_case), rates.get(noop_case)
    if not env or not noop:
        return Target(name, measured, False,
                      f"below the goal; no '{env_case}' and '{best}-noop' cases to bound it")
    env_rate, own = median(env), median(noop)
    bound = sequential_bound(env_rate, own)
    if bound < goal:
        need = 2 * goal
        return Target(name, measured, False,
                      f"{best}'s sequential bound 1/(1/env + 1/learner) = 1/(1/{env_rate:,.0f}"
                      f" + 1/{own:,.0f}) = {bound:,.0f} < {goal:,.0f}: alternating "
                      f"collection and update cannot reach it; it would need env and learner "
                      f"each near {need:,.0f}/s, or the two overlapped on two cores "
                      f"(bounded by min = {min(env_rate, own):,.0f})")
    return Target(name, measured, False,
                  f"below its sequential bound {bound:,.0f} (env {env_rate:,.0f}, learner "
                  f"{own:,.0f}): {learners[best] / bound:.2f} of it, the loss is the learner's "
                  "glue between collection and update")


def threads_target(rates: Mapping[tuple[int, Any], Sequence[float]], goal: float = ENV_GOAL,
                   min_envs: int = ENV_GOAL_MIN_ENVS,
                   scaling: Sequence[float] | None = None) -> Target:
    """The batched env target from ``{(E, kernel_threads or SPLIT): rounds}``: the best of
    the ways to run on two cores (:data:`TWO_CORES`); ``scaling`` (rounds of
    :data:`CORES`), when measured, bounds what a split of one thread's rate can give."""
    name = f"behavior env >= {goal:,.0f} steps/s at E >= {min_envs}, 2 cores"
    two = {(envs, mode): median(values) for (envs, mode), values in rates.items()
           if mode in TWO_CORES and envs >= min_envs and values}
    if not two:
        return Target(name, "not measured", None, f"no E >= {min_envs} measured on 2 cores")
    envs, mode = max(two, key=two.get)
    rate = two[(envs, mode)]
    measured = f"{rate:,.0f} (E = {envs}, {TWO_CORES[mode]}, median)"
    if rate >= goal:
        return Target(name, measured, True)
    one = rates.get((envs, 1))
    if not one:
        return Target(name, measured, False, f"below the goal ({rate / goal:.2f} of it)")
    single = median(one)
    ceiling = 2.0 if not scaling else median(scaling)
    what = ("a perfect 2-way split (2x)" if not scaling else
            f"a perfect split on this machine ({ceiling:.2f}x: two independent CPU-bound "
            f"processes at once against one alone)")
    return Target(name, measured, False,
                  f"{TWO_CORES[mode]} run {rate / single:.2f}x one thread ({single:,.0f}) at "
                  f"E = {envs}; the goal is {goal / single:.1f}x one thread's rate, "
                  + (f"more than {what} could give" if goal > ceiling * single
                     else f"within {what}: the second core's share is what is missing (the "
                          "Python between kernels and the machine's other jobs)"))


def cold_target(first_cpu: Mapping[str, Sequence[float]],
                warm_cpu: Mapping[str, Sequence[float]] | None = None,
                compiles: Mapping[str, int] | None = None,
                goal_s: float = COLD_GOAL_S) -> Target:
    """The cold start target from each env's first-step CPU seconds on an empty cache
    (rounds), and optionally on the filled cache and the kernels each compiled."""
    name = f"first step of every env, empty cache, <= {goal_s:g} s CPU"
    measured_envs = {env: median(values) for env, values in first_cpu.items() if values}
    if not measured_envs:
        return Target(name, "not measured", None, "no env measured")
    worst = max(measured_envs, key=measured_envs.get)
    measured = f"{measured_envs[worst]:.1f} s ({worst}; best {min(measured_envs.values()):.1f} s)"
    if measured_envs[worst] <= goal_s:
        return Target(name, measured, True)
    over = [env for env, cpu in measured_envs.items() if cpu > goal_s]
    reason = (f"{len(over)} of {len(measured_envs)} envs over: numba compiles their kernels "
              "at first use")
    if compiles and worst in compiles:
        reason += f" ({compiles[worst]} functions for {worst})"
    if warm_cpu:
        warm = {env: median(values) for env, values in warm_cpu.items() if values}
        if warm:
            reason += (f"; on the filled cache (after `python -m sdc_gym.precompile`, "
                       f"`make`'s set-up) the worst first step is {max(warm.values()):.1f} s"
                       + (", within the goal" if max(warm.values()) <= goal_s else ""))
    return Target(name, measured, False, reason)


def track_target(now: Sequence[float], scalar: Sequence[float]) -> Target:
    """The single track env (``now``) against the scalar code (``scalar``), env steps/s."""
    name = "single TrackLoop-v0 env >= the scalar code"
    if not now or not scalar:
        return Target(name, "not measured", None, "a side was not measured")
    ratio = median(now) / median(scalar)
    measured = f"{ratio:.2f}x ({median(now):,.0f} / {median(scalar):,.0f} steps/s)"
    if ratio >= 1.0:
        return Target(name, measured, True)
    overlap = max(now) >= min(scalar)
    return Target(name, measured, False,
                  "slower by the medians, but the rounds overlap (within the noise of one "
                  "run)" if overlap else
                  f"slower in every round (best now {max(now):,.0f} < worst scalar "
                  f"{min(scalar):,.0f} steps/s)")


def targets_table(targets: Sequence[Target]) -> list[str]:
    """The markdown lines of the targets table."""
    lines = ["| target | measured | met | the measured reason |", "|---|---|---|---|"]
    for row in targets:
        verdict = "not measured" if row.met is None else "met" if row.met else "not met"
        lines.append(f"| {row.target} | {row.measured} | {verdict} | {row.reason or '-'} |")
    return lines
