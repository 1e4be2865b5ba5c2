"""Traffic light classifiers (red / yellow / other): a whole-image CNN and a crop classifier.

The detector of the drive-by-wire stack needs to know whether the light ahead is red, and
whether it is yellow: the behavior layer stops for a yellow light when it can stop
comfortably, which is what keeps it from meeting a red inside its braking distance. So the
classifiers have three classes (:data:`~sdc_agents.track.light_dataset.CLASS_NAMES`): red,
yellow and *other* (green, all lamps dark, no light in view; all mean "drive on"). Two
approaches of the seed team, both trained by :mod:`sdc_agents.track.train_light_classifier`
on frames of :mod:`sdc_agents.track.light_dataset`:

Whole-image CNN (:class:`WholeImageCNN`, :class:`CNNLightSource`)
    Input: the 200 x 150 camera frame (the ``training`` camera preset). Four 3 x 3 stride-2
    convolutions (3 -> 8 -> 16 -> 32 -> 32 channels, ReLU; 150 x 200 -> 10 x 13 cells), a
    global max pool and a linear layer to three class logits. The stride-2 3 x 3 first layer still
    sees every pixel, which matters: 100 m before the stop line the lit lamp is about 1.3 px
    in radius. The global max pool answers "is there a red lamp anywhere", independent of
    where the light is in the frame (and, from the lamp's colour and its place in the
    housing, which lamp). 15,379 parameters (a 65 kB file); batch-1 inference about 0.5 ms
    on one core with the uint8 -> tensor conversion (channels-last,
    ``torch.inference_mode``; measured on the 2-core dev machine; the JSON beside the
    weights has the figure of the committed model).

Crop classifier (:class:`CropCNN`, :class:`CropLightSource`)
    The light's 3-D position is known from the track map and the car's pose from the
    observation, so the pinhole model gives the housing's pixel bounding box
    (:func:`~sdc_gym.sensors.track_camera.light_bounding_box`). The box is resampled to
    32 x 16 px (:func:`~sdc_agents.track.light_dataset.crop_light`) and classified by a tiny
    CNN (two 3 x 3 conv + 2 x 2 max pool stages, one more conv, global max pool, linear).
    No light in view (none projects into the image facing the camera) means *other*
    without running the model. Works at any camera resolution, since the crop is resized.
    3,763 parameters (18 kB); about 0.3 ms per frame, projection included.

Both sources are :class:`~sdc_gym.stack.track.detector.LightStateSource` objects:
``classify(observation) -> int`` on the env's observation dict (``camera``; the crop source
also ``pose`` and ``next_stop_line``), returning the state code RED (0), YELLOW (1) or
UNKNOWN (4) for *other*: green is not told apart from dark or absent lights, since the
behavior layer treats GREEN and UNKNOWN alike (drive on) and a class it does not need
would only cost accuracy on the ones it does. The predicted class is the arg max of the
logits. Without an observation dict: ``classify_image(image, car_x, car_y, car_yaw) ->
int`` and ``predict_red(image, car_x, car_y, car_yaw) -> bool`` (the CNN ignores the
pose); batches: ``predict_states_batch`` (state codes) and ``predict_red_batch``.
Images are (H, W, 3) uint8 RGB, poses the car reference point x, y (m) and yaw (rad, CCW
from +x), exactly as in the env's observation.

Weights are saved with :func:`save_classifier` as a dict (format version, model kind,
architecture arguments, class names, state dict) and loaded with ``torch.load(weights_only=True)``.
``model_path=None`` loads the committed defaults in ``agents/track/models/`` (see the JSON
beside each file for its training command, seed and held-out accuracy).

Threads: torch's thread count is global state; the sources do not change it. Batch-1
latency figures are for ``torch.set_num_threads(1)``.
"""

from __future__ import annotations

import math
import os
import tempfile
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray
from torch import nn

from sdc_agents.track.light_dataset import (
    CLASS_NAMES,
    CLASS_OTHER,
    CLASS_RED,
    CLASS_STATES,
    CROP_SIZE_PX,
    crop_light,
)
from sdc_gym.geometry import exact_math
from sdc_gym.road.track_map import TrackMap
from sdc_gym.sensors.track_camera import CameraConfig, camera_position, light_bounding_box

MODELS_DIR = Path(__file__).resolve().parent / "models"
DEFAULT_CNN_PATH = MODELS_DIR / "light_cnn.pt"
DEFAULT_CROP_PATH = MODELS_DIR / "light_crop.pt"
MODEL_KINDS = ("cnn", "crop")
FORMAT_VERSION = 2  # 2: three classes (red, yellow, other); 1 was red vs not red
SAVED_FILE_MODE = 0o644  # weights are committed files: readable by all

