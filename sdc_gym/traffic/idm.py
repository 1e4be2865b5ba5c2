"""The Intelligent Driver Model (Treiber, Hennecke & Helbing 2000), vectorized.

IDM gives a follower's acceleration from its speed ``v``, its desired speed ``v0``, the
gap ``s`` to its leader and the leader's speed ``v_l``::

    a = a_max * (1 - (v / v0)**delta - (s_star / s)**2)
    s_star = s0 + v*T + v*(v - v_l) / (2*sqrt(a_max*b))       (desired gap)

The free-road term ``1 - (v/v0)**delta`` pulls the car to ``v0``; the interaction term
``(s_star/s)**2`` brakes when the gap is shorter than the gap the driver wants (a jam
distance ``s0``, a time headway ``T``, and a term that grows when closing in fast, sized
so that the planned braking stays near ``b``). Without a leader (``s = inf``) only the
free-road term remains.

Mapping to highway-env's ``IDMVehicle``
---------------------------------------
highway-env feeds IDM the *centre-to-centre* distance ``d`` along the lane and uses
``DISTANCE_WANTED = 5.0 + LENGTH = 10 m`` as jam distance for its 5 m cars. We feed the
*bumper-to-bumper* gap ``s = d - (L_follower + L_leader)/2`` (cars here have different
lengths), so the jam distance is the bumper gap ``s0 = 10 - 5 = 5 m``. Both give the same
steady-state spacing for 5 m cars (``d = 10 + v*T`` versus ``s = 5 + v*T``); close in they
differ a little, ours braking harder as the gap shrinks (the interaction term diverges at
``s -> 0`` instead of at ``d -> 0``), which is the safer reading for traffic that must not
crash. The other parameters carry over one to one:

=================  ==============================  =====================
ours               highway-env IDMVehicle          default
=================  ==============================  =====================
``a_max``          ``COMFORT_ACC_MAX``             3.0 m/s^2
``b``              ``-COMFORT_ACC_MIN``            5.0 m/s^2
``T``              ``TIME_WANTED``                 1.5 s
``s0``             ``DISTANCE_WANTED - LENGTH``    5.0 m (bumper gap)
``delta``          ``DELTA``                       4.0
``max_braking``    ``ACC_MAX`` (clip in act())     6.0 m/s^2
=================  ==============================  =====================

Semantics kept from highway-env (``IDMVehicle.acceleration``): the free term uses
``max(v, 0)`` and ``|v0|`` guarded away from zero (``utils.not_zero``: ``max(|v0|, 0.01)``),
the gap is guarded the same way (``max(s, 0.01)``), and the result is clipped to
``[-max_braking, max_braking]`` as ``IDMVehicle.act`` clips to ``ACC_MAX``. One difference
is a switch, :attr:`IDMParameters.floor_desired_gap`: Treiber's IDM never lets ``s_star``
fall below ``s0`` (when the leader pulls away fast, the dynamic term goes negative);
highway-env does not floor it, so ``s_star`` shrinks below the jam distance and, once
negative, squares into braking that *grows* the faster the leader pulls away. We floor
by default; ``floor_desired_gap=False`` reproduces highway-env exactly (the oracle test
checks that to 1e-9). A gap ``<= 0`` (the cars overlap) returns full
braking ``-max_braking`` rather than highway-env's sign-blind ``(s_star / s)**2``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]

# highway-env's utils.not_zero epsilon: guards the divisions by v0 and by the gap.
_NOT_ZERO = 1e-2


@dataclass(frozen=True)
class IDMParameters:
    """IDM parameters; defaults map highway-env's IDMVehicle (see the module docstring).

    Attributes:
        a_max: m/s^2, comfortable (maximum free-road) acceleration.
        b: m/s^2 (positive), comfortable deceleration used in the desired gap.
        T: s, desired time headway.
        s0: m, jam distance as a bumper-to-bumper gap.
        delta: free-road acceleration exponent.
        max_braking: m/s^2 (positive), hard clip on |acceleration| (the largest braking).
        floor_desired_gap: keep ``s_star >= s0`` (Treiber); ``False`` = highway-env.
    """

    a_max: float = 3.0
    b: float = 5.0
    T: float = 1.5
    s0: float = 5.0
    delta: float = 4.0
    max_braking: float = 6.0
    floor_desired_gap: bool = True


def desired_gap(
    speed: ArrayLike,
    leader_speed: ArrayLike,
    params: IDMParameters,
    a_max: ArrayLike | None = None,
    b: ArrayLike | None = None,
) -> FloatArray:
    """IDM desired bumper gap ``s_star`` in metres (vectorized; see the module docstring).

    ``a_max`` / ``b`` override the parameters per car (arrays broadcast with ``speed``).
    """
    v = np.asarray(speed, dtype=np.float64)
    a = params.a_max if a_max is None else np.asarray(a_max, dtype=np.float64)
    bb = params.b if b is None else np.asarray(b, dtype=np.float64)
    closing = v * (v - leader_speed) / (2.0 * np.sqrt(a * bb))
    if params.floor_desired_gap:
        return params.s0 + np.maximum(v * params.T + closing, 0.0)
    return params.s0 + v * params.T + closing  # highway-env's order of operations


def idm_acceleration(
    speed: ArrayLike,
    desired_speed: ArrayLike,
    gap: ArrayLike,
    leader_speed: ArrayLike,
    params: IDMParameters = IDMParameters(),
    *,
    a_max: ArrayLike | None = None,
    b: ArrayLike | None = None,
) -> FloatArray:
    """IDM acceleration in m/s^2 for every follower at once.

    Args:
        speed: m/s, the followers' speeds.
        desired_speed: m/s, their desired (free-road) speeds ``v0``.
        gap: m, bumper-to-bumper gap to each leader; ``inf`` where there is no leader.
        leader_speed: m/s, the leaders' speeds along the lane (ignored where gap is inf).
        params: the model parameters.
        a_max, b: optional per-car overrides of ``params.a_max`` / ``params.b`` (e.g. by
            vehicle type), broadcasting with ``speed``.

    Returns:
        The accelerations, broadcast shape of the inputs, clipped to
        ``[-max_braking, max_braking]``.
    """
    v = np.asarray(speed, dtype=np.float64)
    s = np.asarray(gap, dtype=np.float64)
    a = params.a_max if a_max is None else np.asarray(a_max, dtype=np.float64)
    bb = params.b if b is None else np.asarray(b, dtype=np.float64)
    # A missing leader's speed may be anything (even nan): make it harmless.
    vl = np.where(np.isfinite(s), leader_speed, v)
    v0 = np.maximum(np.abs(np.asarray(desired_speed, dtype=np.float64)), _NOT_ZERO)
    acc = idm_core(v, v0, s, vl, a, 2.0 * np.sqrt(a * bb), params)
    acc = np.where(s > 0.0, acc, -params.max_braking)
    return np.minimum(acc, params.max_braking)


def idm_core(
    v: FloatArray,
    v0: FloatArray,
    s: FloatArray,
    vl: FloatArray,
    a: FloatArray | float,
    two_sqrt_ab: FloatArray | float,
    params: IDMParameters,
) -> FloatArray:
    """:func:`idm_acceleration`'s arithmetic without its guards, for the traffic's hot loop.

    Assumes arrays, ``v0 >= 0.01``, finite ``vl`` everywhere, ``two_sqrt_ab = 2 *
    sqrt(a_max * b)`` precomputed (per car) and ``a_max <= max_braking``; clips only
    from below. A gap ``<= 0.01`` hits the ``not_zero`` guard, which brakes fully as long
    as ``s_star > 0`` (always, with the floor). The operations follow highway-env's order,
    so results agree with it to the last bit or two.
    """
    free = 1.0 - (np.maximum(v, 0.0) / v0) ** params.delta
    closing = v * (v - vl) / two_sqrt_ab
    if params.floor_desired_gap:
        s_star = params.s0 + np.maximum(v * params.T + closing, 0.0)
    else:
        s_star = params.s0 + v * params.T + closing
    # inf gap -> ratio 0 (free road); gaps below 0.01 are guarded like not_zero.
    ratio = s_star / np.maximum(s, _NOT_ZERO)
    return np.maximum(a * free - a * (ratio * ratio), -params.max_braking)


def max_speed_for_gap(
    gap: ArrayLike,
    leader_speed: ArrayLike,
    params: IDMParameters = IDMParameters(),
    a_max: ArrayLike | None = None,
    b: ArrayLike | None = None,
) -> FloatArray:
    """Largest speed ``v >= 0`` whose desired gap fits: ``desired_gap(v, leader_speed) <= gap``.

    At that speed the interaction term is at most 1, so IDM brakes by at most ``a_max``:
    the speed to give a car placed ``gap`` metres behind a leader so that it settles in
    without hard braking. Solves ``c*v**2 + (T - c*v_l)*v + s0 - gap = 0`` with
    ``c = 1 / (2*sqrt(a_max*b))``; ``0`` when ``gap < s0``, ``inf`` when ``gap`` is inf.
    """
    s = np.asarray(gap, dtype=np.float64)
    a = params.a_max if a_max is None else np.asarray(a_max, dtype=np.float64)
    bb = params.b if b is None else np.asarray(b, dtype=np.float64)
    c = 0.5 / np.sqrt(a * bb)
    lin = params.T - c * np.where(np.isfinite(s), leader_speed, 0.0)
    room = np.maximum(s - params.s0, 0.0)
    with np.errstate(invalid="ignore"):  # inf - inf where the gap is inf; replaced below
        v = (np.sqrt(lin * lin + 4.0 * c * room) - lin) / (2.0 * c)
    return np.where(np.isfinite(s), np.maximum(v, 0.0), np.inf)
