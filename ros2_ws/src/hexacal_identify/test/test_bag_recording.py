"""The collector's recording (hexacal_identify.bag.bag_recording): one bag, stopped by an error."""

from hexacal_identify.bag import BagError, open_bag
from hexacal_identify.bag.bag_recording import Recording
from hexacal_identify.bag.qos_yaml import DEFAULT_QOS_PROFILES_YAML
from hexacal_msgs_py.names import JOINT_STATE_TYPE
import pytest

TOPIC = '/hexacal/sliders'
# A JointState with an empty header, no names and no values (XCDR1 little endian).
EMPTY_JOINT_STATE = b'\x00\x01\x00\x00' + bytes(8) + b'\x01\x00\x00\x00\x00' + bytes(3) + bytes(16)


def test_a_recording_writes_one_bag_at_a_time(tmp_path):
    failures = []
    recording = Recording(on_failure=failures.append)
    assert recording.close() is None and recording.directory is None
    recording.write(TOPIC, EMPTY_JOINT_STATE, 1)  # not recording: nothing happens
    recording.start(
        tmp_path / 'one',
        custom_data={'hexacal.model': 'hexa_slide'},
        topics=[(TOPIC, JOINT_STATE_TYPE, DEFAULT_QOS_PROFILES_YAML)],
        metadata={'hexacal.collector': {'model': 'hexa_slide'}},
    )
    assert recording.directory == tmp_path / 'one'
    recording.write(TOPIC, EMPTY_JOINT_STATE, 5, 4)
    assert recording.add_topic_once('/hexacal/platform_pose', 'geometry_msgs/msg/PoseStamped', '')
    writer = recording.writer
    assert recording.write_metadata(writer, 'hexacal.plan', {'plan_name': 'p'})
    recording.postures = 1
    recording.flush()
    assert writer.flushed_message_count == 1
    text = recording.close()
    assert text == f'closed bag {tmp_path / "one"}: 1 messages, 1 postures'
    assert not recording.write_metadata(writer, 'hexacal.plan', {})  # no longer the current bag
    with open_bag(tmp_path / 'one') as reader:
        assert [m.topic for m in reader.messages()] == [TOPIC]
    assert failures == []


def test_a_write_error_stops_the_recording_and_is_remembered(tmp_path):
    failures = []
    recording = Recording(on_failure=lambda error: failures.append(recording.close()))
    recording.start(tmp_path / 'two', custom_data={}, topics=[], metadata={})
    recording.write('/never/added', EMPTY_JOINT_STATE, 1)
    assert recording.error is not None and recording.error.startswith('bag-error: ')
    assert failures and failures[0].startswith('closed bag') and recording.writer is None


def test_a_bag_that_cannot_start_is_an_error_and_leaves_nothing_open(tmp_path):
    recording = Recording(on_failure=pytest.fail)
    with pytest.raises(BagError):
        recording.start(
            tmp_path / 'three',
            custom_data={},
            topics=[(TOPIC, 'no_such/msg/Type', '')],
            metadata={},
        )
    assert recording.writer is None
