"""The result file's one owner: strict JSON written atomically, read back, bad files named."""

import json
import math

from hexacal_msgs_py.result_file import (
    FORMAT_KEY,
    read_result_file,
    REPORT_DATA_KEY,
    REPORT_DATA_KEYS,
    RESULT_FORMAT,
    write_result_file,
)
import pytest


def _payload() -> dict:
    return {
        'model': 'hexa_slide',
        'rank': 54,
        'reason': 'converged',
        FORMAT_KEY: RESULT_FORMAT,
        REPORT_DATA_KEY: {'parameters': [0.1, None], 'link_length': 0.75, 'extras': {}},
    }


def test_a_result_reads_back_as_written(tmp_path):
    path = write_result_file(tmp_path / 'result.json', _payload())
    assert path == tmp_path / 'result.json'
    assert read_result_file(path) == _payload()
    # One line of strict JSON, keys in the order given: the bytes json.dumps writes.
    assert path.read_text(encoding='utf-8') == json.dumps(_payload(), allow_nan=False)


def test_the_format_and_report_data_keys_are_named():
    assert RESULT_FORMAT == 'hexacal-result/1'
    assert (FORMAT_KEY, REPORT_DATA_KEY) == ('format', 'report_data')
    assert {'parameters', 'covariance', 'residuals', 'link_length', 'mount'} <= set(
        REPORT_DATA_KEYS
    )


def test_a_plain_calibrate_json_output_reads_as_a_result(tmp_path):
    path = tmp_path / 'plain.json'
    path.write_text(json.dumps({'rank': 53, 'reason': 'rank-deficient'}), encoding='utf-8')
    assert read_result_file(path) == {'rank': 53, 'reason': 'rank-deficient'}


def test_nan_is_refused_before_anything_is_written(tmp_path):
    payload = _payload()
    payload['rank'] = math.nan
    with pytest.raises(ValueError):
        write_result_file(tmp_path / 'result.json', payload)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    'text, problem',
    [
        ('{"rank": 54', 'not a JSON result file'),
        ('[1, 2]', 'not a hexacal result'),
        ('{"rank": 54}', "with 'rank' and 'reason'"),
    ],
)
def test_a_file_that_is_not_a_result_is_named(tmp_path, text, problem):
    path = tmp_path / 'bad.json'
    path.write_text(text, encoding='utf-8')
    with pytest.raises(ValueError, match=problem) as error:
        read_result_file(path)
    assert str(path) in str(error.value)
