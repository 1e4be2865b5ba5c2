"""Train, evaluate and time the traffic light classifiers (red / yellow / other).

Usage::

    python -m sdc_agents.track.train_light_classifier --model cnn --seed 0 --steps 1600 \\
        --output agents/track/models/light_cnn.pt \\
        --original-capstone-dir ../shared/data/udacity/capstone

Training draws fresh frames every step from :class:`~sdc_agents.track.light_dataset.LightDataset`
on the built-in ``default`` track with the 200 x 150 camera (seeded by ``--seed``; nothing is
stored on disk): the whole frame for ``cnn``, the crop of the projected light for ``crop``
(40 % red, 20 % yellow, 40 % other: green, dark or no light; the crop mix has no "no
light" frames: the crop pipeline never runs the model then; the box
is jittered by up to :data:`CROP_BOX_JITTER` of its size so that small pose errors do not
matter). Whole frames are mirrored left-right with probability :data:`FLIP_PROBABILITY`.
Loss: cross-entropy on the three class logits; Adam with a cosine learning rate decay to
zero.

Afterwards the deployed pipeline (:class:`~sdc_agents.track.light_classifier.CNNLightSource` or
:class:`~sdc_agents.track.light_classifier.CropLightSource`, i.e. including the "no light in
view" rule of the crop path) is evaluated on frames of the held-out seeds
:data:`~sdc_agents.track.light_dataset.HELD_OUT_SEEDS` (full mix, no light included), optionally
also on the original simulator track (``wp_yaw_const.csv`` and its light config). Reported:
the red vs not-red accuracy (the issue's target), the 3-class accuracy, recall and
precision of red and yellow, the confusion matrix and the errors by sample kind; the
batch-1 latency is measured on one thread after a warm-up. The weights are written
atomically, and beside them a JSON file with the command, seed, accuracy and latency.

Determinism: the model initialization and the frames come from ``--seed``
(``torch.manual_seed``, one numpy Generator); results are reproducible for a fixed
``--threads`` (floating-point sums depend on the thread split).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import shlex
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from sdc_agents.track.light_classifier import (
    DEFAULT_CNN_PATH,
    DEFAULT_CROP_PATH,
    MODEL_KINDS,
    SAVED_FILE_MODE,
    CNNLightSource,
    CropLightSource,
    images_to_tensor,
    make_model,
    save_classifier,
)
from sdc_agents.track.light_dataset import (
    CLASS_NAMES,
    CLASS_RED,
    CLASS_YELLOW,
    CROP_OTHER_MIX,
    CROP_SIZE_PX,
    HELD_OUT_SEEDS,
    KIND_NAMES,
    SAMPLE_KINDS,
    DatasetConfig,
    LightBatch,
    LightDataset,
    crop_light,
)
from sdc_gym.road.builtin_tracks import get_track_map
from sdc_gym.road.track_map import TrackMap, load_track
from sdc_gym.sensors.track_camera import CameraConfig

DEFAULT_STEPS = {"cnn": 1600, "crop": 600}
DEFAULT_BATCH_SIZE = {"cnn": 64, "crop": 128}
DEFAULT_LEARNING_RATE = 3e-3
DEFAULT_EVAL_IMAGES_PER_SEED = 2000
# One thread: on a shared machine, two OpenMP threads spin against other jobs and made a
# crop-model step 30x slower (656 ms vs 20 ms measured under load).
DEFAULT_THREADS = 1
CROP_BOX_JITTER = 0.1  # each box side moves by up to this fraction of the box size
# The camera's scene is left-right symmetric (road and principal point centred), so a
# mirrored frame is a valid frame: mirroring doubles the rare lights at either image edge.
FLIP_PROBABILITY = 0.5
TIMING_WARMUP_RUNS = 50
TIMING_RUNS = 500
ORIGINAL_WAYPOINTS = "wp_yaw_const.csv"
ORIGINAL_LIGHT_CONFIG = "sim_traffic_light_config.yaml"
MAX_MODEL_BYTES = 1_000_000
_PROGRESS_UPDATE_STEPS = 10


# --- training --------------------------------------------------------------------------------


def jitter_bbox(bbox: NDArray[np.int64], rng: np.random.Generator, fraction: float,
                width: int, height: int) -> NDArray[np.int64]:
    """Move each side of a box (u_min, v_min, u_max, v_max) by up to ``fraction`` of the box
    size (uniform, rounded), keeping at least one pixel and staying in the image."""
    u_min, v_min, u_max, v_max = (int(value) for value in bbox)
    du, dv = fraction * (u_max - u_min), fraction * (v_max - v_min)
    shift = rng.uniform(-1.0, 1.0, size=4) * np.array([du, dv, du, dv])
    u0 = min(max(round(u_min + shift[0]), 0), width - 1)
    v0 = min(max(round(v_min + shift[1]), 0), height - 1)
    u1 = min(max(round(u_max + shift[2]), u0 + 1), width)
    v1 = min(max(round(v_max + shift[3]), v0 + 1), height)
    return np.array([u0, v0, u1, v1], dtype=np.int64)


def batch_crops(batch: LightBatch, rng: np.random.Generator | None = None,
                jitter: float = 0.0) -> NDArray[np.uint8]:
    """32 x 16 crops (N, 32, 16, 3) of each sample's light box (samples need a light)."""
    if np.any(batch.light_index < 0):
        raise ValueError("batch_crops: every sample needs a visible light (no NO_LIGHT kind)")
    height, width = batch.images.shape[1:3]
    crops = np.empty((len(batch.images), *CROP_SIZE_PX, 3), dtype=np.uint8)
    for row, (image, bbox) in enumerate(zip(batch.images, batch.bboxes, strict=True)):
        if rng is not None and jitter > 0:
            bbox = jitter_bbox(bbox, rng, jitter, width, height)
        crops[row] = crop_light(image, bbox, CROP_SIZE_PX)
    return crops


