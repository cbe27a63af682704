"""
The calibration report: a result file with everything, and a self-contained HTML page of it.

``save_result`` writes a result file (its format: hexacal_msgs_py.result_file), a superset of
``IdentificationResult.to_json()`` (what ``hexacal calibrate --json`` prints): the same keys,
plus under ``report_data`` the vectors and arrays a report needs (SI units; NaN as null).
``write_report`` turns such a file (or a plain ``--json`` output, with fewer
figures, or an IdentificationResult) into DIR/index.html plus PNG figures.  The
page embeds the PNGs as data URIs, so it opens offline and alone; the PNG files
sit beside it for reuse.  A tiny inline script records on <body> how many images
decoded (``data-images-loaded`` / ``data-images-total``), for headless checks.

Any machine model: the result names its model (``model``, as ``calibrate --json``
prints it; none = a Hexa Slide), and the page's parameter tables, figures and
workspace map use that model's fields, units, actuator names and default workspace.
"""

from __future__ import annotations

import base64
from dataclasses import replace
import html
import math
from pathlib import Path

from hexacal_msgs_py.files import atomic_write
from hexacal_msgs_py.models import DEFAULT_MODEL, ModelLayout
from hexacal_msgs_py.result_file import (
    ADEQUACY_KEY,
    DEVICE_PRIOR_KEY,
    FORMAT_KEY,
    read_result_file,
    REPORT_DATA_KEY,
    RESULT_FORMAT,
    write_result_file,
)
import numpy as np

from .compliance_section import compliance_section
from ..core.architectures import architecture
from ..core.jsonsafe import json_safe as _plain
from ..core.machine.device import (
    check_mount,
    DEFAULT_LINK_LENGTH_M,
    DEFAULT_MOUNT,
    fixed_point,
    STANDING,
)

UM, MM = 1e6, 1e3
MAP_GRID = 41  # cells per axis of the predicted pose-error map


# --------------------------------------------------------------------------- result file
def result_payload(
    result,
    extras: dict | None = None,
    *,
    measurements=None,
    true_parameters=None,
    link_length: float | None = None,
    mount: str | None = None,
    device_prior=None,
) -> dict:
    """
    ``result.to_json()`` plus the arrays of ``report_data`` (see module doc).

    ``mount``: the device mount (device.py), recorded when given; a report of a file without it
    takes the side of the device's base joint the poses are on.  ``device_prior``: the DevicePrior
    the calibration was given (or its ``{name: {value, std}}`` form), recorded as ``device_prior``
    beside ``device`` and ``device_std`` (what ``calibrate --json`` prints); the page shows prior
    and posterior side by side.
    """
    payload = result.to_json()
    payload[ADEQUACY_KEY] = result.adequacy.to_json()
    if device_prior is not None:
        payload[DEVICE_PRIOR_KEY] = _device_prior_dict(device_prior)
    layout = result.parameters.layout
    n = layout.n_parameters
    used = [int(i) for i in result.used_postures]
    kinds = None
    if measurements is not None:
        kinds = [str(k) for k in np.asarray(measurements.kinds)[used]]
    identifiability = result.identifiability
    truth = None
    if true_parameters is not None:
        truth = np.asarray(getattr(true_parameters, 'vector', true_parameters), dtype=float)[:n]
    if link_length is None:
        link_length = DEFAULT_LINK_LENGTH_M
    payload[FORMAT_KEY] = RESULT_FORMAT
    payload[REPORT_DATA_KEY] = _plain(
        {
            'parameter_names': list(layout.parameter_names),
            'parameters': result.parameters.vector,
            'initial_parameters': result.initial_parameters.vector,
            'true_parameters': truth,
            'std': np.asarray(result.std, dtype=float)[:n],
            'covariance': np.asarray(result.covariance, dtype=float)[:n, :n],
            'initial_rms_residual': result.initial_rms_residual,
            'residuals': {
                'values': result.residuals,
                'channels': [str(c) for c in result.residual_channels],
                'postures': [int(p) for p in result.residual_postures],
            },
            'used_postures': used,
            'poses': result.poses if result.poses is not None else [],
            'kinds': kinds,
            'singular_values': identifiability.singular_values,
            'verdict': identifiability.verdict(),
            'link_length': link_length,
            'extras': extras or {},
        }
    )
    if mount is not None:
        payload[REPORT_DATA_KEY]['mount'] = check_mount(mount)
    return payload


def _device_prior_dict(prior) -> dict:
    """{name: {"value", "std"}} (SI) of a DevicePrior, or such a dict as it is."""
    if isinstance(prior, dict):
        return {
            str(name): {'value': float(entry['value']), 'std': float(entry['std'])}
            for name, entry in prior.items()
        }
    return {name: {'value': float(value), 'std': float(std)} for name, value, std in prior.entries}


