"""The recorded episodes under every processor dispatch this machine can run.

    python benchmarks/reproducibility.py                    # every configuration
    python benchmarks/reproducibility.py --configs openblas=Sandybridge numpy=-X86_V3
    python benchmarks/reproducibility.py --lowest           # the two CI runs
    python benchmarks/reproducibility.py --list             # what would run, and why not

Results must not depend on which kernels the libraries pick for the processor. Each
configuration below runs the recorded-episode tests (``tests/test_batched.py`` and
``tests/test_track_batched.py``: digests of every step of 70 episodes of every env, the
highway's and the track's agents, recorded once) in a fresh process with the libraries
forced onto other kernels:

* ``openblas=CORE``: ``OPENBLAS_CORETYPE=CORE``, the BLAS kernels of another processor
  (numpy's and scipy's OpenBLAS both read it). Cores whose instructions this processor
  lacks are listed as not runnable (a probe process would die of SIGILL).
* ``numpy=-FEATURE``: ``NPY_DISABLE_CPU_FEATURES=FEATURE``, numpy's SIMD kernels without
  that feature group (X86_V4 is AVX-512, X86_V3 AVX2 and FMA), so the next lower ones run.
  Only groups the processor has can be disabled. Without X86_V3 numpy runs the kernels
  of processors that lack AVX2 and FMA, which are outside the promise.
* ``numba=generic``: ``NUMBA_CPU_NAME=generic``, kernels compiled for a generic x86-64
  instead of this processor (compiled afresh: numba caches per CPU name).
* ``torch=default``: ``ATEN_CPU_CAPABILITY=default``, torch without its AVX2/AVX-512
  kernels (the CNN light classifier's episode).

A configuration passes when every recorded episode reproduces bit for bit. The exit code
is 1 when any configuration fails, so CI can run a few of them.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RECORDED_TESTS = ["tests/test_batched.py", "tests/test_track_batched.py"]
OPENBLAS_CORES = ["Prescott", "Core2", "Nehalem", "Sandybridge", "Haswell", "Zen", "SkylakeX",
                  "Cooperlake", "SapphireRapids"]
NUMPY_FEATURE_GROUPS = ["X86_V4", "X86_V3"]

# BLAS calls of several shapes and LAPACK solves: a core whose kernels use instructions this
# processor lacks dies of SIGILL here rather than in the middle of the tests.
_BLAS_PROBE = """
import numpy as np, scipy.linalg
rng = np.random.default_rng(0)
for n in (2, 3, 4, 7, 20, 64, 300):
    a = rng.random((n, n)); b = rng.random(n)
    a @ a; a @ b; b @ b
    np.linalg.solve(a + n * np.eye(n), b); scipy.linalg.solve(a + n * np.eye(n), b)
