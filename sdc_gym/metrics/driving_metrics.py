"""Driving-quality metrics shared by every sdc-gym environment.

The Udacity highway simulator judges a drive by a handful of incidents (exceeding the
acceleration, jerk or speed limit, leaving the road, straddling a lane line too long,
touching another car) and by how far the car gets without one. :class:`DrivingMetrics`
reproduces those rules on the physics samples an environment already has, and adds the
statistics a researcher wants for a report: lap times, distance, speeds, and the raw
per-step acceleration and jerk.

How the simulator measures acceleration (the *block rule*)
----------------------------------------------------------
Physics runs every ``dt`` = 0.02 s. Speeds are grouped into disjoint *blocks* of
``block_steps`` = 10 samples (0.2 s). For each block with mean speed ``v``:

* tangential acceleration ``AccT = (v - v_prev) / 0.2`` where ``v_prev`` is the previous
  block's mean speed;
* normal (centripetal) acceleration ``AccN = v**2 * kappa`` where ``kappa`` is the mean
  curvature of the path over the block;
* total acceleration ``sqrt(AccT**2 + AccN**2)``; an ``"acceleration"`` incident when it
  reaches ``max_acceleration``.

Every ``jerk_blocks`` = 5 block totals (1 s) form a *window*; the jerk is the change of
the window's mean total from the previous window's, divided by the window length (1 s),
and ``|jerk| >= max_jerk`` is a ``"jerk"`` incident. Averaging over blocks and windows is
what makes these numbers robust to the step-to-step noise of a physics engine; the raw
per-step values (see below) are reported alongside for anyone who wants the unfiltered
signal.

Curvature of three points ``p1, p2, p3`` is the Menger curvature
``2 sin(turn angle) / |p3 - p1|``: exactly ``1/R`` for three points on a circle of radius
``R``, 0 on a straight line, and taken as 0 for a degenerate triple (two equal points, e.g.
a stopped car). The magnitude is used, so an S-bend does not cancel out.

Choices this module makes (the simulator leaves them open)
----------------------------------------------------------
* **Curvature triples.** The curvature sample of step ``t`` is that of the three most
  recent positions ``(p[t-2], p[t-1], p[t])``; a block averages the samples of its own
  steps. Its middle points are thus the block's steps shifted back by one. Triples centred
  on the block's steps would need the position *after* the block, delaying every block
  (and the incident it raises) by one step and leaving the last block of an episode
  unmeasured; the shift changes the mean curvature by O(dt) only. The very first step of
  an episode has no ``p[-1]``, so the first block averages the 9 triples it has.
* **First block.** Its ``v_prev`` is the speed given to :meth:`DrivingMetrics.reset`: an
  episode that starts at rest is measured against 0, one that starts at cruise speed is
  not charged for the jump from 0.
* **First jerk window.** It has no previous window, so it produces no jerk value (jerk is
  reported as 0 until the second window closes, at t = 2 s).
* **Raw values.** Velocity ``v_t = (p_t - p_{t-1})/dt``, acceleration
  ``a_t = (v_t - v_{t-1})/dt``, jerk ``j_t = (a_t - a_{t-1})/dt`` (vectors; magnitudes are
  reported). The heading before :meth:`~DrivingMetrics.reset` is unknown, so the raw
  acceleration exists from the 2nd recorded step and the raw jerk from the 3rd (0 before).

Other environments may add incident kinds of their own (the track loop's ``"red_light"``):
pass ``extra_kinds`` to :class:`DrivingMetrics` and the incidents the env detects to
:meth:`~DrivingMetrics.record` (``extra_incidents``). They are counted, logged, ordered
and restart the distance without incident exactly like the built-in kinds; within a step
they come after the built-in kinds, in ``extra_kinds`` order.

Incidents are counted once per *event* (rising edge): consecutive violating steps (or
blocks, or windows) make one incident. A lane-straddle run counts once when it exceeds
``max_straddle_steps``. A collision counts once per contact: a contact with car ``c`` lasts
while consecutive steps report ``c``. Every incident restarts the "distance without
incident". Incidents raised at the same step are ordered as in :data:`INCIDENT_KINDS`.

Chunking invariance
-------------------
:meth:`DrivingMetrics.record` takes the ``k`` physics steps of one environment step at
once. Every quantity is computed per step from the same inputs, and running sums
(distance, progress, block speeds) are accumulated strictly in step order, so feeding a
trajectory one step at a time or in chunks of any size gives bit-identical results.

Implementation: :class:`~sdc_gym.metrics.batch.DrivingMetricsBatch` applies the rules to
a batch of envs at once (arrays with a leading env axis); :class:`DrivingMetrics` is the
batch of one, for a single env. Sums run strictly in step order (the block and window
means are sequential sums, like Python's ``sum`` of floats before 3.12) and lengths use
Python's ``math.hypot``, so results are the same bit for bit whatever the batch.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from sdc_gym.metrics.batch import DrivingMetricsBatch
from sdc_gym.metrics.incidents import INCIDENT_KINDS, Incident, IncidentRules

__all__ = ["INCIDENT_KINDS", "DrivingMetrics", "Incident", "IncidentRules"]


class DrivingMetrics:
    """Incidents, lap timing and distance statistics of one ego car over an episode.

    Call :meth:`reset` at the start of every episode, then :meth:`record` with the physics
    steps of each environment step. Read the results through the properties,
    :meth:`step_info` (per step, for ``info``) and :meth:`summary` (per episode).

    Args:
        rules: sampling and thresholds (:class:`IncidentRules`).
        loop_length: length of the closed road along ``s``, m; ``s`` wraps at this value.
        extra_kinds: incident kinds an env detects itself and passes to :meth:`record`
            (e.g. ``("red_light",)``); reported after :data:`INCIDENT_KINDS`.
    """

    def __init__(
        self, rules: IncidentRules, loop_length: float, extra_kinds: tuple[str, ...] = ()
    ) -> None:
        self._attach(DrivingMetricsBatch(rules, loop_length, 1, extra_kinds), 0)

    @classmethod
    def view(cls, batch: DrivingMetricsBatch, env: int) -> DrivingMetrics:
        """Env ``env`` of an existing batch, with this class's API (read it; the batch
        records)."""
        made = object.__new__(cls)
        made._attach(batch, env)
        return made

    def _attach(self, batch: DrivingMetricsBatch, env: int) -> None:
        self.batch = batch
        self.env = env
        self.rules = batch.rules
        self.loop_length = batch.loop_length
        self.kinds: tuple[str, ...] = batch.kinds
        """Every incident kind this instance counts, in report order."""

    # ------------------------------------------------------------------ episode control
    def reset(self, x: float, y: float, s: float, d: float, speed: float = 0.0) -> None:
        """Start a new episode with the car at ``(x, y)`` / ``(s, d)`` moving at ``speed`` m/s.

        This is step 0 at time 0; it is not checked for incidents.
        """
        self.batch.reset_at(self.env, x, y, s, d, speed)

    def record(
        self,
        xy: np.ndarray | list[list[float]],
        s: np.ndarray | list[float],
        d: np.ndarray | list[float],
        speed: np.ndarray | list[float],
        collision_ids: np.ndarray | None = None,
        extra_incidents: list[tuple[int, str, float]] | None = None,
    ) -> list[Incident]:
        """Add ``k >= 1`` consecutive physics steps and return the incidents they began.

        Args:
            xy: positions, shape ``(k, 2)``, m.
            s: arc-length coordinate, shape ``(k,)``, m, wrapping at ``loop_length``.
            d: lateral offset, shape ``(k,)``, m (positive to the right of travel).
            speed: speed, shape ``(k,)``, m/s.
            collision_ids: shape ``(k,)`` ints; -1 for no contact at that step, else the
                id of a car in contact. ``None`` means no contact at all.
            extra_incidents: incidents of the ``extra_kinds`` that the caller detected in
                these steps, as ``(step index in 0..k-1, kind, value)``.

        Returns:
            The incidents that began during these steps, in step order.
        """
        if self.batch.envs != 1:
            raise RuntimeError("record() of one env of a batch: record the batch")
        speed_a = np.asarray(speed, dtype=np.float64).reshape(1, -1)
        k = speed_a.shape[1]
        ids = None if collision_ids is None else np.asarray(collision_ids,
                                                           dtype=np.int64).reshape(1, k)
        new = self.batch.record(np.asarray(xy, dtype=np.float64).reshape(1, k, 2),
                                np.asarray(s, dtype=np.float64).reshape(1, k),
                                np.asarray(d, dtype=np.float64).reshape(1, k), speed_a, ids,
                                [extra_incidents] if extra_incidents else None)[0]
        return list(new)

    # ------------------------------------------------------------------ read-only results
    def _value(self, name: str) -> Any:
        return getattr(self.batch, name)[self.env].item()

    @property
    def time(self) -> float:
        """Episode time, s."""
        return self._value("steps") * self.rules.dt

    @property
    def steps(self) -> int:
        """Physics steps recorded since reset."""
        return int(self._value("steps"))

    @property
    def distance(self) -> float:
        """Distance travelled, m (sum of straight step lengths)."""
        return float(self._value("distance"))

    @property
    def progress(self) -> float:
        """Unwrapped progress along s since reset, m (negative when driving backwards)."""
        return float(self._value("progress"))

    @property
    def laps_completed(self) -> int:
        """Laps completed: positive multiples of the loop length reached by the progress."""
        return int(self._value("laps"))

    @property
    def lap_times(self) -> list[float]:
        """Duration of each completed lap, s."""
        return list(self.batch.lap_times[self.env])

    @property
    def incident_counts(self) -> dict[str, int]:
        """Incidents by kind; every kind of :attr:`kinds` is present."""
        return dict(zip(self.kinds, self.batch.counts[self.env].tolist(), strict=True))

    @property
    def incidents(self) -> list[Incident]:
        """Every incident of the episode, in step order."""
        return list(self.batch.incidents[self.env])

    @property
    def distance_without_incident(self) -> float:
        """Distance since the last incident (or the start), m."""
        return self.distance - float(self._value("dist_at_incident"))

    @property
    def longest_distance_without_incident(self) -> float:
        """Longest stretch without incident so far, including the current one, m."""
        return max(float(self._value("longest_closed")), self.distance_without_incident)

    @property
    def max_speed(self) -> float:
        """Highest recorded speed, m/s."""
        return float(self._value("max_speed"))

    @property
    def max_acceleration(self) -> float:
        """Highest block total acceleration, m/s^2."""
        return float(self._value("max_acc"))

    @property
    def max_jerk(self) -> float:
        """Highest window jerk magnitude, m/s^3."""
        return float(self._value("max_jerk"))

    @property
    def max_raw_acceleration(self) -> float:
        """Highest per-step acceleration magnitude, m/s^2."""
        return float(self._value("max_raw_acc"))

    @property
    def max_raw_jerk(self) -> float:
        """Highest per-step jerk magnitude, m/s^3."""
        return float(self._value("max_raw_jerk"))

    @property
    def last_acceleration(self) -> float:
        """Total acceleration of the latest completed block, m/s^2."""
        return float(self._value("last_acc"))

    @property
    def last_tangential_acceleration(self) -> float:
        """Signed AccT of the latest completed block, m/s^2 (negative when braking)."""
        return float(self._value("last_acc_t"))

    @property
    def last_normal_acceleration(self) -> float:
        """AccN of the latest completed block, m/s^2 (v^2 times mean |curvature|)."""
        return float(self._value("last_acc_n"))

    @property
    def last_jerk(self) -> float:
        """Signed jerk of the latest completed window, m/s^3 (0 before the second window)."""
        return float(self._value("last_jerk"))

    @property
    def last_raw_acceleration(self) -> float:
        """Per-step acceleration magnitude of the latest step, m/s^2."""
        return float(self._value("last_raw_acc"))

    @property
    def last_raw_jerk(self) -> float:
        """Per-step jerk magnitude of the latest step, m/s^3."""
        return float(self._value("last_raw_jerk"))

    @property
    def mean_speed(self) -> float:
        """Distance over time, m/s (0 before the first step)."""
        return self.distance / self.time if self.steps else 0.0

    # ------------------------------------------------------------------ reports
    def step_info(self) -> dict[str, float | int]:
        """Current values for an env's ``info`` dict: the same keys every call, plain numbers.

        ``speed`` is the latest speed sample, ``acceleration``/``jerk`` the latest block
        and window values, ``raw_*`` the latest per-step magnitudes.
        """
        return self.batch.step_info(self.env)

    def summary(self) -> dict[str, Any]:
        """Episode summary of plain Python types (``json.dumps``-able).

        Times in s, distances in m, speeds in m/s (plus ``mean_speed_mph``),
        accelerations in m/s^2, jerks in m/s^3. Lap statistics are ``None`` without laps.
        """
        return self.batch.summary(self.env)