def training_tensors(kind: str, batch: LightBatch, rng: np.random.Generator | None = None
                     ) -> tuple[torch.Tensor, torch.Tensor]:
    """Model inputs and class targets (int64) of a batch for model ``kind``; with ``rng``,
    the training augmentation (mirrored frames, jittered crop boxes)."""
    if kind == "cnn":
        images = batch.images
        if rng is not None:
            flip = rng.random(len(images)) < FLIP_PROBABILITY
            images = images.copy()
            images[flip] = images[flip, :, ::-1]
        inputs = images_to_tensor(images)
    elif kind == "crop":
        inputs = images_to_tensor(batch_crops(batch, rng, CROP_BOX_JITTER if rng else 0.0))
    else:
        raise ValueError(f"model kind must be one of {MODEL_KINDS}, got {kind!r}")
    return inputs, torch.from_numpy(batch.labels.astype(np.int64))


def train_step(model: nn.Module, optimizer: torch.optim.Optimizer, inputs: torch.Tensor,
               targets: torch.Tensor) -> float:
    """One gradient step on cross-entropy (class targets); returns the loss before it."""
    model.train()
    optimizer.zero_grad(set_to_none=True)
    loss = nn.functional.cross_entropy(model(inputs), targets)
    loss.backward()
    optimizer.step()
    return float(loss.detach())


def dataset_config(kind: str) -> DatasetConfig:
    """The training mix: the full one for the CNN, lights only for the crop model."""
    return DatasetConfig() if kind == "cnn" else DatasetConfig(other_mix=CROP_OTHER_MIX)


@dataclass
class TrainResult:
    model: nn.Module
    losses: list[float] = field(default_factory=list)
    seconds: float = 0.0


def train(kind: str, *, seed: int, steps: int, batch_size: int,
          learning_rate: float = DEFAULT_LEARNING_RATE, track: TrackMap | None = None,
          camera_config: CameraConfig | None = None,
          on_step: Callable[[int, float], None] | None = None) -> TrainResult:
    """Train a fresh model of ``kind`` on frames drawn with ``seed``; ``on_step(step, loss)``
    is called after every step (progress display)."""
    if seed in HELD_OUT_SEEDS:
        raise ValueError(f"seed {seed} is a held-out evaluation seed {HELD_OUT_SEEDS}; "
                         f"train with another one")
    if steps < 1 or batch_size < 2:
        raise ValueError(f"need steps >= 1 and batch_size >= 2, got {steps}, {batch_size}")
    torch.manual_seed(seed)
    model = make_model(kind).to(memory_format=torch.channels_last)
    dataset = LightDataset(get_track_map("default") if track is None else track, camera_config,
                           seed=seed, config=dataset_config(kind))
    optimizer = torch.optim.Adam(model.parameters(), lr=learning_rate)
    schedule = torch.optim.lr_scheduler.LambdaLR(
        optimizer, lambda step: 0.5 * (1.0 + math.cos(math.pi * step / steps)))
    result = TrainResult(model)
    start = time.perf_counter()
    for step in range(steps):
        inputs, targets = training_tensors(kind, dataset.batch(batch_size), dataset.rng)
        result.losses.append(train_step(model, optimizer, inputs, targets))
        schedule.step()
        if on_step is not None:
            on_step(step, result.losses[-1])
    result.seconds = time.perf_counter() - start
    model.eval()
    return result


