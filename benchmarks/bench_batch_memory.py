"""Memory and build time of a batch of envs, per env, against highway-env in the same run.

    python benchmarks/bench_batch_memory.py --envs 256
    python benchmarks/bench_batch_memory.py --envs 256 --before /tmp/before   # a git archive

Each case runs in a fresh process: it first makes, resets and steps a small batch (so that
numba's kernels are compiled or loaded and the imports done), then measures making and
resetting a batch of ``--envs`` envs plus 20 steps: the wall time of make + reset and the
growth of the process's peak resident memory (``ru_maxrss``) over the whole part, divided
by the batch size. Cases: ``HighwayLoopBehavior-v0``'s native batch (this checkout, and the
tree ``--before`` if given, e.g. ``git archive`` of an older commit unpacked with the
installed package's dependencies), and highway-env's ``highway-fast-v0`` in a
``SyncVectorEnv`` of the same size (the peer; at most ``--peer-envs`` envs, since each is a
whole Python env). Printed: per case the build time, the RSS growth and MB per env, and
the ratio of per-env memory to the peer's.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

SDC_CASE = """
import json, resource, sys, time
sys.path.insert(0, {tree!r})
import gymnasium as gym, numpy as np
import sdc_gym
def rss(): return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
def batch(n):
    return gym.make_vec("sdc_gym/HighwayLoopBehavior-v0", num_envs=n,
                        vectorization_mode="vector_entry_point")
warm = batch(4); warm.reset(seed=0); warm.step(np.full(4, 4)); warm.close()
before = rss(); start = time.perf_counter()
envs = batch({envs}); envs.reset(seed=0)
build = time.perf_counter() - start
for _ in range(20):
    envs.step(np.full({envs}, 4))
print(json.dumps({{"build": build, "rss": rss() - before, "module": sdc_gym.__file__}}))
"""

PEER_CASE = """
import json, resource, time
import gymnasium as gym, highway_env, numpy as np
def rss(): return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
def batch(n):
    return gym.vector.SyncVectorEnv([lambda: gym.make("highway-fast-v0") for _ in range(n)])
warm = batch(2); warm.reset(seed=0); warm.step(np.ones(2, dtype=int)); warm.close()
before = rss(); start = time.perf_counter()
envs = batch({envs}); envs.reset(seed=0)
build = time.perf_counter() - start
for _ in range(20):
    envs.step(np.ones({envs}, dtype=int))
print(json.dumps({{"build": build, "rss": rss() - before}}))
"""


def run_case(source: str) -> dict[str, float]:
    """One case in a fresh process; its JSON line."""
    done = subprocess.run([sys.executable, "-c", source], capture_output=True, text=True,
                          check=False)
    if done.returncode:
        raise SystemExit(f"a case failed:\n{done.stderr[-2000:]}")
    return json.loads(done.stdout.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--envs", type=int, default=256)
    parser.add_argument("--peer-envs", type=int, default=64,
                        help="highway-fast-v0 envs in the peer's SyncVectorEnv")
    parser.add_argument("--before", type=Path, default=None,
                        help="another checkout (e.g. a git archive) measured the same way")
    args = parser.parse_args(argv)
    cases = {"sdc-gym (this checkout)": SDC_CASE.format(tree=str(ROOT), envs=args.envs)}
    if args.before is not None:
        cases[f"sdc-gym ({args.before})"] = SDC_CASE.format(tree=str(args.before.resolve()),
                                                            envs=args.envs)
    cases["highway-env highway-fast-v0 (peer)"] = PEER_CASE.format(envs=args.peer_envs)
    results = {name: run_case(source) for name, source in cases.items()}
    for name, result in results.items():
        if "module" in result:  # which tree's package the case imported
            print(f"{name}: {result['module']}")
    peer = results["highway-env highway-fast-v0 (peer)"]
    peer_per_env = peer["rss"] / args.peer_envs
    print("| case | envs | make + reset (s) | peak RSS growth (MB) | MB per env | "
          "x peer per env |\n|---|---:|---:|---:|---:|---:|")
    for name, result in results.items():
        envs = args.peer_envs if "peer" in name else args.envs
        per_env = result["rss"] / envs
        print(f"| {name} | {envs} | {result['build']:.2f} | {result['rss']:.0f} | "
              f"{per_env:.3f} | {per_env / peer_per_env:.2f} |")


if __name__ == "__main__":
    main()