TRAINING_IMAGE_SHAPE = (150, 200, 3)  # rows, columns, RGB: CameraConfig.training()
CNN_CHANNELS = (8, 16, 32, 32)
CROP_CHANNELS = (8, 16, 16)
_PIXEL_SCALE = 1.0 / 255.0
_PIXEL_CENTRE = 0.5  # inputs are centred on mid-grey inside the models
NUM_CLASSES = len(CLASS_NAMES)
_CLASS_STATES = np.array(CLASS_STATES, dtype=np.int64)  # class index -> light state code


class WholeImageCNN(nn.Module):
    """Whole frame (N, 3, H, W) in [0, 1] -> class logits (N, 3). See the module docstring."""

    def __init__(self, channels: tuple[int, ...] = CNN_CHANNELS) -> None:
        super().__init__()
        layers: list[nn.Module] = []
        previous = 3
        for width in channels:
            layers += [nn.Conv2d(previous, width, kernel_size=3, stride=2, padding=1),
                       nn.ReLU(inplace=True)]
            previous = width
        self.features = nn.Sequential(*layers)
        self.head = nn.Linear(previous, NUM_CLASSES)
        self.channels = tuple(channels)

    def forward(self, images: torch.Tensor) -> torch.Tensor:
        features = self.features(images - _PIXEL_CENTRE)
        return self.head(torch.amax(features, dim=(2, 3)))


class CropCNN(nn.Module):
    """Light crop (N, 3, 32, 16) in [0, 1] -> class logits (N, 3). See the module docstring."""

    def __init__(self, channels: tuple[int, ...] = CROP_CHANNELS) -> None:
        super().__init__()
        first, second, third = channels
        self.features = nn.Sequential(
            nn.Conv2d(3, first, kernel_size=3, padding=1), nn.ReLU(inplace=True),
            nn.MaxPool2d(2),
            nn.Conv2d(first, second, kernel_size=3, padding=1), nn.ReLU(inplace=True),
            nn.MaxPool2d(2),
            nn.Conv2d(second, third, kernel_size=3, padding=1), nn.ReLU(inplace=True),
        )
        self.head = nn.Linear(third, NUM_CLASSES)
        self.channels = tuple(channels)

    def forward(self, crops: torch.Tensor) -> torch.Tensor:
        features = self.features(crops - _PIXEL_CENTRE)
        return self.head(torch.amax(features, dim=(2, 3)))


def make_model(kind: str) -> nn.Module:
    """A freshly initialized model of ``kind`` ("cnn" or "crop"; torch's global seed)."""
    if kind == "cnn":
        return WholeImageCNN()
    if kind == "crop":
        return CropCNN()
    raise ValueError(f"model kind must be one of {MODEL_KINDS}, got {kind!r}")


def images_to_tensor(images: NDArray[np.uint8]) -> torch.Tensor:
    """uint8 images (N, H, W, 3) or one (H, W, 3) -> float (N, 3, H, W) in [0, 1],
    channels-last in memory (faster convolutions on CPU, no copy of the pixel layout)."""
    array = np.asarray(images)
    if array.dtype != np.uint8 or array.ndim not in (3, 4) or array.shape[-1] != 3:
        raise ValueError(f"images must be uint8 (H, W, 3) or (N, H, W, 3), got "
                         f"{array.dtype} {array.shape}")
    if array.ndim == 3:
        array = array[None]
    tensor = torch.from_numpy(np.ascontiguousarray(array)).permute(0, 3, 1, 2)
    return tensor.float().mul_(_PIXEL_SCALE)


def save_classifier(path: str | os.PathLike[str], model: nn.Module) -> None:
    """Write the model atomically (a temporary file in the same folder, then a rename)."""
    kind = "cnn" if isinstance(model, WholeImageCNN) else "crop" if isinstance(
        model, CropCNN) else None
    if kind is None:
        raise TypeError(f"save_classifier: expected WholeImageCNN or CropCNN, got "
                        f"{type(model).__name__}")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = {"format": FORMAT_VERSION, "kind": kind, "channels": list(model.channels),
               "classes": list(CLASS_NAMES),
               "state_dict": {name: value.detach().cpu().contiguous()
                              for name, value in model.state_dict().items()}}
    handle, temporary = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(handle, "wb") as stream:
            torch.save(payload, stream)
        os.chmod(temporary, SAVED_FILE_MODE)  # mkstemp makes it owner-only
        os.replace(temporary, path)
    except BaseException:
        Path(temporary).unlink(missing_ok=True)
        raise


