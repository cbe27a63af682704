"""The calibration store's API: entries, verification, deploy checks, rollback, the marker."""

from __future__ import annotations

import json
import os
from pathlib import Path

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.core.machine.model import nominal_set
from hexacal_identify.store import (
    ActivationReason,
    CalibrationStore,
    default_store_dir,
    DeployRefused,
    StoreError,
    StoreState,
)
from hexacal_msgs_py import store_format as fmt
from hexacal_msgs_py.parameters_file import save_parameters
from hexacal_msgs_py.readings import PostureReading
import numpy as np
import pytest

FIT, OTHER = 'f' * 64, 'e' * 64  # digests of the fit's and of other postures


def _file(path: Path, vector, model: str | None = None) -> Path:
    save_parameters(path, vector, model=model)
    return path


@pytest.fixture
def machine(tmp_path):
    """Return parameter files: the default machine, a recalibration of it, a nominal set."""
    vector = default_parameters().vector
    nudged = vector.copy()
    nudged[6] += 20e-6  # chain 1's l by 20 um: what a recalibration of the same machine does
    return {
        'first': _file(tmp_path / 'first.yaml', vector),
        'second': _file(tmp_path / 'second.yaml', nudged),
        'nominal': _file(tmp_path / 'nominal.yaml', nominal_set(2, seed=0).vector),
    }


def _verified(store: CalibrationStore, path: Path, verdict: str = 'pass', on: str = OTHER):
    entry = store.add(path, {fmt.RECORD_POSTURES_DIGEST: FIT, fmt.RECORD_COST: 'absolute'})
    return store.attach_verification(entry.id, {'verdict': verdict}, postures_digest=on)


def test_a_missing_store_is_empty_and_not_created(tmp_path):
    store = CalibrationStore(tmp_path / 'none')
    assert store.entries() == [] and store.active() is None and store.activation() is None
    assert not (tmp_path / 'none').exists()