def save_result(
    path: Path | str,
    result,
    extras: dict | None = None,
    *,
    measurements=None,
    true_parameters=None,
    link_length: float | None = None,
    mount: str | None = None,
    device_prior=None,
) -> Path:
    """Write ``result_payload`` as a result file (hexacal_msgs_py.result_file)."""
    payload = result_payload(
        result,
        extras,
        measurements=measurements,
        true_parameters=true_parameters,
        link_length=link_length,
        mount=mount,
        device_prior=device_prior,
    )
    return write_result_file(path, _plain(payload))


def _atomic_write(path: Path, content: str | bytes) -> Path:
    return atomic_write(path, content)


# --------------------------------------------------------------------------- the report
def write_report(
    source,
    out_dir: Path | str,
    *,
    title: str | None = None,
    verification: dict | None = None,
    **result_options,
) -> Path:
    """
    DIR/index.html (+ PNGs) from a result file path, a payload dict, or an IdentificationResult.

    With an IdentificationResult, ``result_options`` are those of ``result_payload``
    (measurements, true_parameters, link_length, mount, extras): what the identify node passes.
    ``verification``: a verification of this calibration on fresh postures
    (``core.verification.VerificationResult.to_json(per_posture=True)``), shown in its own section
    (a payload's own ``verification`` key is shown the same way).
    """
    if isinstance(source, (str, Path)):
        payload = read_result_file(source)
        title = title or f'hexacal calibration report: {Path(source).name}'
    elif isinstance(source, dict):
        payload = source
    else:
        payload = _plain(result_payload(source, **result_options))
    if verification is not None:
        payload = {**payload, 'verification': _plain(verification)}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    sections = _Sections(payload, out)
    page = _page(title or 'hexacal calibration report', sections.build(), sections.layout)
    return _atomic_write(out / 'index.html', page)


def _vector(values) -> np.ndarray | None:
    if values is None:
        return None
    return np.array([np.nan if v is None else v for v in values], dtype=float)


def _parameters_from_chain_dict(chains: dict | None, model: str) -> np.ndarray | None:
    if not chains:
        return None
    from hexacal_msgs_py.parameters_file import chain_dict_to_parameters

    return np.asarray(chain_dict_to_parameters(chains, model), dtype=float)