def load_classifier(path: str | os.PathLike[str], kind: str | None = None) -> nn.Module:
    """Load a model saved by :func:`save_classifier`, in eval mode; ``kind`` checks it."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"light classifier weights not found: {path} (train them with "
                                f"python -m sdc_agents.track.train_light_classifier)")
    payload: Any = torch.load(path, map_location="cpu", weights_only=True)
    if not isinstance(payload, Mapping) or payload.get("format") != FORMAT_VERSION:
        found = payload.get("format") if isinstance(payload, Mapping) else None
        raise ValueError(f"{path}: not a light classifier file of format {FORMAT_VERSION} "
                         f"(found format {found!r}; retrain with python -m "
                         f"sdc_agents.track.train_light_classifier)")
    if list(payload.get("classes", ())) != list(CLASS_NAMES):
        raise ValueError(f"{path}: classes {payload.get('classes')!r}, expected "
                         f"{list(CLASS_NAMES)}")
    stored = payload.get("kind")
    if stored not in MODEL_KINDS:
        raise ValueError(f"{path}: model kind must be one of {MODEL_KINDS}, got {stored!r}")
    if kind is not None and stored != kind:
        raise ValueError(f"{path}: holds a {stored!r} model, expected {kind!r}")
    channels = tuple(int(width) for width in payload["channels"])
    model = WholeImageCNN(channels) if stored == "cnn" else CropCNN(channels)
    model.load_state_dict(payload["state_dict"])
    return model.eval()


def classes_to_states(classes: NDArray[np.int64]) -> NDArray[np.int64]:
    """Class indices (CLASS_RED, CLASS_YELLOW, CLASS_OTHER) -> state codes (RED, YELLOW,
    UNKNOWN)."""
    return _CLASS_STATES[np.asarray(classes, dtype=np.int64)]


def _source_model(owner: str, model: nn.Module | None,
                  model_path: str | os.PathLike[str] | None, default: Path,
                  kind: str) -> nn.Module:
    """The source's model, ready for inference: ``model`` as given, or loaded from
    ``model_path`` (``default`` when None); giving both is an error naming ``owner``."""
    if model is None:
        model = load_classifier(default if model_path is None else model_path, kind)
    elif model_path is not None:
        raise ValueError(f"{owner}: give model_path or model, not both")
    return _prepare(model)


def _prepare(model: nn.Module) -> nn.Module:
    model.eval()
    for parameter in model.parameters():
        parameter.requires_grad_(False)
    return model.to(memory_format=torch.channels_last)


class CNNLightSource:
    """Red / yellow / other from the whole camera frame (200 x 150) with :class:`WholeImageCNN`.

    A :class:`~sdc_gym.stack.track.detector.LightStateSource`: :meth:`classify` takes the env
    observation (its ``camera`` image); :meth:`classify_image` takes the frame alone.

    Args:
        model_path: weights file; None loads :data:`DEFAULT_CNN_PATH`.
        model: an in-memory model instead of a file (training, tests).
    """

    def __init__(self, model_path: str | os.PathLike[str] | None = None, *,
                 model: WholeImageCNN | None = None) -> None:
        self.model = _source_model("CNNLightSource", model, model_path, DEFAULT_CNN_PATH,
                                   "cnn")

    def logits(self, images: NDArray[np.uint8]) -> NDArray[np.float32]:
        """Class logits (N, 3) for frames (N, 150, 200, 3) (or one frame -> shape (1, 3))."""
        array = np.asarray(images)
        if array.shape[-3:] != TRAINING_IMAGE_SHAPE:
            raise ValueError(f"CNNLightSource: frames must be {TRAINING_IMAGE_SHAPE} (the "
                             f"camera preset 'training'), got {array.shape}")
        with torch.inference_mode():
            return self.model(images_to_tensor(array)).numpy()

    def predict_classes_batch(self, images: NDArray[np.uint8]) -> NDArray[np.int64]:
        """Class index (CLASS_RED, CLASS_YELLOW, CLASS_OTHER) of each frame."""
        return np.argmax(self.logits(images), axis=1)

    def predict_states_batch(self, images: NDArray[np.uint8]) -> NDArray[np.int64]:
        """State code (RED, YELLOW, UNKNOWN) of each frame (N, 150, 200, 3)."""
        return classes_to_states(self.predict_classes_batch(images))

    def predict_red_batch(self, images: NDArray[np.uint8]) -> NDArray[np.bool_]:
        """Whether each frame (N, 150, 200, 3) shows a red light."""
        return self.predict_classes_batch(images) == CLASS_RED

    def predict_red(self, image: NDArray[np.uint8], car_x: float | None = None,
                    car_y: float | None = None, car_yaw: float | None = None) -> bool:
        """Whether the frame (150, 200, 3) shows a red light (the pose is not needed)."""
        return bool(self.predict_classes_batch(image)[0] == CLASS_RED)

    def classify_image(self, image: NDArray[np.uint8], car_x: float | None = None,
                       car_y: float | None = None, car_yaw: float | None = None) -> int:
        """RED (0), YELLOW (1) or UNKNOWN (4, other) for one frame (the pose is not
        needed)."""
        return int(self.predict_states_batch(image)[0])

    def classify(self, observation: Mapping[str, Any]) -> int:
        """RED, YELLOW or UNKNOWN for the env observation's ``camera`` image."""
        return self.classify_image(_observation_image(observation))