# --- evaluation --------------------------------------------------------------------------


@dataclass
class Evaluation:
    """How a pipeline classifies frames of some seeds.

    ``confusion[true class, predicted class]`` counts frames (classes in
    :data:`~sdc_agents.track.light_dataset.CLASS_NAMES` order); ``errors_by_kind`` counts
    3-class errors and ``red_errors_by_kind`` red vs not-red errors by sample kind.
    """

    confusion: NDArray[np.int64]
    errors_by_kind: dict[str, int]
    red_errors_by_kind: dict[str, int]
    images_by_kind: dict[str, int]

    @property
    def images(self) -> int:
        return int(self.confusion.sum())

    @property
    def accuracy(self) -> float:
        """3-class accuracy."""
        return float(np.trace(self.confusion)) / self.images if self.images else math.nan

    @property
    def red_accuracy(self) -> float:
        """Red vs not-red accuracy (the issue's target)."""
        c = self.confusion
        red_correct = c[CLASS_RED, CLASS_RED] + np.delete(np.delete(c, CLASS_RED, 0),
                                                          CLASS_RED, 1).sum()
        return float(red_correct) / self.images if self.images else math.nan

    def recall(self, label: int) -> float:
        """Of the frames of class ``label``, the fraction predicted as ``label``."""
        total = self.confusion[label].sum()
        return float(self.confusion[label, label] / total) if total else math.nan

    def precision(self, label: int) -> float:
        """Of the frames predicted as ``label``, the fraction that are ``label``."""
        total = self.confusion[:, label].sum()
        return float(self.confusion[label, label] / total) if total else math.nan

    def as_dict(self) -> dict[str, Any]:
        return {"images": self.images,
                "red_vs_not_red_accuracy": round(self.red_accuracy, 5),
                "three_class_accuracy": round(self.accuracy, 5),
                "red_recall": round(self.recall(CLASS_RED), 5),
                "red_precision": round(self.precision(CLASS_RED), 5),
                "yellow_recall": round(self.recall(CLASS_YELLOW), 5),
                "yellow_precision": round(self.precision(CLASS_YELLOW), 5),
                "confusion_true_by_predicted": {
                    name: dict(zip(CLASS_NAMES, row.tolist(), strict=True))
                    for name, row in zip(CLASS_NAMES, self.confusion, strict=True)},
                "errors_by_kind": self.errors_by_kind,
                "red_errors_by_kind": self.red_errors_by_kind,
                "images_by_kind": self.images_by_kind}

    def summary_line(self) -> str:
        return (f"red vs not-red {self.red_accuracy:.4%}, 3-class {self.accuracy:.4%}, "
                f"yellow recall {self.recall(CLASS_YELLOW):.4%} precision "
                f"{self.precision(CLASS_YELLOW):.4%} on {self.images} frames; 3-class errors "
                f"{self.errors_by_kind}")


def source_for(kind: str, model: nn.Module, track: TrackMap,
               camera_config: CameraConfig | None = None) -> CNNLightSource | CropLightSource:
    """The deployed pipeline around a model."""
    if kind == "cnn":
        return CNNLightSource(model=model)  # type: ignore[arg-type]
    return CropLightSource(track, camera_config, model=model)  # type: ignore[arg-type]


def predict_batch(source: CNNLightSource | CropLightSource, batch: LightBatch
                  ) -> NDArray[np.int64]:
    """The source's class predictions for a batch."""
    if isinstance(source, CNNLightSource):
        return source.predict_classes_batch(batch.images)
    return source.predict_classes_batch(batch.images, batch.poses)


