"""The traffic batch's hooks for scenarios and road events (see :mod:`sdc_gym.traffic.roles`).

:class:`~sdc_gym.traffic.batch.TrafficBatch` calls these few functions, and only once it
holds object slots or explicit slots (``scripted``), so that random traffic runs the
kernels alone, bit for bit as before:

* :func:`reset_random_row`: a random reset with object slots lays the cars out exactly as
  without them (the same draws in the same order), then parks the object slots;
* :func:`reset_slots_row`: a row from one :class:`~sdc_gym.traffic.slots.SlotSpec` per
  column (scenarios, replays);
* :func:`before_decision_round` / :func:`after_decision`: around each decision round, the
  envs' controllers (``before_decision(batch, state, row)``: a scenario's script, the road
  events) and the roles' overrides;
* :func:`~sdc_gym.traffic.roles.place_objects`: the road objects where they are, in a
  window's samples and in the current state's.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from sdc_gym.traffic.placement import reset_row
from sdc_gym.traffic.roles import after_decision as _after_decision
from sdc_gym.traffic.roles import place_objects
from sdc_gym.traffic.slots import SlotSpec, park, write_slot
from sdc_gym.traffic.state import TrafficState
from sdc_gym.traffic.vehicle_types import KINDS

TrafficBatch = Any  # sdc_gym.traffic.batch.TrafficBatch (typed by name: no import circle)
IntArray = NDArray[np.int64]

__all__ = ["SlotSpec", "TrafficController", "after_decision", "before_decision_round",
           "place_objects", "reset_random_row", "reset_slots_row"]


class TrafficController(Protocol):
    """Changes an env's traffic at its decision instants (a scenario's scripted actions,
    the random road events)."""

    def before_decision(self, batch: TrafficBatch, st: TrafficState, row: int) -> None:
        """Row ``row`` of ``st`` is the env at a decision instant (its ``step`` and ego
        set); change it before the cars decide."""


def reset_random_row(batch: TrafficBatch, st: TrafficState, env: int,
                     rng: np.random.Generator, ego_s: float, ego_d: float,
                     ego_speed: float) -> None:
    """Env ``env``'s random layout of ``car_count`` cars, laid out in a state of those
    columns only (so the draws and the cars are those of an env without object slots),
    copied into the first columns; the object slots parked."""
    cars = batch.config.car_count
    layout = TrafficState(1, cars, batch.config.lane_change_duration)
    reset_row(batch, layout, 0, rng, ego_s, ego_d, ego_speed)
    st.clear_rows(env, batch.config.lane_change_duration)
    for name in TrafficState.CAR_FLOATS + TrafficState.CAR_INTS:
        getattr(st, name)[env, :cars] = getattr(layout, name)[0]
    for name in TrafficState.ENV_INTS + TrafficState.ENV_FLOATS:
        getattr(st, name)[env] = getattr(layout, name)[0]
    for i in range(cars, st.cars):
        park(st, env, i)


def reset_slots_row(batch: TrafficBatch, st: TrafficState, env: int,
                    rng: np.random.Generator, ego_s: float, ego_d: float, ego_speed: float,
                    slots: list[SlotSpec], step: int, respawn_blocked_steps: int) -> None:
    """Row ``env`` from explicit slots, its traffic clock at ``step``."""
    if len(slots) != st.cars:
        raise ValueError(f"the traffic has {st.cars} slots ({batch.config.car_count} cars "
                         f"+ {batch.object_slots} road objects); got {len(slots)}")
    for i, spec in enumerate(slots):
        if not 0 <= spec.type_index < len(KINDS):
            raise ValueError(f"slot {i}: type_index must be in [0, {len(KINDS)}), got "
                             f"{spec.type_index}")
        if not -1 <= spec.lane <= batch.lanes:
            raise ValueError(f"slot {i}: lane must be in [-1, {batch.lanes}], got "
                             f"{spec.lane}")
    st.clear_rows(env, batch.config.lane_change_duration)
    st.step[env] = step
    st.respawn_blocked_until[env] = step + respawn_blocked_steps
    st.ego_s[env], st.ego_d[env], st.ego_speed[env] = (float(ego_s) % batch.loop,
                                                       float(ego_d), float(ego_speed))
    for i, spec in enumerate(slots):
        write_slot(batch, st, env, i, spec, rng)


def before_decision_round(batch: TrafficBatch, st: TrafficState, rows: NDArray[np.bool_],
                          end: IntArray, step0: IntArray, ego_s: NDArray[np.float64],
                          ego_d: NDArray[np.float64], ego_speed: NDArray[np.float64]
                          ) -> IntArray:
    """Before a decision round (the envs with ``rows``, at window frame ``end`` of an
    advance from ``step0``, with the ego's ``(envs, frames)`` states): each deciding env's
    step and latest ego state, as the decision kernel sets them, then its controller.
    Returns ``lc_start`` as it is before the decision (for :func:`after_decision`)."""
    for env in np.flatnonzero(rows).tolist():
        controller = batch.controllers[env]
        if controller is None:
            continue
        st.step[env] = step0[env] + end[env]
        before = int(end[env]) - 1
        if before >= 0:
            st.ego_s[env] = float(ego_s[env, before]) % batch.loop
            st.ego_d[env] = ego_d[env, before]
            st.ego_speed[env] = ego_speed[env, before]
        controller.before_decision(batch, st, env)
    return st.lc_start.copy()


def after_decision(st: TrafficState, lc_start: IntArray, rows: NDArray[np.bool_]) -> None:
    """The roles' overrides after a decision round of the envs with ``rows``
    (:func:`sdc_gym.traffic.roles.after_decision`)."""
    _after_decision(st, lc_start, rows)
