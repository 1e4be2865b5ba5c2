"""The four measurements of ``speed_report.py``, each from the benchmark script that owns it.

Each ``measure_*`` function runs one part at a :class:`Settings` and returns its rounds
(lists of values, one per round, so the report prints min / median / max and judges on the
median); each ``*_lines`` function prints one part's table:

* ``learners``: ``bench_learners.py``'s cases (the env alone, each learner and its no-op
  case, RLlib) interleaved in rounds, then ``learner_time_to_mph.py``'s races;
* ``threads``: ``bench_kernel_threads.py``'s batches (kernel_threads 1 and 2 on one batch per
  E, and the batch split over 2 worker processes) and its peer, highway-env's
  ``highway-fast-v0``;
* ``cold``: ``cold_start.py``'s child processes, each on an empty ``NUMBA_CACHE_DIR`` and
  again on the folder it filled (the fresh process a cold start needs);
* ``track``: ``bench_track_batched.py``'s ``track_single`` worker (the single
  ``TrackLoop-v0`` env under the pursuit driver, a fresh process per round) in this tree
  and in the scalar code's (a ``git archive`` of :data:`SCALAR_COMMIT` unless given).

Heavy imports (torch, numba, the envs) happen inside the functions, so that importing this
module (the tests, ``--help``) costs nothing.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "benchmarks")]

from learner_time_to_mph import DEFAULT_TARGET_MPH, Race, race_table  # noqa: E402
from speed_targets import CORES, SPLIT, bound_cases, sequential_bound, spread  # noqa: E402

SCALAR_COMMIT = "4bba301"
"""The last commit with the scalar track code (docs/batched.md: ``--before`` of 054b497)."""
LEARNER_ENVS = 64
Report = Callable[[str], None]


@dataclass(frozen=True)
class Settings:
    """Sizes of every part; the defaults take ~15-20 minutes in all on this machine."""

    learner_samples: int = 16_384
    learner_rounds: int = 3
    rllib_samples: int = 4_096
    race_budget_s: float = 240.0
    race_check_every: int = 32_768
    race_laps: int = 4
    target_mph: float = DEFAULT_TARGET_MPH
    race_learners: tuple[str, ...] = ("sb3", "sb3-large", "rllib", "torchrl", "pufferlib")
    thread_envs: tuple[int, ...] = (64, 256, 1024, 4096)
    thread_rounds: int = 3
    thread_steps: int = 120_000
    peer_steps: int = 100
    cold_cases: tuple[str, ...] = ("highway", "behavior", "track", "track_behavior")
    cold_steps: int = 50
    track_steps: int = 3_000
    track_rounds: int = 3
    scalar_tree: Path | None = None


QUICK = Settings(learner_samples=2_048, learner_rounds=1, rllib_samples=2_048,
                 race_budget_s=10.0, race_check_every=4_096, race_laps=2,
                 thread_envs=(256,), thread_rounds=1, thread_steps=2_048, peer_steps=20,
                 cold_cases=("track",), cold_steps=5, track_steps=300, track_rounds=1)
"""A smoke run of every part: minutes, mostly process start-up and a cold compile."""


@dataclass
class LearnerResult:
    rates: dict[str, list[float]] = field(default_factory=dict)
    races: list[Race] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


@dataclass
class ColdResult:
    first_cpu: dict[str, list[float]] = field(default_factory=dict)
    warm_cpu: dict[str, list[float]] = field(default_factory=dict)
    compiles: dict[str, int] = field(default_factory=dict)
    process_cpu: dict[str, list[float]] = field(default_factory=dict)


@dataclass
class TrackResult:
    now: list[float] = field(default_factory=list)
    scalar: list[float] = field(default_factory=list)
    scalar_tree: str = ""


def quick(settings: Settings) -> Settings:
    """``settings`` shrunk to :data:`QUICK`'s sizes (the scalar tree kept)."""
    return replace(QUICK, scalar_tree=settings.scalar_tree, target_mph=settings.target_mph)


