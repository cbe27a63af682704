"""
The nodes' side of the calibration store without DDS: session/deployment.py, session/history.py.

The identify session keeps every calibration in its store, attaches its verifications and
deploys or rolls back on request; the kinematics node's DeployFollower sees a deploy through
the store's active marker and accepts a parameters message only when it is the deployed one.
"""

from __future__ import annotations

import logging
from pathlib import Path

from hexacal_identify.core.architectures import architecture
from hexacal_identify.session import CalibrationSession, Settings
from hexacal_identify.session.deployment import (
    ActiveWatch,
    DeployFollower,
    followed_model,
    NO_ACTIVE,
    store_dir,
)
from hexacal_identify.session.history import History
from hexacal_identify.store import CalibrationStore
from hexacal_msgs_py.names import DEPLOYMENT_STATUS_NAME
from hexacal_msgs_py.parameters_file import read_parameters_file, save_parameters
from hexacal_msgs_py.store_format import vector_digest
import numpy as np
from test_calibration_session import nominal, receive, Recorder, simulated  # noqa: F401

MODEL = 'hexa_slide'


def parameters_file(directory: Path, name: str, shift_m: float = 0.0) -> Path:
    """Write the default Hexa Slide parameters, every length parameter moved by shift_m."""
    vector = architecture(MODEL).default_parameters().vector.copy()
    vector[0] += shift_m
    path = directory / name
    save_parameters(path, vector, model=MODEL)
    return path


def test_store_dir_is_the_configured_one_else_the_models_default(tmp_path, monkeypatch):
    monkeypatch.setenv('HEXACAL_STORE', str(tmp_path / 'default'))
    assert store_dir(str(tmp_path / 'mine'), MODEL) == (tmp_path / 'mine').resolve()
    assert store_dir('', MODEL) == tmp_path / 'default' / MODEL


def test_the_vector_digest_of_a_file_is_the_messages_and_one_bit_changes_it(tmp_path):
    path = parameters_file(tmp_path, 'p.yaml')
    saved = read_parameters_file(path)
    vector = architecture(MODEL).default_parameters().vector
    assert vector_digest(saved.model, saved.vector) == vector_digest(MODEL, vector)
    nudged = vector.copy()
    nudged[3] = np.nextafter(nudged[3], np.inf)
    assert vector_digest(MODEL, nudged) != vector_digest(MODEL, vector)
    assert vector_digest('gough_stewart', vector) != vector_digest(MODEL, vector)


def test_the_follower_takes_deploys_and_rollbacks_and_only_the_deployed_message(tmp_path):
    store = CalibrationStore(tmp_path / 'store')
    first = store.add(parameters_file(tmp_path, 'a.yaml'), {})
    second = store.add(parameters_file(tmp_path, 'b.yaml', 2e-5), {})
    follower = DeployFollower.start(str(tmp_path / 'store'), MODEL)
    assert follower.deployed is None and follower.values() == NO_ACTIVE
    assert follower.poll() is None  # nothing changed: no second read
    store.deploy(first.id, force=True)
    deployed = follower.poll()
    assert deployed is not None and deployed.active.entry.id == first.id
    assert follower.values()['active_reason'] == 'forced'
    assert follower.values()['active_calibration'] == first.id
    assert follower.poll() is None
    a_vector = read_parameters_file(first.parameters_path).vector
    b_vector = read_parameters_file(second.parameters_path).vector
    assert follower.deployed_match(MODEL, a_vector) is not None
    assert follower.deployed_match(MODEL, b_vector) is None  # stored, not deployed
    store.deploy(second.id, force=True)
    assert follower.poll().active.entry.id == second.id
    store.rollback()
    back = follower.poll()
    assert back.active.entry.id == first.id and str(back.active.reason) == 'rolled-back'
    assert np.array_equal(back.vector, a_vector)


def test_a_follower_without_model_takes_the_default_store_with_an_active_calibration(
    tmp_path, monkeypatch
):
    monkeypatch.setenv('HEXACAL_STORE', str(tmp_path))
    store = CalibrationStore(tmp_path / MODEL)
    store.deploy(store.add(parameters_file(tmp_path, 'a.yaml'), {}).id, force=True)
    follower = DeployFollower.start('', None)
    assert follower.root == tmp_path / MODEL and follower.deployed is not None


