"""How the package's numba kernels are compiled and cached (``sdc_gym.kernel_compiler``)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import numpy as np
import pytest

from sdc_gym import kernel_compiler
from sdc_gym.kernel_compiler import PackageStampLocator, bind, kernel, package_stamp

PACKAGE = Path(kernel_compiler.__file__).resolve().parent


def test_every_module_using_numba_installs_the_package_locator_first():
    """A module that compiles before the locator is installed would cache under numba's
    per-file stamp (and the two locators would overwrite each other's index)."""
    missing = [str(path.relative_to(PACKAGE)) for path in sorted(PACKAGE.rglob("*.py"))
               if path.name != "kernel_compiler.py"
               and ("from numba import" in (text := path.read_text())
                    or "import numba" in text) and "kernel_compiler" not in text]
    assert not missing, f"import sdc_gym.kernel_compiler before numba's decorators: {missing}"


def test_kernels_are_cached_under_the_stamp_of_all_kernel_modules():
    from sdc_gym.envs.track_kernel import run_steps
    from sdc_gym.vehicle.dbw_kernel import step_vehicle

    for function in (run_steps, step_vehicle):
        locator = function._cache._impl.locator
        assert isinstance(locator, PackageStampLocator)
        assert locator.get_source_stamp() == package_stamp()


def test_the_stamp_changes_with_any_kernel_module_and_only_with_those(tmp_path, monkeypatch):
    tree = tmp_path / "sdc_gym"
    for name in ("vehicle/dbw_kernel.py", "envs/track_kernel.py", "config.py"):
        (tree / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(PACKAGE / name, tree / name)
    monkeypatch.setattr(kernel_compiler, "PACKAGE", tree)

    def stamp() -> str:
        package_stamp.cache_clear()
        return package_stamp()

    try:
        first = stamp()
        (tree / "config.py").write_text((tree / "config.py").read_text() + "\n# no kernels\n")
        assert stamp() == first  # not a kernel module: the caches stay current
        dbw = tree / "vehicle" / "dbw_kernel.py"
        dbw.write_text(dbw.read_text().replace("_SMALL_HALF_TURN = 1e-4",
                                               "_SMALL_HALF_TURN = 2e-4"))
        assert stamp() != first  # a callee of the frame kernel changed: recompile all
    finally:
        package_stamp.cache_clear()


@kernel
def _add_into(values, amount, out):
    for i in range(values.size):
        out[i] = values[i] + amount[0]


def test_a_bound_call_runs_the_kernel_on_the_same_arrays():
    values, amount, out = np.arange(4.0), np.array([0.5]), np.zeros(4)
    call = bind(_add_into, values, amount, out)
    call()
    np.testing.assert_array_equal(out, [0.5, 1.5, 2.5, 3.5])
    amount[0] = -1.0  # arrays are read at each call, in place
    call()
    np.testing.assert_array_equal(out, [-1.0, 0.0, 1.0, 2.0])


def test_a_kernel_cannot_allocate():
    """No runtime: numba refuses an allocation at compile time (a loud error, never a
    leak or a silent fallback)."""
    from numba.core.errors import TypingError

    @kernel
    def allocate(n):
        return np.zeros(n)

    with pytest.raises(TypingError, match=r"No implementation of function .*zeros"):
        allocate(3)


def test_cache_files_carry_the_stamp_and_files_of_other_stamps_are_pruned(tmp_path):
    """numba unpickles an index's signatures before it compares stamps: an index from
    before a NamedTuple moved module would raise instead of going stale. So the stamp is
    part of every file name, and a folder's files of other stamps are deleted."""
    from sdc_gym.geometry.exact_math import py_hypot

    py_hypot(3.0, 4.0)
    locator = py_hypot._cache._impl.locator
    current = package_stamp()[:12]
    assert locator.get_disambiguator().endswith(f"-{current}")
    kept = tmp_path / f"exact_math.py_hypot-10-{current}.py311.nbi"
    stale = [tmp_path / "exact_math.py_hypot-10.py311.nbi",  # before stamps in names
             tmp_path / "exact_math.py_hypot-10-0123456789ab.py311.1.nbc"]
    for path in (kept, *stale):
        path.write_bytes(b"x")
    kernel_compiler._prune_stale_files.cache_clear()
    kernel_compiler._prune_stale_files(str(tmp_path))
    assert kept.exists() and not any(path.exists() for path in stale)


def test_compile_progress_counts_this_package_s_compilations_and_says_so() -> None:
    import io

    from numba import njit
    from rich.console import Console

    from sdc_gym.kernel_compiler import compile_progress

    def twice(x: float) -> float:
        return 2.0 * x

    twice.__module__ = "sdc_gym.progress_probe"  # counted: one of the package's functions
    compiled = njit(twice)  # no cache: it compiles on every run of the test

    def outside(x: float) -> float:
        return x + 1.0

    other = njit(outside)  # another module's function: not counted
    output = io.StringIO()
    with compile_progress(Console(file=output, width=200)) as counter:
        assert compiled(2.0) == 4.0
        assert other(2.0) == 3.0
        assert compiled(3.0) == 6.0  # already compiled: no second event
    assert counter.count == 1
    text = output.getvalue()
    assert "compiling sdc-gym's kernels on first use" in text
    assert "compiled 1 sdc-gym kernels in" in text
    quiet = io.StringIO()
    with compile_progress(Console(file=quiet)) as counter:
        assert compiled(4.0) == 8.0
    assert counter.count == 0 and quiet.getvalue() == ""


def test_first_use_notice_says_on_stderr_that_kernels_compile_but_not_under_progress(
        capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch) -> None:
    from numba import njit

    def thrice(x: float) -> float:
        return 3.0 * x

    thrice.__module__ = "sdc_gym.notice_probe"  # one of the package's functions
    notice = kernel_compiler._NOTICE  # registered when sdc_gym.kernel_compiler loads
    if os.environ.get("SDC_GYM_COMPILE_NOTICE") == "0":
        pytest.skip("the notice is off in this environment (SDC_GYM_COMPILE_NOTICE=0)")
    monkeypatch.setattr(kernel_compiler, "NOTICE_EVERY", 0.0)  # every compile reports
    monkeypatch.setattr(notice, "count", 0)  # as in a fresh process
    assert njit(thrice)(2.0) == 6.0  # uncached: compiles on every run of the test
    assert njit(thrice)(1.0) == 3.0  # a second dispatcher: a progress line
    first = capsys.readouterr().err
    with kernel_compiler.compile_progress():
        assert njit(thrice)(4.0) == 12.0
    under_progress = capsys.readouterr().err
    assert first.startswith("sdc-gym: compiling the kernels on first use")
    assert "sdc-gym: ... 2 kernels compiled" in first and "notice_probe.thrice" in first
    assert notice.count == 2 and "sdc-gym: ..." not in under_progress


def test_the_recycling_kernel_is_compiled_when_a_traffic_batch_is_made() -> None:
    """Not at the first recycle, mid-episode: a fresh process has no signature of
    ``recycle_rows`` before the batch and exactly the one the steps use after it."""
    import subprocess
    import sys

    probe = (
        "import numpy as np\n"
        "from sdc_gym.road.highway_map import HighwayMap\n"
        "from sdc_gym.traffic.batch import TrafficBatch\n"
        "from sdc_gym.traffic.placement import recycle_rows\n"
        "assert not recycle_rows.signatures, recycle_rows.signatures\n"
        "t = np.linspace(0, 2 * np.pi, 400, endpoint=False)\n"
        "road = HighwayMap.from_waypoints('oval', np.column_stack([1500 * np.cos(t), "
        "400 * np.sin(t)]))\n"
        "TrafficBatch(road, envs=2)\n"
        "print(len(recycle_rows.signatures))\n")
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True,
                          timeout=600, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stdout.strip() == "1"
