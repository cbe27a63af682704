"""
The calibration store survives a writer killed at any step: the whole entry or event, or nothing.

A child process writes to the store and stops at a named step (store.store_writes' stage hook); the
test kills it there with SIGKILL, then checks what a reader sees and that the next writer cleans
up what the dead one left.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
import signal
import subprocess
import sys

from hexacal_identify.core.architectures import default_parameters
from hexacal_identify.store import CalibrationStore, store_writes, StoreState
from hexacal_msgs_py import store_format as fmt
from hexacal_msgs_py.parameters_file import save_parameters
import pytest

CHILD = r"""
import sys, time
from hexacal_identify.store import CalibrationStore, store_writes

root, stage, action, argument = sys.argv[1:5]

def hook(name):
    if name == stage:
        print('at ' + name, flush=True)
        time.sleep(120)  # killed here

store_writes._CRASH_HOOK = hook
store = CalibrationStore(root)
if action == 'add':
    store.add(argument, {'postures_digest': 'f' * 64})
elif action == 'verify':
    store.attach_verification(argument, {'verdict': 'pass'}, postures_digest='e' * 64)
else:
    store.deploy(argument)
print('finished', flush=True)
"""


@pytest.fixture
def parameters(tmp_path) -> Path:
    path = tmp_path / 'calibrated.yaml'
    save_parameters(path, default_parameters().vector)
    return path


def _killed_at(root: Path, stage: str, action: str, argument: str) -> None:
    """Run a store write in a child process and SIGKILL it at `stage`."""
    child = subprocess.Popen(
        [sys.executable, '-c', CHILD, str(root), stage, action, argument],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        line = child.stdout.readline()
        assert line.strip() == f'at {stage}', line + child.stderr.read()
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.wait(timeout=30)
        child.stdout.close()
        child.stderr.close()
    assert child.returncode == -signal.SIGKILL


def _leftovers(root: Path) -> list[Path]:
    return list(root.rglob(f'{fmt.TEMP_PREFIX}*'))


@pytest.mark.parametrize('stage', ['wrote parameters.yaml', 'wrote record.json', 'before rename'])
def test_an_add_killed_before_its_rename_leaves_nothing_visible(tmp_path, parameters, stage):
    root = tmp_path / 'store'
    _killed_at(root, stage, 'add', str(parameters))
    store = CalibrationStore(root)
    assert store.entries() == []
    assert _leftovers(root), 'the dead writer left its temporary directory'
    entry = store.add(parameters, {})  # the next writer cleans up, under the lock
    assert [e.id for e in store.entries()] == [entry.id]
    assert _leftovers(root) == []


def test_an_add_killed_after_its_rename_leaves_the_whole_entry(tmp_path, parameters):
    root = tmp_path / 'store'
    _killed_at(root, 'after rename', 'add', str(parameters))
    (entry,) = CalibrationStore(root).entries()
    assert entry.parameters_path.read_bytes() == parameters.read_bytes()
    assert entry.record[fmt.RECORD_POSTURES_DIGEST] == 'f' * 64


def test_a_deploy_killed_before_its_event_changes_nothing(tmp_path, parameters):
    root = tmp_path / 'store'
    store = CalibrationStore(root)
    entry = store.add(parameters, {fmt.RECORD_POSTURES_DIGEST: 'f' * 64})
    _killed_at(root, 'before link', 'verify', entry.id)
    assert store.get(entry.id).verdict is None
    store.attach_verification(entry.id, {'verdict': 'pass'}, postures_digest='e' * 64)
    _killed_at(root, 'before link', 'deploy', entry.id)
    assert store.active() is None and store.get(entry.id).state == StoreState.VERIFIED
    assert not store.active_marker().exists()
    assert store.deploy(entry.id).state == StoreState.ACTIVE
    assert _leftovers(root) == []


def test_a_deploy_killed_after_its_event_is_done_and_the_marker_catches_up(tmp_path, parameters):
    root = tmp_path / 'store'
    store = CalibrationStore(root)
    entry = store.add(parameters, {fmt.RECORD_POSTURES_DIGEST: 'f' * 64})
    store.attach_verification(entry.id, {'verdict': 'pass'}, postures_digest='e' * 64)
    _killed_at(root, 'after link', 'deploy', entry.id)
    assert store.active().id == entry.id  # the event is the truth
    assert not store.active_marker().exists()  # killed before the marker was replaced
    store.add(parameters, {})  # any next write brings the marker up to date
    assert json.loads(store.active_marker().read_text())[fmt.ACTIVE_ID] == entry.id


def test_an_interrupted_rename_leaves_nothing(tmp_path, parameters, monkeypatch):
    """An error at the rename itself (disk full, ENOSPC...) removes the temporary directory."""
    root = tmp_path / 'store'
    store = CalibrationStore(root)
    real_rename = os.rename

    def failing_rename(source, target):
        if Path(source).name.startswith(fmt.TEMP_PREFIX):
            raise OSError(28, 'No space left on device')
        return real_rename(source, target)

    monkeypatch.setattr(store_writes.os, 'rename', failing_rename)
    with pytest.raises(OSError, match='No space'):
        store.add(parameters, {})
    monkeypatch.setattr(store_writes.os, 'rename', real_rename)
    assert store.entries() == [] and _leftovers(root) == []


def test_an_event_never_replaces_another(tmp_path, parameters):
    """A writer that ignored the lock and took the next number: the event goes after it."""
    store = CalibrationStore(tmp_path / 'store')
    entry = store.add(parameters, {fmt.RECORD_POSTURES_DIGEST: 'f' * 64})
    first = store.attach_verification(entry.id, {'verdict': 'fail'}, postures_digest='e' * 64)
    events = tmp_path / 'store' / fmt.EVENTS_DIR
    (taken,) = list(events.iterdir())
    intruder = events / fmt.event_file_name(2, fmt.EventType.VERIFIED, entry.id)
    intruder.write_text(taken.read_text())
    assert first.verdict == 'fail'
    assert store_writes.write_new_file(intruder, b'{}') is False  # the hard link does not replace
    assert json.loads(intruder.read_text())[fmt.EVENT_VERDICT] == 'fail'
    store.attach_verification(entry.id, {'verdict': 'pass'}, postures_digest='e' * 64)
    assert sorted(fmt.event_sequence(p.name) for p in events.iterdir()) == [1, 2, 3]
    assert store.get(entry.id).verdict == 'pass'


def test_readers_never_see_a_half_written_store_while_writers_work(tmp_path, parameters):
    """A reader polling while entries and their verifications are written sees whole states."""
    import threading

    store = CalibrationStore(tmp_path / 'store')
    done, problems, seen = threading.Event(), [], []

    def read() -> None:
        reader = CalibrationStore(tmp_path / 'store')
        while not done.is_set():
            try:
                entries = reader.entries()
            except Exception as error:  # noqa: B902 (anything a reader hits is the failure)
                problems.append(error)
                return
            seen.append(len(entries))
            for entry in entries:
                if entry.verdict is not None and entry.state != StoreState.VERIFIED:
                    problems.append(f'{entry.id}: verdict {entry.verdict}, state {entry.state}')

    thread = threading.Thread(target=read)
    thread.start()
    try:
        for _ in range(12):
            entry = store.add(parameters, {fmt.RECORD_POSTURES_DIGEST: 'f' * 64})
            store.attach_verification(entry.id, {'verdict': 'pass'}, postures_digest='e' * 64)
    finally:
        done.set()
        thread.join(timeout=30)
    assert problems == []
    assert seen and max(seen) <= 12 and len(store.entries()) == 12