class _Sections:
    """Builds each section's HTML and figure from a payload; a section without its data says so."""

    def __init__(self, payload: dict, out: Path):
        self.payload = payload
        self.out = out
        data = payload.get(REPORT_DATA_KEY) or {}
        self.data = data
        self.model = (
            payload.get('model') or DEFAULT_MODEL
        )  # results written before models existed: Hexa Slide
        self.architecture = architecture(
            self.model
        )  # an unknown model is a ValueError naming the known ones
        self.layout: ModelLayout = self.architecture.layout
        self.parameters = _vector(data.get('parameters'))
        if self.parameters is None:
            self.parameters = _parameters_from_chain_dict(payload.get('parameters'), self.model)
        self.initial = _vector(data.get('initial_parameters'))
        self.truth = _vector(data.get('true_parameters'))
        std = _vector(data.get('std'))
        if std is None and payload.get('std'):  # plain --json output: -1 marks an unknown std
            std = _parameters_from_chain_dict(payload['std'], self.model)
            std = np.where(std < 0, np.nan, std)
        self.std = std
        covariance = data.get('covariance')
        self.covariance = (
            None
            if covariance is None
            else np.array(
                [[np.nan if v is None else v for v in row] for row in covariance], dtype=float
            )
        )
        self.names = data.get('parameter_names') or list(self.layout.parameter_names)
        n = self.layout.n_parameters
        for name, values in (
            ('parameters', self.parameters),
            ('initial parameters', self.initial),
            ('true parameters', self.truth),
            ('standard deviations', self.std),
            ('parameter names', self.names),
        ):
            if values is not None and len(values) != n:
                raise ValueError(
                    f"the result's {name} have {len(values)} entries, but its model "
                    f'{self.model} has {n} parameters'
                )
        self.link_length = float(data.get('link_length') or DEFAULT_LINK_LENGTH_M)
        self.poses = np.array(data.get('poses') or np.zeros((0, 6)), dtype=float).reshape(-1, 6)
        # The device mount: recorded, else the side of O the poses are on (standing: the platform
        # above it).
        self.mount = check_mount(
            data.get('mount')
            or (STANDING if len(self.poses) and np.median(self.poses[:, 2]) > 0 else DEFAULT_MOUNT)
        )
        # Where the machine works: its architecture's default workspace, on this result's measuring
        # link.
        self.workspace = replace(
            self.architecture.default_workspace(), link_length=self.link_length
        )

    def build(self) -> list[str]:
        parts = [self.summary()]
        if self.payload.get('verification'):
            parts.append(verification_section(self.payload['verification'], self.figure))
        if self.payload.get('adequacy'):
            parts.append(self.adequacy())
        parts.append(self.identified())
        if self.payload.get('device_identified'):
            parts.append(self.device_parameters())
        if compliance_section(self.payload):
            parts.append(compliance_section(self.payload))
        for section in (
            self.corrections,
            self.truth_errors,
            self.residuals,
            self.identifiability,
            self.pose_error_map,
            self.postures,
        ):
            parts.append(section())
        return parts

    # -- helpers
    def figure(self, name: str, draw) -> str:
        path = draw(self.out / name)
        encoded = base64.b64encode(Path(path).read_bytes()).decode('ascii')
        return (
            f'<figure><img src="data:image/png;base64,{encoded}" alt="{html.escape(name)}">'
            f'<figcaption>{html.escape(name)}</figcaption></figure>'
        )

    @staticmethod
    def missing(title: str, why: str) -> str:
        return (
            f'<section><h2>{html.escape(title)}</h2>'
            f"<p class='note'>Not shown: {html.escape(why)}.</p></section>"
        )

    # -- sections
    def summary(self) -> str:
        p = self.payload
        outcome = p.get('reason')
        if (p.get('adequacy') or {}).get('verdict') == 'fail':  # never simply "converged"
            outcome = f'{outcome}, but the fit is inadequate (see Adequacy)'
        rows = [
            ('Outcome', outcome, 'outcome'),
            ('Cost function', p.get('cost'), 'cost'),
            (
                'Machine model',
                f'{self.layout.title}: {self.layout.n_parameters} parameters, actuators '
                f'{self.layout.actuator_names[0]}..{self.layout.actuator_names[-1]}',
                'model',
            ),
            (
                'Rank',
                f'{p.get("rank")} of '
                + str(
                    (p.get('identifiability') or {}).get('n_parameters', self.layout.n_parameters)
                ),
                'rank',
            ),
            (
                'Condition number (column-scaled)',
                _fmt(p.get('condition_number'), '{:.4g}'),
                'condition',
            ),
            ('Iterations', p.get('iterations'), 'iterations'),
            ('Solve time', _fmt(p.get('solve_seconds'), '{:.3f} s'), 'solve-time'),
            ('Postures used', p.get('postures_used'), 'postures-used'),
            ('Postures rejected', len(p.get('postures_rejected') or []), 'postures-rejected'),
        ]
        if p.get('weights'):  # what weighed the fit (a result file without the key: unsaid)
            rows.append(('Weights', p.get('weights_note') or p['weights'], 'weights'))
        initial_rms = self.data.get('initial_rms_residual') or {}
        for channel, value in (p.get('rms_residual') or {}).items():
            scale, unit = (UM, 'urad') if channel.startswith('phi') else (UM, 'um')
            before = initial_rms.get(channel)
            text = f'{value * scale:.3f} {unit}' if value is not None else 'n/a'
            if before is not None:
                text += f' (before: {before * scale:.3f} {unit})'
            rows.append((f'RMS residual {channel}', text, f'rms-{channel}'))
        if self.parameters is not None and self.initial is not None:
            correction = self.parameters - self.initial
            k = int(np.nanargmax(np.abs(correction)))
            rows.append(
                (
                    'Largest correction',
                    f'{correction[k] * MM:+.4f} mm ({self.names[k]})',
                    'largest-correction',
                )
            )
        if self.std is not None and np.any(np.isfinite(self.std)):
            k = int(np.nanargmax(self.std))
            rows.append(
                ('Largest std', f'{self.std[k] * UM:.3f} um ({self.names[k]})', 'largest-std')
            )
        if self.truth is not None and self.initial is not None and self.parameters is not None:
            before = np.max(np.abs(self.initial - self.truth))
            after = np.max(np.abs(self.parameters - self.truth))
            rows.append(
                (
                    'Largest parameter error (truth known)',
                    f'before {before * MM:.4f} mm, after {after * UM:.3f} um',
                    'truth-error',
                )
            )
        extras = self.data.get('extras') or {}
        if extras.get('calibration_id'):  # the identify node's: its calibration store entry
            where = f'{extras["calibration_id"]} in {extras.get("calibration_store", "")}'
            rows.append(('Calibration store entry', where, 'store-entry'))
        if 'active_calibration' in extras:  # which calibration the machine used when written
            active = extras['active_calibration']
            text = (
                f'{active} ({extras.get("active_reason")} since {extras.get("active_since")})'
                if active
                else 'none deployed'
            )
            rows.append(('Active calibration', text, 'active-calibration'))
        validation = extras.get('validation') or p.get('validation')
        if validation:
            for when in ('before', 'after'):
                v = validation.get(when) or {}
                if 'position_mean_m' in v:
                    rows.append(
                        (
                            f'Validation pose error {when}',
                            f'{v["position_mean_m"] * UM:.2f} um, '
                            f'{math.degrees(v["orientation_mean_rad"]):.5f} deg',
                            f'validation-{when}',
                        )
                    )
        table = ''.join(
            f"<tr><th>{html.escape(str(k))}</th><td id='{i}'>{html.escape(str(v))}</td></tr>"
            for k, v, i in rows
        )
        rejected = p.get('postures_rejected') or []
        rejected_html = ''
        if rejected:
            items = ''.join(
                f'<li>posture {r.get("index")}: {html.escape(str(r.get("reason")))}</li>'
                for r in rejected
            )
            rejected_html = f'<h3>Rejected postures</h3><ul>{items}</ul>'
        return (
            f"<section><h2>Summary</h2><table class='summary'>{table}</table>"
            f'{rejected_html}</section>'
        )

    def adequacy(self) -> str:
        """Return the fit against its noise model: verdict, figures, worst postures/channels."""
        a = self.payload['adequacy']
        verdict = str(a.get('verdict'))
        rows = [
            ('Verdict', verdict, 'adequacy-verdict'),
            ('Why', a.get('reason'), 'adequacy-reason'),
        ]
        if a.get('variance_factor') is not None:
            low, high = a.get('expected_range') or (None, None)
            rows.append(
                (
                    'Variance factor',
                    f'{_fmt(a["variance_factor"], "{:.4g}")} (expected {_fmt(low, "{:.3g}")}'
                    f'..{_fmt(high, "{:.3g}")} for {a.get("dof")} degrees of freedom)',
                    'adequacy-variance-factor',
                )
            )
        for title, key, name in (
            ('Largest contributions: postures', 'worst_postures', 'index'),
            ('Largest contributions: channels', 'worst_channels', 'channel'),
        ):
            if a.get(key):
                text = ', '.join(
                    f'{c.get(name)} ({c.get("share", 0.0):.0%} of the sum, '
                    f'{_fmt(c.get("rms_whitened"), "{:.2g}")} x the noise)'
                    for c in a[key]
                )
                rows.append((title, text, f'adequacy-{key.replace("_", "-")}'))
        table = ''.join(
            f"<tr><th>{html.escape(k)}</th><td id='{i}'>{html.escape(str(v))}</td></tr>"
            for k, v, i in rows
        )
        note = (
            "<p class='note'>The residuals whitened by the reading noise (the postures' scatter "
            'or the noise model: see Weights): their sum of squares over '
            'the degrees of freedom (residuals - rank) is ~1 when the noise explains them; the '
            'range is chi-square&#39;s 0.1 % .. 99.9 %.</p>'
        )
        return f"<section><h2>Adequacy</h2><table class='summary'>{table}</table>{note}</section>"

    def identified(self) -> str:
        """
        Return the identified parameters per chain.

        The identified parameters per chain, in the model's own keys (A0/B/a/l, A/B/l0, ...) and
        display units.
        """
        layout = self.layout
        title = f'Identified parameters: {layout.title}'
        if self.parameters is None:
            return self.missing(title, 'the result file has no parameters')
        per_chain = self.parameters.reshape(layout.n_chains, layout.fields_per_chain)
        dimensionless = set(_dimensionless(layout))
        header, legend = '<th>chain</th><th>actuator</th>', ''
        for key in layout.chain_keys:
            fields = layout.fields[key.offset:key.offset + (key.count or 1)]
            unit = 'x1000' if set(fields) <= dimensionless else 'mm'
            header += (
                f"<th title='{html.escape(key.description)}'>{html.escape(key.name)} [{unit}]</th>"
            )
            legend += (
                f'<li><b>{html.escape(key.name)}</b> ({", ".join(fields)}): '
                f'{html.escape(key.description)}</li>'
            )
        rows = ''
        for chain in range(layout.n_chains):
            cells = ''
            for key in layout.chain_keys:
                values = per_chain[chain, key.offset:key.offset + (key.count or 1)] * MM
                cells += f'<td>{", ".join(f"{v:.4f}" for v in values)}</td>'
            rows += (
                f'<tr><td>chain_{chain + 1}</td>'
                f'<td>{html.escape(layout.actuator_names[chain])}</td>{cells}</tr>'
            )
        return (
            f"<section><h2>{html.escape(title)}</h2><table class='data' "
            "id='identified-parameters'>"
            f"<tr>{header}</tr>{rows}</table><ul class='note'>{legend}</ul></section>"
        )

    def device_parameters(self) -> str:
        """
        Return the prior and posterior of each identified device parameter.

        Prior (value +- std, or none) and posterior of each identified device parameter, um / urad.
        """
        from ..core.machine.device import DEVICE_PARAMETER_NAMES

        title = 'Device parameters: prior and posterior'
        identified = [
            n for n in DEVICE_PARAMETER_NAMES if n in (self.payload.get('device_identified') or ())
        ]
        device = self.payload.get('device') or {}
        device_std = self.payload.get('device_std') or {}
        prior = self.payload.get('device_prior') or {}
        rows = ''
        for name in identified:
            unit = 'um' if name == 'dL' else 'urad'
            given = prior.get(name)
            prior_text = (
                'none'
                if not given
                else (f'{given["value"] * UM:.3f} +- {given["std"] * UM:.3f} {unit}')
            )
            value, std = device.get(name), device_std.get(name)
            posterior = (
                'n/a'
                if value is None
                else (
                    f'{value * UM:.3f} +- {_fmt(None if std is None else std * UM, "{:.3f}")} '
                    f'{unit}'
                )
            )
            rows += (
                f"<tr><td>{html.escape(name)}</td><td>{unit}</td><td id='device-prior-{name}'>"
                f'{html.escape(prior_text)}</td><td '
                f"id='device-posterior-{name}'>{html.escape(posterior)}</td>"
                '</tr>'
            )
        note = (
            "<p class='note'>dL (link length offset) in um, angles (inclinometer zeros alpha0, "
            'beta0, axis skew gamma, rotary zero phi0) in urad; +- one standard deviation. A '
            'prior enters the fit as one weighted row (value - prior) / std.</p>'
        )
        return (
            f"<section><h2>{title}</h2><table class='data' "
            "id='device-parameters'><tr><th>parameter</th>"
            '<th>unit</th><th>prior</th><th>identified (posterior)</th></tr>'
            f'{rows}</table>{note}</section>'
        )

    def corrections(self) -> str:
        title = 'Parameter corrections and their standard deviations'
        if self.parameters is None or self.initial is None or self.std is None:
            return self.missing(
                title,
                'the result file has no initial parameters (save it with report.save_result)',
            )
        from . import figures

        correction = self.parameters - self.initial
        image = self.figure(
            'corrections.png',
            lambda path: figures.parameter_corrections(correction, self.std, path, self.layout),
        )
        rows = ''.join(
            f'<tr><td>{html.escape(n)}</td><td>{c * MM:+.4f}</td>'
            f'<td>{_fmt(s * UM, "{:.3f}")}</td></tr>'
            for n, c, s in zip(self.names, correction, self.std)
        )
        table = (
            f'<details><summary>All {len(self.names)} parameters</summary><table '
            "class='data'><tr><th>parameter</th>"
            f'<th>correction [mm]</th><th>std [um]</th></tr>{rows}</table></details>'
        )
        return f'<section><h2>{title}</h2>{image}{table}</section>'

    def truth_errors(self) -> str:
        title = 'Errors before and after, per chain (simulation: truth known)'
        if self.truth is None or self.initial is None or self.parameters is None:
            return self.missing(title, 'the true parameters are not known (a real machine)')
        from . import figures

        before, after = self.initial - self.truth, self.parameters - self.truth
        images = self.figure(
            'parameter_errors.png',
            lambda path: figures.parameter_errors(
                before,
                after,
                'Parameter errors before (square) and after (circle), cf. paper Figs. 4-6',
                path,
                self.layout,
            ),
        )
        images += self.figure(
            'chain_errors.png',
            lambda path: figures.chain_errors(
                before, after, 'Errors in kinematic chains, cf. paper Figs. 7-9', path, self.layout
            ),
        )
        return f'<section><h2>{title}</h2>{images}</section>'

    def residuals(self) -> str:
        title = 'Residuals per posture and channel'
        residuals = self.data.get('residuals')
        if not residuals or not residuals.get('values'):
            return self.missing(title, 'the result file has no residual rows')
        from . import figures

        values = _vector(residuals['values'])
        image = self.figure(
            'residuals.png',
            lambda path: figures.residuals_by_posture(
                np.asarray(residuals['postures']), values, np.asarray(residuals['channels']), path
            ),
        )
        return f'<section><h2>{title}</h2>{image}</section>'

    def identifiability(self) -> str:
        title = 'Identifiability: singular values of the scaled identification Jacobian'
        identifiability = self.payload.get('identifiability') or {}
        singular = self.data.get('singular_values') or identifiability.get('singular_values')
        verdict = self.data.get('verdict') or _verdict_from_json(identifiability)
        if not singular:
            return self.missing(title, 'the result file has no singular values')
        from . import figures
        from ..core.fit.identifiability import DEFAULT_RANK_TOLERANCE

        image = self.figure(
            'singular_values.png',
            lambda path: figures.singular_values(
                {'this calibration': _vector(singular)}, DEFAULT_RANK_TOLERANCE, path
            ),
        )
        return (
            f"<section><h2>{title}</h2><p class='verdict' id='verdict'>{html.escape(verdict)}</p>"
            f'{image}</section>'
        )

    def pose_error_map(self) -> str:
        title = 'Predicted position error over the workspace'
        if self.covariance is None or self.parameters is None:
            return self.missing(title, 'the result file has no covariance')
        from . import figures

        x, y, std = predicted_position_error_map(
            self.parameters,
            self.covariance,
            self.link_length,
            xy_range_m=self.workspace.xy_range_m,
            model=self.model,
            mount=self.mount,
        )
        poses = self.poses
        image = self.figure(
            'pose_error_map.png',
            lambda path: figures.pose_error_map(x, y, std, path, poses[:, :2]),
        )
        finite = std[np.isfinite(std)]
        numbers = (
            (
                '<p>Linearised: std = sqrt(trace(J_p C J_p<sup>T</sup>)), J_p = dP/du at each '
                '(x, y) on the L-sphere with zero rotation, C the parameter covariance. Median '
                f'{np.median(finite) * UM:.2f} um, max {np.max(finite) * UM:.2f} um over the '
                'feasible cells.</p>'
            )
            if finite.size
            else ''
        )
        return f'<section><h2>{title}</h2>{numbers}{image}</section>'

    def postures(self) -> str:
        title = 'Postures used'
        poses = self.poses
        if not len(poses):
            return self.missing(title, 'the result file has no poses')
        from . import figures

        kinds = self.data.get('kinds')
        if (
            kinds is None
            # not recorded: a posture at [0, 0, -L] ([0, 0, L] standing) within 1 mm was a
            # fixed one
        ):
            at_fixed = (
                np.linalg.norm(poses[:, :3] - fixed_point(self.link_length, self.mount), axis=1)
                < 1e-3
            )
            kinds = np.where(at_fixed, 'fixed', 'sphere')
        image = self.figure(
            'postures.png',
            lambda path: figures.postures_on_sphere(
                poses, np.asarray(kinds), path, self.workspace.xy_range_m
            ),
        )
        return f'<section><h2>{title}</h2>{image}</section>'


