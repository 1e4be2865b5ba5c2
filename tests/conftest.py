"""Shared test fixtures: the original Udacity data lives in ../shared beside the checkout."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED = Path(__file__).resolve().parents[2] / "shared"
UDACITY = SHARED / "data" / "udacity"
HIGHWAY_MAP_FILE = UDACITY / "path_planning" / "highway_map.csv"


@pytest.fixture(scope="session")
def original_highway():
    """The original highway map loaded from ../shared (never copied into the project)."""
    from sdc_gym.road.highway_map import load_highway_map

    if not HIGHWAY_MAP_FILE.is_file():
        pytest.fail(f"the original map is expected at {HIGHWAY_MAP_FILE}")
    return load_highway_map(HIGHWAY_MAP_FILE)


@pytest.fixture(scope="session", autouse=True)
def sb3_log_folder(tmp_path_factory):
    """stable-baselines3 makes a fresh SB3-<date> folder in the system temp directory on
    every ``learn()`` without a TensorBoard folder; keep those inside pytest's own."""
    import os

    previous = os.environ.get("SB3_LOGDIR")
    os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3_logs"))
    yield
    if previous is None:
        del os.environ["SB3_LOGDIR"]
    else:
        os.environ["SB3_LOGDIR"] = previous
