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

The parts: ``payload`` (the result file's payload), ``verification_page`` (the verification
section and its page alone), ``markup`` (the page shell, units, number formats); the
workspace map's numbers come from ``core.assessment.position_error``.
"""

from __future__ import annotations

from dataclasses import replace
import html
import math
from pathlib import Path

from hexacal_msgs_py.files import atomic_write
from hexacal_msgs_py.models import DEFAULT_MODEL, ModelLayout
from hexacal_msgs_py.result_file import read_result_file, REPORT_DATA_KEY
import numpy as np

from .compliance_section import compliance_section
from .markup import dimensionless_fields as _dimensionless
from .markup import embedded_figure
from .markup import MM, UM
from .markup import number_text as _fmt
from .markup import page as _page
from .markup import vector
from .markup import vector_or_none as _vector
from .payload import result_payload, save_result
from .verification_page import verification_section, write_verification_report
from ..core.architectures import architecture
from ..core.assessment.position_error import MAP_GRID, predicted_position_error_map
from ..core.jsonsafe import json_safe as _plain
from ..core.machine.device import (
    check_mount,
    DEFAULT_LINK_LENGTH_M,
    DEFAULT_MOUNT,
    fixed_point,
    STANDING,
)


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
    return atomic_write(out / 'index.html', page)


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
            chain_std = _parameters_from_chain_dict(payload['std'], self.model)
            if chain_std is not None:
                std = np.where(chain_std < 0, np.nan, chain_std)
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
        return embedded_figure(self.out, name, draw)

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

        values = vector(residuals['values'])
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
        from ..core.assessment.identifiability import DEFAULT_RANK_TOLERANCE

        image = self.figure(
            'singular_values.png',
            lambda path: figures.singular_values(
                {'this calibration': vector(singular)}, DEFAULT_RANK_TOLERANCE, path
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


__all__ = [
    'MAP_GRID',
    'predicted_position_error_map',
    'result_payload',
    'save_result',
    'verification_section',
    'write_report',
    'write_verification_report',
]
