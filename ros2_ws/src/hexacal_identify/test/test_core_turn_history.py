"""The device-turn history of the collector (hexacal_identify.core.detection.turn_history)."""

import math

from hexacal_identify.core.detection.turn_history import turn_problem, TurnHistory
import pytest

MS = 1_000_000  # ns


def test_without_carried_turns_the_default_applies():
    history = TurnHistory()
    history.note(10 * MS, None)
    assert history.changes == ()
    assert history.turn_at(20 * MS, 2 * MS, default=0.5) == 0.5


def test_a_posture_takes_the_turn_carried_up_to_its_paired_inclinometer_stamp():
    history = TurnHistory()
    history.note(0, 0.0)
    history.note(1 * MS, 0.0)  # unchanged: not kept again
    history.note(100 * MS, math.pi)
    assert history.changes == ((0, 0.0), (100 * MS, math.pi))
    assert history.turn_at(50 * MS, 2 * MS, default=1.0) == 0.0
    # The paired inclinometer message may be up to max_skew later than the last sample.
    assert history.turn_at(98 * MS, 2 * MS, default=1.0) == math.pi


def test_a_lookup_forgets_older_changes():
    history = TurnHistory()
    for k, turn in enumerate((0.0, 1.0, 2.0, 3.0)):
        history.note(k * 10 * MS, turn)
    assert history.turn_at(25 * MS, 0, default=0.0) == 2.0
    assert history.changes == ((20 * MS, 2.0), (30 * MS, 3.0))


def test_messages_that_stop_carrying_a_turn_fall_back_to_the_default():
    history = TurnHistory()
    history.note(0, math.pi)
    history.note(10 * MS, None)
    assert history.turn_at(5 * MS, 0, default=0.25) == math.pi
    assert history.turn_at(15 * MS, 0, default=0.25) == 0.25


def test_the_history_is_bounded():
    history = TurnHistory(max_changes=3)
    for k in range(10):
        history.note(k, float(k % 2))
    assert history.changes == ((7, 1.0), (8, 0.0), (9, 1.0))


@pytest.mark.parametrize(
    ('value', 'problem'),
    [
        (0, None),
        (-2 * math.pi, None),
        (math.pi / 2, None),
        (True, 'must be a number'),
        ('pi', 'must be a number'),
        (7.0, 'within +-2 pi'),
        (math.nan, 'within +-2 pi'),
        (math.inf, 'within +-2 pi'),
    ],
)
def test_turn_problem_names_what_is_wrong(value, problem):
    found = turn_problem(value)
    if problem is None:
        assert found is None
    else:
        assert problem in found
