"""
Test that BagReader.messages(topics) reads only the chunks holding those topics (#12 item 2).

A complete MCAP file's summary lists, per chunk, the channels it holds messages
of; messages() of some topics leaves the other chunks unread (the posture
topic of a 50-posture bag is in 50 of its 227 chunks).  The messages and their
order are exactly those of reading everything and filtering; a file without
a summary (cut short) is still read by the forward scan.
"""

from __future__ import annotations

from pathlib import Path

from hexacal_identify.bag import BagCorruptError, BagWriter, open_bag
from hexacal_identify.bag import mcap_records
from hexacal_msgs_py.names import INCLINOMETER_NAMES, JOINT_STATE_TYPE, SLIDER_NAMES
import pytest

BAGS = Path(__file__).resolve().parents[4] / 'bags'  # the repository's sample bags
SLIDERS, INCLINOMETER, POSTURE = '/hexacal/sliders', '/hexacal/inclinometer', '/hexacal/posture'


def _key(message):
    return (
        message.topic,
        message.type_name,
        message.log_time_ns,
        message.publish_time_ns,
        message.data_bytes,
    )


def _filtered(reader, topics):
    keys = {t.lstrip('/') for t in topics}
    return [_key(m) for m in reader.messages() if m.topic.lstrip('/') in keys]


@pytest.fixture
def expanded_chunks(monkeypatch):
    """Count the chunks messages() decompresses and unpacks."""
    count = [0]
    original = mcap_records._chunk_records

    def counting(*args, **kwargs):
        count[0] += 1
        return original(*args, **kwargs)

    monkeypatch.setattr(mcap_records, '_chunk_records', counting)
    return count


@pytest.mark.parametrize(
    'bag', ['sphere30_nonoise', 'sphere50_noise10', 'sphere60_fixed20_noise10']
)
def test_sample_bags_same_messages_per_topic_fewer_chunks(bag, expanded_chunks):
    reader = open_bag(BAGS / bag)
    topics = sorted(reader.topics())
    assert any(t.endswith('/posture') for t in topics)
    expanded_chunks[0] = 0
    everything = [_key(m) for m in reader.messages()]
    all_chunks = expanded_chunks[0]
    for topic in topics:
        expanded_chunks[0] = 0
        selected = [_key(m) for m in reader.messages([topic])]
        assert selected == [k for k in everything if k[0] == topic], topic
        if topic.endswith('/posture'):
            assert len(selected) == reader.topics()[topic].count
            assert (
                expanded_chunks[0] <= len(selected) < all_chunks
            )  # only the chunks with a posture
    two = [topics[0], topics[-1]]
    assert [_key(m) for m in reader.messages(two)] == _filtered(reader, two)


def _phased_bag(directory: Path) -> Path:
    """
    Record sliders alone, then sliders and inclinometer, then the inclinometer alone.

    The chunks hold either topic or both.
    """
    with BagWriter(directory, chunk_size_bytes=1024) as writer:
        writer.add_topic(SLIDERS, JOINT_STATE_TYPE)
        writer.add_topic(INCLINOMETER, JOINT_STATE_TYPE)
        for i in range(300):
            stamp = 1_000_000_000 + i * 10_000_000
            if i < 200:
                writer.write(
                    SLIDERS, {'name': list(SLIDER_NAMES), 'position': [0.4 + 1e-4 * i] * 6}, stamp
                )
            if i >= 100:
                writer.write(
                    INCLINOMETER,
                    {'name': list(INCLINOMETER_NAMES), 'position': [1e-5 * i, 0.0]},
                    stamp + 1,
                )
    return directory


def test_chunks_of_other_topics_are_not_read(tmp_path, expanded_chunks):
    bag = _phased_bag(tmp_path / 'phased')
    reader = open_bag(bag)
    expanded_chunks[0] = 0
    everything = [_key(m) for m in reader.messages()]
    all_chunks = expanded_chunks[0]
    for topics in ([SLIDERS], [INCLINOMETER], [SLIDERS, INCLINOMETER], ['hexacal/inclinometer']):
        expanded_chunks[0] = 0
        got = [_key(m) for m in reader.messages(topics)]
        if len(topics) == 1:
            assert expanded_chunks[0] < all_chunks
        assert got == _filtered(reader, topics) and got
    assert len(everything) == 400


def test_a_file_without_summary_is_scanned_with_the_same_messages(tmp_path):
    bag = _phased_bag(tmp_path / 'phased')
    mcap = next(bag.glob('*.mcap'))
    complete = open_bag(mcap)
    data = mcap.read_bytes()
    summary_start = int.from_bytes(data[-8 - 20:-8 - 12], 'little')  # the footer's summary_start
    cut = tmp_path / 'no_summary.mcap'
    cut.write_bytes(data[:summary_start])  # data section and DataEnd, no summary, no footer
    scanned = open_bag(cut)
    assert scanned.info().truncated and not complete.info().truncated
    assert scanned._files[0].chunk_channels == {} and complete._files[0].chunk_channels
    for topics in ([SLIDERS], [INCLINOMETER]):
        assert [_key(m) for m in scanned.messages(topics)] == [
            _key(m) for m in complete.messages(topics)
        ]


def test_damage_in_a_chunk_that_is_read_is_still_corrupt_error(tmp_path):
    bag = _phased_bag(tmp_path / 'phased')
    mcap = next(bag.glob('*.mcap'))
    reader = open_bag(bag)
    chunk_channels = reader._files[0].chunk_channels
    sliders_only = [offset for offset, ids in sorted(chunk_channels.items()) if len(ids) == 1][0]
    data = bytearray(mcap.read_bytes())
    data[sliders_only + 200] ^= (
        0xFF  # inside the first sliders-only chunk: its CRC no longer matches
    )
    mcap.write_bytes(bytes(data))
    reader = open_bag(bag)
    with pytest.raises(BagCorruptError):
        list(reader.messages())
    with pytest.raises(BagCorruptError):
        list(reader.messages([SLIDERS]))
    # A chunk of another topic is not read at all (its damage does not concern these messages).
    assert len(list(reader.messages([INCLINOMETER]))) == 200
