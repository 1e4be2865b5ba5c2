"""Ray: the envs registered in every worker, and evaluation as Ray tasks, on a real local
cluster (2 CPUs, one per test module) that is shut down after the module."""

from __future__ import annotations

import csv
import json
import signal
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import evaluate
from sdc_evaluation.episodes import EpisodeSpec, run_episode
from sdc_evaluation.runner import InProcessBackend, ProcessPoolBackend, run_episodes
from tests import ray_workers
from tests.processes import all_gone
from tests.processes import descendants as descendant_pids

ray = pytest.importorskip("ray")

HIGHWAY = "sdc_gym/HighwayLoop-v0"
BEHAVIOR = ray_workers.BEHAVIOR
SHORT = {"laps": 1, "max_duration": 12.0}
MISSING_MODEL = "ppo:/nonexistent/policy.zip"
OVAL = Path(__file__).resolve().parents[1] / "configs" / "highway_oval.yaml"


@pytest.fixture(scope="module")
def cluster():
    """A local Ray cluster of 2 CPUs for the module; the code under test finds it running
    (``sdc_gym.ray.ray_session`` then uses it and leaves it up)."""
    from ray import cloudpickle  # Ray's own copy pickles the functions it sends

    # The functions run in workers travel by value: workers need not import tests.
    cloudpickle.register_pickle_by_value(ray_workers)
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()
    cloudpickle.unregister_pickle_by_value(ray_workers)


def fresh_worker(probe):
    """Run ``probe`` in a new worker process (a runtime env of its own: no worker of the
    pool that may have imported sdc_gym already)."""
    marker = f"{probe.__name__}-{np.random.default_rng().integers(1 << 30)}"
    remote = ray.remote(num_cpus=0, runtime_env={"env_vars": {"SDC_GYM_TEST": marker}})
    return ray.get(remote(probe).remote())


def test_the_plain_id_fails_in_a_worker_and_the_registered_envs_work(cluster):
    import sdc_gym.ray

    expected, _ = gym.make(BEHAVIOR, config=ray_workers.PROBE_CONFIG).reset(
        seed=ray_workers.PROBE_SEED)
    # The failure RLlib's workers hit with the plain id: the worker never imported sdc_gym.
    had_package, outcome = fresh_worker(ray_workers.plain_id)
    assert not had_package and outcome.startswith("NamespaceNotFound")
    # Gymnasium's module prefix imports the package in the worker.
    np.testing.assert_array_equal(fresh_worker(ray_workers.prefixed_id), expected)
    # Ray's registry (what RLlib and Tune look up first): the creator imports sdc_gym.
    assert sdc_gym.ray.register_envs() == sdc_gym.ENV_IDS
    had_package, observation = fresh_worker(ray_workers.registered_creator)
    assert not had_package
    np.testing.assert_array_equal(observation, expected)


def test_no_cluster_at_the_address_is_a_quick_clear_error(tmp_path):
    import socket

    from sdc_gym.ray import unreachable

    with socket.socket() as probe:  # a port of this machine where nothing listens
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    assert "no Ray cluster answers at" in unreachable(f"127.0.0.1:{port}")
    assert "no Ray cluster at 'nohost'" in unreachable("nohost")
    with pytest.raises(SystemExit, match=f"--ray 127.0.0.1:{port}: no Ray cluster answers.*"
                                         "ray start --head"):
        evaluate.main(["--agents", "lane_keeping", "--ray", f"127.0.0.1:{port}",
                       "--output", str(tmp_path / "run")])
    assert not (tmp_path / "run").exists()


def read_rows(path):
    with path.open(newline="") as handle:
        return [{key: value for key, value in row.items() if key != "wall_time"}
                for row in csv.DictReader(handle)]


def test_ray_run_writes_the_local_pools_rows_and_reports_a_raising_episode(cluster, tmp_path,
                                                                          capsys, monkeypatch):
    # evaluate.py refuses a missing model before any episode; without those checks the
    # same agent raises inside every episode, in the pool's workers and Ray's tasks alike.
    monkeypatch.setattr(evaluate, "check_agent_env", lambda spec, env_id: None)
    monkeypatch.setattr(evaluate, "check_agent_builds", lambda spec, env: None)
    common = ["--agents", "lane_keeping", "fsm_bold", MISSING_MODEL, "--seeds", "0", "1",
              "--config", str(OVAL), "--laps", "1", "--no-plots",
              "--no-progress", "--bootstrap-resamples", "200"]
    pool = evaluate.main([*common, "--workers", "2", "--output", str(tmp_path / "pool")])
    on_ray = evaluate.main([*common, "--ray", "--output", str(tmp_path / "ray")])
    out = capsys.readouterr().out
    rows = read_rows(tmp_path / "ray" / "episodes.csv")
    assert rows == read_rows(tmp_path / "pool" / "episodes.csv")  # same episodes, same rows
    assert [(row["agent"], row["seed"]) for row in rows] == [
        ("lane_keeping", "0"), ("lane_keeping", "1"), ("fsm_bold", "0"), ("fsm_bold", "1")]
    # The raising agent: reported per episode with seed and reason; the rest finished.
    for result in (pool, on_ray):
        assert [(f.agent, f.seed) for f in result["failures"]] == [(MISSING_MODEL, 0),
                                                                    (MISSING_MODEL, 1)]
        assert all(f.reason == "ValueError: ppo: no model file at /nonexistent/policy.zip"
                   for f in result["failures"])
    assert out.count(f"{MISSING_MODEL} seed 1 failed: ValueError") == 2
    summary = json.loads((tmp_path / "ray" / "summary.json").read_text())
    assert summary["run"]["ray"] == "local"
    assert [f["seed"] for f in summary["run"]["failures"]] == [0, 1]
    details = summary["run"]["failures"][0]["details"]  # the worker's traceback, plain
    assert "ray::_episode_task()" in details and "\x1b" not in details
    assert 'raise ValueError(f"{kind}: no model file at {model_path}")' in details


