"""Results that do not depend on the processor: no BLAS, LAPACK or numpy SIMD math with
processor-dependent rounding on the simulation's path.

Known answers: a fused multiply-add's single rounding, a sum whose value depends on its
order, the built-in roads' exact lengths (the same bits on every machine), filterpy's
equations. Across kernels: fingerprints of the roads, a Kalman track and short episodes
are the same under the oldest OpenBLAS core and numpy without AVX-512 where the processor
has it (processes of their own); ``benchmarks/reproducibility.py`` runs the recorded
episodes under every configuration the processor can run. A scan of the source keeps the
banned calls out.
"""

from __future__ import annotations

import ast
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from sdc_gym.geometry import exact_math
from sdc_gym.geometry.fixed_order import dot_rows, fma, inverse, matmul, solve_2x2
from sdc_gym.road import builtin_highways, builtin_tracks
from sdc_gym.road.layout import closing_lengths
from sdc_gym.stack.highway.kalman import FixedOrderKalmanFilter

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT / "benchmarks"))
import reproducibility  # noqa: E402
import reproducibility_probe  # noqa: E402

# numpy functions whose float64 / complex results come from kernels chosen per processor
# (numpy.lib.introspect.opt_func_info lists X86_V4 variants for them) and are not exactly
# rounded, and the functions that hand work to BLAS or LAPACK.
DISPATCHED_MATH = {
    "sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "sinh", "cosh", "tanh",
    "arcsinh", "arccosh", "arctanh", "exp", "exp2", "expm1", "log", "log2", "log10", "log1p",
    "power", "float_power", "cbrt", "angle",
}
BLAS = {"dot", "vdot", "inner", "matmul", "einsum", "tensordot", "linalg", "kron"}
# The simulation: every module a seed and actions pass through to an episode, and the
# reference agents' decisions. Rendering for people and the training scripts are not.
SIMULATION = [ROOT / "sdc_gym", ROOT / "agents" / "highway", ROOT / "agents" / "track" /
              "dbw_agent.py", ROOT / "agents" / "track" / "light_classifier.py",
              ROOT / "agents" / "lane_keeping.py"]
NOT_SIMULATION = {"render", "fixed_order.py"}


def _simulation_files() -> list[Path]:
    files: list[Path] = []
    for place in SIMULATION:
        found = [place] if place.is_file() else sorted(place.rglob("*.py"))
        files += [f for f in found if not NOT_SIMULATION & set(f.relative_to(ROOT).parts)]
    return files


def test_no_processor_dependent_math_on_the_simulation_path() -> None:
    offences = []
    for path in _simulation_files():
        tree = ast.parse(path.read_text(), filename=str(path))
        for node in ast.walk(tree):
            where = f"{path.relative_to(ROOT)}:{getattr(node, 'lineno', '?')}"
            if isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult):
                offences.append(f"{where}: `@` (BLAS)")
            if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                    and node.value.id == "np"
                    and node.attr in DISPATCHED_MATH | BLAS):
                offences.append(f"{where}: np.{node.attr}")
    assert offences == []


def test_the_banned_list_covers_numpy_s_dispatched_inexact_functions() -> None:
    from numpy.lib.introspect import opt_func_info

    exact = {"argmax", "argmin", "fmax", "fmin", "maximum", "minimum", "equal", "greater",
             "greater_equal", "less", "less_equal", "not_equal", "frexp", "ldexp",
             "negative", "absolute"}  # absolute: exact for reals; complex via complex_abs
    dispatched = {name for name, signatures in opt_func_info().items()
                  for signature, targets in signatures.items()
                  if set(signature) & set("dD") and "X86_V4" in targets["available"]}
    assert dispatched - exact <= DISPATCHED_MATH


def test_elementwise_math_keeps_shapes_and_is_the_c_library_s() -> None:
    import math

    for function, reference in ((exact_math.sin, math.sin), (exact_math.cos, math.cos),
                                (exact_math.exp, math.exp), (exact_math.log10, math.log10)):
        assert function(np.float64(0.5)).shape == ()  # a 0-d input stays 0-d
        assert function(np.ones((2, 3))).shape == (2, 3)
        values = np.linspace(0.1, 30.0, 301)
        assert function(values).tolist() == [reference(v) for v in values.tolist()]
    assert exact_math.atan2(np.float64(1.0), np.float64(-1.0)) == math.atan2(1.0, -1.0)


def test_fma_rounds_once() -> None:
    assert 0.1 * 10.0 - 1.0 == 0.0
    assert fma(0.1, 10.0, -1.0) == 5.551115123125783e-17  # 0.1's representation error


def test_dot_rows_sums_in_four_lanes_then_pairs() -> None:
    rows = np.array([[1e16, 1.0, -1e16, 1.0], [1.0, 2.0, 3.0, 4.0]])
    # Lanes (1e16, 1, -1e16, 1): (1e16 - 1e16) + (1 + 1) = 2; in order it would be 1.
    assert dot_rows(rows, np.ones(4)).tolist() == [2.0, 10.0]
    integers = np.arange(60.0).reshape(3, 20)
    assert dot_rows(integers, np.arange(20.0)).tolist() == (integers @ np.arange(20.0)).tolist()
    assert dot_rows(np.ones((2, 3, 5)), np.ones(5)).shape == (2, 3)
    with pytest.raises(ValueError, match=r"shapes \(2, 3\) and \(4,\)"):
        dot_rows(np.ones((2, 3)), np.ones(4))


