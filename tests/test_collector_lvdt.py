"""
The collector with the real driver in measuring_mode lvdt and passive_actuator (real processes).

The driver publishes the LVDT's link length on hexacal/link and its measuring mode (and, in
passive_actuator mode, the released joint) on its status; the collector records them, treats
the link as one more stream of the settled detector and publishes postures with link_length -
the length the driver's machine stands at (its status's extension), within the noise - and
records each posture's released actuator in the bag.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from system_support import (  # noqa: F401 - probe: a fixture
    fast_collector_parameters,
    hexacal,
    node_argv,
    probe,
    STOP_TIMEOUT_S,
)
from test_driver_measuring_modes import Machine, start_driver

LINK_LENGTH_M = 0.75
STEPS = (
    np.array([1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 1e-3]),
    np.array([-2e-3, 1e-3, -1e-3, 2e-3, 0.0, 1e-3]),
)


def _collector_and_driver(ros_processes, probe, bag: Path, measuring_mode: str):  # noqa: F811
    """
    Start the fast collector recording `bag`, then the driver in `measuring_mode` at 100 Hz.

    Returns the two processes, the driver's Machine and the names of its sliders.
    """
    probe.subscribe_postures()
    collector = ros_processes.start(
        node_argv('collector', fast_collector_parameters(bag.parent, bag_name=bag.name)),
        name='collector',
    )
    probe.wait_for_node('collector', '/', collector)
    probe.wait_for_posture_publisher()  # volatile: a posture before the match would be lost
    driver = start_driver(ros_processes, measuring_mode=measuring_mode, rate_hz=100.0)
    machine = Machine(probe, driver)
    return collector, driver, machine, machine.sliders[-1][0]


def test_collector_records_the_link_and_postures_carry_it(
    ros_processes, tmp_path, probe  # noqa: F811 - fixture
):
    bags = tmp_path / 'bags'
    collector, driver, machine, names = _collector_and_driver(
        ros_processes, probe, bags / 'lvdt', 'lvdt'
    )
    extensions = []
    for step in STEPS:
        count = len(probe.postures)
        target = machine.positions() + step
        machine.command(names, target, 0.5)
        machine.wait(
            lambda: np.max(np.abs(machine.positions() - target)) < 3e-6,
            'the six commanded actuators at their setpoints',
        )
        seen = len(probe.statuses)  # the driver's next status is one at rest

        def at_rest():
            later = [v for _, _, v in probe.statuses[seen:] if 'link_extension_m' in v]
            return later[-1] if later else None

        status = machine.wait(at_rest, "the driver's status at rest")
        extensions.append(float(status['link_extension_m']))
        machine.wait(lambda: len(probe.postures) > count, 'a posture at the new target')
        posture = probe.postures[-1]
        assert posture.link_length is not None
        # The link's noise is +-1e-6 m: its mean is within a few um of the true length.
        assert abs(posture.link_length - (LINK_LENGTH_M + extensions[-1])) < 3e-6
        assert posture.scatter.link_length_sample_count >= 10
        assert 0.0 < posture.scatter.link_length_standard_error < 1e-6
        assert np.max(np.abs(np.array(posture.actuator_positions) - target)) < 3e-6
    assert len(set(extensions)) == len(STEPS)
    # The collector's status names the link as one of its streams, with its topic and rate.
    link = [v for _, _, v in probe.statuses if v.get('stream.link.topic') == '/hexacal/link']
    assert link and float(link[-1]['stream.link.rate_hz']) > 50.0
    assert ros_processes.stop(driver, STOP_TIMEOUT_S) == 0, driver.describe()
    assert ros_processes.stop(collector, STOP_TIMEOUT_S) == 0, collector.describe()

    from hexacal_identify.bag import open_bag
    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag

    assert '/hexacal/link' in open_bag(bags / 'lvdt').topics()
    recorded = postures_from_bag(bags / 'lvdt')
    assert recorded.measuring_mode == 'lvdt'
    # The bag holds the postures the probe received; before them perhaps one more, at rest before
    # the first step, published before the probe's subscription matched the collector.
    stamps = [p.stamp_ns for p in recorded.postures]
    assert stamps[-len(probe.postures):] == [p.stamp_ns for p in probe.postures]
    assert len(recorded.postures) - len(probe.postures) in (0, 1)
    assert all(p.link_length is not None for p in recorded.postures)
    redetected = postures_from_bag(bags / 'lvdt', source='raw')
    lengths = [p.link_length for p in redetected.postures]
    assert all(length is not None for length in lengths)
    for extension in extensions:  # each commanded posture found again offline
        assert min(abs(length - LINK_LENGTH_M - extension) for length in lengths) < 3e-6


def test_collector_records_each_postures_released_actuator(
    ros_processes, tmp_path, probe  # noqa: F811 - fixture
):
    released = 'slider_3'
    bags = tmp_path / 'bags'
    collector, driver, machine, names = _collector_and_driver(
        ros_processes, probe, bags / 'passive', 'passive_actuator'
    )
    answer = machine.set_bool(f'/hexacal/release/{released}', True)
    assert answer.success, answer.message
    machine.wait(
        lambda: machine.driver_status(lambda v: v['released_joint'] == released),
        'the status naming the released joint',
    )
    index = names.index(released)
    five = [name for name in names if name != released]
    count = len(probe.postures)
    targets = np.delete(machine.positions(), index) + np.array([2e-3, -1e-3, 1.5e-3, 0.0, -2e-3])
    machine.command(five, targets, 0.5)
    machine.wait(lambda: len(probe.postures) > count, 'a posture with slider_3 released')
    posture = probe.postures[-1]
    assert posture.link_length is None  # no LVDT in this mode
    assert ros_processes.stop(driver, STOP_TIMEOUT_S) == 0, driver.describe()
    assert ros_processes.stop(collector, STOP_TIMEOUT_S) == 0, collector.describe()

    from hexacal_identify.calibration_steps.bag_postures import postures_from_bag

    recorded = postures_from_bag(bags / 'passive')
    assert recorded.measuring_mode == 'passive_actuator'
    assert recorded.measuring.released_at(recorded.postures[-1].stamp_ns) == released
    completed = hexacal('bag-info', bags / 'passive', timeout=120)
    assert completed.returncode == 0, completed.stderr
    lines = [line for line in completed.stdout.splitlines() if line.startswith('Posture ')]
    assert lines and lines[-1].endswith(f'released actuator {released}')
