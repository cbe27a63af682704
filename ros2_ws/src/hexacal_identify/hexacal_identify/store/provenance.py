"""
The provenance record of a calibration, from what made it (CLI and identify node alike).

Keys are the contract's (``hexacal_msgs_py.store_format``); values JSON-safe, SI units.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable, Mapping

from hexacal_msgs_py import store_format as fmt

from .calibration_store import hexacal_version, json_safe


def fit_figures(result: Any) -> dict[str, Any]:
    """Return the fit's figures of an IdentificationResult (FIT_* keys)."""
    figures: dict[str, Any] = {
        fmt.FIT_REASON: result.reason,
        fmt.FIT_RANK: int(result.rank),
        fmt.FIT_PARAMETERS: int(result.parameters.layout.n_parameters),
        fmt.FIT_CONDITION: float(result.condition_number),
        fmt.FIT_COST: result.cost,
        fmt.FIT_ITERATIONS: int(result.iterations),
        fmt.FIT_RMS_RESIDUAL: dict(result.rms_residual),
        fmt.FIT_POSTURES_USED: len(result.used_postures),
        fmt.FIT_POSTURES_REJECTED: len(result.rejected_postures),
        'variance_factor': getattr(result, 'variance_factor', None),
        'weighted_by_noise_model': getattr(result, 'weighted', None),
    }
    adequacy = getattr(result, 'adequacy', None)  # the model-adequacy figures, where computed
    if adequacy is not None:
        to_json = getattr(adequacy, 'to_json', None)
        figures[fmt.FIT_ADEQUACY] = to_json() if to_json is not None else adequacy
    return json_safe(figures)


def calibration_record(
    result: Any,
    *,
    source: str,
    postures: Iterable[Any],
    nominal_file: Path | str | None = None,
    noise: Any = None,
    robust_loss: str | None = None,
    link_length: float | None = None,
    mount: str | None = None,
    device_prior: Mapping[str, Any] | None = None,
    bag: Path | str | None = None,
    extra: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """
    Return the provenance record of a calibration result (what ``CalibrationStore.add`` takes).

    `postures` are the PostureReadings given to the fit (their digest tells a verification on
    other postures from one on the same); `noise` a NoiseModel or None; `bag` the bag they were
    read from, if any (its path and the digest of its files).
    """
    posture_list = list(postures)
    from ..core.machine.device import DEVICE_PARAMETER_NAMES

    defects = {
        name: float(value)
        for name, value in zip(DEVICE_PARAMETER_NAMES, result.device.vector)
        if name in result.free_device
    }
    record: dict[str, Any] = {
        fmt.RECORD_SOURCE: source,
        fmt.RECORD_MODEL: result.parameters.model,
        fmt.RECORD_POSTURES_DIGEST: fmt.postures_digest(posture_list),
        fmt.RECORD_POSTURES_COUNT: len(posture_list),
        fmt.RECORD_COST: result.cost,
        fmt.RECORD_NOISE: None
        if noise is None
        else {'actuator_m': noise.actuator_m, 'angle_rad': noise.angle_rad},
        fmt.RECORD_ROBUST_LOSS: robust_loss,
        fmt.RECORD_LINK_LENGTH: link_length,
        fmt.RECORD_MOUNT: mount,
        fmt.RECORD_DEVICE_DEFECTS: {
            'identified': list(result.free_device),
            'values': defects,
        },
        fmt.RECORD_DEVICE_PRIOR: device_prior,
        fmt.RECORD_VERSION: hexacal_version(),
        fmt.RECORD_FIT: fit_figures(result),
    }
    if nominal_file is not None:
        record[fmt.RECORD_NOMINAL_FILE] = str(Path(nominal_file).resolve())
        record[fmt.RECORD_NOMINAL_DIGEST] = fmt.file_digest(nominal_file)
    if bag is not None:
        record[fmt.RECORD_BAG] = {'path': str(Path(bag).resolve()), 'digest': bag_digest(bag)}
    if extra:
        record.update(extra)
    return json_safe(record)


def bag_digest(path: Path | str) -> str:
    """
    Return the sha256 (hex) of a bag: of each file's relative name and bytes, in name order.

    A bag directory (metadata.yaml + .mcap files) or a single .mcap file.
    """
    import hashlib

    root = Path(path)
    digest = hashlib.sha256(b'hexacal-bag-v1')
    paths = sorted(p for p in root.rglob('*') if p.is_file()) if root.is_dir() else [root]
    for file in paths:
        name = file.relative_to(root).as_posix() if root.is_dir() else file.name
        digest.update(name.encode('utf-8') + b'\0' + fmt.file_digest(file).encode('ascii'))
    return digest.hexdigest()
