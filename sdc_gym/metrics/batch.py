"""The driving metrics of a batch of envs: every env's running state as an array.

:class:`DrivingMetricsBatch` applies the rules of :mod:`sdc_gym.metrics.driving_metrics`
to ``(envs, frames)`` arrays of physics samples per call, in one compiled pass over every
env's samples (:func:`~sdc_gym.metrics.kernel.record_batch`: each sample's values from
the previous sample's, in step order, exactly as a sample-by-sample walk on Python floats
computes them). Lap times and incidents are kept per env in Python lists (they are rare).
An env's results do not depend on the other envs of the batch or on how its samples are
chunked.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.metrics import kernel
from sdc_gym.metrics.incidents import INCIDENT_KINDS, Incident, IncidentRules
from sdc_gym.packed_rows import PackedRows
from sdc_gym.units import MPS_TO_MPH

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]

_NO_INCIDENTS: tuple[Incident, ...] = ()
_NO_EXTRA = np.zeros((0, 4))
_NO_CONTACTS = np.full((1, 1), -1, dtype=np.int64)


class DrivingMetricsBatch(PackedRows):
    """Incidents, laps and distance statistics of ``envs`` ego cars (one per env).

    Args:
        rules: sampling and thresholds.
        loop_length: length of the closed road along ``s``, m.
        envs: number of envs.
        extra_kinds: incident kinds the env detects itself (see :meth:`record`).

    The running state is held in arrays of one value per env, named as the rules name
    them (``steps``, ``laps``, ``distance``, ``progress``, ``max_speed``, ``last_acc``,
    ...: :data:`~sdc_gym.metrics.kernel.FLOAT_ROWS` and
    :data:`~sdc_gym.metrics.kernel.INT_ROWS`); they are updated in place (read them, do
    not assign them). ``counts`` is ``(envs, kinds)``; ``lap_times`` and ``incidents``
    hold a list per env.
    """

    FLOATS = kernel.FLOAT_ROWS
    INTS = kernel.INT_ROWS
    PACKED_ROWS = (("_floats", "FLOATS"), ("_ints", "INTS"))

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
        inv_dt = 1.0 / rules.dt
        constants = np.zeros(14)
        constants[[kernel.R_DT, kernel.R_BLOCK_STEPS, kernel.R_JERK_BLOCKS, kernel.R_MAX_ACC,
                   kernel.R_MAX_JERK, kernel.R_SPEED_LIMIT, kernel.R_D_MIN, kernel.R_D_MAX,
                   kernel.R_MAX_STRADDLE, kernel.R_LOOP, kernel.R_INV_DT2, kernel.R_INV_DT3,
                   kernel.R_BLOCK_SECONDS, kernel.R_WINDOW_SECONDS]] = (
            rules.dt, rules.block_steps, rules.jerk_blocks, rules.max_acceleration,
            rules.max_jerk, rules.speed_limit, rules.road_d_min, rules.road_d_max,
            rules.max_straddle_steps, self.loop_length, inv_dt**2, inv_dt**3,
            rules.block_seconds, rules.jerk_window_seconds)
        self._rules = constants
        self._bands = np.array(rules.straddle_bands, dtype=np.float64).reshape(-1, 2)
        self._floats = np.zeros((len(self.FLOATS), envs))
        self._ints = np.zeros((len(self.INTS), envs), dtype=np.int64)
        self._bind_rows()
        self.ready = np.zeros(envs, dtype=bool)
        self._all_ready = False
        # The three positions before the next sample (copies of the start after a reset):
        # x of p[t-3], p[t-2], p[t-1], then their y.
        self.back = np.zeros((envs, 6))
        self.counts = np.zeros((envs, len(kinds)), dtype=np.int64)
        self.lap_times: list[list[float]] = [[] for _ in range(envs)]
        self.incidents: list[list[Incident]] = [[] for _ in range(envs)]
        self._events = np.zeros((0, 4))
        self._laps = np.zeros((0, 2))

    # ------------------------------------------------------------------ episode control

    def reset_at(self, env: int, x: float, y: float, s: float, d: float,
                 speed: float = 0.0) -> None:
        """Start env ``env``'s episode with the car at (x, y) / (s, d) moving at ``speed``.

        This is step 0 at time 0; it is not checked for incidents. Before it, positions
        are unknown: copies of the start stand in, and the samples that use them are
        masked out (the first curvature, acceleration and jerk samples).
        """
        self._floats[:, env] = 0.0
        self._ints[:, env] = 0
        self.back[env, :3] = float(x)
        self.back[env, 3:] = float(y)
        self.s_last[env] = float(s)
        self.next_lap_mark[env] = self.loop_length
        self.last_speed[env] = self.prev_block_v[env] = float(speed)
        self.contact[env] = -1
        self.counts[env] = 0
        self.lap_times[env] = []
        self.incidents[env] = []
        self.ready[env] = True
        self._all_ready = bool(self.ready.all())

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
        if not self._all_ready:
            raise RuntimeError("call reset() before record()")
        envs, k = speed.shape
        if k == 0:
            return [_NO_INCIDENTS] * envs
        extra = _NO_EXTRA
        if extra_incidents:
            rows = []
            for env, items in enumerate(extra_incidents):
                for i, kind, value in items:
                    if kind not in self.extra_kinds or not 0 <= i < k:
                        raise ValueError(
                            f"extra incident ({i}, {kind!r}): the kind must be one of "
                            f"extra_kinds {sorted(self.extra_kinds)} and the index within "
                            f"the {k} recorded steps")
                    rows.append((env, i, self.kind_order[kind], float(value)))
            if rows:
                extra = np.array(rows, dtype=np.float64)
        capacity = envs * (3 * k + 8) + len(extra)
        if len(self._events) < capacity:
            self._events = np.zeros((capacity, 4))
            self._laps = np.zeros((envs * (k + 2), 2))
        contacts = _NO_CONTACTS if collision_ids is None else collision_ids
        count, laps = kernel.record_batch(
            self._rules, self._bands, self._floats, self._ints, self.back, self.counts,
            xy, s, d, speed, contacts, collision_ids is not None, extra, self._events,
            self._laps)
        if laps:
            for env, lap_time in self._laps[:laps].tolist():
                self.lap_times[int(env)].append(lap_time)
        if not count:
            return [_NO_INCIDENTS] * envs
        return self._log(count, xy, s, d)

    def _log(self, count: int, xy: FloatArray, s: FloatArray, d: FloatArray
             ) -> list[tuple[Incident, ...] | list[Incident]]:
        """The kernel's incident events as :class:`Incident` s, per env in step order."""
        dt = self.rules.dt
        result: list[tuple[Incident, ...] | list[Incident]] = [_NO_INCIDENTS] * self.envs
        for env, i, kind_index, value in self._events[:count].tolist():
            env, i = int(env), int(i)
            step = int(self.steps[env]) - xy.shape[1] + 1 + i
            incident = Incident(self.kinds[int(kind_index)], step * dt, step,
                                float(xy[env, i, 0]), float(xy[env, i, 1]), float(s[env, i]),
                                float(d[env, i]), value)
            if result[env] is _NO_INCIDENTS:
                result[env] = []
            result[env].append(incident)  # type: ignore[union-attr]
            self.incidents[env].append(incident)
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
