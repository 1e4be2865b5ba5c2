"""The endurance study's stretches: distances between incidents read off the episode's
trace (``benchmarks/study_fsm_endurance.py``)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from study_fsm_endurance import stretches


def test_stretches_between_incidents_and_the_censored_rest():
    """At 10 m/s for 10 s, incidents at 5 s and 2 s (in any order): stretches of 20 m and
    30 m, and 50 m still clean at the end."""
    time = np.linspace(0.0, 10.0, 501)
    done, last = stretches([5.0, 2.0], time, 10.0 * time)
    assert done == pytest.approx([20.0, 30.0])
    assert last == pytest.approx(50.0)


def test_no_incident_is_one_censored_stretch_of_the_whole_drive():
    time = np.linspace(0.0, 4.0, 9)
    distance = np.array([0.0, 1.0, 3.0, 6.0, 10.0, 15.0, 21.0, 28.0, 36.0])
    assert stretches([], time, distance) == ([], 36.0)