class CropLightSource:
    """Red / yellow / other from the crop of a light, its box projected from the track map.

    A :class:`~sdc_gym.stack.track.detector.LightStateSource`: :meth:`classify` takes the env
    observation (``camera``, ``pose`` and, if present, ``next_stop_line``, whose index is
    the light to look at: light ``i`` belongs to stop line ``i``); :meth:`classify_image`
    takes the frame and the pose.

    Args:
        track: the track map (light positions and facing directions).
        camera_config: the camera that took the frames (default: the 200 x 150 preset);
            the projection must match it.
        model_path: weights file; None loads :data:`DEFAULT_CROP_PATH`.
        model: an in-memory model instead of a file (training, tests).
    """

    def __init__(self, track: TrackMap, camera_config: CameraConfig | None = None,
                 model_path: str | os.PathLike[str] | None = None, *,
                 model: CropCNN | None = None) -> None:
        self.model = _source_model("CropLightSource", model, model_path, DEFAULT_CROP_PATH,
                                   "crop")
        self.track = track
        self.camera_config = CameraConfig.training() if camera_config is None else camera_config
        self._positions = np.asarray(track.light_positions, dtype=np.float64)
        self._facing = np.column_stack([exact_math.cos(track.light_yaw),
                                        exact_math.sin(track.light_yaw)])

    def visible_light(self, car_x: float, car_y: float, car_yaw: float,
                      light_index: int | None = None
                      ) -> tuple[int, tuple[int, int, int, int]] | None:
        """The light to classify and its pixel bbox ``(u_min, v_min, u_max, v_max)``, or
        None when it does not show its lamps in the image.

        ``light_index`` given: that light, if its lamps face the camera and its housing
        projects into the image. None: the nearest such light ahead.
        """
        config = self.camera_config
        if light_index is not None and not 0 <= light_index < len(self._positions):
            raise ValueError(f"light_index must be in [0, {len(self._positions)}) for track "
                             f"{self.track.name!r}, got {light_index}")
        camera = camera_position(car_x, car_y, car_yaw, config)[:2]
        to_light = self._positions[:, :2] - camera
        # Elementwise products, not `@` or einsum: BLAS's rounding depends on the processor.
        ahead = to_light[:, 0] * math.cos(car_yaw) + to_light[:, 1] * math.sin(car_yaw)
        faces_camera = (self._facing[:, 0] * -to_light[:, 0]
                        + self._facing[:, 1] * -to_light[:, 1]) > 0
        in_range = np.hypot(to_light[:, 0], to_light[:, 1]) <= config.max_range_m
        wanted = faces_camera & in_range & (ahead > 0)
        if light_index is not None:
            wanted &= np.arange(len(wanted)) == light_index
        candidates = np.flatnonzero(wanted)
        # Nearest first: the renderer draws it last, on top of any farther light.
        for light in candidates[np.argsort(ahead[candidates], kind="stable")]:
            bbox = light_bounding_box(self._positions[light], float(self.track.light_yaw[light]),
                                      car_x, car_y, car_yaw, config)
            if bbox is not None and bbox[0] < bbox[2] and bbox[1] < bbox[3]:
                return int(light), bbox
        return None

    def crop(self, image: NDArray[np.uint8], car_x: float, car_y: float, car_yaw: float,
             light_index: int | None = None) -> NDArray[np.uint8] | None:
        """The 32 x 16 crop of the light (see :meth:`visible_light`), or None."""
        config = self.camera_config
        if np.shape(image) != (config.height, config.width, 3):
            raise ValueError(f"CropLightSource: frame shape {np.shape(image)} does not match "
                             f"the camera config ({config.height}, {config.width}, 3)")
        found = self.visible_light(car_x, car_y, car_yaw, light_index)
        return None if found is None else crop_light(image, found[1], CROP_SIZE_PX)

    def logits_of_crops(self, crops: NDArray[np.uint8]) -> NDArray[np.float32]:
        """Class logits (N, 3) for crops (N, 32, 16, 3) (or one crop -> (1, 3))."""
        array = np.asarray(crops)
        if array.shape[-3:] != (*CROP_SIZE_PX, 3):
            raise ValueError(f"CropLightSource: crops must be {(*CROP_SIZE_PX, 3)}, got "
                             f"{array.shape}")
        with torch.inference_mode():
            return self.model(images_to_tensor(array)).numpy()

    def predict_classes_batch(self, images: NDArray[np.uint8], poses: NDArray[np.float64]
                              ) -> NDArray[np.int64]:
        """Class index of each frame (N, H, W, 3) taken from pose (N, 3) (x, y, yaw): the
        nearest light ahead's; no light in view: CLASS_OTHER."""
        crops = [self.crop(image, *(float(value) for value in pose))
                 for image, pose in zip(images, poses, strict=True)]
        classes = np.full(len(crops), CLASS_OTHER, dtype=np.int64)
        seen = [row for row, crop in enumerate(crops) if crop is not None]
        if seen:
            logits = self.logits_of_crops(np.stack([crops[row] for row in seen]))
            classes[seen] = np.argmax(logits, axis=1)
        return classes

    def predict_states_batch(self, images: NDArray[np.uint8], poses: NDArray[np.float64]
                             ) -> NDArray[np.int64]:
        """State code (RED, YELLOW, UNKNOWN) of each frame; see
        :meth:`predict_classes_batch`."""
        return classes_to_states(self.predict_classes_batch(images, poses))

    def predict_red_batch(self, images: NDArray[np.uint8], poses: NDArray[np.float64]
                          ) -> NDArray[np.bool_]:
        """Whether each frame (N, H, W, 3) taken from pose (N, 3) shows red."""
        return self.predict_classes_batch(images, poses) == CLASS_RED

    def predict_class(self, image: NDArray[np.uint8], car_x: float, car_y: float,
                      car_yaw: float, light_index: int | None = None) -> int:
        """Class index of the light (see :meth:`visible_light`) in this frame (not in view:
        CLASS_OTHER)."""
        crop = self.crop(image, car_x, car_y, car_yaw, light_index)
        return CLASS_OTHER if crop is None else int(np.argmax(self.logits_of_crops(crop)[0]))

    def predict_red(self, image: NDArray[np.uint8], car_x: float, car_y: float,
                    car_yaw: float, light_index: int | None = None) -> bool:
        """Whether the light (see :meth:`visible_light`) is red in this frame (not in view:
        False)."""
        return self.predict_class(image, car_x, car_y, car_yaw, light_index) == CLASS_RED

    def classify_image(self, image: NDArray[np.uint8], car_x: float, car_y: float,
                       car_yaw: float, light_index: int | None = None) -> int:
        """RED (0), YELLOW (1) or UNKNOWN (4, other) for one frame and the car pose it was
        taken from."""
        return CLASS_STATES[self.predict_class(image, car_x, car_y, car_yaw, light_index)]

    def classify(self, observation: Mapping[str, Any]) -> int:
        """RED, YELLOW or UNKNOWN from the env observation: ``camera``, ``pose`` (x, y,
        yaw) and the light of ``next_stop_line`` (its index; the nearest light ahead when
        absent or -1)."""
        pose = observation.get("pose")
        if pose is None or np.shape(pose) != (3,):
            raise ValueError("CropLightSource: the observation needs 'pose' (x, y, yaw), got "
                             f"{pose!r}")
        x, y, yaw = (float(value) for value in pose)
        line = observation.get("next_stop_line")
        light = None if line is None or float(line[0]) < 0 else round(float(line[0]))
        return self.classify_image(_observation_image(observation), x, y, yaw, light)


def _observation_image(observation: Mapping[str, Any]) -> NDArray[np.uint8]:
    image = observation.get("camera")
    if image is None:
        raise ValueError("the observation has no 'camera' image: make the env with "
                         "config camera.enabled = True (preset 'training')")
    return np.asarray(image)
