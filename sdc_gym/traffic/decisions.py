"""One decision instant of the traffic, for the envs of a batch that are at one.

At a decision every car of those envs gets, in this order (see
:mod:`sdc_gym.traffic.highway_traffic` for the rules):

1. finished lane changes free their origin lane;
2. cars beyond ``spawn_range`` are recycled (:func:`sdc_gym.traffic.placement.recycle`);
3. the leader and follower of every car in every lane (:mod:`sdc_gym.traffic.leaders`),
   and the bumper gaps to them along the follower's lane;
4. IDM accelerations in every lane (as if there), with the leader over the lane(s) the car
   occupies, and the braking a lane change would impose on the new follower (MOBIL's
   safety criterion);
5. lane-change wishes (clear +-clearance, incentive, safety), sustained, at most one
   start per target lane per env (the lowest slot);
6. rogue events (hard braking, cut-ins), when enabled.

Every array is ``(envs, ...)``: the arithmetic of all those envs runs in the same numpy
calls. The accelerations are held until the next decision.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.traffic.config import TrafficConfig
from sdc_gym.traffic.gather import gather
from sdc_gym.traffic.idm import _NOT_ZERO as _IDM_NOT_ZERO
from sdc_gym.traffic.leaders import nearest_objects
from sdc_gym.traffic.placement import recycle
from sdc_gym.traffic.state import IDLE, NEVER, TrafficState

# The kernels take the batch (sdc_gym.traffic.batch.TrafficBatch, which imports them) for
# its constants: typed by name only, so that the modules do not import each other.
TrafficBatch = Any

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


def stopping_gap(v_back: FloatArray, v_front: FloatArray, cfg: TrafficConfig,
                 delay: float) -> FloatArray:
    """Gap (m) a car at ``v_back`` eats up behind one at ``v_front`` (constant speed) before
    it has matched its speed, braking at ``max_braking`` after ``delay`` seconds."""
    closing = np.maximum(v_back - v_front, 0.0)
    return closing * delay + closing * closing / (2.0 * cfg.idm.max_braking)


def objects(batch: TrafficBatch, st: TrafficState) -> tuple[FloatArray, FloatArray,
                                                            FloatArray, NDArray[np.bool_]]:
    """s, d, speed ``(envs, cars + 1)`` of every object (the cars, then the ego) and the
    lanes each occupies ``(envs, lanes, cars + 1)``: a car its origin and target lane,
    the ego every lane its footprint touches."""
    s_all = np.concatenate([st.s, st.ego_s[:, None]], axis=1)
    d_all = np.concatenate([st.d, st.ego_d[:, None]], axis=1)
    v_all = np.concatenate([st.speed, st.ego_speed[:, None]], axis=1)
    lanes = batch.lane_column
    occupies = np.empty((st.envs, batch.lanes, st.cars + 1), dtype=bool)
    cars = occupies[:, :, :-1]
    np.equal(lanes, st.origin[:, None, :], out=cars)
    cars |= lanes == st.target_lane[:, None, :]
    occupies[:, :, -1] = batch.ego_lanes(st.ego_d)
    return s_all, d_all, v_all, occupies


def relative(batch: TrafficBatch, s_all: FloatArray, ego_s: FloatArray) -> FloatArray:
    """s of every object minus the ego's, folded to [-L/2, L/2)."""
    rel = s_all - ego_s[:, None]
    rel += batch.half_loop
    np.remainder(rel, batch.loop_0d, out=rel)
    rel -= batch.half_loop
    return rel