def verification_section(verification: dict, figure) -> str:
    """
    Return the verification section.

    Nominal vs calibrated figures, verdict, and the per-posture figure.

    ``verification`` is ``VerificationResult.to_json(per_posture=True)`` (SI units, null for NaN);
    ``figure(name, draw)`` embeds a PNG (``_Sections.figure``).
    """
    title = 'Verification on fresh postures (no ground truth)'
    sets = {name: verification.get(name) or {} for name in ('nominal', 'calibrated')}

    def cell(name: str, key: str, scale: float, unit: str) -> str:
        value = sets[name].get(key)
        return 'n/a' if value is None else f'{value * scale:.2f} {unit}'

    rows = [
        ('Position error rms', 'position_rms_m', UM, 'um'),
        ('Position error max', 'position_max_m', UM, 'um'),
        ('Rotary error rms', 'rotary_rms_rad', UM, 'urad'),
    ]
    table = '<tr><th></th><th>nominal</th><th>calibrated</th></tr>'
    for label, key, scale, unit in rows:
        table += (
            f'<tr><th>{label}</th><td '
            f"id='verification-nominal-{key}'>{cell('nominal', key, scale, unit)}</td>"
            f"<td id='verification-calibrated-{key}'>"
            f'{cell("calibrated", key, scale, unit)}</td></tr>'
        )
    table += (
        '<tr><th>Forward kinematics failed</th>'
        + ''.join(
            f"<td id='verification-{name}-fk-failures'>"
            f'{int(sets[name].get("fk_failures") or 0)}</td>'
            for name in sets
        )
        + '</tr>'
    )
    improvement = verification.get('improvement')
    threshold = verification.get('threshold_m')
    summary_rows = [
        ('Postures', verification.get('postures'), 'verification-postures'),
        (
            'Improvement (nominal rms / calibrated rms)',
            'n/a' if improvement is None else f'{improvement:.1f} x',
            'verification-improvement',
        ),
        (
            'Threshold',
            ('n/a' if threshold is None else f'{threshold * UM:.2f} um')
            + (
                f' ({verification["threshold_source"]})'
                if verification.get('threshold_source')
                else ''
            ),
            'verification-threshold',
        ),
    ]
    noise = verification.get('expected_noise')
    if noise and noise.get('position_rms_m') is not None:
        summary_rows.append(
            (
                'Expected from reading noise alone',
                f'{noise["position_rms_m"] * UM:.2f} um, '
                f'{(noise.get("rotary_rms_rad") or 0) * UM:.2f} urad',
                'verification-expected-noise',
            )
        )
    summary_rows.append(
        (
            'Verdict',
            verification.get('verdict_reason') or verification.get('verdict'),
            'verification-verdict',
        )
    )
    summary = ''.join(
        f"<tr><th>{html.escape(str(k))}</th><td id='{i}'>{html.escape(str(v))}</td></tr>"
        for k, v, i in summary_rows
    )
    failures = ''
    for name in sets:
        failed = sets[name].get('failed_postures') or []
        if failed:
            items = ''.join(
                f'<li>posture {f.get("index")}: {html.escape(str(f.get("reason")))}</li>'
                for f in failed
            )
            failures += (
                f'<h3>Forward kinematics failed with the {name} parameters</h3><ul>{items}</ul>'
            )
    image = ''
    per_posture = verification.get('per_posture') or {}
    if per_posture.get('nominal_position_error_m') is not None:
        from . import figures

        before = _vector(per_posture['nominal_position_error_m'])
        after = _vector(per_posture['calibrated_position_error_m'])
        rotary = [per_posture.get(f'{name}_rotary_error_rad') for name in sets]
        image = figure(
            'verification.png',
            lambda path: figures.verification_errors(
                before,
                after,
                threshold if threshold is not None else float('nan'),
                path,
                kinds=np.asarray(per_posture.get('kinds') or ['sphere'] * len(before)),
                nominal_rotary_rad=_vector(rotary[0]),
                calibrated_rotary_rad=_vector(rotary[1]),
            ),
        )
    text = (
        '<p>Fresh postures, not used in the fit: what the device measured (position by eq. 4, the '
        'fixed point for fixed-position postures; phi from the rotary sensor) against forward '
        'kinematics at the measured actuator readings, with the nominal and with the calibrated '
        'parameters.</p>'
    )
    return (
        f"<section id='verification'><h2>{title}</h2>{text}<table class='data' "
        "id='verification-figures'>"
        f"{table}</table><table class='summary'>{summary}</table>{failures}{image}</section>"
    )