# ------------------------------------------------------------------ learners
def learner_cases() -> tuple[list[str], list[str]]:
    """``bench_learners`` cases to run here and the notes of those skipped: the env alone,
    each importable learner with its no-op case, RLlib (no no-op case) when Ray imports."""
    from learners_pufferlib import puffer_importable

    cases, notes = ["env", "env-split", "env-large", "sb3", "sb3-noop", "sb3-split",
                    "sb3-large", "sb3-large-noop"], []
    if importlib.util.find_spec("torchrl") is not None:
        cases += ["torchrl", "torchrl-noop"]
    else:
        notes.append("torchrl cases skipped: torchrl is not installed (pip install --no-deps "
                     "torchrl==0.14.1 tensordict==0.15.3 pyvers)")
    if puffer_importable():
        cases += ["pufferlib", "pufferlib-noop"]
    else:
        notes.append(f"pufferlib cases skipped: {puffer_importable.reason}")
    if importlib.util.find_spec("ray") is not None:
        cases.append("rllib")
    else:
        notes.append('rllib case skipped: Ray is not installed (pip install -e ".[ray]")')
    return cases, notes


@contextmanager
def maybe_ray() -> Iterator[None]:
    """One local Ray cluster for the learners part (shut down at its end), if Ray imports."""
    if importlib.util.find_spec("ray") is None:
        yield
        return
    from sdc_gym.ray import LOCAL, ray_session

    with ray_session(LOCAL):
        yield


def measure_learners(settings: Settings, report: Report = print) -> LearnerResult:
    """The cases' rounds and the races. RLlib's case and race come last, together, in one
    local Ray cluster (shut down after them), so that its processes do not run beside the
    other learners' measurements."""
    import warnings

    import bench_learners
    import learner_time_to_mph as ttm

    warnings.filterwarnings("ignore")
    cases, notes = learner_cases()
    result = LearnerResult({case: [] for case in cases}, notes=list(notes))
    for note in notes:
        report(note)

    def rounds(names: list[str]) -> None:
        for round_ in range(settings.learner_rounds):
            for case in names:
                fn, noop = bench_learners.CASES[case]
                samples = settings.rllib_samples if case == "rllib" else settings.learner_samples
                result.rates[case].append(fn(LEARNER_ENVS, samples, noop, 1))
                report(f"  round {round_ + 1} {case}: {result.rates[case][-1]:,.0f} samples/s")

    def races(names: list[str]) -> None:
        args = _race_args(settings, names)
        found, race_notes = ttm.run_races(args, report)
        result.races += found
        result.notes += race_notes

    on_ray = [case for case in cases if case == "rllib"]
    rounds([case for case in cases if case not in on_ray])
    races([name for name in settings.race_learners if name != "rllib"])
    if "rllib" in settings.race_learners or on_ray:
        with maybe_ray():
            rounds(on_ray)
            if "rllib" in settings.race_learners:
                races(["rllib"])
    return result


def _race_args(settings: Settings, learners: list[str]) -> Any:
    import argparse

    return argparse.Namespace(learners=learners,
                              target_mph=settings.target_mph, budget_s=settings.race_budget_s,
                              check_every=settings.race_check_every, laps=settings.race_laps,
                              envs=LEARNER_ENVS, seed=0)


def learner_lines(result: LearnerResult) -> list[str]:
    """The cases' table (with x sb3), the sequential bounds, the races' table."""
    from statistics import median

    base = median(result.rates["sb3"]) if result.rates.get("sb3") else None
    lines = [f"PPO samples/s end to end, E = {LEARNER_ENVS}, the project's PPO "
             "(min / median / max over rounds)", "",
             "| case | samples/s | x sb3 (medians) |", "|---|---|---:|"]
    for case, values in result.rates.items():
        if values:
            ratio = f"{median(values) / base:.2f}" if base else "-"
            lines.append(f"| {case} | {spread(values)} | {ratio} |")
    rows = []
    for case, values in result.rates.items():
        if not values or case.startswith("env") or case.endswith("-noop"):
            continue
        env_case, noop_case = bound_cases(result.rates, case)
        if result.rates.get(env_case) and result.rates.get(noop_case):
            rows.append((case, env_case, median(result.rates[env_case]),
                         median(result.rates[noop_case]), median(values)))
    if rows:
        lines += ["", "| learner | env case | env alone | learner alone | sequential bound | "
                  "end to end | / bound |", "|---|---|---:|---:|---:|---:|---:|"]
        for case, env_case, env, own, end in rows:
            bound = sequential_bound(env, own)
            lines.append(f"| {case} | {env_case} | {env:,.0f} | {own:,.0f} | {bound:,.0f} | "
                         f"{end:,.0f} | {end / bound:.2f} |")
    lines += ["", "Time to the target mean mph (validation laps, seeds from 2000)", "",
              *race_table(result.races), *result.notes]
    return lines


