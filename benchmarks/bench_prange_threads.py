"""Does a ``prange`` over the env axis pay on this machine? The feasibility probe of issue 27.

    python benchmarks/bench_prange_threads.py [--envs 64 256 1024] [--rounds 7] [--calls 200]

Compiles, as the package's ``@kernel`` would (``cache=True, _nrt=False``) plus
``parallel=True``, an env-axis loop shaped like ``geometry/exact_math._atan2_loop`` and the
traffic kernels (each env's row of ``atan2``/``sin`` on its own cars, no reduction across
envs), and reports: the threading layer numba picked (workqueue/omp/tbb), whether 1 and 2
threads give bit-identical results, and per E the seconds of ``--calls`` calls with 1 and
2 threads (min/median/max over ``--rounds`` rounds, the two thread counts alternating in
each round so that both see the same load) and the ratio of medians (1 thread / 2
threads: above 1 means two threads are faster). Also prints the load average, since on
the shared 2-core machine the second thread competes with every other process.
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time

import numba
import numpy as np
from numba import njit, prange


@njit(cache=True, _nrt=False, parallel=True)
def env_rows(y: np.ndarray, x: np.ndarray, out: np.ndarray) -> None:
    """Per env (row) and car: ``atan2`` then a few ``sin``: independent rows, no reduction."""
    for env in prange(x.shape[0]):
        for car in range(x.shape[1]):
            angle = math.atan2(y[env, car], x[env, car])
            out[env, car] = angle + math.sin(angle) + math.sin(2.0 * angle)


def seconds(envs: int, threads: int, calls: int, y: np.ndarray, x: np.ndarray,
            out: np.ndarray) -> float:
    numba.set_num_threads(threads)
    started = time.perf_counter()
    for _ in range(calls):
        env_rows(y, x, out)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--envs", type=int, nargs="+", default=[64, 256, 1024])
    parser.add_argument("--cars", type=int, default=40)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--calls", type=int, default=200)
    args = parser.parse_args()
    print(f"numba {numba.__version__}, NUMBA_NUM_THREADS {numba.config.NUMBA_NUM_THREADS}, "
          f"load average {os.getloadavg()}")
    generator = np.random.default_rng(0)
    previous = numba.get_num_threads()
    try:
        for envs in args.envs:
            y = generator.normal(size=(envs, args.cars))
            x = generator.normal(size=(envs, args.cars))
            one, two = np.empty_like(x), np.empty_like(x)
            numba.set_num_threads(1)
            env_rows(y, x, one)
            numba.set_num_threads(2)
            env_rows(y, x, two)
            identical = bool((one.view(np.int64) == two.view(np.int64)).all())
            times: dict[int, list[float]] = {1: [], 2: []}
            for _ in range(args.rounds):
                for threads in (1, 2):
                    times[threads].append(seconds(envs, threads, args.calls, y, x, one))
            cells = {t: [min(v), statistics.median(v), max(v)] for t, v in times.items()}
            ratio = cells[1][1] / cells[2][1]
            print(f"E={envs:5d} layer {numba.threading_layer()} bit-identical {identical} | "
                  + " | ".join(f"{t} thread(s) " + "/".join(f"{s * 1e3:.1f}" for s in c)
                               + " ms" for t, c in cells.items())
                  + f" | 2-thread speedup {ratio:.2f}x")
    finally:
        numba.set_num_threads(previous)
    print(f"load average after {os.getloadavg()}")


if __name__ == "__main__":
    main()
