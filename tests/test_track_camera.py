"""The track camera: pinhole projection, light bounding boxes, rendering and its variation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sdc_gym.config import ConfigError
from sdc_gym.lights import GREEN, RED, UNKNOWN, YELLOW
from sdc_gym.sensors.track_camera import (
    HOUSING_RGB,
    LAMP_OFF_RGB,
    LAMP_ON_RGB,
    LAMP_SPACING_M,
    LIGHT_HOUSING_DEPTH_M,
    CameraConfig,
    TrackCamera,
    light_bounding_box,
    light_box_corners,
    project_points,
    render_background,
    world_to_camera,
)

LEVEL = CameraConfig(pitch_rad=0.0, variation=False)  # camera at (1.5, 0, 1.5) for car at 0
CLEAN = CameraConfig(variation=False)  # default pitch 0.10 rad


def test_defaults_and_training_preset():
    config = CameraConfig()
    assert (config.width, config.height, config.fx, config.fy) == (800, 600, 2574.0, 2744.0)
    assert (config.cx, config.cy) == (400.0, 300.0)
    small = CameraConfig.training()
    assert (small.width, small.height, small.cx, small.cy) == (200, 150, 100.0, 75.0)
    assert (small.fx, small.fy) == (2574 / 4, 2744 / 4)
    assert CameraConfig.training(noise_sigma=0.0).noise_sigma == 0.0


def test_point_ahead_left_and_above_projects_to_hand_computed_pixel():
    # 50 m ahead of the camera, 2 m left, 3.5 m above it (pitch 0): camera X = -2 (left is
    # -X), Y = -3.5 (up is -Y), Z = 50, so u = 2574 * -2 / 50 + 400 = 297.04 and
    # v = 2744 * -3.5 / 50 + 300 = 107.92.
    point = [1.5 + 50.0, 2.0, 1.5 + 3.5]
    np.testing.assert_allclose(world_to_camera(point, 0.0, 0.0, 0.0, LEVEL), [-2.0, -3.5, 50.0])
    u, v, depth = project_points(point, 0.0, 0.0, 0.0, LEVEL)
    assert (u, v, depth) == pytest.approx((297.04, 107.92, 50.0))
    # The same point relative to a car at (100, 200) heading +y (yaw 90 deg): ahead is +y,
    # left is -x; the camera is at (100, 201.5).
    turned = [100.0 - 2.0, 201.5 + 50.0, 5.0]
    assert project_points(turned, 100.0, 200.0, math.pi / 2, LEVEL) == pytest.approx(
        (297.04, 107.92, 50.0))


def test_pitch_moves_the_horizon_down_by_fy_tan_pitch():
    # A point far ahead at camera height lies on the horizon row cy + fy tan(pitch):
    # 300 + 2744 * tan(0.1) = 575.32 for the default camera.
    u, v, _ = project_points([1.5 + 1e6, 0.0, 1.5], 0.0, 0.0, 0.0, CLEAN)
    assert (u, v) == pytest.approx((400.0, 300 + 2744 * math.tan(0.1)), abs=1e-3)
    assert v == pytest.approx(575.32, abs=0.01)
    background = render_background(CLEAN)
    assert background[574, 0, 2] > 200  # sky (blue) just above the horizon
    assert tuple(background[576, 0]) == (70, 105, 50)  # grass just below
    assert tuple(background[599, 400]) == (100, 100, 104)  # road straight ahead


def test_points_behind_the_camera_have_no_pixel():
    u, v, depth = project_points([[-10.0, 0.0, 1.5], [11.5, 0.0, 1.5]], 0.0, 0.0, 0.0, LEVEL)
    assert np.isnan(u[0]) and np.isnan(v[0]) and depth[0] == pytest.approx(-11.5)
    assert (u[1], v[1]) == pytest.approx((400.0, 300.0))


def test_box_corners():
    corners = light_box_corners([10.0, 0.0, 5.0], math.pi / 2)  # facing +y: depth along y
    assert corners.shape == (8, 3)
    np.testing.assert_allclose(corners.min(0), [9.5, -0.25, 4.025])
    np.testing.assert_allclose(corners.max(0), [10.5, 0.25, 5.975])


def test_bounding_box_of_a_light_50_m_ahead():
    # Housing centred 50 m ahead at camera height, facing the camera. Its near face is at
    # Z = 49.75 m: rows 300 -+ 2744 * 0.975 / 49.75 = 246.22 .. 353.78 and columns
    # 400 -+ 2574 * 0.5 / 49.75 = 374.13 .. 425.87; the touched pixels are 246..353, 374..425.
    bbox = light_bounding_box([51.5, 0.0, 1.5], math.pi, 0.0, 0.0, 0.0, LEVEL)
    assert bbox == (374, 246, 426, 354)
    assert bbox[3] - bbox[1] == pytest.approx(2744 * 1.95 / 50.0, abs=1.5)  # 107.0 px


@pytest.mark.parametrize(("center", "why"), [
    ([-20.0, 0.0, 5.0], "behind the car"),
    ([2.0, 0.0, 1.5], "straddling the camera"),
    ([201.5, 0.0, 1.5], "beyond max_range_m (150 m)"),
    ([51.5, 30.0, 1.5], "left of the frame"),
])
def test_bounding_box_none_when_not_visible(center, why):
    assert light_bounding_box(center, math.pi, 0.0, 0.0, 0.0, LEVEL) is None, why


def test_bounding_box_clipped_at_the_image_edge():
    # Centre 40 m ahead and 6.3 m left: u = 400 - 2574 * 6.3 / 40 = -5.4, off the image, but
    # the box's right edge (5.8 m left) reaches u = 400 - 2574 * 5.8 / 40.25 = 29.09 at its
    # far face (Z = 40.25; the near face gives 24.42); rows 300 -+ 2744 * 0.975 / 39.75
    # = 232.69 .. 367.31. Clipped at column 0.
    edge = light_bounding_box([41.5, 6.3, 1.5], math.pi, 0.0, 0.0, 0.0, LEVEL)
    assert edge == (0, 232, 30, 368)


def _lamp_pixels(config, centre, facing, car=(0.0, 0.0, 0.0)):
    """Integer pixel (row, column) of the red, yellow, green lamp centres."""
    front = np.array(centre) + LIGHT_HOUSING_DEPTH_M / 2 * np.array(
        [math.cos(facing), math.sin(facing), 0.0])
    lamps = front + np.array([[0, 0, LAMP_SPACING_M], [0, 0, 0], [0, 0, -LAMP_SPACING_M]])
    u, v, _ = project_points(lamps, *car, config)
    return [(int(row), int(col)) for row, col in zip(v, u, strict=True)]


def _window_mean(image, pixel, half=1):
    row, col = pixel
    return image[row - half:row + half + 1, col - half:col + half + 1].reshape(-1, 3).mean(0)


LIGHT_AHEAD = [41.5, 0.0, 5.0]  # 40 m ahead of the camera, 3.5 m above it


@pytest.mark.parametrize(("state", "lit"), [(RED, 0), (YELLOW, 1), (GREEN, 2), (UNKNOWN, None)])
def test_render_lights_the_lamp_of_the_state(state, lit):
    camera = TrackCamera(CLEAN)
    image = camera.render(0.0, 0.0, 0.0, [LIGHT_AHEAD], [math.pi], [state])
    assert image.shape == (600, 800, 3) and image.dtype == np.uint8
    for lamp, (lamp_state, pixel) in enumerate(
            zip((RED, YELLOW, GREEN), _lamp_pixels(CLEAN, LIGHT_AHEAD, math.pi), strict=True)):
        expected = LAMP_ON_RGB[lamp_state] if lamp == lit else LAMP_OFF_RGB[lamp_state]
        np.testing.assert_array_equal(_window_mean(image, pixel), expected)


def test_render_with_noise_red_versus_green_lamp_regions():
    camera = TrackCamera(CameraConfig.training())
    config = camera.config
    red_lamp, _, green_lamp = _lamp_pixels(config, LIGHT_AHEAD, math.pi)
    rng = np.random.default_rng(3)
    red = camera.render(0.0, 0.0, 0.0, [LIGHT_AHEAD], [math.pi], [RED], rng)
    r_top, g_bottom = _window_mean(red, red_lamp), _window_mean(red, green_lamp)
    assert r_top[0] > 180 and r_top[1] < 70  # bright red on top
    assert g_bottom[1] < 100  # green lamp dim
    green = camera.render(0.0, 0.0, 0.0, [LIGHT_AHEAD], [math.pi], [GREEN], rng)
    g_top, g_bottom = _window_mean(green, red_lamp), _window_mean(green, green_lamp)
    assert g_bottom[1] > 180 and g_bottom[0] < 70 and g_top[0] < 110


def test_light_seen_from_behind_shows_only_its_housing():
    camera = TrackCamera(CLEAN)
    image, labels = camera.render_with_labels(0.0, 0.0, 0.0, [LIGHT_AHEAD], [0.0], [RED])
    for pixel in _lamp_pixels(CLEAN, LIGHT_AHEAD, math.pi):
        np.testing.assert_array_equal(_window_mean(image, pixel), HOUSING_RGB)
    assert len(labels) == 1 and labels[0].facing is False


def test_labels_far_to_near_with_the_bounding_boxes():
    camera = TrackCamera(CLEAN)
    positions = [[31.5, -1.0, 5.0], [101.5, 1.0, 5.0], [-30.0, 0.0, 5.0], [301.5, 0.0, 5.0]]
    yaws = [math.pi] * 4
    image, labels = camera.render_with_labels(0.0, 0.0, 0.0, positions, yaws,
                                              [GREEN, RED, RED, RED])
    assert [label.index for label in labels] == [1, 0]  # behind and beyond range skipped
    assert [label.state for label in labels] == [RED, GREEN]
    assert labels[0].depth_m > labels[1].depth_m
    for label in labels:
        assert label.bbox == light_bounding_box(positions[label.index], math.pi, 0.0, 0.0, 0.0,
                                                CLEAN)
        u_min, v_min, u_max, v_max = label.bbox
        crop = image[v_min:v_max, u_min:u_max]
        assert (crop == HOUSING_RGB).all(-1).mean() > 0.3  # the crop is mostly housing


def test_out_of_range_light_is_not_drawn():
    camera = TrackCamera(CLEAN)
    far = camera.render(0.0, 0.0, 0.0, [[201.5, 0.0, 5.0]], [math.pi], [RED])
    np.testing.assert_array_equal(far, camera.background)
    noisy = TrackCamera(CameraConfig.training())
    with_far = noisy.render(0.0, 0.0, 0.0, [[201.5, 0.0, 5.0]], [math.pi], [RED],
                            np.random.default_rng(5))
    without = noisy.render(0.0, 0.0, 0.0, np.zeros((0, 3)), [], [], np.random.default_rng(5))
    np.testing.assert_array_equal(with_far, without)


def test_noise_statistics_and_brightness_gain():
    camera = TrackCamera(CameraConfig.training(brightness_jitter=0.0, noise_sigma=4.0))
    image = camera.render(0.0, 0.0, 0.0, np.zeros((0, 3)), [], [], np.random.default_rng(0))
    difference = image.astype(float) - camera.background
    sky = difference[:100]  # far from 0 and 255: no clipping
    assert abs(sky.mean()) < 0.1
    assert sky.std() == pytest.approx(4.0, abs=0.15)  # rounded N(0, 4): std 4.01
    bright = TrackCamera(CameraConfig.training(brightness_jitter=0.3, noise_sigma=0.0))
    ratios = [bright.render(0.0, 0.0, 0.0, np.zeros((0, 3)), [], [],
                            np.random.default_rng(seed))[100:].mean()
              / bright.background[100:].mean() for seed in range(5)]
    assert all(0.69 < ratio < 1.31 for ratio in ratios)
    assert max(ratios) - min(ratios) > 0.05


def test_render_deterministic_per_seed():
    camera = TrackCamera(CameraConfig.training())
    args = (3.0, 1.0, 0.05, [LIGHT_AHEAD, [80.0, 2.0, 5.0]], [math.pi, 3.0], [RED, GREEN])
    first = camera.render(*args, np.random.default_rng(11))
    again = camera.render(*args, np.random.default_rng(11))
    other = camera.render(*args, np.random.default_rng(12))
    np.testing.assert_array_equal(first, again)
    assert (first != other).mean() > 0.5


def test_bad_input_raises_clear_errors():
    camera = TrackCamera(CameraConfig.training())
    with pytest.raises(ValueError, match="needs an rng"):
        camera.render(0.0, 0.0, 0.0, [LIGHT_AHEAD], [math.pi], [RED])
    with pytest.raises(ValueError, match="state must be one of"):
        TrackCamera(CLEAN).render(0.0, 0.0, 0.0, [LIGHT_AHEAD], [math.pi], [3])
    with pytest.raises(ValueError, match="light yaws must have shape \\(1,\\)"):
        TrackCamera(CLEAN).render(0.0, 0.0, 0.0, [LIGHT_AHEAD], [0.0, 1.0], [RED])
    with pytest.raises(ValueError, match=r"CameraConfig\.fx must be a finite number > 0 px"):
        CameraConfig(fx=-1.0)
    with pytest.raises(ValueError, match="brightness_jitter"):
        CameraConfig(brightness_jitter=0.9)


def test_from_mapping():
    config = CameraConfig.from_mapping({"preset": "training", "noise_sigma": 0.0})
    assert (config.width, config.fx, config.noise_sigma) == (200, 643.5, 0.0)
    resized = CameraConfig.from_mapping({"width": 640})
    assert (resized.width, resized.cx, resized.cy) == (640, 320.0, 300.0)
    with pytest.raises(ConfigError, match="unknown config key 'focal'"):
        CameraConfig.from_mapping({"focal": 100.0})
    with pytest.raises(ConfigError, match="'preset' must be one of"):
        CameraConfig.from_mapping({"preset": "tiny"})
    with pytest.raises(ConfigError, match=r"camera: CameraConfig\.pitch_rad"):
        CameraConfig.from_mapping({"pitch_rad": 2.0})


def test_distance_jitter_draws_the_light_as_if_nearer_or_farther():
    # Only the apparent distance varies (no gain, no noise). The housing 50 m ahead at
    # camera height drawn g times its size: its near face at Z = 50 - 0.25 g, rows
    # 300 -+ 2744 * 0.975 g / Z, columns 400 -+ 2574 * 0.5 g / Z (as the 50 m box test for
    # g = 1). g is the frame's first draw from the rng: uniform in [0.8, 1.2].
    config = CameraConfig(pitch_rad=0.0, brightness_jitter=0.0, noise_sigma=0.0,
                          distance_jitter=0.2)
    camera = TrackCamera(config)
    boxes = set()
    for seed in range(4):
        g = np.random.default_rng(seed).uniform(0.8, 1.2)
        near = 50.0 - 0.25 * g
        half_u, half_v = 2574 * 0.5 * g / near, 2744 * 0.975 * g / near
        expected = (math.floor(400 - half_u), math.floor(300 - half_v),
                    math.ceil(400 + half_u), math.ceil(300 + half_v))
        image, [label] = camera.render_with_labels(0.0, 0.0, 0.0, [[51.5, 0.0, 1.5]],
                                                   [math.pi], [RED],
                                                   np.random.default_rng(seed))
        assert label.bbox == expected
        u_min, v_min, _, v_max = label.bbox
        assert (image[v_min + 1:v_max - 1, u_min + 1] == HOUSING_RGB).all()  # left of lamps
        boxes.add(label.bbox)
    assert len(boxes) == 4  # a different apparent distance every frame
    # Off by default: the un-jittered box of light_bounding_box, (374, 246, 426, 354).
    assert CameraConfig().distance_jitter == 0.0
    with pytest.raises(ValueError, match=r"distance_jitter must be a finite number in \[0, "):
        CameraConfig(distance_jitter=0.5)
