"""
Names in and of hexacal's bags: the bag directories and hexacal's metadata keys.

A recording goes to `<output_dir>/<bag name>/`. The collector stores what the offline
tools need beside the messages: MCAP metadata records (name -> string mapping) and
metadata.yaml `custom_data` keys, named here.
"""

from __future__ import annotations

from datetime import datetime
import json
from pathlib import Path

# MCAP metadata record of the collector: namespace, model, detector settings, input mapping.
COLLECTOR_METADATA = 'hexacal.collector'
# MCAP metadata record of the plan the driver walked: these driver parameters (see
# hexacal_driver.driver_node), as strings.
PLAN_METADATA = 'hexacal.plan'
PLAN_PARAMETERS = (
    'plan',
    'plan_name',
    'postures',
    'seed',
    'link_length',
    'settle_s',
    'dwell_s',
    'rate_hz',
    'slider_noise_m',
    'angle_noise_rad',
    'device_defects',
    'device_turn',
)
# metadata.yaml custom_data: the recording node's name, its model, the input mapping (JSON).
RECORDED_BY_CUSTOM_DATA = 'hexacal.recorded_by'
MODEL_CUSTOM_DATA = 'hexacal.model'
INPUTS_CUSTOM_DATA = 'hexacal.inputs'
# A bag named by the time recording started.
DATED_BAG_NAME_FORMAT = 'hexacal_%Y%m%d_%H%M%S'


def bag_name_problem(bag_name: str) -> str | None:
    """Return why `bag_name` is not a plain directory name, or None."""
    if '/' in bag_name or bag_name in ('.', '..'):
        return f'bag_name must be a plain directory name, got {bag_name!r}'
    return None


def next_bag_directory(
    output_dir: str | Path, bag_name: str, *, first: bool, now: datetime | None = None
) -> Path:
    """
    Return the directory of the next bag in `output_dir`.

    An explicit `bag_name` is used as given for the first bag (the writer refuses to
    overwrite); otherwise the name (default: the date and time) gets the first free suffix
    `_2`, `_3`, ... among the existing directories.
    """
    output_dir = Path(output_dir)
    base = bag_name or (now or datetime.now()).strftime(DATED_BAG_NAME_FORMAT)
    candidate = output_dir / base
    if bag_name and first:
        return candidate
    suffix = 1
    while candidate.exists():
        suffix += 1
        candidate = output_dir / f'{base}_{suffix}'
    return candidate


def collector_records(
    recorded_by: str,
    namespace: str,
    model: str,
    inputs: dict[str, str],
    detector_settings: dict[str, str],
) -> tuple[dict[str, str], dict[str, dict[str, str]]]:
    """
    Return the custom data and metadata a collector's bag records about how it was made.

    `recorded_by`: the collector's fully qualified name; `inputs`: its input mapping
    (InputMapping.to_metadata); `detector_settings`: its detector's settings as text.
    """
    custom_data = {
        RECORDED_BY_CUSTOM_DATA: recorded_by,
        MODEL_CUSTOM_DATA: model,
        INPUTS_CUSTOM_DATA: json.dumps(inputs),
    }
    collector = {'namespace': namespace, 'model': model}
    return custom_data, {COLLECTOR_METADATA: {**collector, **detector_settings, **inputs}}
