"""On every sample bag and cost function the identifiability verdict is the expected one.

The recorded bags: the costs that cannot see a translation of the frame (sphere, and
relative where it applies) are refused at rank 53 of 54 naming what to fix, the others
identify all 54 parameters, and fixed-position costs on bags without such postures
are named as such.  The pivots are scipy.linalg.qr's (unit tests:
ros2_ws/src/hexacal_identify/test/test_core_pivoted_qr.py).
"""

from __future__ import annotations

from pathlib import Path

from hexacal_identify.core.errors import RankDeficientError, TooFewPosturesError
from hexacal_identify.core.fit.residuals import COSTS
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.calibration_steps.bag_postures import postures_from_bag
from hexacal_identify.calibration_steps.calibration_run import calibrate
import pytest

BAGS = Path(__file__).resolve().parents[1] / 'bags'


def _verdict(postures, cost):
    try:
        report = calibrate(nominal_set(2, seed=0), postures, cost=cost).identifiability
    except RankDeficientError as error:
        report = error.report
    except (
        TooFewPosturesError
    ) as error:  # a fixed-position cost of a bag without such postures: named
        return str(error)
    return (
        report.rank,
        report.pivot_order,
        report.to_json()['unidentifiable_combinations'],
        report.unidentifiable_parameters,
        report.verdict(),
    )


@pytest.mark.parametrize(
    'bag', ['sphere30_nonoise', 'sphere50_noise10', 'sphere60_fixed20_noise10']
)
def test_bag_verdicts(bag):
    postures = postures_from_bag(BAGS / bag).postures
    for cost in COSTS:
        verdict = _verdict(postures, cost)
        if cost in ('fixed', 'sphere-fixed', 'relative') and bag != 'sphere60_fixed20_noise10':
            assert 'fixed-position posture' in verdict, cost
        elif cost in ('sphere', 'fixed', 'relative'):
            assert verdict[0] == 53 and verdict[3], cost  # refused, naming what to fix
            assert set(verdict[3]) <= set(verdict[1]), cost  # suggestions are parameters
        else:
            assert verdict[0] == 54 and not verdict[3], cost
