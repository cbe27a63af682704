"""The identify node weighs postures by the scatter they carry on hexacal/posture (real DDS)."""

from __future__ import annotations

from dataclasses import replace

from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_msgs_py.readings import PostureScatter
import pytest
from system_support import (
    node_argv,
    probe,  # noqa: F401 - fixture
    simulated_postures,
    write_parameter_files,
)


@pytest.mark.slow
def test_postures_with_scatter_are_weighed_by_it(ros_processes, tmp_path, probe):
    _, nominal = write_parameter_files(tmp_path)
    parameters = {'nominal': str(nominal), 'output_dir': str(tmp_path / 'out'), 'report_dir': ''}
    identify = ros_processes.start(node_argv('identify', parameters), name='identify')
    probe.wait_for_node('identify', '/', identify)
    probe.subscribe_status()
    # The simulated readings' true spread (+-10 um / urad uniform), sent in velocity/effort.
    spread = PostureScatter(tuple(NoiseModel.from_microns(10.0).standard_deviations()), (1,) * 9)
    postures = [replace(p, scatter=spread) for p in simulated_postures(30, seed=5)]
    probe.publish_postures(postures)
    probe.spin_until(
        lambda: probe.postures_received_by_identify() == 30,
        60.0,
        'identify to hold 30 postures',
        identify.describe,
    )
    response = probe.call_trigger()
    assert response.success, response.message
    _, _, values = probe.spin_until(
        lambda: [s for s in probe.statuses if s[2].get('outcome') == 'converged'],
        30.0,
        'the result status',
    )[-1]
    assert values['weights'] == 'scatter', values
    assert "each posture's measured scatter" in values['weights_note']
    assert values['adequacy.verdict'] == 'pass', values['adequacy.reason']
