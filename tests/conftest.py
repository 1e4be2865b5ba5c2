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
