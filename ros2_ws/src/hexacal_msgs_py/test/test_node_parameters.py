"""Node parameter specs are ROS-free; the descriptor built from one carries its type and range."""

import json
import subprocess
import sys

from hexacal_msgs_py.node_parameters import parameter_descriptor, ParameterSpec


def test_the_spec_module_imports_no_ros():
    script = (
        'import json, sys\n'
        'import hexacal_msgs_py.node_parameters\n'
        'print(json.dumps(sorted(sys.modules)))\n'
    )
    completed = subprocess.run(
        [sys.executable, '-c', script], capture_output=True, text=True, timeout=120
    )
    assert completed.returncode == 0, completed.stderr
    modules = json.loads(completed.stdout)
    assert [m for m in modules if m.split('.')[0] in ('rclpy', 'rcl_interfaces')] == []


def test_a_float_gets_a_floating_point_range():
    descriptor = parameter_descriptor('noise', ParameterSpec(0.5, 'noise, m', 0.0, 2.0, 'finite'))
    assert descriptor.name == 'noise' and descriptor.read_only
    assert descriptor.description == 'noise, m' and descriptor.additional_constraints == 'finite'
    (span,) = descriptor.floating_point_range
    assert (span.from_value, span.to_value, span.step) == (0.0, 2.0, 0.0)
    assert list(descriptor.integer_range) == []


def test_an_int_gets_an_integer_range_and_a_bool_none():
    descriptor = parameter_descriptor('count', ParameterSpec(3, 'count', 1, 9), read_only=False)
    (span,) = descriptor.integer_range
    assert (span.from_value, span.to_value, span.step) == (1, 9, 1)
    assert not descriptor.read_only
    flag = parameter_descriptor('flag', ParameterSpec(True, 'a switch'))
    assert list(flag.integer_range) == [] and list(flag.floating_point_range) == []


def test_a_list_is_dynamically_typed():
    descriptor = parameter_descriptor('offsets', ParameterSpec([0.0, 0.0], 'offsets, rad'))
    assert descriptor.dynamic_typing


def test_a_number_without_low_and_high_gets_no_range():
    descriptor = parameter_descriptor('prior', ParameterSpec(0.0, 'a prior, rad'), read_only=False)
    assert list(descriptor.floating_point_range) == [] and list(descriptor.integer_range) == []
    assert not descriptor.read_only