def evaluate(source: CNNLightSource | CropLightSource, track: TrackMap,
             seeds: Sequence[int] = HELD_OUT_SEEDS,
             images_per_seed: int = DEFAULT_EVAL_IMAGES_PER_SEED,
             camera_config: CameraConfig | None = None, chunk: int = 250) -> Evaluation:
    """How ``source`` classifies ``images_per_seed`` frames (full mix) of each seed."""
    confusion = np.zeros((len(CLASS_NAMES), len(CLASS_NAMES)), dtype=np.int64)
    errors = dict.fromkeys(KIND_NAMES.values(), 0)
    red_errors = dict.fromkeys(KIND_NAMES.values(), 0)
    totals = dict.fromkeys(KIND_NAMES.values(), 0)
    for seed in seeds:
        dataset = LightDataset(track, camera_config, seed=seed)
        left = images_per_seed
        while left > 0:
            batch = dataset.batch(min(chunk, left))
            left -= len(batch.images)
            predicted = predict_batch(source, batch)
            np.add.at(confusion, (batch.labels, predicted), 1)
            wrong = predicted != batch.labels
            red_wrong = (predicted == CLASS_RED) != batch.is_red
            for kind in SAMPLE_KINDS:
                mask = batch.kinds == kind
                name = KIND_NAMES[kind]
                totals[name] += int(np.sum(mask))
                errors[name] += int(np.sum(wrong & mask))
                red_errors[name] += int(np.sum(red_wrong & mask))
    return Evaluation(confusion, errors, red_errors, totals)


