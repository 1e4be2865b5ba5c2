"""Oriented-rectangle contact: known overlaps and near misses."""

from __future__ import annotations

import numpy as np

from sdc_gym.geometry.collision import boxes_overlap, first_contact


def test_axis_aligned_boxes_touch_exactly_at_the_sum_of_half_lengths():
    for gap, expected in ((4.69, True), (4.7, True), (4.71, False)):
        assert boxes_overlap([0, 0], 0.0, 4.7, 1.9, [gap, 0], 0.0, 4.7, 1.9) == expected


def test_rotated_box_corner_reaches_further_than_its_side():
    # A square of side 2 rotated 45 degrees reaches sqrt(2) from its centre along x.
    assert boxes_overlap([0, 0], 0.0, 2.0, 2.0, [1.0 + np.sqrt(2) - 0.01, 0], np.pi / 4, 2.0, 2.0)
    assert not boxes_overlap([0, 0], 0.0, 2.0, 2.0, [1.0 + np.sqrt(2) + 0.01, 0], np.pi / 4,
                             2.0, 2.0)


def test_side_by_side_in_adjacent_lanes_do_not_touch():
    # Lane centres 4 m apart, 1.9 m wide cars, even a 2.5 m wide truck: no contact.
    assert not boxes_overlap([0, 0], 0.0, 4.7, 1.9, [0, 4.0], 0.0, 10.0, 2.5)
    assert boxes_overlap([0, 0], 0.0, 4.7, 1.9, [0, 2.1], 0.0, 10.0, 2.5)


def test_first_contact_reports_the_car_per_step():
    ego = np.array([[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]])
    heading = np.zeros(3)
    # Car 7 sits at x = 6.6: the ego at x = 2 is 4.6 m from it (< 4.7), car 9 far away.
    cars_x = np.array([[6.6, 100.0]] * 3)
    cars_y = np.zeros((3, 2))
    contact = first_contact(ego, heading, 4.7, 1.9, cars_x, cars_y, np.zeros((3, 2)),
                            np.array([4.7, 4.7]), np.array([1.9, 1.9]), np.array([7, 9]))
    assert contact.tolist() == [-1, -1, 7]
