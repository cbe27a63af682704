"""
Whether a calibration's residuals are what its noise model predicts (the fit's adequacy).

With a noise model the identification whitens its residual rows: each row of a
posture is divided by the spread the reading noise gives it (through eq. 4 and
FK).  If the model describes the machine and the noise model is right, the sum
of squared whitened rows is chi-square distributed with ``dof = rows - rank``
degrees of freedom, so the variance factor ``s0^2 = r^T W r / dof`` lies near 1,
inside the chi-square quantiles ``[chi2_p(dof), chi2_(1-p)(dof)] / dof``.  Far
above that range the residuals cannot come from the reading noise: postures the
detector took badly, a defective device, or a machine the model does not
describe (backlash, compliance) - or a noise model that under-states the noise.
Naming the postures and channels whose whitened rows carry most of ``r^T W r``
points at which.

The test's tail.  Only a variance factor above the range fails (below it the noise model
over-states the noise, which harms no estimate), so the test is one-sided, and its false-alarm
probability ``TAIL_PROBABILITY`` is 1 %, not 0.1 %: a misfit the 54 geometric parameters can
partly absorb (compliance: the leg springs of the MuJoCo Hexa Slide deflect it by up to 8 um
against 2 um readings) leaves whitened residuals only 1.1-1.5 times the noise on the fit's own
postures, while fresh postures show it whole (verification rms 7-18 um against 5-8 um for the
same machine made rigid).  With 30 postures (66 degrees of freedom) the 0.1 % bound, s0^2 <=
1.63, passed 4 of 8 noise draws of that machine (variance factors 1.25-2.18, one at 1.61); the
1 % bound, 1.45, fails 7 of them, and neither fails the rigid machine (0.83-1.18).  A global
test of a least-squares fit is run at a larger false-alarm rate than a single-observation test
for this reason (Baarda's B-method); a fail names the postures and channels to look at.

The quantiles are scipy's (``scipy.special.gammaincinv``, as ``scipy.stats.chi2``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
import enum
import math

import numpy as np

# The 1 % and 99 % quantiles: a sound calibration fails one time in a hundred (module doc: a
# misfit the parameters partly absorb slips through the 0.1 % bound half the time).
TAIL_PROBABILITY = 1e-2
# Above this multiple of the upper bound (residuals twice the noise's), the verdict says in plain
# words that the reading noise cannot explain them.
FAR_ABOVE_FACTOR = 4.0
WORST_COUNT = 5  # postures and channels named
NO_NOISE_MODEL = (
    'no noise model to judge by: give the reading noise (--noise-um, or the noise parameters '
    'of the identify node) to compare the residuals with it'
)
CAUSES = 'a detector problem, a defective device, or a machine the model does not describe'


class Verdict(enum.StrEnum):
    """The adequacy verdict: its values are the JSON's and the status topic's."""

    PASS = 'pass'
    FAIL = 'fail'
    UNKNOWN = 'unknown'


@dataclass(frozen=True)
class WhitenedResiduals:
    """A fit's rows divided by the spread the noise model gives them (dimensionless)."""

    values: np.ndarray
    channels: np.ndarray  # channel of each row (x, y, z, phi, ...; prior.<name> for a prior row)
    postures: np.ndarray  # original posture index of each row; -1 for a prior row


@dataclass(frozen=True)
class Contribution:
    """A posture's or channel's share of r^T W r, and the rms of its whitened rows."""

    name: str  # posture index as text, or channel name
    share: float  # of r^T W r, 0..1
    rms: float  # rms whitened residual (1: what the noise predicts)

    def to_json(self, key: str) -> dict:
        name: int | str = int(self.name) if key == 'index' else self.name
        return {key: name, 'share': self.share, 'rms_whitened': self.rms}


