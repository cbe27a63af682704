"""
Cost functions of the paper (eqs. 7, 8, 10, 12, 13): residuals and their Jacobians.

Every residual is written ``r(u)`` with Jacobian ``dr/du``; the solver takes the
Gauss-Newton step ``du = -J^+ r``.  Computed quantities come from forward
kinematics with parameters u; dX/du comes from implicit differentiation
(``kinematics.pose_sensitivities``), never from finite differences.

Cost functions (``COSTS``):

* ``absolute``      eq. 7, every posture: [x_m - x_c, y_m - y_c, z_m - z_c, phi_m - phi_c],
                    with the measured position from the inclinometer (eq. 4).
* ``sphere``        eq. 8, every posture: [L - |P_c|, phi_m - phi_c] (fixed postures lie
                    on the sphere too).
* ``fixed``         eq. 10, fixed-position postures only: [0 - x_c, 0 - y_c, -L - z_c, phi_m -
  phi_c]
                    (+L - z_c for a standing device, ``DeviceModel.mount``; -L_m of the
                    posture with an LVDT).
* ``sphere-fixed``  eq. 8 on sphere postures and eq. 10 on fixed-position postures.
* ``relative``      eq. 12 on sphere postures: |P_c^j| - |P_c^k|, and eq. 13 on fixed
                    postures: P_c^j - P_c^k, each for consecutive postures (j = k + 1)
                    of the same kind, plus phi_m - phi_c on every posture.  Differences
                    cancel a link-length or inclinometer offset; the paper leaves the
                    pairing open, consecutive pairs are the choice made here.  With an
                    LVDT, eq. 12 compares L_m^j - L_m^k and eq. 13 F^j - F^k (below).

The LVDT link (section 4's telescopic variant, ``Measurements.link_lengths``): its length is
free and measured, so a fixed-position posture fixes the link's direction (the inclinometer
reads zero: P on the vertical through O) and the LVDT says where along it.  Its fixed position
F^k is where the inclinometer reads zero at the posture's own length, (0, 0, -L_m^k) (through
the defect model as below: L_m^k + dL along the direction of a zero reading), in eq. 10 and
in the difference of eq. 13; likewise eq. 8 compares |P_c| with L_m^k + dL and eq. 12
|P_c^j| - |P_c^k| with L_m^j - L_m^k.  Without link lengths L_m^k = L: eqs. 8, 10, 12 and 13
as printed, to the last bit.

With device defects (``device.DeviceDefects``) the measured side changes: the
measured position comes from the defect model, L becomes L + dL, phi_m becomes
phi_read - phi0, and the fixed position is where the defective inclinometer
reads zero.  Their derivatives are the 5 device columns of the Jacobian.
Measured positions, the fixed position and their derivatives come from
``device`` for the device's mount (hanging: eq. 4 as in device.py; standing:
the same readings give -p), so nothing here depends on the mount.

For weighting by known sensor noise, each row also carries its derivatives
w.r.t. its posture's 9 noise sources (6 slider readings, alpha, beta, phi):
``noise_jacobian``; rows of the relative cost also depend on the partner posture.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InvalidMeasurementError
from ..machine.device import (
    device_position,
    DeviceDefects,
    DeviceModel,
    DevicePosition,
    fixed_position,
    N_DEVICE_PARAMETERS,
)
from ..machine.kinematics import PoseSensitivity, wrap_angle
from ..machine.measurements import FIXED, Measurements, SPHERE

COSTS = ('absolute', 'sphere', 'fixed', 'sphere-fixed', 'relative')
COST_EQUATIONS = {
    'absolute': 'eq. 7',
    'sphere': 'eq. 8',
    'fixed': 'eq. 10',
    'sphere-fixed': 'eqs. 8 + 10',
    'relative': 'eqs. 12 + 13',
}
N_NOISE_SOURCES = 9  # per posture: 6 sliders, alpha, beta, phi
DL, ALPHA0, BETA0, GAMMA, PHI0 = range(N_DEVICE_PARAMETERS)


@dataclass(frozen=True)
class ChannelSigma:
    """Noise scale per channel; residual rows are divided by it (1 = unweighted, as the paper)."""

    position_m: float = 1.0
    angle_rad: float = 1.0


@dataclass
class ResidualBlock:
    """Rows of residuals with their Jacobian, channel, posture and noise derivatives."""

    values: np.ndarray
    jacobian: np.ndarray | None  # (rows, 54 [+ 5 device])
    channels: np.ndarray
    postures: np.ndarray  # posture index (into the cost's measurements) of each row
    noise_jacobian: np.ndarray | None = None  # (rows, 9) w.r.t. the row's posture's noise sources
    partners: np.ndarray | None = None  # (rows,) second posture of a relative row, -1 if none
    partner_noise_jacobian: np.ndarray | None = None  # (rows, 9)


@dataclass
class _Pieces:
    """What every block needs at the current poses."""

    poses: np.ndarray
    d_params: np.ndarray | None  # dX/du (N, 6, n), or None when only the factored form is given
    d_actuators: np.ndarray | None  # dX/d lambda (N, 6, 6)
    with_device: bool
    factored: PoseSensitivity | None = None  # dX/du kept factored: rows formed in one pass each

    @property
    def has_jacobian(self) -> bool:
        return self.d_params is not None or self.factored is not None

    def pose_rows(self, index: np.ndarray | None, coordinates: slice, factor: float) -> np.ndarray:
        """Factor * dX[coordinates]/du for postures ``index`` (None: all), (k, m, n)."""
        if self.factored is not None:
            return self.factored.rows(index, coordinates, factor)
        assert self.d_params is not None  # has_jacobian without the factored form
        d_params = self.d_params if index is None else self.d_params[index]
        return factor * d_params[:, coordinates, :]

    def position_combination(self, index: np.ndarray, weights: np.ndarray) -> np.ndarray:
        """sum_i weights[:, i] dP_i/du for postures ``index``, weights (k, 3) -> (k, n)."""
        if self.factored is not None:
            full = np.zeros((len(index), 6))
            full[:, :3] = weights
            return self.factored.combined(index, full)
        assert self.d_params is not None
        return np.einsum('ni,nik->nk', weights, self.d_params[index, :3, :])


class CostFunction:
    """Residuals of one cost function over a fixed set of measured postures."""

    def __init__(
        self, cost: str, measurements: Measurements, device: DeviceModel, sigma: ChannelSigma
    ):
        if cost not in COSTS:
            raise ValueError(f'unknown cost function {cost!r}; choose one of {", ".join(COSTS)}')
        self.cost = cost
        self.measurements = measurements
        self.link_length = device.link_length
        self.mount = device.mount
        # LVDT variant (section 4): a measured link length per posture replaces the constant L.
        self.link_lengths = (
            measurements.link_lengths
            if measurements.link_lengths is not None
            else np.full(len(measurements), device.link_length)
        )
        self.lvdt = measurements.link_lengths is not None
        self.sigma = sigma
        if cost == 'relative' and measurements.device_turn is not None:
            raise InvalidMeasurementError(
                'the relative cost function (eqs. 12 + 13) pairs consecutive postures and '
                f'cancels offsets itself; {int(np.count_nonzero(measurements.device_turn))} '
                'posture(s) were taken with the device turned about its link: use the absolute '
                'cost (eq. 7), which identifies the offsets from them'
            )
        self.is_fixed = measurements.kinds == FIXED
        self.is_sphere = measurements.kinds == SPHERE
        self._measured_cache: tuple[DeviceDefects, DevicePosition] | None = None

    def usable(self) -> np.ndarray:
        """Mask of postures this cost function uses."""
        if self.cost == 'fixed':
            return self.is_fixed.copy()
        return np.ones(len(self.measurements), bool)

    def missing_postures(self) -> str | None:
        """
        Why these postures cannot feed this cost function at all (None when they can).

        Eqs. 10 and 13 compare fixed-position postures and eq. 12 compares sphere postures: a
        cost that needs a kind the measurement set lacks is a named error, not an empty block.
        """
        n_fixed, n_sphere = int(self.is_fixed.sum()), int(self.is_sphere.sum())
        needs = {
            'fixed': (('fixed-position', n_fixed, 1),),
            'sphere-fixed': (('fixed-position', n_fixed, 1),),
            'relative': (('fixed-position', n_fixed, 2), ('sphere', n_sphere, 2)),
        }.get(self.cost, ())
        for kind, have, least in needs:
            if have < least:
                return (
                    f'the {self.cost} cost function needs at least {least} {kind} posture(s) and '
                    f'the measurements hold {have} ({n_sphere} sphere, {n_fixed} fixed-position); '
                    'record postures of that kind or choose another cost function'
                )
        return None

    def measured(self, defects: DeviceDefects = DeviceDefects()):
        """
        Return positions from the readings through the defect model.

        Positions from the readings through the defect model; the last result is kept (defects
        rarely change).
        """
        if self._measured_cache is None or self._measured_cache[0] != defects:
            alpha, beta = self.measurements.inclinometer.T
            self._measured_cache = (
                defects,
                device_position(
                    alpha,
                    beta,
                    self.link_lengths,
                    defects,
                    self.mount,
                    self.measurements.device_turn,
                ),
            )
        return self._measured_cache[1]

    def fixed_position(self, defects: DeviceDefects = DeviceDefects(), device_turn: float = 0.0):
        """
        Return where the inclinometer reads zero (eq. 10).

        Where the (defective, possibly turned) inclinometer reads zero: the fixed position of eq.
        10, at the nominal length L (a posture's own, with an LVDT: ``fixed_positions``).
        """
        return fixed_position(self.link_length, defects, self.mount, device_turn)

    def fixed_positions(self, defects: DeviceDefects, index: np.ndarray):
        """
        Return fixed positions and their device derivatives of postures ``index``.

        Fixed positions (k, 3) and their device derivatives (k, 3, 4) of postures ``index``: a
        turned device reads zero elsewhere (its offsets turn with it); with an LVDT each at its
        posture's measured length (module doc).
        """
        turns = self.measurements.turns[index]
        zeros = np.zeros(len(index))
        # An LVDT link fixes the direction, not the length: L_m of each posture (module doc).
        fixed = device_position(
            zeros,
            zeros,
            self.link_lengths[index],
            defects,
            self.mount,
            turns if np.any(turns) else None,
        )
        return fixed.position, fixed.d_defects

    def initial_poses(self, defects: DeviceDefects = DeviceDefects()) -> np.ndarray:
        """
        Return the expected postures: the FK start and branch reference.

        Measured position and phi, theta = psi = 0 (the FK start and branch reference).
        """
        n = len(self.measurements)
        fixed, _ = self.fixed_positions(defects, np.arange(n))
        position = np.where(self.is_fixed[:, None], fixed, self.measured(defects).position)
        return np.column_stack([position, np.zeros((n, 2)), self.measured_phi(defects)])

    def measured_phi(self, defects: DeviceDefects = DeviceDefects()) -> np.ndarray:
        """
        Return phi from the rotary readings.

        A device turned about its link reads phi - turn + phi0, wrapped.
        """
        return wrap_angle(self.measurements.rotary + self.measurements.turns - defects.phi0)

    def residuals(
        self,
        poses: np.ndarray,
        sensitivity: np.ndarray | PoseSensitivity | None,
        defects: DeviceDefects = DeviceDefects(),
        with_device: bool = False,
        with_noise: bool = True,
    ) -> ResidualBlock:
        """
        Return the stacked residuals and, with ``sensitivity``, the Jacobian.

        Stacked residuals; with ``sensitivity`` also the Jacobian (54 columns, + 5 device columns
        if ``with_device``) and, for a PoseSensitivity and ``with_noise``, each row's noise
        derivatives.
        """
        if isinstance(sensitivity, PoseSensitivity):
            pieces = _Pieces(
                poses,
                None,
                sensitivity.wrt_actuators if with_noise else None,
                with_device,
                sensitivity,
            )
        else:
            pieces = _Pieces(poses, sensitivity, None, with_device)
        blocks = [self._phi_block(pieces, defects)]
        everyone = np.ones(len(poses), bool)
        if self.cost == 'absolute':
            blocks.append(self._measured_position_block(pieces, defects))
        elif self.cost == 'fixed':
            blocks.append(self._fixed_block(pieces, defects, everyone))
        elif self.cost == 'sphere':
            blocks.append(self._length_block(pieces, defects, everyone))
        elif self.cost == 'sphere-fixed':
            blocks.append(self._length_block(pieces, defects, self.is_sphere))
            blocks.append(self._fixed_block(pieces, defects, self.is_fixed))
        else:
            blocks.append(self._relative_length_block(pieces))
            blocks.append(self._relative_position_block(pieces, defects))
        return _stack(blocks)

    # -- helpers ------------------------------------------------------------------
    def _jacobian(
        self, pieces: _Pieces, rows_from_pose: np.ndarray | None, device_rows: np.ndarray
    ) -> np.ndarray | None:
        """[d r/d u | d r/d device] from rows_from_pose (rows, n) and device_rows (rows, 5)."""
        if not pieces.has_jacobian or rows_from_pose is None:
            return None
        return np.hstack([rows_from_pose, device_rows]) if pieces.with_device else rows_from_pose

    @staticmethod
    def _noise(
        pieces: _Pieces,
        index: np.ndarray,
        d_row_d_pose: np.ndarray,
        d_row_d_readings: np.ndarray | None,
    ):
        """
        Return row derivatives w.r.t. [6 actuators, alpha, beta, phi] through FK.

        d_row_d_pose (rows, 6) is carried through forward kinematics.
        """
        if pieces.d_actuators is None:
            return None
        noise = np.zeros((len(index), N_NOISE_SOURCES))
        noise[:, :6] = np.einsum('ri,rij->rj', d_row_d_pose, pieces.d_actuators[index])
        if d_row_d_readings is not None:
            noise[:, 6:] = d_row_d_readings
        return noise

    # -- blocks -----------------------------------------------------------------
    def _phi_block(self, pieces: _Pieces, defects: DeviceDefects) -> ResidualBlock:
        n = len(pieces.poses)
        index = np.arange(n)
        scale = 1.0 / self.sigma.angle_rad
        values = wrap_angle(self.measured_phi(defects) - pieces.poses[:, 5]) * scale
        jac = None
        if pieces.has_jacobian:
            device_rows = np.zeros((n, N_DEVICE_PARAMETERS))
            device_rows[:, PHI0] = -scale
            jac = self._jacobian(
                pieces, pieces.pose_rows(None, slice(5, 6), -scale)[:, 0, :], device_rows
            )
        d_pose = np.zeros((n, 6))
        d_pose[:, 5] = -scale
        readings = np.zeros((n, 3))
        readings[:, 2] = scale
        return ResidualBlock(
            values, jac, np.full(n, 'phi'), index, self._noise(pieces, index, d_pose, readings)
        )

    def _position_rows(
        self,
        pieces: _Pieces,
        index: np.ndarray,
        targets: np.ndarray,
        d_targets_d_device: np.ndarray,
        d_targets_d_readings: np.ndarray | None,
    ) -> ResidualBlock:
        """
        Return the rows target - P_c for postures ``index``.

        Rows target - P_c for postures ``index``; targets (k, 3), derivatives (k, 3, 4) and (k, 3,
        2).
        """
        scale = 1.0 / self.sigma.position_m
        k = len(index)
        values = ((targets - pieces.poses[index, :3]) * scale).reshape(-1)
        jac = None
        if pieces.has_jacobian:
            device_rows = np.zeros((k, 3, N_DEVICE_PARAMETERS))
            device_rows[:, :, :4] = d_targets_d_device * scale
            everyone = k == len(pieces.poses) and np.array_equal(index, np.arange(k))
            rows = pieces.pose_rows(None if everyone else index, slice(0, 3), -scale)
            jac = self._jacobian(pieces, rows.reshape(3 * k, -1), device_rows.reshape(3 * k, -1))
        d_pose = np.zeros((k, 3, 6))
        d_pose[:, [0, 1, 2], [0, 1, 2]] = -scale
        readings: np.ndarray | None = None
        if d_targets_d_readings is not None:
            per_posture = np.zeros((k, 3, 3))
            per_posture[:, :, :2] = d_targets_d_readings * scale
            readings = per_posture.reshape(3 * k, 3)
        rows = np.repeat(index, 3)
        noise = self._noise(pieces, rows, d_pose.reshape(3 * k, 6), readings)
        channels = np.tile(np.array(['x', 'y', 'z']), k)
        return ResidualBlock(values, jac, channels, rows, noise)

    def _measured_position_block(self, pieces: _Pieces, defects: DeviceDefects) -> ResidualBlock:
        measured = self.measured(defects)
        index = np.arange(len(pieces.poses))
        return self._position_rows(
            pieces, index, measured.position, measured.d_defects, measured.d_readings
        )

    def _fixed_block(
        self, pieces: _Pieces, defects: DeviceDefects, mask: np.ndarray
    ) -> ResidualBlock:
        index = np.flatnonzero(mask)
        targets, d_device = self.fixed_positions(defects, index)
        return self._position_rows(pieces, index, targets, d_device, None)

    def _lengths(self, pieces: _Pieces, index: np.ndarray):
        position = pieces.poses[index, :3]
        length = np.linalg.norm(position, axis=1)
        direction = position / length[:, None]
        d_params = None
        if pieces.has_jacobian:
            d_params = pieces.position_combination(index, direction)
        d_pose = np.zeros((len(index), 6))
        d_pose[:, :3] = direction
        return length, d_params, d_pose

    def _length_block(
        self, pieces: _Pieces, defects: DeviceDefects, mask: np.ndarray
    ) -> ResidualBlock:
        index = np.flatnonzero(mask)
        scale = 1.0 / self.sigma.position_m
        length, d_params, d_pose = self._lengths(pieces, index)
        values = (self.link_lengths[index] + defects.dL - length) * scale
        jac = None
        if d_params is not None:
            device_rows = np.zeros((len(index), N_DEVICE_PARAMETERS))
            device_rows[:, DL] = scale
            jac = self._jacobian(pieces, -d_params * scale, device_rows)
        noise = self._noise(pieces, index, -d_pose * scale, np.zeros((len(index), 3)))
        return ResidualBlock(values, jac, np.full(len(index), 'link_length'), index, noise)

    def _relative_length_block(self, pieces: _Pieces) -> ResidualBlock:
        index = np.flatnonzero(self.is_sphere)
        scale = 1.0 / self.sigma.position_m
        length, d_params, d_pose = self._lengths(pieces, index)
        values = np.diff(length) * scale
        if self.lvdt:  # the link's own change of length is measured (module doc)
            values -= np.diff(self.link_lengths[index]) * scale
        jac = None
        if d_params is not None:
            jac = self._jacobian(
                pieces,
                np.diff(d_params, axis=0) * scale,
                np.zeros((len(values), N_DEVICE_PARAMETERS)),
            )
        block = ResidualBlock(
            values, jac, np.full(len(values), 'link_length_difference'), index[1:]
        )
        return self._with_partner_noise(block, pieces, index, d_pose * scale)

    def _relative_position_block(
        self, pieces: _Pieces, defects: DeviceDefects
    ) -> ResidualBlock:
        index = np.flatnonzero(self.is_fixed)
        scale = 1.0 / self.sigma.position_m
        pairs = max(len(index) - 1, 0)
        values = (np.diff(pieces.poses[index, :3], axis=0) * scale).reshape(-1)
        device_rows = np.zeros((3 * pairs, N_DEVICE_PARAMETERS))
        if self.lvdt and pairs:  # F^j - F^k: fixed positions at their own lengths (module doc)
            fixed, d_fixed = self.fixed_positions(defects, index)
            values -= (np.diff(fixed, axis=0) * scale).reshape(-1)
            device_rows[:, :4] = -(np.diff(d_fixed, axis=0) * scale).reshape(3 * pairs, 4)
        jac = None
        if pieces.has_jacobian:
            diff = np.diff(pieces.pose_rows(index, slice(0, 3), 1.0), axis=0) * scale
            jac = self._jacobian(pieces, diff.reshape(3 * pairs, -1), device_rows)
        channels = np.tile(np.array(['x_difference', 'y_difference', 'z_difference']), pairs)
        block = ResidualBlock(values, jac, channels, np.repeat(index[1:], 3))
        d_pose = np.zeros((len(index), 3, 6))
        d_pose[:, [0, 1, 2], [0, 1, 2]] = scale
        return self._with_partner_noise(block, pieces, index, d_pose, rows_per_pair=3)

    def _with_partner_noise(
        self,
        block: ResidualBlock,
        pieces: _Pieces,
        index: np.ndarray,
        d_value_d_pose: np.ndarray,
        rows_per_pair: int = 1,
    ) -> ResidualBlock:
        """Rows value_j - value_k: noise derivatives from posture j (+) and its partner k (-)."""
        if pieces.d_actuators is None or len(index) < 2:
            return block
        d_pose = d_value_d_pose.reshape(len(index), rows_per_pair, 6)
        later = np.repeat(index[1:], rows_per_pair)
        earlier = np.repeat(index[:-1], rows_per_pair)
        block.noise_jacobian = self._noise(
            pieces, later, d_pose[1:].reshape(-1, 6), np.zeros((len(later), 3))
        )
        block.partner_noise_jacobian = self._noise(
            pieces, earlier, -d_pose[:-1].reshape(-1, 6), np.zeros((len(earlier), 3))
        )
        block.partners = earlier
        return block


def _stack(blocks: list[ResidualBlock]) -> ResidualBlock:
    def join(name):
        parts = [getattr(b, name) for b in blocks]
        if any(p is None for p in parts):
            return None
        return np.concatenate(parts)

    partners = None
    if any(b.partners is not None for b in blocks) and all(
        b.noise_jacobian is not None for b in blocks
    ):
        partners = np.concatenate(
            [b.partners if b.partners is not None else np.full(len(b.values), -1) for b in blocks]
        )
        partner_noise = np.concatenate(
            [
                b.partner_noise_jacobian
                if b.partner_noise_jacobian is not None
                else np.zeros((len(b.values), N_NOISE_SOURCES))
                for b in blocks
            ]
        )
    else:
        partner_noise = None
    width = next(
        (b.jacobian.shape[1] for b in blocks if b.jacobian is not None and b.jacobian.size), 0
    )
    jacobian = None
    if blocks[0].jacobian is not None:
        jacobian = np.concatenate(
            [
                b.jacobian.reshape(-1, width)
                if b.jacobian is not None and b.jacobian.size
                else np.zeros((0, width))
                for b in blocks
            ]
        )
    return ResidualBlock(
        join('values'),
        jacobian,
        join('channels'),
        join('postures'),
        join('noise_jacobian'),
        partners,
        partner_noise,
    )
