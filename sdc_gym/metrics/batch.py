"""The driving metrics of a batch of envs: every env's running state as an array.

:class:`DrivingMetricsBatch` applies the rules of :mod:`sdc_gym.metrics.driving_metrics`
to ``(envs, frames)`` arrays of physics samples per call: geometry, running sums and
rising edges are array expressions over the frames (each frame's value from the previous
frame's, exactly as a sample-by-sample walk computes it), the block rule a walk over the
chunk's frames that closes the blocks of every env whose block completes there. Lap
times and incidents are kept per env in Python lists (they are rare). An env's results
do not depend on the other envs of the batch or on how its samples are chunked.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry.exact_math import hypot
from sdc_gym.metrics.incidents import INCIDENT_KINDS, Incident, IncidentRules
from sdc_gym.units import MPS_TO_MPH

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_NO_INCIDENTS: tuple[Incident, ...] = ()


def _shift(first: NDArray, values: NDArray) -> NDArray:
    """``values`` one frame later: ``first`` (per env), then all but the last frame."""
    return np.concatenate([first[:, None], values[:, :-1]], axis=1)


class DrivingMetricsBatch:
    """Incidents, laps and distance statistics of ``envs`` ego cars (one per env).

    Args:
        rules: sampling and thresholds.
        loop_length: length of the closed road along ``s``, m.
        envs: number of envs.
        extra_kinds: incident kinds the env detects itself (see :meth:`record`).
    """

    FLOATS = ("s_last",
              "distance", "progress", "next_lap_mark", "last_mark_time", "max_speed",
              "last_speed", "max_raw_acc", "max_raw_jerk", "last_raw_acc", "last_raw_jerk",
              "blk_sum", "kap_sum", "prev_block_v", "window_sum", "prev_window_mean",
              "last_acc", "last_acc_t", "last_acc_n", "last_jerk", "max_acc", "max_jerk",
              "dist_at_incident", "longest_closed")
    INTS = ("steps", "laps", "blk_n", "kap_n", "window_n", "straddle_run", "contact",
            "incident_total")
    BOOLS = ("has_prev_window", "acc_flag", "jerk_flag", "speeding", "off_road", "ready")

    def __init__(self, rules: IncidentRules, loop_length: float, envs: int,
                 extra_kinds: tuple[str, ...] = ()) -> None:
        if not loop_length > 0.0:
            raise ValueError(f"loop_length must be > 0, got {loop_length}")
        kinds = (*INCIDENT_KINDS, *extra_kinds)
        if len(set(kinds)) != len(kinds):
            raise ValueError(f"extra_kinds must be new, distinct kinds (built-in: "
                             f"{list(INCIDENT_KINDS)}), got {list(extra_kinds)}")
        self.rules = rules
        self.loop_length = float(loop_length)
        self.envs = envs
        self.kinds: tuple[str, ...] = kinds
        self.kind_order = {kind: i for i, kind in enumerate(kinds)}
        self.extra_kinds = frozenset(extra_kinds)
        self.info_keys = tuple(f"incidents_{kind}" for kind in kinds)
        self._inv_dt = 1.0 / rules.dt
        self._inv_dt2 = self._inv_dt**2
        self._inv_dt3 = self._inv_dt**3
        for name in self.FLOATS:
            setattr(self, name, np.zeros(envs))
        for name in self.INTS:
            setattr(self, name, np.zeros(envs, dtype=np.int64))
        for name in self.BOOLS:
            setattr(self, name, np.zeros(envs, dtype=bool))
        # The three positions before the next sample (copies of the start after a reset).
        self.back_x = np.zeros((envs, 3))
        self.back_y = np.zeros((envs, 3))
        self.counts = np.zeros((envs, len(kinds)), dtype=np.int64)
        self.lap_times: list[list[float]] = [[] for _ in range(envs)]
        self.incidents: list[list[Incident]] = [[] for _ in range(envs)]
        self._bands = rules.straddle_bands

    # ------------------------------------------------------------------ episode control
    def reset_at(self, env: int, x: float, y: float, s: float, d: float,
                 speed: float = 0.0) -> None:
        """Start env ``env``'s episode with the car at (x, y) / (s, d) moving at ``speed``.

        This is step 0 at time 0; it is not checked for incidents. Before it, positions
        are unknown: copies of the start stand in, and the samples that use them are
        masked out (the first curvature, acceleration and jerk samples).
        """
        for name in self.FLOATS:
            getattr(self, name)[env] = 0.0
        for name in self.INTS:
            getattr(self, name)[env] = 0
        for name in self.BOOLS:
            getattr(self, name)[env] = False
        self.back_x[env] = float(x)
        self.back_y[env] = float(y)
        self.s_last[env] = float(s)
        self.next_lap_mark[env] = self.loop_length
        self.last_speed[env] = self.prev_block_v[env] = float(speed)
        self.contact[env] = -1
        self.counts[env] = 0
        self.lap_times[env] = []
        self.incidents[env] = []
        self.ready[env] = True

    # ------------------------------------------------------------------ recording
    def record(self, xy: FloatArray, s: FloatArray, d: FloatArray, speed: FloatArray,
               collision_ids: IntArray | None = None,
               extra_incidents: list[list[tuple[int, str, float]]] | None = None,
               ) -> list[tuple[Incident, ...] | list[Incident]]:
        """Add ``k`` consecutive physics steps of every env; the incidents they began.

        Args:
            xy: positions ``(envs, k, 2)``, m.
            s, d, speed: ``(envs, k)``: arc length (m, wrapping at ``loop_length``),
                lateral offset (m, positive to the right), speed (m/s).
            collision_ids: ``(envs, k)`` ints, -1 for no contact at that step, else the id
                of a car in contact; ``None``: no contact at all.
            extra_incidents: per env, incidents of the ``extra_kinds`` the caller
                detected in these steps, as ``(step index, kind, value)``.

        Returns:
            Per env, the incidents that began during these steps, in step order.
        """
        if not self.ready.all():
            raise RuntimeError("call reset() before record()")
        rules = self.rules
        envs, k = speed.shape
        if k == 0:
            return [_NO_INCIDENTS] * envs
        # Geometry: velocity, acceleration and jerk (times dt, dt^2, dt^3) per step, and
        # the Menger curvature 2 |cross| / (|a| |b| |a + b|) of the last three positions
        # (0 for a degenerate triple). Positions with the three before the chunk (copies
        # of the start before a reset), then their differences: each value is the one a
        # step-by-step walk computes.
        px = np.concatenate([self.back_x, xy[..., 0]], axis=1)  # (envs, k + 3)
        py = np.concatenate([self.back_y, xy[..., 1]], axis=1)
        vx, vy = px[:, 1:] - px[:, :-1], py[:, 1:] - py[:, :-1]  # [m + 2]: step m
        ax, ay = vx[:, 1:] - vx[:, :-1], vy[:, 1:] - vy[:, :-1]  # [m + 1]: step m
        # One pass of math.hypot over: the step lengths (and the one before), the
        # accelerations, the jerks and the chords p[t] - p[t-2].
        norms = hypot(np.concatenate([vx[:, 1:], ax[:, 1:], ax[:, 1:] - ax[:, :-1],
                                      px[:, 3:] - px[:, 1:-2]], axis=1),
                      np.concatenate([vy[:, 1:], ay[:, 1:], ay[:, 1:] - ay[:, :-1],
                                      py[:, 3:] - py[:, 1:-2]], axis=1))
        lengths_all = norms[:, :k + 1]
        lengths = lengths_all[:, 1:]
        raw_acc = norms[:, k + 1:2 * k + 1]
        raw_jerk = norms[:, 2 * k + 1:3 * k + 1]
        den = lengths_all[:, :-1] * lengths
        den *= norms[:, 3 * k + 1:]
        cross = np.abs(vx[:, 1:-1] * vy[:, 2:] - vy[:, 1:-1] * vx[:, 2:])
        cross *= 2.0
        curv = np.divide(cross, den, out=np.zeros_like(den), where=den != 0.0)
        self.back_x, self.back_y = px[:, -3:].copy(), py[:, -3:].copy()
        t0 = self.steps.copy()
        early = t0 < 3
        if np.count_nonzero(early):
            self._mask_warmup(t0, curv, raw_acc, raw_jerk)

        # Running sums, strictly in step order.
        cum_dist = np.empty((envs, k + 1))
        cum_dist[:, 0] = self.distance
        cum_dist[:, 1:] = lengths
        np.add.accumulate(cum_dist, axis=1, out=cum_dist)
        length, half = self.loop_length, 0.5 * self.loop_length
        ds = s - _shift(self.s_last, s)
        ds += half
        np.remainder(ds, length, out=ds)
        ds -= half
        cum_prog = np.empty((envs, k + 1))
        cum_prog[:, 0] = self.progress
        cum_prog[:, 1:] = ds
        np.add.accumulate(cum_prog, axis=1, out=cum_prog)
        self.distance = cum_dist[:, -1].copy()
        self.progress = cum_prog[:, -1].copy()
        self.s_last = s[:, -1].copy()
        self.steps = t0 + k
        lapped = self.progress >= self.next_lap_mark
        if np.count_nonzero(lapped):
            for env in np.flatnonzero(lapped).tolist():
                self._count_laps(env, cum_prog[env].tolist(), int(t0[env]))

        # Maxima and latest values.
        np.maximum(self.max_speed, speed.max(axis=1), out=self.max_speed)
        self.last_speed = speed[:, -1].copy()
        np.maximum(self.max_raw_acc, raw_acc.max(axis=1) * self._inv_dt2, out=self.max_raw_acc)
        np.maximum(self.max_raw_jerk, raw_jerk.max(axis=1) * self._inv_dt3,
                   out=self.max_raw_jerk)
        self.last_raw_acc = raw_acc[:, -1] * self._inv_dt2
        self.last_raw_jerk = raw_jerk[:, -1] * self._inv_dt3

        # Per-step incidents: rising edges of each condition.
        pending: list[tuple[NDArray, NDArray, int, FloatArray]] = []
        order = self.kind_order
        speeding = speed > rules.speed_limit
        self._rising(pending, self.speeding, speeding, order["speed"], speed)
        self.speeding = speeding[:, -1].copy()
        off = (d < rules.road_d_min) | (d > rules.road_d_max)
        self._rising(pending, self.off_road, off, order["off_road"], d)
        self.off_road = off[:, -1].copy()
        if self._bands:
            inside = np.zeros(d.shape, dtype=bool)
            for lo, hi in self._bands:
                inside |= (d > lo) & (d < hi)
            frames = np.arange(k)
            last_out = np.maximum.accumulate(np.where(inside, -1, frames), axis=1)
            run = np.where(last_out >= 0, frames - last_out,
                           self.straddle_run[:, None] + frames + 1)
            hit = run == rules.max_straddle_steps + 1
            if np.count_nonzero(hit):
                rows, cols = np.nonzero(hit)
                pending.append((rows, cols, order["lane"], run[rows, cols] * rules.dt))
            self.straddle_run = run[:, -1].copy()
        if collision_ids is not None:
            contact = np.where(collision_ids < 0, -1, collision_ids)
            new = (collision_ids >= 0) & (collision_ids != _shift(self.contact, contact))
            if np.count_nonzero(new):
                rows, cols = np.nonzero(new)
                pending.append((rows, cols, order["collision"],
                                collision_ids[rows, cols].astype(np.float64)))
            self.contact = contact[:, -1].copy()
        else:
            self.contact = np.full(envs, -1, dtype=np.int64)
        extra: list[tuple[int, int, int, float]] = []
        if extra_incidents:
            for env, items in enumerate(extra_incidents):
                for i, kind, value in items:
                    if kind not in self.extra_kinds or not 0 <= i < k:
                        raise ValueError(
                            f"extra incident ({i}, {kind!r}): the kind must be one of "
                            f"extra_kinds {sorted(self.extra_kinds)} and the index within "
                            f"the {k} recorded steps")
                    extra.append((env, i, order[kind], float(value)))

        self._block_rule(speed, curv, pending)

        if not pending and not extra:
            return [_NO_INCIDENTS] * envs
        return self._log(pending, extra, t0, xy, s, d, cum_dist)

    @staticmethod
    def _rising(pending: list[tuple[NDArray, NDArray, int, FloatArray]], before: NDArray,
                now: NDArray, kind: int, values: FloatArray) -> None:
        start = now & ~_shift(before, now)
        if np.count_nonzero(start):
            rows, cols = np.nonzero(start)
            pending.append((rows, cols, kind, values[rows, cols]))

    def _mask_warmup(self, t0: IntArray, curv: FloatArray, acc: FloatArray,
                     jerk: FloatArray) -> None:
        """Blank the samples that would use positions from before the reset.

        Sample ``m`` of the chunk is global step ``t = t0 + 1 + m``; its curvature and raw
        acceleration need ``p[t-2]`` (so ``t >= 2``), its raw jerk ``p[t-3]`` (``t >= 3``).
        Curvature becomes NaN (dropped from the block mean), raw values 0 (neutral for max).
        """
        t = t0[:, None] + 1 + np.arange(curv.shape[1])[None, :]
        curv[t < 2] = np.nan
        acc[t < 2] = 0.0
        jerk[t < 3] = 0.0

    def _count_laps(self, env: int, cum_prog: list[float], t0: int) -> None:
        """Record every lap mark crossed in this chunk, timed by linear interpolation."""
        dt = self.rules.dt
        mark = float(self.next_lap_mark[env])
        last = float(self.last_mark_time[env])
        laps = int(self.laps[env])
        for i in range(1, len(cum_prog)):
            p0, p1 = cum_prog[i - 1], cum_prog[i]
            while p1 >= mark:
                # p0 < mark <= p1 here, so p1 > p0 and the fraction lies in (0, 1].
                t_cross = (t0 + i - 1 + (mark - p0) / (p1 - p0)) * dt
                self.lap_times[env].append(t_cross - last)
                last = t_cross
                laps += 1
                mark = (laps + 1) * self.loop_length
        self.next_lap_mark[env], self.last_mark_time[env], self.laps[env] = mark, last, laps

    def _block_rule(self, speed: FloatArray, curv: FloatArray,
                    pending: list[tuple[NDArray, NDArray, int, FloatArray]]) -> None:
        """The block rule: running sums per block (strictly in step order), closed at the
        frame that completes each env's block of ``block_steps`` samples."""
        rules = self.rules
        n = rules.block_steps
        valid = curv == curv  # NaN != NaN: warm-up samples are dropped from the mean
        curv = np.where(valid, curv, 0.0)
        for m in range(speed.shape[1]):
            self.blk_sum += speed[:, m]
            self.kap_sum += curv[:, m]
            self.kap_n += valid[:, m]
            self.blk_n += 1
            closing = np.flatnonzero(self.blk_n >= n)
            if len(closing):
                self._close_block(closing, m, pending)

    def _close_block(self, rows: IntArray, m: int,
                     pending: list[tuple[NDArray, NDArray, int, FloatArray]]) -> None:
        rules = self.rules
        order = self.kind_order
        v = self.blk_sum[rows] / rules.block_steps
        count = self.kap_n[rows]
        kappa_mean = np.divide(self.kap_sum[rows], count, out=np.zeros(len(rows)),
                               where=count > 0)
        acc_t = (v - self.prev_block_v[rows]) / rules.block_seconds
        acc_n = v * v * kappa_mean
        total = hypot(acc_t, acc_n)
        self.prev_block_v[rows] = v
        self.last_acc_t[rows], self.last_acc_n[rows], self.last_acc[rows] = acc_t, acc_n, total
        self.max_acc[rows] = np.maximum(self.max_acc[rows], total)
        violating = total >= rules.max_acceleration
        start = violating & ~self.acc_flag[rows]
        if np.count_nonzero(start):
            pending.append((rows[start], np.full(np.count_nonzero(start), m),
                            order["acceleration"], total[start]))
        self.acc_flag[rows] = violating
        self.blk_sum[rows] = self.kap_sum[rows] = 0.0
        self.blk_n[rows] = self.kap_n[rows] = 0
        self.window_sum[rows] += total
        self.window_n[rows] += 1
        full = rows[self.window_n[rows] == rules.jerk_blocks]
        if not len(full):
            return
        mean = self.window_sum[full] / rules.jerk_blocks
        self.window_sum[full] = 0.0
        self.window_n[full] = 0
        has_prev = self.has_prev_window[full]
        jerk_rows = full[has_prev]  # the first window has no jerk
        if len(jerk_rows):
            jerk = (mean[has_prev] - self.prev_window_mean[jerk_rows]) / rules.jerk_window_seconds
            self.last_jerk[jerk_rows] = jerk
            self.max_jerk[jerk_rows] = np.maximum(self.max_jerk[jerk_rows], np.abs(jerk))
            violating = np.abs(jerk) >= rules.max_jerk
            start = violating & ~self.jerk_flag[jerk_rows]
            if np.count_nonzero(start):
                pending.append((jerk_rows[start], np.full(np.count_nonzero(start), m),
                                order["jerk"], jerk[start]))
            self.jerk_flag[jerk_rows] = violating
        self.prev_window_mean[full] = mean
        self.has_prev_window[full] = True

    def _log(self, pending: list[tuple[NDArray, NDArray, int, FloatArray]],
             extra: list[tuple[int, int, int, float]], t0: IntArray, xy: FloatArray,
             s: FloatArray, d: FloatArray, cum_dist: FloatArray
             ) -> list[tuple[Incident, ...] | list[Incident]]:
        """Turn the pending (env, index, kind, value) entries into Incidents, per env in
        step order (same step: in kind order)."""
        by_env: dict[int, list[tuple[int, int, float]]] = {}
        for rows, cols, kind, values in pending:
            for env, i, value in zip(rows.tolist(), cols.tolist(), values.tolist(),
                                     strict=True):
                by_env.setdefault(env, []).append((i, kind, value))
        for env, i, kind, value in extra:
            by_env.setdefault(env, []).append((i, kind, value))
        dt = self.rules.dt
        result: list[tuple[Incident, ...] | list[Incident]] = [_NO_INCIDENTS] * self.envs
        for env, items in by_env.items():
            items.sort(key=lambda item: (item[0], item[1]))
            new = []
            start = int(t0[env])
            for i, kind_index, value in items:
                kind = self.kinds[kind_index]
                step = start + 1 + i
                new.append(Incident(kind, step * dt, step, float(xy[env, i, 0]),
                                    float(xy[env, i, 1]), float(s[env, i]), float(d[env, i]),
                                    float(value)))
                self.counts[env, kind_index] += 1
                # The stretch without incident ends at this step's distance.
                dist = float(cum_dist[env, i + 1])
                self.longest_closed[env] = max(float(self.longest_closed[env]),
                                               dist - float(self.dist_at_incident[env]))
                self.dist_at_incident[env] = dist
            self.incidents[env].extend(new)
            self.incident_total[env] += len(new)
            result[env] = new
        return result

    # ------------------------------------------------------------------ reports
    def time(self) -> FloatArray:
        """Episode time per env, s."""
        return self.steps * self.rules.dt

    def step_info(self, env: int) -> dict[str, float | int]:
        """Env ``env``'s current values for an ``info`` dict (plain numbers, the same
        keys every call)."""
        info: dict[str, float | int] = {
            "time": int(self.steps[env]) * self.rules.dt,
            "distance": float(self.distance[env]),
            "progress": float(self.progress[env]),
            "laps": int(self.laps[env]),
            "speed": float(self.last_speed[env]),
            "acceleration": float(self.last_acc[env]),
            "jerk": float(self.last_jerk[env]),
            "raw_acceleration": float(self.last_raw_acc[env]),
            "raw_jerk": float(self.last_raw_jerk[env]),
            "distance_without_incident": float(self.distance[env] - self.dist_at_incident[env]),
            "incidents": int(self.incident_total[env]),
        }
        for key, count in zip(self.info_keys, self.counts[env].tolist(), strict=True):
            info[key] = count
        return info

    def step_arrays(self) -> dict[str, NDArray]:
        """Every env's :meth:`step_info` values as arrays (for vector envs)."""
        info: dict[str, NDArray] = {
            "time": self.steps * self.rules.dt,
            "distance": self.distance.copy(),
            "progress": self.progress.copy(),
            "laps": self.laps.copy(),
            "speed": self.last_speed.copy(),
            "acceleration": self.last_acc.copy(),
            "jerk": self.last_jerk.copy(),
            "raw_acceleration": self.last_raw_acc.copy(),
            "raw_jerk": self.last_raw_jerk.copy(),
            "distance_without_incident": self.distance - self.dist_at_incident,
            "incidents": self.incident_total.copy(),
        }
        for index, key in enumerate(self.info_keys):
            info[key] = self.counts[:, index].copy()
        return info

    def summary(self, env: int) -> dict[str, Any]:
        """Env ``env``'s episode summary of plain Python types (``json.dumps``-able).

        Times in s, distances in m, speeds in m/s (plus ``mean_speed_mph``),
        accelerations in m/s^2, jerks in m/s^3. Lap statistics are ``None`` without laps.
        """
        laps = list(self.lap_times[env])
        steps = int(self.steps[env])
        distance = float(self.distance[env])
        time = steps * self.rules.dt
        mean_speed = distance / time if steps else 0.0
        since = distance - float(self.dist_at_incident[env])
        return {
            "lap_times": laps,
            "laps": int(self.laps[env]),
            "mean_lap_time": sum(laps) / len(laps) if laps else None,
            "best_lap_time": min(laps) if laps else None,
            "distance": distance,
            "time": time,
            "mean_speed": mean_speed,
            "mean_speed_mph": mean_speed * MPS_TO_MPH,
            "max_speed": float(self.max_speed[env]),
            "distance_without_incident": since,
            "longest_distance_without_incident": max(float(self.longest_closed[env]), since),
            "incidents": dict(zip(self.kinds, self.counts[env].tolist(), strict=True)),
            "incident_total": int(self.incident_total[env]),
            "max_acceleration": float(self.max_acc[env]),
            "max_jerk": float(self.max_jerk[env]),
            "max_raw_acceleration": float(self.max_raw_acc[env]),
            "max_raw_jerk": float(self.max_raw_jerk[env]),
        }