def test_a_worker_that_dies_is_reported_and_the_other_episodes_finish(cluster):
    from sdc_evaluation.ray_backend import RayBackend

    specs = [EpisodeSpec("lane_keeping", HIGHWAY, seed, SHORT) for seed in (0, 1, 2)]
    runs = run_episodes(specs, progress=False, backend=RayBackend(episode=ray_workers.die_on_seed))
    [failure] = runs.failures
    assert failure.seed == ray_workers.DIES_ON_SEED and failure.agent == "lane_keeping"
    assert failure.reason.startswith("the worker died: WorkerCrashedError")
    alone = [run_episode(spec) for spec in specs if spec.seed != ray_workers.DIES_ON_SEED]
    assert [r["seed"] for r in runs.results] == [0, 2]
    for got, expected in zip(runs.results, alone, strict=True):
        assert got["distance"] == expected["distance"] and got["time"] == expected["time"]
        np.testing.assert_array_equal(got["trace"].speed, expected["trace"].speed)


class RecordingEvents:
    def __init__(self):
        self.log = []

    def started(self, index):
        self.log.append(("started", index))

    def progress(self, index, laps, fields):
        self.log.append(("progress", index))

    def finished(self, index, result):
        self.log.append(("finished", index))

    def failed(self, index, reason, details):
        self.log.append(("failed", index, reason))


@pytest.mark.parametrize("backend", ["in_process", "pool", "ray"])
def test_every_backend_reports_each_episode_once_with_progress(cluster, backend):
    from sdc_evaluation.ray_backend import RayBackend

    specs = [EpisodeSpec("lane_keeping", HIGHWAY, 0, SHORT),
             EpisodeSpec(MISSING_MODEL, HIGHWAY, 3, SHORT)]
    events = RecordingEvents()
    {"in_process": InProcessBackend(), "pool": ProcessPoolBackend(2),
     "ray": RayBackend()}[backend].run(specs, events)
    ends = sorted(entry for entry in events.log if entry[0] in ("finished", "failed"))
    assert ends == [("failed", 1, "ValueError: ppo: no model file at /nonexistent/policy.zip"),
                    ("finished", 0)]
    # 12 s of driving: 600 steps, a progress report every 100 (the ray backend's arrive
    # through its queue, all before the result is collected or later ignored).
    assert ("progress", 0) in events.log


def descendants(pid: int) -> dict[int, str]:
    """Every live process below ``pid``, with its command line."""
    found = {}
    for child in descendant_pids(pid):
        try:
            found[child] = (Path("/proc") / str(child) / "cmdline").read_bytes() \
                .replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
    return found


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGKILL], ids=["ctrl_c", "kill_9"])
def test_ctrl_c_or_kill_9_stops_the_run_and_no_process_of_its_cluster_is_left(tmp_path, signum):
    """evaluate.py --ray with a cluster started on the spot, interrupted (Ctrl-C) or killed
    (``kill -9``) while its episodes run: no process of its cluster (GCS, raylet, agents,
    workers, the watchdog) is left. Ray's fate sharing alone left the raylet's agents
    running after a kill -9: sdc_gym.ray_watchdog ends them."""
    import os
    import subprocess
    import time

    # A shell's background job ignores SIGINT; a terminal's Ctrl-C reaches Python's handler.
    launcher = ("import signal, sys, runpy; "
                "signal.signal(signal.SIGINT, signal.default_int_handler); "
                "sys.argv = ['evaluate.py'] + sys.argv[1:]; "
                "runpy.run_path('evaluate.py', run_name='__main__')")
    process = subprocess.Popen(
        [sys.executable, "-c", launcher, "--agents", "fsm_bold", "--seeds", "0", "1",
         "--laps", "20", "--ray", "--workers", "2", "--no-plots", "--no-progress",
         "--output", str(tmp_path / "run")],
        cwd=Path(__file__).resolve().parents[1], stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE, start_new_session=True)
    try:
        deadline = time.monotonic() + 120
        seen: dict[int, str] = {}
        while time.monotonic() < deadline:
            seen.update(descendants(process.pid))
            if sum("ray::_episode_task" in command for command in seen.values()) >= 2:
                break
            assert process.poll() is None, process.stderr.read().decode()
            time.sleep(0.5)
        else:
            pytest.fail(f"no episode task started in 120 s: {sorted(seen.values())}")
        assert any("gcs_server" in command for command in seen.values())
        assert any("raylet" in command for command in seen.values())
        assert any("sdc_gym.ray_watchdog" in command for command in seen.values())
        process.send_signal(signum)
        assert process.wait(timeout=60) != 0
    finally:
        if process.poll() is None:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
    if signum == signal.SIGINT:
        assert "KeyboardInterrupt" in process.stderr.read().decode()
    alive = all_gone(list(seen), wait_s=10.0)  # they exit within a few seconds of the owner
    assert not alive, f"left running: {[seen[pid] for pid in alive]}"
    assert not (tmp_path / "run" / "episodes.csv").exists()  # interrupted: no results
