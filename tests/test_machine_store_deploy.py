"""
System test: on a Gough-Stewart system a deploy reaches the kinematics node.

The identify and kinematics nodes are started as `bringup`/the launch file builds them
(bringup.system.launches) for a Gough-Stewart nominal file and no kinematics parameters
file, with the default calibration stores ($HEXACAL_STORE/<model>), as real processes over
Fast DDS. identify calibrates Gough-Stewart postures into the machine's store and deploys
(forced: no verification here, tests/test_deploy.py has the verified path); the kinematics
node, told no file, follows the same store and takes the deployed calibration.
"""

from __future__ import annotations

from hexacal_identify.bringup.system import launches
from hexacal_identify.store import CalibrationStore
from hexacal_msgs_py.parameters_file import read_parameters_file
import numpy as np
import pytest
from rosproc import venv_executable
from system_support import probe  # noqa: F401 - fixture
from system_support import simulated_postures, write_parameter_files

GS = 'gough_stewart'


@pytest.mark.slow
def test_a_deploy_on_a_gough_stewart_system_reaches_the_kinematics_node(
    ros_processes, tmp_path, probe  # noqa: F811
):
    _, nominal = write_parameter_files(tmp_path, GS)
    stores = tmp_path / 'stores'
    nodes = {
        node.executable: node
        for node in launches(
            nominal=str(nominal),
            output_dir=str(tmp_path / 'out'),
            with_driver=False,
            with_kinematics=True,
            identify={'report_dir': ''},
            kinematics={'command_topic': 'command', 'markers_rate_hz': 0.0},
        )
    }
    env = {'HEXACAL_STORE': str(stores)}
    started = {}
    for name in ('identify', 'kinematics'):
        argv = nodes[name].command()
        argv[0] = venv_executable(name)
        started[name] = ros_processes.start(argv, env=env, name=name)

    def details() -> str:
        return '\n'.join(process.describe(20) for process in started.values())

    probe.subscribe_status()
    for name, process in started.items():
        probe.wait_for_node(name, '/', process)

    def kinematics_statuses() -> list[dict]:
        return [v for _, _, v in probe.statuses if 'parameters_updates' in v]

    probe.spin_until(
        lambda: any(v['outcome'] == 'waiting' for v in kinematics_statuses()),
        60.0,
        'the kinematics node waiting for a deploy',
        details,
    )
    probe.publish_postures(simulated_postures(40, seed=1, model=GS), subscribers=1, model=GS)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 40, 60.0, '40 postures', details
    )
    response = probe.call_trigger('/hexacal/calibrate')
    assert response.success, response.message
    store = CalibrationStore(stores / GS)  # the machine's store, not the Hexa Slide's
    (entry,) = store.entries()
    assert not (stores / 'hexa_slide').exists()
    response = probe.call_trigger('/hexacal/deploy_force')
    assert response.success, response.message
    status = probe.spin_until(
        lambda: next(
            (
                v
                for v in reversed(kinematics_statuses())
                if v.get('active_calibration') == entry.id and v['outcome'] == 'parameters'
            ),
            None,
        ),
        60.0,
        'the kinematics node on the deployed Gough-Stewart calibration',
        details,
    )
    assert status['active_reason'] == 'forced' and status['model'] == GS
    deployed = read_parameters_file(store.active().parameters_path)
    assert deployed.model == GS and np.all(np.isfinite(deployed.vector))