def idm_terms(batch: TrafficBatch, st: TrafficState, v_all: FloatArray
              ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Per object (cars, then the ego, who "wants" its current speed): speed, ``v T``,
    ``a_max * (free-road term)``, ``a_max``, ``2 sqrt(a_max b)``."""
    idm = batch.config.idm
    v0 = np.concatenate([st.desired, np.maximum(st.ego_speed, 0.1)[:, None]], axis=1)
    a = np.concatenate([st.a_max, batch.ego_a_max[: st.envs]], axis=1)
    tsab = np.concatenate([st.tsab, batch.ego_tsab_column[: st.envs]], axis=1)
    ratio = np.maximum(v_all, 0.0)
    ratio /= v0
    free = ratio ** idm.delta
    np.subtract(1.0, free, out=free)
    free *= a
    return v_all, v_all * idm.T, free, a, tsab


def idm(cfg: TrafficConfig, v: FloatArray, vt: FloatArray, afree: FloatArray,
        a: FloatArray, tsab: FloatArray, leader_v: FloatArray, gap: FloatArray
        ) -> FloatArray:
    """:func:`sdc_gym.traffic.idm.idm_core` from per-follower terms (the same operations
    on the same values, so the same bits), the free-road term shared by every lane."""
    params = cfg.idm
    w = np.subtract(v, leader_v)
    w *= v
    w /= tsab  # closing term
    if params.floor_desired_gap:
        w += vt
        np.maximum(w, 0.0, out=w)
        w += params.s0
    else:
        w += params.s0 + vt
    w /= np.maximum(gap, _IDM_NOT_ZERO)
    w *= w
    w *= a
    np.subtract(afree, w, out=w)
    return np.maximum(w, -params.max_braking, out=w)


def begin_change(batch: TrafficBatch, st: TrafficState, start: NDArray[np.bool_],
                 lane: IntArray, duration: float) -> None:
    """Start lane changes of the ``start`` cars into ``lane``, lasting ``duration`` s."""
    steps = math.ceil(duration / batch.dt - 1e-9)
    now = st.step[:, None]
    st.target_lane = np.where(start, lane, st.target_lane)
    st.lc_start = np.where(start, now, st.lc_start)
    st.lc_end = np.where(start, now + steps, st.lc_end)
    st.lc_duration = np.where(start, duration, st.lc_duration)
    st.pending = np.where(start, -1, st.pending)
    st.held = np.where(start, 0, st.held)


def decide(batch: TrafficBatch, st: TrafficState, rngs: list[np.random.Generator]) -> None:
    """One decision instant for every env of ``st`` (see the module docstring).

    ``st.step`` is each env's step at the decision, ``st.ego_*`` the ego's latest state
    before it, ``rngs`` the envs' generators (recycling and rogue events draw from them).
    """
    cfg = batch.config
    n = st.cars
    if n == 0:
        return
    now = st.step[:, None]
    finished = st.lc_end <= now  # finished lane changes free their origin lane
    if np.count_nonzero(finished):
        st.origin = np.where(finished, st.target_lane, st.origin)
        st.lc_start = np.where(finished, NEVER, st.lc_start)
        st.lc_end = np.where(finished, IDLE, st.lc_end)
    s_all, d_all, v_all, occupies = objects(batch, st)
    rel = relative(batch, s_all, st.ego_s)
    farthest = np.abs(rel).max(axis=1)
    if np.count_nonzero(farthest > batch.range):
        far_envs = np.flatnonzero(farthest > batch.range)
        if any([recycle(batch, st, int(e), rel[e, :n], rngs[e]) for e in far_envs]):
            s_all, d_all, v_all, occupies = objects(batch, st)  # cars moved: rebuild
            rel = relative(batch, s_all, st.ego_s)
            farthest = np.abs(rel).max(axis=1)
    kappa = batch.geometry.curvature(s_all)
    st.kappa = kappa[:, :n]
    scale_all = kappa * d_all
    scale_all += 1.0
    half_all = np.concatenate([st.half_length, batch.ego_half_column[: st.envs]], axis=1)

    # Leaders (ahead) and followers (behind) of every car in every lane: (envs, lanes, n).
    li, ds_ahead, fi, ds_behind = nearest_objects(
        rel, occupies, farthest >= 0.25 * batch.loop, batch.loop)
    own_half = st.half_length[:, None, :]
    lead_gap = ds_ahead * scale_all[:, None, :n]
    lead_gap -= own_half + gather(half_all[:, None, :], li)
    follow_gap = ds_behind * gather(scale_all[:, None, :], fi)
    follow_gap -= own_half + gather(half_all[:, None, :], fi)
    lead_v = gather(v_all[:, None, :], li)

    # The leader over the lane(s) each car occupies: the nearest of its lanes' leaders
    # (lanes it does not occupy pushed to inf).
    own_gaps = lead_gap + batch.penalty.take(occupies[:, :, :n].view(np.uint8))
    own = own_gaps.argmin(axis=1)[:, None, :]
    own_gap = gather(own_gaps.transpose(0, 2, 1), own.transpose(0, 2, 1)).transpose(0, 2, 1)
    own_lead_v = gather(lead_v.transpose(0, 2, 1), own.transpose(0, 2, 1)).transpose(0, 2, 1)

    # IDM in every lane (as if there) and with the own leader, and for the new follower
    # behind the car in every lane (MOBIL's imposed braking; its leader: the car).
    v, vt, afree, a, tsab = idm_terms(batch, st, v_all)
    car = (slice(None), None, slice(None, n))
    acc_lane = idm(cfg, v[car], vt[car], afree[car], a[car], tsab[car], lead_v, lead_gap)
    acc = idm(cfg, v[car], vt[car], afree[car], a[car], tsab[car], own_lead_v, own_gap)
    imposed = idm(cfg, gather(v[:, None, :], fi), gather(vt[:, None, :], fi),
                  gather(afree[:, None, :], fi), gather(a[:, None, :], fi),
                  gather(tsab[:, None, :], fi), st.speed[:, None, :], follow_gap)

    # Lane-change wishes: clear +-clearance, MOBIL incentive and safety; sustained.
    brake_until = st.brake_until  # as it was before this decision's rogue events
    adjacent = batch.adjacent_of[st.origin]  # (envs, n, lanes)
    clear_ahead = ds_ahead >= cfg.lane_change_clearance
    clear_behind = ds_behind >= cfg.lane_change_clearance
    candidate = np.subtract(acc_lane, acc) > cfg.lane_change_min_gain
    candidate &= adjacent.transpose(0, 2, 1)
    candidate &= clear_ahead
    candidate &= clear_behind
    eligible = st.lc_end == IDLE
    eligible &= st.speed >= cfg.lane_change_min_speed
    eligible &= now >= brake_until
    candidate &= eligible[:, None, :]
    if np.count_nonzero(candidate):
        limit = -cfg.lane_change_max_braking_imposed
        candidate &= (acc_lane >= limit) & ((imposed >= limit) | np.isinf(follow_gap))
        best = np.where(candidate, acc_lane, -np.inf).argmax(axis=1)
        want = np.where(gather(candidate.transpose(0, 2, 1), best[..., None])[..., 0], best,
                        -1)
    else:
        want = np.full((st.envs, n), -1, dtype=np.int64)
    wish = want >= 0
    wish &= want == st.pending
    st.held = held = (st.held + 1) * wish
    st.pending = want
    start = held >= batch.sustain_decisions if batch.sustain_decisions else want >= 0
    if np.count_nonzero(start):
        # One start per target lane per decision (the lowest slot): two cars entering a
        # lane at once did not see each other in their checks. The others keep their
        # sustained wish and retry at the next decision.
        keyed = np.where(start, want, batch.lanes)
        first = np.full((st.envs, batch.lanes + 1), n, dtype=np.int64)
        np.minimum.at(first, (np.arange(st.envs)[:, None], keyed), np.arange(n)[None, :])
        start &= gather(first, keyed) == np.arange(n)[None, :]
        begin_change(batch, st, start, want, cfg.lane_change_duration)

    acc = acc[:, 0]
    if batch.rogue_p > 0.0:
        acc = _rogue(batch, st, rngs, acc, brake_until, adjacent.transpose(0, 2, 1),
                     clear_ahead & clear_behind, lead_gap, follow_gap, lead_v,
                     gather(v_all[:, None, :], fi))
    st.acc = acc
    st.half_acc = acc * 0.5


def _rogue(batch: TrafficBatch, st: TrafficState, rngs: list[np.random.Generator],
           acc: FloatArray, brake_until: IntArray, adjacent: NDArray[np.bool_],
           clear: NDArray[np.bool_], lead_gap: FloatArray, follow_gap: FloatArray,
           lead_v: FloatArray, follow_v: FloatArray) -> FloatArray:
    """Rogue events: hard-braking episodes and cut-ins (see :class:`TrafficConfig`).

    A cut-in takes a gap the normal rule refuses (someone within the clearance) but one
    that braking at ``idm.max_braking`` after a decision period's delay survives, for
    the car cutting in and for its new follower (a car or the ego): a surprise, not a
    certain crash.
    """
    cfg = batch.config
    now = st.step[:, None]
    u = np.stack([rng.random((2 + batch.lanes, st.cars)) for rng in rngs])
    event = u[:, 0] < batch.rogue_p
    brake = event & (u[:, 1] < 0.5) & (now >= st.brake_until)
    cut = event & (u[:, 1] >= 0.5)
    st.brake_until = np.where(brake, now + batch.brake_steps, st.brake_until)
    st.cut_in_until = np.where(cut, now + batch.cut_in_window_steps, st.cut_in_until)
    st.rogue_brake_count = st.rogue_brake_count + brake.sum(axis=1)
    # Eligible as for a lane change (those that just started one are not idle).
    trying = (st.speed >= cfg.lane_change_min_speed) & (st.lc_end == IDLE)
    trying &= now >= brake_until
    trying &= now < st.cut_in_until
    if np.count_nonzero(trying):
        v = st.speed[:, None, :]
        delay, gap = batch.decision_dt, cfg.rogue_cut_in_gap
        room = (lead_gap >= gap + stopping_gap(v, lead_v, cfg, delay)) & (
            follow_gap >= gap + stopping_gap(follow_v, v, cfg, delay))
        candidate = trying[:, None, :] & adjacent & ~clear & room
        pick = np.where(candidate, u[:, 2:], -1.0).argmax(axis=1)
        go = gather(candidate.transpose(0, 2, 1), pick[..., None])[..., 0]
        if np.count_nonzero(go):
            begin_change(batch, st, go, pick, cfg.rogue_cut_in_duration)
            st.cut_in_until = np.where(go, 0, st.cut_in_until)
            st.rogue_cut_in_count = st.rogue_cut_in_count + go.sum(axis=1)
    braking = now < st.brake_until
    return np.where(braking, np.minimum(acc, -cfg.rogue_brake_decel), acc)
