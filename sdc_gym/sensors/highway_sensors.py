"""What the highway planner is told: sensor fusion rows and the original telemetry message.

Sensor fusion is one row per traffic car, ``[id, x, y, vx, vy, s, d]`` (m, m/s), as in the
original. Optional, seeded imperfections: Gaussian noise on positions and velocities,
dropouts (a car missing from a frame), and the original's quirk near the end of the loop
where some cars report ``s = d = 0`` for several frames (the seed planner falls back to
x, y there). All are off by default, so the default sensor is the original's noiseless one.

:func:`telemetry_message` builds the flat dict the original sends in
``42["telemetry",{...}]``: yaw in degrees, speed in mph, every number first made a 32-bit
float and then rounded to the 7 significant digits the original prints (its
``JSONObject`` keeps floats and prints them with C#'s ``float.ToString()``). The env hands
it out as a :class:`TelemetryMessage`, which builds that dict only when first read, with
the Frenet fields in the original's convention unless the env says ``frenet: exact``
(:mod:`sdc_gym.sensors.original_telemetry`).
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sdc_gym.geometry import exact_math
from sdc_gym.geometry.original_frenet import OriginalFrenet
from sdc_gym.sensors.original_telemetry import original_frenet_fields
from sdc_gym.units import MPS_TO_MPH

FUSION_FIELDS = ("id", "x", "y", "vx", "vy", "s", "d")


@dataclass(frozen=True)
class SensorConfig:
    """Sensor imperfections; all zero (off) by default.

    Attributes:
        position_noise: m, standard deviation added to x, y, s and d of each car.
        velocity_noise: m/s, standard deviation added to vx and vy.
        dropout_probability: chance per car per frame that the car is missing.
        zero_sd_probability: chance per car per frame, inside the zone, that a fault
            begins during which the car reports s = d = 0 (the original's quirk).
        zero_sd_zone: m before the loop's seam (s = length) where the quirk can begin.
        zero_sd_frames: (min, max) frames a fault lasts.
    """

    position_noise: float = 0.0
    velocity_noise: float = 0.0
    dropout_probability: float = 0.0
    zero_sd_probability: float = 0.0
    zero_sd_zone: float = 300.0
    zero_sd_frames: tuple[int, int] = (5, 25)

    def __post_init__(self) -> None:
        for name in ("position_noise", "velocity_noise", "zero_sd_zone"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"sensor {name} must be >= 0, got {getattr(self, name)!r}")
        for name in ("dropout_probability", "zero_sd_probability"):
            if not 0.0 <= getattr(self, name) <= 1.0:
                raise ValueError(f"sensor {name} must be in [0, 1], got {getattr(self, name)!r}")
        low, high = self.zero_sd_frames
        if not 1 <= low <= high:
            raise ValueError(f"sensor zero_sd_frames must be 1 <= min <= max, got {(low, high)}")

    @property
    def is_perfect(self) -> bool:
        return (self.position_noise == 0 and self.velocity_noise == 0
                and self.dropout_probability == 0 and self.zero_sd_probability == 0)


class HighwaySensors:
    """Turns the traffic state of a batch of envs into sensor fusion rows, applying the
    configured faults (each env's from its own generator)."""

    def __init__(self, config: SensorConfig, car_count: int, loop_length: float,
                 envs: int = 1) -> None:
        self.config = config
        self.loop_length = loop_length
        self._zero_frames_left = np.zeros((envs, car_count), dtype=np.int64)
        self._perfect = config.is_perfect
        # Without dropouts every row is present: one read-only mask serves every frame.
        self._all_present = np.ones((envs, car_count), dtype=bool)
        self._all_present.flags.writeable = False

    def reset_at(self, env: int) -> None:
        self._zero_frames_left[env] = 0

    def read(
        self, ids: NDArray[np.int64], x: NDArray[np.float64], y: NDArray[np.float64],
        vx: NDArray[np.float64], vy: NDArray[np.float64], s: NDArray[np.float64],
        d: NDArray[np.float64], rngs: list[np.random.Generator],
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """One frame of every env: rows ``[id, x, y, vx, vy, s, d]`` ``(envs, n, 7)`` and
        which rows are present ``(envs, n)`` (a read-only array, shared between frames,
        when the sensor has no dropouts)."""
        fusion = np.stack([ids, x, y, vx, vy, s, d], axis=-1).astype(np.float64)
        present = self._all_present[: len(ids)]
        if self._perfect:
            return fusion, present
        config = self.config
        n = ids.shape[1]
        present = present.copy()
        for env, rng in enumerate(rngs):
            row = fusion[env]
            if config.position_noise > 0:
                row[:, [1, 2, 5, 6]] += rng.normal(0.0, config.position_noise, (n, 4))
                row[:, 5] = np.mod(row[:, 5], self.loop_length)
            if config.velocity_noise > 0:
                row[:, [3, 4]] += rng.normal(0.0, config.velocity_noise, (n, 2))
            if config.zero_sd_probability > 0:
                left = self._zero_frames_left[env]
                in_zone = s[env] > self.loop_length - config.zero_sd_zone
                start = in_zone & (left == 0) & (rng.random(n) < config.zero_sd_probability)
                low, high = config.zero_sd_frames
                left[start] = rng.integers(low, high + 1, int(start.sum()))
                faulty = left > 0
                row[faulty, 5:7] = 0.0
                left[faulty] -= 1
            if config.dropout_probability > 0:
                present[env] = rng.random(n) >= config.dropout_probability
                row[~present[env]] = 0.0
        return fusion, present


def round_significant(values: NDArray[np.float64], digits: int = 7) -> NDArray[np.float64]:
    """Round to ``digits`` significant digits, like printing a number as ``%.7g`` text."""
    values = np.asarray(values, dtype=np.float64)
    magnitude = np.abs(values)
    exponent = np.floor(exact_math.log10(np.where(magnitude > 0, magnitude, 1.0)))
    scale = exact_math.power(10.0, digits - 1 - exponent)
    return np.round(values * scale) / scale


def telemetry_message(
    x: float, y: float, yaw: float, speed: float, s: float, d: float,
    previous_path: NDArray[np.float64], end_path_s: float, end_path_d: float,
    sensor_fusion: NDArray[np.float64], frenet: OriginalFrenet | None = None,
) -> dict[str, Any]:
    """The flat telemetry object of the original (yaw in rad and speed in m/s go in; the
    message carries degrees and mph). ``sensor_fusion`` holds the present rows only.

    ``frenet``: the map's :class:`~sdc_gym.geometry.original_frenet.OriginalFrenet` to
    report s, d, end_path_s/d and the fusion rows' s, d as the original does (from the
    positions; the s, d passed in are then unused), or ``None`` to send them as given.
    """
    if frenet is not None:
        s, d, end_path_s, end_path_d, sensor_fusion = original_frenet_fields(
            frenet, x, y, previous_path, sensor_fusion)
    scalars = np.array([x, y, np.degrees(yaw) % 360.0, speed * MPS_TO_MPH, s, d, end_path_s,
                        end_path_d])
    # One pass over every number of the message (it runs every env step): to 32 bits,
    # then to the 7 significant digits the original prints.
    flat = round_significant(np.concatenate([scalars, previous_path.T.ravel(),
                                             sensor_fusion.ravel()]).astype(np.float32))
    count = len(previous_path)
    ego = flat[:8].tolist()
    rows = flat[8 + 2 * count:].reshape(-1, 7).tolist()
    for row in rows:
        row[0] = int(row[0])
    return {
        "x": ego[0], "y": ego[1], "yaw": ego[2], "speed": ego[3], "s": ego[4], "d": ego[5],
        "previous_path_x": flat[8:8 + count].tolist(),
        "previous_path_y": flat[8 + count:8 + 2 * count].tolist(),
        "end_path_s": ego[6], "end_path_d": ego[7],
        "sensor_fusion": rows,
    }


class TelemetryMessage(Mapping[str, Any]):
    """The original's telemetry object, built on first access.

    Formatting a message costs about as much as a tenth of a physics step, and most steps
    (training, evaluation) nobody reads it, so the env stores the inputs and builds the
    dict lazily. It behaves as a read-only mapping; ``dict(message)`` (or
    :meth:`to_dict`) gives a plain dict, e.g. for ``json.dumps``; pickling (vector envs
    in subprocesses) sends the plain dict.
    """

    __slots__ = ("_arguments", "_message")

    def __init__(self, *arguments: Any) -> None:
        """Takes :func:`telemetry_message`'s arguments (arrays must not change later)."""
        self._arguments: tuple[Any, ...] | None = arguments
        self._message: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        if self._message is None:
            assert self._arguments is not None
            self._message = telemetry_message(*self._arguments)
            self._arguments = None
        return self._message

    def __getitem__(self, key: str) -> Any:
        return self.to_dict()[key]

    def __iter__(self) -> Iterator[str]:
        return iter(self.to_dict())

    def __len__(self) -> int:
        return len(self.to_dict())

    def __repr__(self) -> str:
        return f"TelemetryMessage({self.to_dict()!r})"

    def __reduce__(self) -> tuple[Any, ...]:
        return (dict, (self.to_dict(),))