def test_matmul_solve_and_inverse_known_answers() -> None:
    a = np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0]])
    b = np.array([[1.0, 0.0, 2.0], [0.0, 1.0, 1.0]])
    assert matmul(a, b).tolist() == [[1.0, 2.0, 4.0], [3.0, 4.0, 10.0], [5.0, 6.0, 16.0]]
    assert matmul(a, np.array([1.0, 1.0])).tolist() == [3.0, 7.0, 11.0]
    assert solve_2x2([[0.0, 1.0], [1.0, 0.0]], [2.0, 3.0]) == (3.0, 2.0)  # pivoting
    assert solve_2x2([[2.0, 1.0], [1.0, 3.0]], [3.0, 5.0]) == pytest.approx((0.8, 1.4),
                                                                            rel=1e-15)
    with pytest.raises(ValueError, match="singular"):
        solve_2x2([[1.0, 2.0], [2.0, 4.0]], [1.0, 1.0])
    assert inverse([[2.0, 1.0], [1.0, 1.0]]).tolist() == [[1.0, -1.0], [-1.0, 2.0]]
    with pytest.raises(np.linalg.LinAlgError):
        inverse([[1.0, 2.0], [2.0, 4.0]])


def test_complex_abs_and_products_are_numpys_fused_kernels() -> None:
    assert exact_math.complex_abs(np.array([3 + 4j, 0j, -5e-3 + 12e-3j])).tolist() == [
        5.0, 0.0, 0.013]
    assert exact_math.fused_product_sum(0.1, 10.0, -1.0, 1.0) == 5.551115123125783e-17
    from numpy._core._multiarray_umath import __cpu_features__

    if not __cpu_features__.get("AVX2") or not __cpu_features__.get("FMA3"):
        pytest.skip("numpy's fused complex kernel needs AVX2 and FMA on this processor")
    parts = np.random.default_rng(0).normal(size=(4, 50_000))
    z, w = parts[0] + 1j * parts[1], parts[2] + 1j * parts[3]
    assert np.array_equal(exact_math.complex_abs(z), np.abs(z))
    product = z * w  # numpy's fused complex multiplication
    assert np.array_equal(exact_math.fused_product_sum(z.real, w.imag, z.imag, w.real),
                          product.imag)
    assert np.array_equal(exact_math.fused_product_sum(z.real, w.real, -z.imag, w.imag),
                          product.real)


def test_built_in_roads_have_the_same_bits_everywhere() -> None:
    # The highway's closing straights as LAPACK computed them with the SkylakeX kernels
    # (the episodes' recordings were made there); Haswell's kernels gave ...f4e.
    assert [v.hex() for v in closing_lengths(builtin_highways._DEFAULT_LAYOUT)] == [
        "0x1.c623088734f4dp+8", "0x1.750e12dcad8a6p+8"]
    # The track's layout: Haswell's and SkylakeX's kernels agree on it.
    assert [v.hex() for v in closing_lengths(builtin_tracks._DEFAULT_LAYOUT)] == [
        "0x1.7c942cc8fa4ebp+10", "0x1.51c9c5b341643p+10"]
    assert builtin_highways.get_highway_map("default").reference.length.hex() == (
        "0x1.afaf934b743d2p+12")
    assert builtin_highways.get_highway_map("oval").reference.length.hex() == (
        "0x1.5e9dd417d3ee4p+10")


def test_fixed_order_kalman_filter_is_filterpys_filter() -> None:
    rng = np.random.default_rng(2)
    ours, theirs = FixedOrderKalmanFilter(4, 4), KalmanFilter(4, 4)
    for kf in (ours, theirs):
        kf.x = np.array([[5.0], [6.0], [22.0], [0.0]])
        kf.P = np.diag([0.3, 0.3, 0.6, 0.6])
        kf.R = kf.P.copy()
        kf.H = np.eye(4)
    transition = np.eye(4)
    transition[0, 2] = transition[1, 3] = 0.1
    for _ in range(40):
        z = theirs.x + rng.normal(size=(4, 1))
        for kf in (ours, theirs):
            kf.predict(F=transition, Q=0.01)
            kf.update(z.copy())
        np.testing.assert_allclose(ours.x, theirs.x, rtol=1e-12)
        np.testing.assert_allclose(ours.P, theirs.P, rtol=1e-10)
    ours.update(None)
    assert np.array_equal(ours.x_post, ours.x)
    with pytest.raises(ValueError, match="control inputs"):
        ours.predict(u=np.ones((1, 1)), B=np.ones((4, 1)))


def test_fingerprints_are_the_same_under_other_kernels() -> None:
    expected = reproducibility_probe.fingerprints()
    for name, env in reproducibility.lowest_configurations(compile_generic=False):
        result = subprocess.run([sys.executable, str(ROOT / "tests" /
                                                     "reproducibility_probe.py")],
                                env={**os.environ, **env}, capture_output=True, text=True,
                                timeout=600, check=False)
        assert result.returncode == 0, f"{name}: {result.stderr[-2000:]}"
        assert json.loads(result.stdout) == expected, name