def test_a_follower_without_model_follows_the_first_default_store_deployed_into(
    tmp_path, monkeypatch
):
    monkeypatch.setenv('HEXACAL_STORE', str(tmp_path))
    follower = DeployFollower.start('', None)  # nothing deployed anywhere yet
    assert follower.deployed is None and str(tmp_path / MODEL) in follower.where
    assert str(tmp_path / 'gough_stewart') in follower.where
    vector = architecture('gough_stewart').default_parameters().vector
    path = tmp_path / 'gs.yaml'
    save_parameters(path, vector, model='gough_stewart')
    other = CalibrationStore(tmp_path / 'gough_stewart')
    entry = other.add(path, {})
    other.deploy(entry.id, force=True)
    deployed = follower.poll()  # the Gough-Stewart store's deploy reaches it
    assert deployed is not None and deployed.active.entry.id == entry.id
    assert follower.root == tmp_path / 'gough_stewart' and follower.where == str(follower.root)
    hexa = CalibrationStore(tmp_path / MODEL)  # followed from now on: one store, not two
    hexa.deploy(hexa.add(parameters_file(tmp_path, 'a.yaml'), {}).id, force=True)
    assert follower.poll() is None and follower.deployed.model == 'gough_stewart'


def test_the_followed_model_is_the_named_one_or_the_files_and_they_must_agree():
    assert followed_model('', None) is None
    assert followed_model('gough_stewart', None) == 'gough_stewart'
    assert followed_model('', MODEL) == MODEL
    assert followed_model(MODEL, MODEL) == MODEL
    try:
        followed_model('gough_stewart', MODEL)
    except ValueError as error:
        assert 'gough_stewart' in str(error) and MODEL in str(error)
    else:
        raise AssertionError('a model unlike the parameters file is accepted')
    try:
        followed_model('delta', None)
    except ValueError as error:
        assert "'delta'" in str(error)
    else:
        raise AssertionError('an unknown model is accepted')


def test_the_watch_reads_the_store_again_only_when_the_marker_changes(tmp_path):
    store = CalibrationStore(tmp_path / 'store')
    entry = store.add(parameters_file(tmp_path, 'a.yaml'), {})
    watch = ActiveWatch(tmp_path / 'store')
    assert watch.look() and watch.active is None
    assert not watch.look()
    store.deploy(entry.id, force=True)
    assert watch.look() and watch.active.entry.id == entry.id
    assert watch.values()['active_since'] and not watch.look()


def test_history_refuses_an_unverified_deploy_and_forces_it_on_request(tmp_path):
    history, root = History(), str(tmp_path / 'store')
    entry, values = history.add(root, MODEL, parameters_file(tmp_path, 'a.yaml'), {})
    assert entry is not None and values['calibration_id'] == entry.id
    refused = history.deploy(root, MODEL, entry.id, False, '/hexacal/deploy')
    assert not refused.success and refused.values['outcome'] == 'deploy-refused'
    assert refused.values['reason'] == 'unverified' and '--force' in refused.message
    assert 'hexacal/deploy_force' in refused.message
    assert history.active_values(root, MODEL) == NO_ACTIVE
    forced = history.deploy(root, MODEL, entry.id, True, '/hexacal/deploy')
    assert forced.success and forced.values['active_reason'] == 'forced'
    assert forced.values['active_calibration'] == entry.id
    rollback = history.rollback(root, MODEL)
    assert not rollback.success and rollback.values['outcome'] == 'rollback-refused'
    none = history.deploy(root, MODEL, None, False, '/hexacal/deploy')
    assert not none.success and none.values['outcome'] == 'no-calibration'