# ------------------------------------------------------------------ threads
def measure_threads(settings: Settings,
                    report: Report = print) -> dict[tuple[int, Any] | str, list[float]]:
    """``{(E, kernel_threads): rounds, (E, SPLIT): rounds, "peer": rounds, CORES: rounds}``
    (bench_kernel_threads' method: :data:`speed_targets.SPLIT` the 2-process batch,
    :data:`speed_targets.CORES` the machine's two-core scaling, ``core_scaling``)."""
    import warnings

    import bench_kernel_threads as kt

    warnings.filterwarnings("ignore")
    rates: dict[tuple[int, Any] | str, list[float]] = {"peer": []}
    for envs in settings.thread_envs:
        vector, rng = kt.make(envs, max(kt.THREADS))
        split, split_rng = kt.make_split(envs)
        threads_of = vector.unwrapped.batch.world.kernel_threads
        for mode in (*kt.THREADS, SPLIT):
            rates[(envs, mode)] = []
        for round_ in range(settings.thread_rounds):
            for threads in kt.THREADS:
                threads_of.set(threads)
                rates[(envs, threads)].append(kt.steps_per_second(vector, rng,
                                                                  settings.thread_steps))
            rates[(envs, SPLIT)].append(kt.steps_per_second(split, split_rng,
                                                            settings.thread_steps))
            rates["peer"].append(kt.env_steps_per_second(kt.PEER, settings.peer_steps,
                                                         seed=round_))
            report(f"  E = {envs} round {round_ + 1}: " + ", ".join(
                f"{t} thread(s) {rates[(envs, t)][-1]:,.0f}" for t in kt.THREADS)
                + f", {SPLIT} {rates[(envs, SPLIT)][-1]:,.0f}, {kt.PEER} "
                f"{rates['peer'][-1]:,.1f} env steps/s")
        vector.close()
        split.close()
    rates[CORES] = kt.core_scaling(settings.thread_rounds)
    report(f"  two independent CPU-bound processes at once: {spread(rates[CORES], 2)}x one")
    return rates


def thread_lines(rates: dict[tuple[int, Any] | str, list[float]]) -> list[str]:
    from statistics import median

    peer = median(rates["peer"])
    lines = ["HighwayLoopBehavior-v0 batch, env steps/s (min / median / max over rounds); "
             "peer highway-fast-v0 (one env)", "",
             f"| E | kernel_threads 1 | kernel_threads 2 | {SPLIT} | 2 threads / 1 | "
             f"{SPLIT} / 1 | 1 thread / peer | {SPLIT} / peer |",
             "|---:|---|---|---|---:|---:|---:|---:|"]
    for envs in sorted({key[0] for key in rates if isinstance(key, tuple)}):
        one, two, split = rates[(envs, 1)], rates[(envs, 2)], rates[(envs, SPLIT)]
        lines.append(f"| {envs} | {spread(one)} | {spread(two)} | {spread(split)} | "
                     f"{median(two) / median(one):.2f}x | {median(split) / median(one):.2f}x "
                     f"| {median(one) / peer:,.0f}x | {median(split) / peer:,.0f}x |")
    lines.append(f"peer highway-fast-v0: {spread(rates['peer'], 1)} env steps/s")
    if rates.get(CORES):
        lines.append(f"this machine's two cores: two independent CPU-bound processes at once "
                     f"do {spread(rates[CORES], 2)}x the work of one alone (the ceiling of any "
                     "2-way split)")
    return lines


# ------------------------------------------------------------------ cold start
def first_step_cpu(result: dict[str, Any]) -> float:
    """make + reset + first step CPU of a ``cold_start.child`` result."""
    return sum(result["times"][phase]["cpu"] for phase in ("make", "reset", "first step"))