def inference_ms(source: CNNLightSource | CropLightSource, batch: LightBatch,
                 warmup: int = TIMING_WARMUP_RUNS, runs: int = TIMING_RUNS) -> dict[str, float]:
    """Batch-1 latency of ``classify_image`` (conversion, crop and projection included), ms, on
    one torch thread (restored afterwards): median and 90th percentile over ``runs``."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        frames = [(batch.images[i], *(float(v) for v in batch.poses[i]))
                  for i in range(len(batch.images))]
        times = []
        for run in range(warmup + runs):
            image, x, y, yaw = frames[run % len(frames)]
            start = time.perf_counter()
            source.classify_image(image, x, y, yaw)
            if run >= warmup:
                times.append(time.perf_counter() - start)
    finally:
        torch.set_num_threads(threads)
    milliseconds = np.array(times) * 1e3
    return {"median": round(float(np.median(milliseconds)), 4),
            "p90": round(float(np.percentile(milliseconds, 90)), 4)}


# --- command line ------------------------------------------------------------------------


def _write_json(path: Path, data: dict[str, Any]) -> None:
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "w", encoding="utf-8") as stream:
            json.dump(data, stream, indent=2)
            stream.write("\n")
        os.chmod(temporary, SAVED_FILE_MODE)
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def _mix_record(config: DatasetConfig) -> dict[str, Any]:
    """The class fractions and the kinds of the other class, by name (for the JSON)."""
    red, yellow, other = config.class_fractions
    return {"red": red, "yellow": yellow, "other": round(other, 6),
            "other_kinds": {KIND_NAMES[kind]: weight for kind, weight in config.other_mix}}


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m sdc_agents.track.train_light_classifier",
        description="Train a red / yellow / other traffic light classifier on generated "
                    "frames.")
    parser.add_argument("--model", choices=MODEL_KINDS, required=True,
                        help="cnn: whole 200x150 frame; crop: projected light box")
    parser.add_argument("--seed", type=int, default=0, help="training seed (not one of "
                        f"the held-out seeds {list(HELD_OUT_SEEDS)})")
    parser.add_argument("--steps", type=int, default=None,
                        help=f"gradient steps (default {DEFAULT_STEPS})")
    parser.add_argument("--batch-size", type=int, default=None,
                        help=f"frames per step (default {DEFAULT_BATCH_SIZE})")
    parser.add_argument("--lr", type=float, default=DEFAULT_LEARNING_RATE,
                        help="Adam learning rate at the start of the cosine decay")
    parser.add_argument("--threads", type=int, default=DEFAULT_THREADS,
                        help="torch threads for training")
    parser.add_argument("--eval-images", type=int, default=DEFAULT_EVAL_IMAGES_PER_SEED,
                        help="held-out frames per evaluation seed")
    parser.add_argument("--original-capstone-dir", type=Path, default=None,
                        help=f"also evaluate on the original track ({ORIGINAL_WAYPOINTS} and "
                        f"{ORIGINAL_LIGHT_CONFIG} in this folder)")
    parser.add_argument("--output", type=Path, default=None,
                        help=f"weights file (default {DEFAULT_CNN_PATH.name} or "
                        f"{DEFAULT_CROP_PATH.name} in {DEFAULT_CNN_PATH.parent}); the "
                        "metadata goes beside it with the suffix .json")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = _parser()
    args = parser.parse_args(argv)
    if args.seed in HELD_OUT_SEEDS:
        parser.error(f"--seed {args.seed} is a held-out evaluation seed "
                     f"{list(HELD_OUT_SEEDS)}; train with another one")
    if args.eval_images < 1:
        parser.error(f"--eval-images must be >= 1, got {args.eval_images}")
    kind: str = args.model
    steps = DEFAULT_STEPS[kind] if args.steps is None else args.steps
    batch_size = DEFAULT_BATCH_SIZE[kind] if args.batch_size is None else args.batch_size
    output: Path = args.output or (DEFAULT_CNN_PATH if kind == "cnn" else DEFAULT_CROP_PATH)
    original = None
    if args.original_capstone_dir is not None:
        folder = args.original_capstone_dir
        original = load_track(folder / ORIGINAL_WAYPOINTS, folder / ORIGINAL_LIGHT_CONFIG,
                              name="original sim")
    torch.set_num_threads(args.threads)

    from rich.progress import BarColumn, Progress, TextColumn, TimeRemainingColumn

    track = get_track_map("default")
    with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[info]}"),
                  TimeRemainingColumn(), disable=args.no_progress) as progress:
        task = progress.add_task(f"train {kind}", total=steps, info="")
        recent: list[float] = []

        def on_step(step: int, loss: float) -> None:
            recent.append(loss)
            if (step + 1) % _PROGRESS_UPDATE_STEPS == 0 or step + 1 == steps:
                progress.update(task, completed=step + 1,
                                info=f"loss {np.mean(recent):.4f}")
                recent.clear()

        result = train(kind, seed=args.seed, steps=steps, batch_size=batch_size,
                       learning_rate=args.lr, track=track, on_step=on_step)
    source = source_for(kind, result.model, track)
    held_out = evaluate(source, track, images_per_seed=args.eval_images)
    print(f"held-out seeds {list(HELD_OUT_SEEDS)}: {held_out.summary_line()}")
    original_eval = None
    if original is not None:
        original_eval = evaluate(source_for(kind, result.model, original), original,
                                 images_per_seed=args.eval_images)
        print(f"original track: {original_eval.summary_line()}")
    timing = inference_ms(source, LightDataset(track, seed=HELD_OUT_SEEDS[0]).batch(100))
    print(f"inference (batch 1, 1 thread): median {timing['median']:.3f} ms, "
          f"p90 {timing['p90']:.3f} ms; training {result.seconds:.0f} s")

    save_classifier(output, result.model)
    size = output.stat().st_size
    if size > MAX_MODEL_BYTES:
        print(f"warning: {output} is {size} bytes, over the {MAX_MODEL_BYTES} byte budget")
    metadata = {
        "model": kind,
        "weights": output.name,
        "classes": list(CLASS_NAMES),
        "class_states": "red -> RED 0, yellow -> YELLOW 1, other -> UNKNOWN 4",
        "command": "python -m sdc_agents.track.train_light_classifier " + shlex.join(argv),
        "seed": args.seed,
        "steps": steps,
        "batch_size": batch_size,
        "learning_rate": args.lr,
        "torch_threads": args.threads,
        "training_mix": _mix_record(dataset_config(kind)),
        "training_seconds": round(result.seconds, 1),
        "final_loss_mean_last_50": round(float(np.mean(result.losses[-50:])), 5),
        "parameters": sum(p.numel() for p in result.model.parameters()),
        "weights_bytes": size,
        "camera": "CameraConfig.training() 200x150",
        "held_out": {"track": "default", "seeds": list(HELD_OUT_SEEDS),
                     **held_out.as_dict()},
        "original_track": None if original_eval is None else {
            "track": f"{ORIGINAL_WAYPOINTS} + {ORIGINAL_LIGHT_CONFIG}",
            "seeds": list(HELD_OUT_SEEDS), **original_eval.as_dict()},
        "inference_ms_batch1_1thread": timing,
        "machine": {"cpus": os.cpu_count(), "processor": platform.processor() or None,
                    "torch": torch.__version__},
    }
    _write_json(output.with_suffix(".json"), metadata)
    print(f"wrote {output} ({size} bytes) and {output.with_suffix('.json').name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
