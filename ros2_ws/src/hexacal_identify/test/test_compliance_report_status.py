"""Identified compliances on the calibration status and in the HTML report, with their stds."""

import math

from hexacal_identify.calibration_steps.calibration_run import status_fields
from hexacal_identify.core.architectures import architecture
from hexacal_identify.core.fit.compliance import ComplianceModel, simulate_loaded_measurements
from hexacal_identify.core.fit.identification import identify, SolverOptions
from hexacal_identify.core.fit.statics import MassModel
from hexacal_identify.core.machine.measurements import NoiseModel
from hexacal_identify.core.machine.postures import sample_poses
from hexacal_identify.core.modes.passive_actuator import release_conditions
from hexacal_identify.report.compliance_section import compliance_rows, compliance_section
from hexacal_identify.report.page import result_payload, write_report
import numpy as np
import pytest

MASSES = MassModel(platform_mass=20.0, leg_mass=2.0, link_mass=1.5)
NOISE = NoiseModel.from_microns(2.0)


@pytest.fixture(scope='module')
def results():
    true = architecture('hexa_slide').default_parameters()
    rng = np.random.default_rng(3)
    poses = sample_poses(true, 40, rng)
    released = np.argmin(release_conditions(true, poses, 0.75), axis=1)
    model = ComplianceModel('shared', MASSES, 'passive_actuator', released)
    measurements, _ = simulate_loaded_measurements(
        true, poses, model, np.array([2e-8, 1e-7]), noise=NOISE, rng=rng
    )
    nominal = true.with_vector(true.vector + rng.normal(0.0, 2e-4, true.vector.size))
    compliant = identify(nominal, measurements, SolverOptions(noise=NOISE, compliance=model))
    rigid = identify(nominal, measurements, SolverOptions(noise=NOISE))
    return compliant, rigid


@pytest.mark.slow
def test_the_status_carries_each_compliance_and_its_std(results):
    compliant, rigid = results
    fields = status_fields(compliant)
    assert fields['compliance_mode'] == 'shared'
    for name in ('chains', 'link'):
        assert float(fields[f'compliance.{name}']) == pytest.approx(
            compliant.compliance[name], rel=1e-5
        )
        std = float(fields[f'std.compliance.{name}'])
        assert std == pytest.approx(compliant.compliance_std[name], rel=1e-5) and std > 0
    assert float(fields['compliance.link']) == pytest.approx(1e-7, rel=0.1)
    assert not any('compliance' in key for key in status_fields(rigid))


@pytest.mark.slow
def test_the_report_rows_are_the_identified_compliances(results):
    compliant, rigid = results
    payload = result_payload(compliant)
    rows = {row[0]: row for row in compliance_rows(payload['compliance'])}
    value, std = compliant.compliance['link'], compliant.compliance_std['link']
    assert rows['link'] == (
        'link', f'{value:.4g}', f'{std:.3g}', f'{1 / value:.4g}', f'{100 * std / value:.1f} %'
    )
    assert compliance_section(result_payload(rigid)) == ''


def test_the_page_has_the_section_only_with_compliances(tmp_path):
    compliance = {
        'mode': 'per_chain', 'unit': 'm/N',
        'values': {**{f'chain_{c}': c * 1e-8 for c in range(1, 7)}, 'link': 1e-7},
        'std': {**{f'chain_{c}': 1e-9 for c in range(1, 7)}, 'link': 2e-9},
    }
    page = write_report(
        {'model': 'hexa_slide', 'compliance': compliance}, tmp_path / 'compliant'
    ).read_text()
    assert "<table class='data' id='compliances'>" in page and 'choice per_chain' in page
    assert "<tr id='compliance-link'><td>link</td><td>1e-07</td><td>2e-09</td>" \
        '<td>1e+07</td><td>2.0 %</td></tr>' in page
    for c in range(1, 7):
        assert f"<tr id='compliance-chain_{c}'><td>chain_{c}</td><td>{c * 1e-8:.4g}</td>" in page
    rigid = write_report({'model': 'hexa_slide'}, tmp_path / 'rigid').read_text()
    assert 'Axial compliances' not in rigid


def test_unknown_figures_read_n_a():
    rows = compliance_rows({'values': {'chains': 2e-8, 'link': 0.0},
                            'std': {'chains': None, 'link': math.nan}})
    assert rows == [('chains', '2e-08', 'n/a', '5e+07', 'n/a'),
                    ('link', '0', 'n/a', 'n/a', 'n/a')]
