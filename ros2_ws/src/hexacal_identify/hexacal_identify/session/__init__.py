"""
The identify node's calibration session without ROS (no rclpy, no message packages).

session.CalibrationSession holds what the node decides: the postures received and rejected
(received_postures), the nominal file read once per version (nominal), calibrations and
verifications on request with their outcomes (outcome), the latest calibration, and the HTML
reports written after the answer (html_reports), the calibration store's side of the node
(history: every calibration kept, its verifications attached, deploy and rollback) and of the
kinematics node (deployment: the active calibration, followed through the store's marker). The
node reads its parameters into a node_settings.Settings, converts messages, runs the session's
methods on its threads and publishes through a StatusSink.
"""

from .html_reports import ReportJob, ReportQueue, VerificationTask
from .node_settings import parameter_problem, Settings, SETTINGS_PARAMETERS
from .nominal import file_identity, NominalFile
from .outcome import failure, Level, Outcome, Reason, ReportState
from .paths import DEFAULT_OUTPUT, output_path
from .prior import device_prior, PRIOR_PARAMETERS
from .received_postures import PostureStore, Receipt
from .session import CalibrationSession, Log, StatusSink
from .verification import LatestCalibration

__all__ = [
    'CalibrationSession',
    'DEFAULT_OUTPUT',
    'device_prior',
    'failure',
    'file_identity',
    'LatestCalibration',
    'Level',
    'Log',
    'NominalFile',
    'Outcome',
    'output_path',
    'parameter_problem',
    'PostureStore',
    'PRIOR_PARAMETERS',
    'Reason',
    'Receipt',
    'ReportJob',
    'ReportQueue',
    'ReportState',
    'Settings',
    'SETTINGS_PARAMETERS',
    'StatusSink',
    'VerificationTask',
]
