"""Camera frames per wall second: the track camera at 800 x 600 and at 200 x 150.

    python benchmarks/bench_camera.py [--frames 500] [--repeats 3]

Each run renders ``--frames`` frames of a car driving up to two traffic lights (one over
the road, one to its right, 5 m high, red and green), from 140 m to 25 m before the first,
so the lights grow from a few pixels to hundreds; brightness jitter and sensor noise on
(the defaults) and, for comparison, off. The best of ``--repeats`` runs is reported, with
the number of lights drawn per frame on average.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time

import numpy as np

from sdc_gym.lights import GREEN, RED
from sdc_gym.sensors.track_camera import LIGHT_CENTER_HEIGHT_M, CameraConfig, TrackCamera

LIGHT_POSITIONS = np.array([[165.0, 0.0, LIGHT_CENTER_HEIGHT_M],
                            [172.0, -4.0, LIGHT_CENTER_HEIGHT_M]])  # m; the car drives +x
LIGHT_YAWS = np.array([math.pi, math.pi])  # facing the oncoming car
LIGHT_STATES = np.array([RED, GREEN], dtype=np.int8)
START_X_M, END_X_M = 165.0 - 140.0, 165.0 - 25.0


def time_camera(config: CameraConfig, frames: int, seed: int) -> tuple[float, float]:
    """Frames per second and mean lights drawn per frame for one run."""
    camera = TrackCamera(config)
    rng = np.random.default_rng(seed)
    car_x = np.linspace(START_X_M, END_X_M, frames)
    drawn = 0
    started = time.perf_counter()
    for x in car_x:
        _, labels = camera.render_with_labels(float(x), 0.0, 0.0, LIGHT_POSITIONS, LIGHT_YAWS,
                                              LIGHT_STATES, rng)
        drawn += len(labels)
    wall = time.perf_counter() - started
    return frames / wall, drawn / frames


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--frames", type=int, default=500, help="frames per run")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    presets = (("full", CameraConfig()), ("training", CameraConfig.training()))
    print(f"{'camera':10} {'size':>9} {'variation':>9} {'lights/frame':>12} {'frames/s':>9}")
    for name, preset in presets:
        for variation in (True, False):
            config = dataclasses.replace(preset, variation=variation)
            runs = [time_camera(config, args.frames, seed) for seed in range(args.repeats)]
            rate = max(run[0] for run in runs)
            size = f"{config.width}x{config.height}"
            print(f"{name:10} {size:>9} {'on' if variation else 'off':>9} "
                  f"{runs[0][1]:>12.2f} {rate:>9.0f}")


if __name__ == "__main__":
    main()