def test_add_copies_the_file_with_its_record(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    entry = store.add(machine['first'], {fmt.RECORD_COST: 'absolute'})
    assert entry.state == StoreState.STORED and entry.verdict is None
    assert len(entry.id) >= 8 and all(c in '0123456789abcdef' for c in entry.id)
    assert entry.parameters_path.read_bytes() == machine['first'].read_bytes()
    assert entry.parameters_path.parent.parent == tmp_path / 'store' / fmt.ENTRIES_DIR
    assert entry.digest == fmt.file_digest(machine['first'])
    assert entry.time.endswith('Z') and entry.time.startswith('20')
    record = json.loads((entry.parameters_path.parent / fmt.RECORD_FILE).read_text())
    assert record[fmt.RECORD_COST] == 'absolute' and record[fmt.RECORD_MODEL] == 'hexa_slide'
    assert record[fmt.RECORD_DIGEST] == entry.digest and record[fmt.RECORD_VERSION]
    machine['first'].write_text('changed afterwards')  # the store keeps its own copy
    assert store.get(entry.id).parameters_path.read_bytes() != b'changed afterwards'


def test_entries_are_oldest_first_and_found_by_prefix_or_digest(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    first = store.add(machine['first'], {})
    second = store.add(machine['second'], {})
    again = store.add(machine['first'], {})  # the same file again: a new entry, nothing merged
    assert [e.id for e in store.entries()] == [first.id, second.id, again.id]
    assert store.get(second.id[:6]).id == second.id
    assert store.find_digest(first.digest).id == again.id  # the newest, none being active
    assert store.find_digest('0' * 64) is None
    # A parameters message is a vector: matched by the digest of the vector and its model.
    vector = default_parameters().vector
    assert store.find_digest(fmt.vector_digest('hexa_slide', vector)).id == again.id
    assert store.find_digest(fmt.vector_digest('gough_stewart', vector)) is None
    with pytest.raises(StoreError, match='no entry'):
        store.get('abcdef0123')
    with pytest.raises(StoreError, match='too short'):
        store.get(first.id[:2])


def test_an_ambiguous_prefix_is_named(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    entry = store.add(machine['first'], {})
    # A second entry whose id shares exactly 6 hex digits (the 7th differs, whatever the
    # entry's random id is), written in the store's format by hand.
    other = 'e' if entry.id[6] == 'f' else 'f'
    twin_id = entry.id[:6] + other * 6
    twin = tmp_path / 'store' / fmt.ENTRIES_DIR / twin_id
    twin.mkdir()
    twin.joinpath(fmt.PARAMETERS_FILE).write_bytes(entry.parameters_path.read_bytes())
    record = dict(entry.record, id=twin_id)
    twin.joinpath(fmt.RECORD_FILE).write_text(json.dumps(record))
    with pytest.raises(StoreError, match='ambiguous') as error:
        store.get(entry.id[:6])
    assert entry.id in str(error.value) and twin_id in str(error.value)
    assert store.get(entry.id[:7]).id == entry.id


def test_not_a_parameters_file_is_refused(tmp_path):
    bad = tmp_path / 'bad.yaml'
    bad.write_text('just: text\n')
    with pytest.raises(StoreError, match='not stored'):
        CalibrationStore(tmp_path / 'store').add(bad, {})


def test_a_directory_of_other_files_is_not_a_store(tmp_path):
    (tmp_path / 'notes.txt').write_text('mine')
    with pytest.raises(StoreError, match='not a calibration store'):
        CalibrationStore(tmp_path).entries()


def test_a_parameters_file_edited_in_the_store_is_named(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    entry = store.add(machine['first'], {})
    entry.parameters_path.write_text(entry.parameters_path.read_text() + '# edited\n')
    with pytest.raises(StoreError, match='modified after it was stored'):
        store.entries()


def test_deploy_needs_a_passing_verification_on_other_postures(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    entry = store.add(machine['first'], {fmt.RECORD_POSTURES_DIGEST: FIT})
    with pytest.raises(DeployRefused) as refused:
        store.deploy(entry.id)
    assert refused.value.reason == 'unverified' and '--force' in str(refused.value)
    store.attach_verification(entry.id, {'verdict': 'fail'}, postures_digest=OTHER)
    with pytest.raises(DeployRefused, match='not pass') as refused:
        store.deploy(entry.id)
    assert refused.value.reason == 'verification-failed'
    same = store.attach_verification(entry.id, {'verdict': 'pass'}, postures_digest=FIT)
    assert same.state == StoreState.STORED and same.verdict == 'pass'  # not deployable
    with pytest.raises(DeployRefused) as refused:
        store.deploy(entry.id)
    assert refused.value.reason == 'verified-on-fit-postures'
    unknown = store.attach_verification(entry.id, {'verdict': 'pass'})
    assert unknown.verdict == 'pass'
    with pytest.raises(DeployRefused) as refused:
        store.deploy(entry.id)
    assert refused.value.reason == 'postures-unknown'
    assert store.active() is None and not store.active_marker().exists()
    verified = store.attach_verification(entry.id, {'verdict': 'pass', 'x': 1}, OTHER)
    assert verified.state == StoreState.VERIFIED
    assert verified.record[fmt.RECORD_VERIFICATION]['x'] == 1  # the latest figures
    deployed = store.deploy(entry.id)
    assert deployed.state == StoreState.ACTIVE and store.active().id == entry.id
    activation = store.activation()
    assert activation.reason == ActivationReason.VERIFIED and activation.since >= entry.time


def test_a_verdict_is_required_and_the_verified_file_must_be_the_entrys(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    entry = store.add(machine['first'], {})
    with pytest.raises(StoreError, match='verdict'):
        store.attach_verification(entry.id, {'verdict': 'maybe'})
    with pytest.raises(StoreError, match='another parameters file'):
        store.attach_verification(
            entry.id, {'verdict': 'pass', 'calibrated_digest': fmt.file_digest(machine['second'])}
        )
    assert store.get(entry.id).verdict is None


def test_force_deploys_unverified_and_records_it(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    entry = store.add(machine['first'], {})
    forced = store.deploy(entry.id, force=True)
    assert forced.state == StoreState.FORCED and forced.active
    assert store.activation().reason == ActivationReason.FORCED
    event = json.loads(next((tmp_path / 'store' / fmt.EVENTS_DIR).glob('*deployed*')).read_text())
    assert event[fmt.EVENT_FORCED] is True
    assert [r['reason'] for r in event[fmt.EVENT_REFUSALS]] == ['unverified']


def test_a_plausible_recalibration_deploys_and_a_jump_is_refused(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    first = _verified(store, machine['first'])
    store.deploy(first.id)
    second = _verified(store, machine['second'])
    deployed = store.deploy(second.id)
    assert deployed.state == StoreState.ACTIVE
    assert store.get(first.id).state == StoreState.VERIFIED  # no longer active
    event = json.loads(sorted((tmp_path / 'store' / fmt.EVENTS_DIR).iterdir())[-1].read_text())
    checks = event[fmt.EVENT_CHECKS]
    assert checks['parameter_name'] == 'chain_1.l'
    assert checks['parameter_change_m'] == pytest.approx(20e-6, rel=1e-6)
    assert 0 < checks['pose_change_m'] < 0.1e-3 and checks['fk_failures'] == 0
    jump = _verified(store, machine['nominal'])
    with pytest.raises(DeployRefused) as refused:
        store.deploy(jump.id)
    reasons = [r.reason for r in refused.value.refusals]
    assert reasons[0] == 'parameter-jump' and 'pose-jump' in reasons, reasons
    assert store.active().id == second.id  # nothing changed
    # A looser limit lets it through; so does force, recorded as forced.
    assert store.deploy(jump.id, force=True).state == StoreState.FORCED


def test_thresholds_are_the_callers(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    store.deploy(_verified(store, machine['first']).id)
    second = _verified(store, machine['second'])
    with pytest.raises(DeployRefused) as refused:
        store.deploy(second.id, max_parameter_change_m=10e-6)
    assert refused.value.reason == 'parameter-jump' and '0.020 mm' in str(refused.value)


def test_another_model_is_a_jump(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    store.deploy(_verified(store, machine['first']).id)
    gough = _file(
        tmp_path / 'gs.yaml', default_parameters('gough_stewart').vector, 'gough_stewart'
    )
    with pytest.raises(DeployRefused) as refused:
        store.deploy(_verified(store, gough).id)
    assert refused.value.reason == 'model-changed'


def test_rollback_returns_to_the_previous_active_one(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    with pytest.raises(StoreError, match='no calibration was deployed'):
        store.rollback()
    first, second = _verified(store, machine['first']), _verified(store, machine['second'])
    store.deploy(first.id)
    with pytest.raises(StoreError, match='first deployed'):
        store.rollback()
    store.deploy(second.id)
    restored = store.rollback()
    assert restored.id == first.id and restored.state == StoreState.ACTIVE
    assert store.get(second.id).state == StoreState.ROLLED_BACK
    assert store.activation().reason == ActivationReason.ROLLED_BACK
    with pytest.raises(StoreError, match='nothing to roll back to'):
        store.rollback()
    # Deployed again, the rolled-back one is active again, and a rollback returns to first.
    assert store.deploy(second.id).state == StoreState.ACTIVE
    assert store.rollback().id == first.id


def test_redeploying_the_active_one_changes_nothing(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    entry = _verified(store, machine['first'])
    store.deploy(entry.id)
    before = os.stat(store.active_marker())
    events = sorted((tmp_path / 'store' / fmt.EVENTS_DIR).iterdir())
    assert store.deploy(entry.id).state == StoreState.ACTIVE
    assert sorted((tmp_path / 'store' / fmt.EVENTS_DIR).iterdir()) == events
    assert os.stat(store.active_marker()).st_ino == before.st_ino


def test_the_marker_changes_identity_on_every_deploy_and_rollback(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    first, second = _verified(store, machine['first']), _verified(store, machine['second'])
    identities = []
    for step in (lambda: store.deploy(first.id), lambda: store.deploy(second.id), store.rollback):
        step()
        status = os.stat(store.active_marker())
        marker = json.loads(store.active_marker().read_text())
        assert marker[fmt.ACTIVE_ID] == store.active().id
        assert marker[fmt.ACTIVE_DIGEST] == store.active().digest
        identities.append((status.st_ino, status.st_mtime_ns))
    assert len(set(identities)) == 3
    assert json.loads(store.active_marker().read_text())[fmt.ACTIVE_REASON] == 'rolled-back'


def test_nothing_is_overwritten(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    entry = _verified(store, machine['first'])
    store.deploy(entry.id)
    second = _verified(store, machine['second'])
    store.deploy(second.id)
    store.rollback()
    root = tmp_path / 'store'
    kept = {
        p: (os.stat(p).st_ino, p.read_bytes())
        for p in root.rglob('*')
        if p.is_file() and p.name not in (fmt.ACTIVE_FILE, fmt.LOCK_FILE)
    }
    store.deploy(second.id)
    store.add(machine['nominal'], {})
    for path, (inode, data) in kept.items():
        assert os.stat(path).st_ino == inode and path.read_bytes() == data, path
    names = sorted(p.name for p in (root / fmt.EVENTS_DIR).iterdir())
    assert [fmt.event_sequence(n) for n in names] == list(range(1, len(names) + 1))


def test_default_store_dir_is_per_model_and_overridable(monkeypatch, tmp_path):
    monkeypatch.setenv(fmt.STORE_ENV, str(tmp_path))
    assert default_store_dir('gough_stewart') == tmp_path / 'gough_stewart'
    monkeypatch.delenv(fmt.STORE_ENV)
    monkeypatch.setenv('XDG_DATA_HOME', str(tmp_path / 'data'))
    assert default_store_dir('hexa_slide') == tmp_path / 'data/hexacal/calibrations/hexa_slide'


def test_postures_digest_is_of_the_values():
    one = PostureReading(0, (0.1, 0.2, 0.3, 0.4, 0.5, 0.6), 0.01, 0.02, 0.03)
    same = PostureReading(99, (0.1, 0.2, 0.3, 0.4, 0.5, 0.6), 0.01, 0.02, 0.03)
    other = PostureReading(0, (0.1, 0.2, 0.3, 0.4, 0.5, 0.6), 0.01, 0.02, 0.0300001)
    assert fmt.postures_digest([one]) == fmt.postures_digest([same])  # the stamp is not data
    assert fmt.postures_digest([one]) != fmt.postures_digest([other])
    assert fmt.postures_digest([one, other]) != fmt.postures_digest([other, one])
    assert len(fmt.postures_digest([])) == 64


def test_importing_the_store_imports_no_numpy():
    import subprocess
    import sys

    code = 'import sys, hexacal_identify.store; print("numpy" in sys.modules)'
    output = subprocess.run(
        [sys.executable, '-c', code], capture_output=True, text=True, check=True
    ).stdout
    assert output.strip() == 'False'


def test_nan_figures_are_stored_as_null(tmp_path, machine):
    store = CalibrationStore(tmp_path / 'store')
    entry = store.add(machine['first'], {'fit': {'std': np.array([1.0, np.nan])}})
    assert entry.record['fit']['std'] == [1.0, None]
