"""
Rebuild a bag directory's metadata.yaml from its MCAP files, like `ros2 bag reindex`.

Files without a valid footer (recorder killed, disk full) are read up to the
last complete record, so a crashed recording becomes an ordinary bag again.
The MCAP files themselves are not modified.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Mapping

from .bag_info import BagInfo, METADATA_FILE_NAME
from .errors import BagMetadataError, BagMissingFileError, BagNotFoundError, BagWriteError
from .mcap_file import McapFile
from .reader import BagReader, load_metadata_yaml, mcap_files_in
from .writer import metadata_document, ROS_DISTRO, write_metadata_yaml


def reindex(
    directory: str | os.PathLike[str], *, custom_data: Mapping[str, str] | None = None
) -> BagInfo:
    """
    Write <directory>/metadata.yaml describing the directory's .mcap files; return it.

    custom_data and ros_distro of an existing readable metadata.yaml are kept
    unless `custom_data` is given.
    """
    bag_directory = Path(directory)
    if not bag_directory.is_dir():
        raise BagNotFoundError(f'{bag_directory} is not a directory')
    files = mcap_files_in(bag_directory)
    if not files:
        raise BagMissingFileError(f'{bag_directory} has no .mcap file to reindex')
    previous = _previous_metadata(bag_directory / METADATA_FILE_NAME)
    info = BagReader(bag_directory, [McapFile(path) for path in files]).info()
    if custom_data is None:
        custom_data = previous.get('custom_data') or {}
    document = metadata_document(
        info, custom_data=custom_data, ros_distro=str(previous.get('ros_distro') or ROS_DISTRO)
    )
    try:
        write_metadata_yaml(bag_directory, document)
    except OSError as error:
        target = bag_directory / METADATA_FILE_NAME
        raise BagWriteError(
            f'cannot write {target}: {error}', path=str(target), os_error=error
        ) from error
    return info


def _previous_metadata(path: Path) -> dict:
    if not path.exists():
        return {}
    try:
        information = load_metadata_yaml(path)
    except BagMetadataError:
        return {}  # incomplete or damaged: exactly what reindex replaces
    custom = information.get('custom_data')
    if not isinstance(custom, dict) or not all(isinstance(k, str) for k in custom):
        information['custom_data'] = {}
    else:
        information['custom_data'] = {k: str(v) for k, v in custom.items()}
    return information