def write_verification_report(
    verification: dict, out_dir: Path | str, *, title: str | None = None
) -> Path:
    """
    Write DIR/index.html with the verification section alone.

    DIR/index.html (+ verification.png) with the verification section alone (``hexacal verify
    --report``).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    verification = _plain(verification)
    layout = architecture(verification.get('model') or DEFAULT_MODEL).layout

    def figure(name: str, draw) -> str:
        path = draw(out / name)
        encoded = base64.b64encode(Path(path).read_bytes()).decode('ascii')
        return (
            f'<figure><img src="data:image/png;base64,{encoded}" alt="{html.escape(name)}">'
            f'<figcaption>{html.escape(name)}</figcaption></figure>'
        )

    rows = [
        ('Machine model', f'{layout.title}'),
        ('Source', verification.get('source') or 'n/a'),
        ('Nominal parameters', verification.get('nominal_file') or 'n/a'),
        ('Calibrated parameters', verification.get('calibrated_file') or 'n/a'),
        (
            'Device',
            f'link {(verification.get("link_length_m") or DEFAULT_LINK_LENGTH_M) * MM:.1f} mm, '
            f'{verification.get("mount") or DEFAULT_MOUNT}',
        ),
    ]
    header = ''.join(
        f'<tr><th>{html.escape(k)}</th><td>{html.escape(str(v))}</td></tr>' for k, v in rows
    )
    sections = [
        f"<section><h2>Summary</h2><table class='summary'>{header}</table></section>",
        verification_section(verification, figure),
    ]
    return _atomic_write(
        out / 'index.html', _page(title or 'hexacal verification report', sections, layout)
    )


def predicted_position_error_map(
    parameters: np.ndarray,
    covariance: np.ndarray,
    link_length: float,
    grid: int = MAP_GRID,
    xy_range_m: float | None = None,
    model: str | None = None,
    mount: str = DEFAULT_MOUNT,
):
    """
    (x, y, std) of the linearised position error, sqrt(trace(J_p C J_p^T)), on an x, y grid (m).

    J_p = dP/du at (x, y, -sqrt(L^2 - x^2 - y^2), 0, 0, 0) (+sqrt standing); cells the machine
    cannot reach (its architecture's default workspace, on this link) are NaN.  Parameters without
    a variance count as exact.  ``model`` None = the Hexa Slide; ``xy_range_m`` None = the
    workspace's.
    """
    from ..core.machine.postures import acceptable_poses
    from ..core.fit.uncertainty import position_covariances

    arch = architecture(model)
    n = arch.layout.n_parameters
    params = arch.parameters(np.asarray(parameters, dtype=float)[:n])
    workspace = replace(arch.default_workspace(), link_length=link_length)
    if xy_range_m is None:
        xy_range_m = workspace.xy_range_m
    axis = np.linspace(-xy_range_m, xy_range_m, grid)
    x, y = np.meshgrid(axis, axis)
    radius2 = link_length**2 - x**2 - y**2
    side = np.sign(
        fixed_point(link_length, mount)[2]
    )  # -1 hanging, +1 standing: the platform's side of O
    poses = np.column_stack(
        [
            x.ravel(),
            y.ravel(),
            side * np.sqrt(np.maximum(radius2, 0.0)).ravel(),
            np.zeros((x.size, 3)),
        ]
    )
    ok = (radius2.ravel() > 0) & acceptable_poses(params, poses, workspace)
    std = np.full(x.size, np.nan)
    if np.any(ok):
        cov = np.nan_to_num(np.asarray(covariance, dtype=float)[:n, :n], nan=0.0, posinf=0.0)
        variance = np.trace(position_covariances(params, cov, poses[ok]), axis1=1, axis2=2)
        std[ok] = np.sqrt(np.maximum(variance, 0.0))
    return x, y, std.reshape(x.shape)


def _verdict_from_json(identifiability: dict) -> str:
    if not identifiability:
        return 'unknown'
    if identifiability.get('identifiable'):
        return (
            f'all {identifiability.get("n_parameters")} parameters identifiable (rank '
            f'{identifiability.get("rank")}, '
            f'condition number {identifiability.get("condition_number", float("nan")):.3g})'
        )
    combos = '; '.join(identifiability.get('unidentifiable_combinations') or [])
    return (
        f'rank {identifiability.get("rank")} of {identifiability.get("n_parameters")}: '
        f'not identifiable: {combos}'
    )


def _fmt(value, pattern: str) -> str:
    if value is None or (isinstance(value, float) and not math.isfinite(value)):
        return 'n/a'
    return pattern.format(value)


_STYLE = """
body { font-family: sans-serif; margin: 2em auto; max-width: 1150px; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; margin-top: 2em; }
table.summary th { text-align: left; padding-right: 2em; font-weight: normal; color: #555; }
table.data { border-collapse: collapse; font-size: 0.85em; }
table.data td, table.data th { padding: 1px 8px; }
figure { margin: 1em 0; } img { max-width: 100%; } figcaption { font-size: 0.8em; color: #777; }
.verdict { font-weight: bold; white-space: pre-wrap; } .note { color: #777; }
"""

# Counts the images that decoded once the page has loaded, for headless checks (works offline: no
# requests).
_IMAGE_CHECK = """
window.addEventListener('load', function () {
  var images = document.images, loaded = 0;
  for (var i = 0; i < images.length; i++) {
    if (images[i].complete && images[i].naturalWidth > 0) loaded++;
  }
  document.body.setAttribute('data-images-loaded', String(loaded));
  document.body.setAttribute('data-images-total', String(images.length));
});
"""


def _dimensionless(layout: ModelLayout) -> list[str]:
    """
    Return the per-chain fields without a unit.

    Per-chain fields without a unit (the Hexa Slide's rail components ax, ay): shown as 1000 x the
    value.
    """
    return [name for name, unit in zip(layout.fields, layout.field_units) if unit == '1']


def _page(title: str, sections: list[str], layout: ModelLayout) -> str:
    dimensionless = _dimensionless(layout)
    scaled = (
        f' (dimensionless {", ".join(dimensionless)} as 1000 x the value)' if dimensionless else ''
    )
    return (
        "<!DOCTYPE html>\n<html lang='en'><head><meta charset='utf-8'>"
        f'<title>{html.escape(title)}</title><style>{_STYLE}</style></head>\n<body>'
        f'<h1>{html.escape(title)}</h1>'
        f"<p class='note'>Units: parameters in mm{scaled}, standard deviations "
        'and residuals in um and urad; the files hold SI units.</p>\n'
        + '\n'.join(sections)
        + f'\n<script>{_IMAGE_CHECK}</script></body></html>\n'
    )


__all__ = [
    'predicted_position_error_map',
    'result_payload',
    'save_result',
    'verification_section',
    'write_report',
    'write_verification_report',
]
