"""`hexacal demo --actuator-speed`: the executor's speed limit, the simulated drive's twice it."""

import argparse
from pathlib import Path

from hexacal_identify.cli import demo
from hexacal_identify.cli.demo_run import demo_paths, system_launches
import pytest


def _arguments(*argv: str) -> argparse.Namespace:
    parser = argparse.ArgumentParser()
    demo.add_parsers(parser.add_subparsers(dest='command'))
    return parser.parse_args(['demo', *argv])


def _speeds(args: argparse.Namespace, tmp_path: Path) -> tuple[float, float]:
    args.out = tmp_path
    paths = demo_paths(args)
    nodes = system_launches(args, paths, paths.plan, paths.nominal, refine=True)
    return (nodes['executor'].parameters['max_actuator_speed_m_s'],
            nodes['driver'].parameters['max_actuator_speed_m_s'])


def test_the_speed_goes_to_the_executor_and_twice_it_to_the_drive(tmp_path):
    assert _speeds(_arguments(), tmp_path) == (demo.EXECUTOR_SPEED_M_S,
                                               2 * demo.EXECUTOR_SPEED_M_S)
    assert _speeds(_arguments('--actuator-speed', '1.5'), tmp_path) == (1.5, 3.0)


def test_the_released_machine_on_mujoco_moves_slower_unless_told():
    slow = demo.PASSIVE_PHYSICS_SPEED
    assert slow < demo.EXECUTOR_SPEED_M_S
    assert demo.actuator_speed(_arguments('--physics', 'mujoco')) == slow
    assert demo.actuator_speed(
        _arguments('--physics', 'mujoco', '--measuring-mode', 'lvdt')
    ) == demo.EXECUTOR_SPEED_M_S
    assert demo.actuator_speed(_arguments('--physics', 'mujoco', '--actuator-speed', '0.4')) == 0.4


@pytest.mark.parametrize('speed', ['0', '-1', 'nan', '5.5'])
def test_a_speed_out_of_range_is_refused_by_name(speed):
    with pytest.raises(ValueError, match='--actuator-speed'):
        demo._check_args(_arguments('--actuator-speed', speed))