@dataclass(frozen=True)
class Adequacy:
    """The variance factor, its expected range, the verdict and its reason."""

    verdict: Verdict
    reason: str
    variance_factor: float | None = None
    expected_range: tuple[float, float] | None = None
    dof: int | None = None
    worst_postures: list[Contribution] = field(default_factory=list)
    worst_channels: list[Contribution] = field(default_factory=list)

    @property
    def failed(self) -> bool:
        return self.verdict == Verdict.FAIL

    def to_json(self) -> dict:
        """Return the ``adequacy`` object of ``hexacal calibrate --json`` (see formats.md)."""
        return {
            'variance_factor': self.variance_factor,
            'expected_range': list(self.expected_range) if self.expected_range else None,
            'dof': self.dof,
            'verdict': self.verdict.value,
            'reason': self.reason,
            'worst_postures': [c.to_json('index') for c in self.worst_postures],
            'worst_channels': [c.to_json('channel') for c in self.worst_channels],
        }

    def status_fields(self) -> dict[str, str]:
        """Return the flattened ``adequacy.*`` keys of the calibration status."""
        fields = {'adequacy.verdict': self.verdict.value, 'adequacy.reason': self.reason}
        if self.variance_factor is not None and self.expected_range is not None:
            fields['adequacy.variance_factor'] = f'{self.variance_factor:.6g}'
            fields['adequacy.expected_low'] = f'{self.expected_range[0]:.6g}'
            fields['adequacy.expected_high'] = f'{self.expected_range[1]:.6g}'
            fields['adequacy.dof'] = str(self.dof)
        if self.worst_postures:
            fields['adequacy.worst_postures'] = ','.join(c.name for c in self.worst_postures)
        if self.worst_channels:
            fields['adequacy.worst_channels'] = ','.join(c.name for c in self.worst_channels)
        return fields

    def lines(self) -> list[str]:
        """Return the text the CLI prints (none without a noise model: that text is unchanged)."""
        if self.verdict == Verdict.UNKNOWN:
            return []
        lines = [f'adequacy: {self.verdict.value}: {self.reason}']
        if self.failed:
            postures = ', '.join(
                f'{c.name} ({c.share:.0%}, {c.rms:.1f}x)' for c in self.worst_postures
            )
            channels = ', '.join(
                f'{c.name} ({c.share:.0%}, {c.rms:.1f}x)' for c in self.worst_channels
            )
            lines.append(f'  largest contributions (share, rms / noise): postures {postures}')
            lines.append(f'  channels {channels}')
        return lines


def chi2_quantile(probability: float, dof: int) -> float:
    """Return the chi-square quantile of ``probability`` with ``dof`` degrees of freedom."""
    if dof <= 0:
        raise ValueError(f'chi-square needs dof > 0, got {dof}')
    # scipy.stats.chi2.ppf is 2 gammaincinv(dof / 2, p): the same numbers, without importing
    # scipy.stats (0.23 s here; scipy.special comes with scipy.optimize, which the fit loads).
    from scipy.special import gammaincinv

    return float(2.0 * gammaincinv(0.5 * dof, probability))


def expected_range(dof: int, tail: float = TAIL_PROBABILITY) -> tuple[float, float]:
    """Return the range of s0^2 = chi2(dof) / dof between the tail and 1 - tail quantiles."""
    return chi2_quantile(tail, dof) / dof, chi2_quantile(1.0 - tail, dof) / dof


def assess(whitened: WhitenedResiduals | None, rank: int) -> Adequacy:
    """
    Judge a fit by its whitened residuals (None: no noise model) and its rank.

    dof = rows - rank; the verdict is pass inside the expected range or below it (a noise
    model that over-states the noise), fail above it.
    """
    if whitened is None:
        return Adequacy(Verdict.UNKNOWN, NO_NOISE_MODEL)
    values = np.asarray(whitened.values, dtype=float)
    dof = len(values) - int(rank)
    if dof <= 0:
        return Adequacy(
            Verdict.UNKNOWN,
            f'no degrees of freedom to judge by ({len(values)} residuals, rank {rank})',
        )
    chi2 = float(values @ values)
    factor = chi2 / dof
    low, high = expected_range(dof)
    figures = (
        f'variance factor {factor:.3g}, expected {low:.3g}..{high:.3g} for {dof} degrees of '
        'freedom'
    )
    worst_postures = _worst(values, np.asarray(whitened.postures), chi2, skip=-1)
    worst_channels = _worst(values, np.asarray(whitened.channels).astype(str), chi2)
    if factor > high:
        ratio = math.sqrt(factor)
        if factor > FAR_ABOVE_FACTOR * high:
            reason = (
                f'{figures}: the residuals ({ratio:.3g} times the noise) cannot be explained by '
                f'the reading noise: {CAUSES}'
            )
        else:
            reason = (
                f'{figures}: the residuals ({ratio:.3g} times the noise) are larger than the '
                f'reading noise predicts: a noise model that under-states it, or {CAUSES}'
            )
        verdict = Verdict.FAIL
    elif factor < low:
        reason = (
            f'{figures}: the residuals are smaller than the noise model predicts (it may '
            'over-state the reading noise)'
        )
        verdict = Verdict.PASS
    else:
        reason = f'{figures}: the residuals are what the reading noise predicts'
        verdict = Verdict.PASS
    return Adequacy(verdict, reason, factor, (low, high), dof, worst_postures, worst_channels)


def _worst(values: np.ndarray, keys: np.ndarray, chi2: float, skip=None) -> list[Contribution]:
    """Return the WORST_COUNT keys whose rows carry the largest share of chi2, largest first."""
    contributions = []
    for key in dict.fromkeys(keys.tolist()):
        if skip is not None and key == skip:
            continue
        rows = values[keys == key]
        total = float(rows @ rows)
        contributions.append(
            Contribution(str(key), total / chi2 if chi2 > 0 else 0.0, math.sqrt(total / len(rows)))
        )
    contributions.sort(key=lambda c: -c.share)
    return contributions[:WORST_COUNT]