"""


def _run(env: dict[str, str], code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code], env={**os.environ, **env},
                          capture_output=True, text=True, timeout=120, check=False)


def _openblas_core_in_use(core: str) -> str | None:
    """The core OpenBLAS reports it uses when asked for ``core`` (None: not runnable)."""
    result = _run({"OPENBLAS_CORETYPE": core, "OPENBLAS_VERBOSE": "2"}, _BLAS_PROBE)
    if result.returncode != 0:
        return None
    found = re.findall(r"Core: (\w+)", result.stdout + result.stderr)
    return found[-1] if found else "?"


def _numpy_features() -> set[str]:
    result = _run({}, "import numpy as np; from numpy._core._multiarray_umath import "
                      "__cpu_features__ as f; print(' '.join(k for k, v in f.items() if v))")
    return set(result.stdout.split())


def configurations() -> list[tuple[str, dict[str, str] | None, str]]:
    """Every configuration as (name, environment or None if not runnable, note)."""
    items: list[tuple[str, dict[str, str] | None, str]] = [("default", {}, "as installed")]
    seen: dict[str, str] = {}
    for core in OPENBLAS_CORES:
        used = _openblas_core_in_use(core)
        if used is None:
            items.append((f"openblas={core}", None, "its kernels need instructions this "
                                                   "processor lacks (SIGILL)"))
        elif used in seen:
            items.append((f"openblas={core}", None, f"runs {used}'s kernels, as "
                                                    f"openblas={seen[used]} does"))
        else:
            seen[used] = core
            items.append((f"openblas={core}", {"OPENBLAS_CORETYPE": core},
                          f"OpenBLAS uses {used}"))
    features = _numpy_features()
    for group in NUMPY_FEATURE_GROUPS:
        if group in features:
            items.append((f"numpy=-{group}", {"NPY_DISABLE_CPU_FEATURES": group},
                          "numpy's next lower SIMD kernels"))
        else:
            items.append((f"numpy=-{group}", None, f"this processor has no {group}"))
    items.append(("numba=generic", {"NUMBA_CPU_NAME": "generic"},
                  "kernels compiled for a generic x86-64"))
    items.append(("torch=default", {"ATEN_CPU_CAPABILITY": "default"},
                  "torch without SIMD kernels"))
    lowest = [env for name, env, _ in items if env and name.startswith("openblas=")][:1]
    lowest_numpy = [env for name, env, _ in items if env and name.startswith("numpy=")][-1:]
    if lowest and lowest_numpy:
        items.append(("all-lowest", {**lowest[0], **lowest_numpy[0],
                                     "NUMBA_CPU_NAME": "generic",
                                     "ATEN_CPU_CAPABILITY": "default"},
                      "the oldest BLAS core, numpy's lowest kernels, generic numba, torch"))
    return items


def lowest_configurations(compile_generic: bool = True) -> list[tuple[str, dict[str, str]]]:
    """The configurations farthest from the default within the promise (CI runs these):
    the oldest OpenBLAS core this processor runs, and numpy without AVX-512 where the
    processor has it, else (``compile_generic``) numba's kernels for a generic x86-64.

    Not numpy without X86_V3: its baseline kernels are those of processors without AVX2
    and FMA, outside the promise (docs/guarantees.md); ``--configs numpy=-X86_V3`` shows
    what changes there."""
    cores = [core for core in OPENBLAS_CORES if _openblas_core_in_use(core) is not None]
    chosen = [(f"openblas={cores[0]}", {"OPENBLAS_CORETYPE": cores[0]})]
    if "X86_V4" in _numpy_features():
        chosen.append(("numpy=-X86_V4", {"NPY_DISABLE_CPU_FEATURES": "X86_V4"}))
    elif compile_generic:
        chosen.append(("numba=generic", {"NUMBA_CPU_NAME": "generic"}))
    return chosen


def run_recorded_tests(env: dict[str, str]) -> tuple[bool, str, float]:
    """Run the recorded-episode tests under ``env``: (passed, pytest's summary, seconds)."""
    start = time.perf_counter()
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-p", "no:cacheprovider", "-k", "recorded",
         *RECORDED_TESTS], cwd=ROOT, env={**os.environ, **env}, capture_output=True,
        text=True, check=False)
    lines = [line for line in result.stdout.splitlines() if line.strip()]
    summary = lines[-1] if lines else result.stderr.strip()[-200:]
    failed = [line for line in lines if line.startswith("FAILED")]
    if failed:
        summary += " | " + "; ".join(line.split("::")[-1] for line in failed[:6])
    return result.returncode == 0, summary, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--configs", nargs="*", default=None,
                        help="names from --list (default: every runnable one)")
    parser.add_argument("--list", action="store_true", help="list the configurations")
    parser.add_argument("--lowest", action="store_true",
                        help="the oldest OpenBLAS core, numpy without AVX-512 (or generic "
                             "numba)")
    args = parser.parse_args()
    if args.lowest:
        args.configs = [name for name, _ in lowest_configurations()]
    items = configurations()
    names = [name for name, _, _ in items]
    if args.configs is not None:
        unknown = [name for name in args.configs if name not in names]
        if unknown:
            parser.error(f"unknown configuration(s) {unknown}; choose from {names}")
    if args.list:
        for name, env, note in items:
            print(f"{name:22s} {'runs' if env is not None else 'skipped':8s} {note}")
        return
    chosen = [item for item in items if args.configs is None or item[0] in args.configs]
    failures = 0
    for name, env, note in chosen:
        if env is None:
            if args.configs is not None:
                print(f"{name:22s} NOT RUNNABLE HERE: {note}", flush=True)
                failures += 1
            else:
                print(f"{name:22s} skipped: {note}", flush=True)
            continue
        passed, summary, seconds = run_recorded_tests(env)
        failures += not passed
        print(f"{name:22s} {'PASS' if passed else 'FAIL'} {seconds:6.0f} s  {summary}  "
              f"({note})", flush=True)
    sys.exit(1 if failures else 0)


if __name__ == "__main__":
    main()