def measure_cold(settings: Settings, report: Report = print, rounds: int = 1) -> ColdResult:
    """Each case in a fresh process on an empty numba cache, then on the filled one."""
    import cold_start

    result = ColdResult()
    for _ in range(rounds):
        for case in settings.cold_cases:
            with tempfile.TemporaryDirectory(prefix="numba-cold-") as cache:
                cold = cold_start.run_child(ROOT, case, settings.cold_steps, cache)
                warm = cold_start.run_child(ROOT, case, settings.cold_steps, cache)
            result.first_cpu.setdefault(case, []).append(first_step_cpu(cold))
            result.warm_cpu.setdefault(case, []).append(first_step_cpu(warm))
            result.process_cpu.setdefault(case, []).append(cold["process_cpu"])
            result.compiles[case] = max(result.compiles.get(case, 0),
                                        sum(1 for c in cold["compiles"] if c["top"]))
            report(f"  {case}: first step {result.first_cpu[case][-1]:.1f} s CPU cold, "
                   f"{result.warm_cpu[case][-1]:.1f} s warm")
    return result


def cold_lines(result: ColdResult) -> list[str]:
    import cold_start

    lines = ["First step (make + reset + step) CPU s per env in a fresh process, empty "
             "NUMBA_CACHE_DIR (cold) and the folder it filled (warm)", "",
             "| env | case | cold first step | warm first step | cold process CPU | "
             "functions compiled |", "|---|---|---:|---:|---:|---:|"]
    for case, values in result.first_cpu.items():
        env_id, num_envs, _ = cold_start.CASES[case]
        label = env_id.split("/")[-1] + (f", make_vec E = {num_envs}" if num_envs else "")
        lines.append(f"| {label} | {case} | {spread(values, 1)} | "
                     f"{spread(result.warm_cpu[case], 1)} | "
                     f"{spread(result.process_cpu[case], 1)} | {result.compiles[case]} |")
    return lines


# ------------------------------------------------------------------ track
def scalar_tree(folder: Path, commit: str = SCALAR_COMMIT) -> Path:
    """``git archive`` of ``commit`` (this repository's) extracted into ``folder``."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", commit], capture_output=True,
                             check=False)
    if archive.returncode:
        raise SystemExit(f"--scalar-tree: no tree given and `git archive {commit}` failed "
                         f"({archive.stderr.decode(errors='replace').strip()}); give a "
                         f"checkout of {commit} with --scalar-tree")
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive.stdout, check=True)
    return folder


def measure_track(settings: Settings, report: Report = print) -> TrackResult:
    """Env steps/s of the single ``TrackLoop-v0`` env, now and in the scalar tree,
    interleaved rounds of fresh processes."""
    import bench_track_batched

    with tempfile.TemporaryDirectory(prefix="scalar-track-") as folder:
        tree = settings.scalar_tree or scalar_tree(Path(folder))
        if not (tree / "sdc_gym").is_dir():
            raise SystemExit(f"--scalar-tree: {tree} holds no sdc_gym/ (a checkout of "
                             f"{SCALAR_COMMIT} is expected)")
        result = TrackResult(scalar_tree=str(settings.scalar_tree or
                                             f"git archive {SCALAR_COMMIT}"))
        for round_ in range(settings.track_rounds):
            for side, where in (("scalar", tree), ("now", ROOT)):
                rate = bench_track_batched.run_worker(where, "track_single",
                                                      steps=settings.track_steps)
                getattr(result, side).append(rate["steps_per_s"])
            report(f"  round {round_ + 1}: now {result.now[-1]:,.0f}, scalar "
                   f"{result.scalar[-1]:,.0f} env steps/s")
    return result


def track_lines(result: TrackResult) -> list[str]:
    from statistics import median

    return [f"Single TrackLoop-v0 env under bench_track's pursuit driver, env steps/s (min / "
            f"median / max over rounds, a fresh process each); scalar code: "
            f"{result.scalar_tree}", "",
            "| code | env steps/s | x scalar (medians) |", "|---|---|---:|",
            f"| scalar ({SCALAR_COMMIT}) | {spread(result.scalar)} | 1.00 |",
            f"| now | {spread(result.now)} | {median(result.now) / median(result.scalar):.2f} |"]


def load() -> str:
    return " ".join(f"{value:.2f}" for value in os.getloadavg())