def test_the_session_keeps_verifies_and_deploys_its_calibration(tmp_path, nominal):  # noqa: F811
    recorder = Recorder()
    session = CalibrationSession(recorder, logging.getLogger('test_deployment'), lambda: None)
    store = tmp_path / 'store'
    settings = Settings(
        nominal=str(nominal),
        output_dir=str(tmp_path),
        report_dir='',
        calibration_store=str(store),
        verify_threshold_m=5e-4,
    )
    session.announce_active(settings)
    announced = recorder.statuses(DEPLOYMENT_STATUS_NAME)[-1][4]
    assert announced['outcome'] == 'none-deployed' and announced['active_calibration'] == ''
    receive(session, simulated(40, 0), nominal)
    outcome = session.calibrate(settings)
    assert outcome.success, outcome.message
    entry = CalibrationStore(store).get(outcome.values['calibration_id'])
    assert entry.state == 'stored' and entry.record['postures'] == 40
    assert entry.record['fit']['rank'] == int(outcome.values['rank'])
    assert entry.record['cost'] == 'absolute' and entry.record['nominal_digest']
    assert outcome.values['active_calibration'] == ''
    refused = session.deploy(settings)
    assert not refused.success and refused.values['reason'] == 'unverified'
    receive(session, simulated(12, 7), nominal)
    verified = session.verify(settings)
    assert verified.success, verified.message
    assert CalibrationStore(store).get(entry.id).verdict == 'pass'
    recorder.published.clear()
    deployed = session.deploy(settings)
    assert deployed.success, deployed.message
    assert deployed.values['active_calibration'] == entry.id
    assert deployed.values['active_reason'] == 'verified'
    # The now-active calibration is published, then the deployment status.
    assert recorder.parameter_messages()[0][1] == tuple(
        read_parameters_file(entry.parameters_path).vector
    )
    assert recorder.statuses(DEPLOYMENT_STATUS_NAME)[-1][4]['outcome'] == 'deployed'
    # A restarted session says what is active, since when and why.
    restarted = CalibrationSession(recorder, logging.getLogger('test_deployment'), lambda: None)
    restarted.announce_active(settings)
    announced = recorder.statuses(DEPLOYMENT_STATUS_NAME)[-1]
    assert announced[4]['outcome'] == 'active' and announced[4]['active_calibration'] == entry.id
    assert announced[4]['active_reason'] == 'verified' and 'since' in announced[3]


def test_the_report_names_the_store_entry_and_the_active_calibration(
    tmp_path, nominal  # noqa: F811
):
    session = CalibrationSession(Recorder(), logging.getLogger('test_deployment'), lambda: None)
    store = CalibrationStore(tmp_path / 'store')
    active = store.add(parameters_file(tmp_path, 'a.yaml'), {})
    store.deploy(active.id, force=True)
    settings = Settings(
        nominal=str(nominal),
        output_dir=str(tmp_path),
        report_dir='report',
        calibration_store=str(tmp_path / 'store'),
    )
    receive(session, simulated(40, 0), nominal)
    outcome = session.calibrate(settings)
    assert outcome.success, outcome.message
    session.write_reports()
    page = (tmp_path / 'report' / 'index.html').read_text()
    assert f'{outcome.values["calibration_id"]} in {tmp_path / "store"}' in page
    assert f'{active.id} (forced since ' in page


def test_the_live_session_reports_a_message_not_deployed_and_the_active_keys():
    from hexacal_identify.core.sessions.kinematics_session import LiveSession

    params = architecture(MODEL).default_parameters()
    session = LiveSession.start(params, 'file.yaml', 0.75, 'hanging', 0)
    start = session.start_report('', '/command', '/stores/hexa_slide')
    assert 'ignored unless deployed' in start.log_line and '/stores/hexa_slide' in start.log_line
    report = session.not_deployed('hexacal/parameters', '/stores/hexa_slide')
    assert report.outcome == 'not-deployed' and report.level == 'WARN'
    session.deployment = {'active_calibration': 'abc', 'active_since': 't', 'active_reason': 'x'}
    assert session.status_values(report)['active_calibration'] == 'abc'
    waiting = LiveSession.start(None, '', 0.75, 'hanging', 0).start_report('', '/c', '/s')
    assert waiting.outcome == 'waiting' and 'deployed in /s' in waiting.log_line
