"""
PNG figures of the study and the calibration report (matplotlib, headless).

Display units are labelled: parameter errors in mm (a dimensionless parameter,
such as the Hexa Slide's rail-direction components, as 1000 x its value, like
the paper's Table 1), pose errors in um and deg.

Parameter figures are labelled with the machine model's own fields (its
``ModelLayout``): pass ``layout``, or let the figure take the one model whose
parameter vector has that many entries (54 Hexa Slide, 42 Gough-Stewart).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Mapping, Sequence

from hexacal_msgs_py.models import model_for_vector_size, ModelLayout
import matplotlib

matplotlib.use('Agg')  # no display: figures are files
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

MM = 1e3


def _layout(n_values: int, layout: ModelLayout | None) -> ModelLayout:
    """
    Return the layout of a parameter vector of ``n_values`` entries.

    The layout of a parameter vector of ``n_values`` entries (``layout`` if given).
    """
    return layout if layout is not None else model_for_vector_size(n_values)


def _per_chain_label(layout: ModelLayout) -> str:
    return f'parameter (chain-major: {" ".join(layout.fields)} per chain)'


def _chain_separators(ax, layout: ModelLayout) -> None:
    for chain in range(1, layout.n_chains):
        ax.axvline(chain * layout.fields_per_chain + 0.5, color='0.85', lw=0.8)


def _save(fig, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def parameter_errors(
    initial_m: np.ndarray,
    final_m: np.ndarray,
    title: str,
    path: Path,
    layout: ModelLayout | None = None,
) -> Path:
    """Figs. 4-6: initial (square) and final (circle) error of each of the model's parameters."""
    layout = _layout(len(initial_m), layout)
    fig, ax = plt.subplots(figsize=(10, 3.6))
    index = np.arange(1, len(initial_m) + 1)
    ax.axhline(0.0, color='0.6', lw=0.8)
    ax.plot(index, initial_m * MM, 's', mfc='none', color='tab:red', label='initial error')
    ax.plot(index, final_m * MM, 'o', mfc='none', color='tab:blue', label='final error')
    _chain_separators(ax, layout)
    ax.set_xlabel(_per_chain_label(layout))
    ax.set_ylabel('error [mm]')
    ax.set_title(title)
    ax.legend(loc='upper right')
    return _save(fig, path)


def chain_errors(
    initial_m: np.ndarray,
    final_m: np.ndarray,
    title: str,
    path: Path,
    layout: ModelLayout | None = None,
) -> Path:
    """Figs. 7-9: per kinematic chain, each parameter's error before and after (log scale)."""
    layout = _layout(len(initial_m), layout)
    shape = (layout.n_chains, layout.fields_per_chain)
    fig, axes = plt.subplots(1, layout.n_chains, figsize=(13, 3.4), sharey=True)
    before = np.abs(np.asarray(initial_m).reshape(shape)) * MM
    after = np.abs(np.asarray(final_m).reshape(shape)) * MM
    x = np.arange(layout.fields_per_chain)
    for chain, ax in enumerate(axes):
        ax.bar(x - 0.2, np.maximum(before[chain], 1e-9), 0.4, color='tab:red', label='before')
        ax.bar(x + 0.2, np.maximum(after[chain], 1e-9), 0.4, color='tab:blue', label='after')
        ax.set_yscale('log')
        ax.set_xticks(x, layout.fields, rotation=90, fontsize=7)
        ax.set_title(f'chain {chain + 1}', fontsize=9)
    axes[0].set_ylabel('|error| [mm]')
    axes[0].legend(fontsize=7)
    fig.suptitle(title)
    return _save(fig, path)


def noise_table(
    levels: Sequence[float],
    ours_um: Sequence[float],
    ours_spread_um: Sequence[float],
    paper_um: Sequence[float],
    ours_deg: Sequence[float],
    paper_deg: Sequence[float],
    path: Path,
    noise_unit: str = 'um',
) -> Path:
    """
    Draw Table 3: mean validation pose error after calibration, hexacal vs the paper.

    The noise levels are labelled in `noise_unit` (ActuatorQuantities.small: um on sliders,
    urad on cranks, whose readings are all angles).
    """
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.6))
    x = np.arange(len(levels))
    left.bar(
        x - 0.2,
        ours_um,
        0.4,
        yerr=ours_spread_um,
        label='hexacal (mean over seeds)',
        color='tab:blue',
    )
    left.bar(x + 0.2, paper_um, 0.4, label='paper, Table 3', color='tab:gray')
    ticks = [f'+-{level:g} {noise_unit}' for level in levels]
    left.set_xticks(x, ticks)
    left.set_ylabel('mean position error [um]')
    left.legend(fontsize=8)
    right.bar(x - 0.2, ours_deg, 0.4, color='tab:blue')
    right.bar(x + 0.2, paper_deg, 0.4, color='tab:gray')
    right.set_xticks(x, ticks)
    right.set_ylabel('mean orientation error [deg]')
    fig.suptitle('Pose error after calibration, 50 validation postures')
    return _save(fig, path)


def singular_values(spectra: dict[str, np.ndarray], rank_tolerance: float, path: Path) -> Path:
    """Column-scaled singular values of the identification Jacobian, one line per cost function."""
    fig, ax = plt.subplots(figsize=(8, 3.8))
    for label, values in spectra.items():
        values = np.asarray(values)
        ax.semilogy(
            np.arange(1, len(values) + 1), np.maximum(values / values[0], 1e-18), '.-', label=label
        )
    ax.axhline(
        rank_tolerance, color='k', ls='--', lw=0.8, label=f'rank threshold {rank_tolerance:g}'
    )
    ax.set_xlabel('singular value index')
    ax.set_ylabel('sigma / sigma_max')
    ax.set_title('Identifiability: singular values of the scaled identification Jacobian')
    ax.legend(fontsize=8)
    return _save(fig, path)


# --------------------------------------------------------------------------- calibration report
# and planning
UM = 1e6


def parameter_corrections(
    correction_m: np.ndarray, std_m: np.ndarray, path: Path, layout: ModelLayout | None = None
) -> Path:
    """
    Draw each parameter's correction with +-std error bars.

    Each parameter's correction (identified - initial) with +-std error bars, and the std alone
    (log).
    """
    layout = _layout(len(correction_m), layout)
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(11, 5.6), sharex=True)
    index = np.arange(1, len(correction_m) + 1)
    std = np.where(np.isfinite(std_m), std_m, np.nan)
    top.axhline(0.0, color='0.6', lw=0.8)
    top.errorbar(
        index,
        correction_m * MM,
        yerr=np.nan_to_num(std) * MM,
        fmt='o',
        ms=3,
        capsize=2,
        color='tab:blue',
        ecolor='tab:red',
        label='correction +- std',
    )
    top.set_ylabel('correction [mm]')
    top.legend(loc='upper right', fontsize=8)
    dimensionless = [name for name, unit in zip(layout.fields, layout.field_units) if unit == '1']
    top.set_title(
        'Identified corrections'
        + (f' (dimensionless {", ".join(dimensionless)}: x1000)' if dimensionless else '')
    )
    bottom.semilogy(index, np.where(std > 0, std * UM, np.nan), 's', ms=3, color='tab:red')
    bottom.set_ylabel('std [um]')
    bottom.set_xlabel(_per_chain_label(layout))
    for ax in (top, bottom):
        _chain_separators(ax, layout)
    return _save(fig, path)


def residuals_by_posture(
    postures: np.ndarray, values: np.ndarray, channels: np.ndarray, path: Path
) -> Path:
    """
    Draw the final residuals per posture.

    Final residuals per posture, one marker per channel: lengths in um (left), angles in urad
    (right).
    """
    channels = np.asarray(channels).astype(str)
    angular = np.char.startswith(channels, 'phi')
    fig, axes = plt.subplots(1, 2, figsize=(11, 3.6))
    for ax, mask, unit in ((axes[0], ~angular, 'um'), (axes[1], angular, 'urad')):
        for channel in dict.fromkeys(channels[mask].tolist()):
            rows = channels == channel
            ax.plot(postures[rows], values[rows] * UM, '.', ms=5, label=channel)
        ax.axhline(0.0, color='0.6', lw=0.8)
        ax.set_xlabel('posture index')
        ax.set_ylabel(f'residual [{unit}]')
        if np.any(mask):
            ax.legend(fontsize=7, ncol=2)
    axes[0].set_title('Length / position residuals')
    axes[1].set_title('Rotary (phi) residuals')
    return _save(fig, path)


def pose_error_map(
    x_m: np.ndarray,
    y_m: np.ndarray,
    std_m: np.ndarray,
    path: Path,
    postures_xy_m: np.ndarray | None = None,
) -> Path:
    """
    Draw the predicted std of the position error over the workspace.

    Predicted std of the position error over the workspace (heat map, um); NaN cells are
    infeasible.
    """
    fig, ax = plt.subplots(figsize=(6.2, 5.0))
    mesh = ax.pcolormesh(x_m * MM, y_m * MM, std_m * UM, shading='auto', cmap='viridis')
    fig.colorbar(mesh, ax=ax, label='predicted position error std [um]')
    if postures_xy_m is not None and len(postures_xy_m):
        ax.plot(
            postures_xy_m[:, 0] * MM,
            postures_xy_m[:, 1] * MM,
            'w+',
            ms=6,
            label='measured postures',
        )
        ax.legend(fontsize=8, loc='upper right')
    ax.set_xlabel('x [mm]')
    ax.set_ylabel('y [mm]')
    ax.set_aspect('equal')
    ax.set_title('Predicted pose error on the L-sphere, zero rotation')
    return _save(fig, path)


def postures_on_sphere(
    poses: np.ndarray, kinds: np.ndarray, path: Path, xy_range_m: float = 0.4
) -> Path:
    """
    Draw the postures used, seen from above.

    The postures used, seen from above (x, y on the L-sphere), coloured by kind; arrows show the
    tilt.
    """
    fig, ax = plt.subplots(figsize=(5.6, 5.0))
    kinds = np.asarray(kinds).astype(str)
    colours = {'sphere': 'tab:blue', 'fixed': 'tab:orange'}
    for kind in dict.fromkeys(kinds.tolist()):
        rows = kinds == kind
        ax.scatter(
            poses[rows, 0] * MM,
            poses[rows, 1] * MM,
            s=22,
            color=colours.get(kind, 'k'),
            label=f'{kind} ({int(rows.sum())})',
            zorder=3,
        )
        # theta tilts about Y (moves x'), psi about X: a short arrow shows each posture's tilt
        ax.quiver(
            poses[rows, 0] * MM,
            poses[rows, 1] * MM,
            np.degrees(poses[rows, 3]),
            -np.degrees(poses[rows, 4]),
            color=colours.get(kind, 'k'),
            alpha=0.45,
            angles='xy',
            scale_units='xy',
            scale=0.25,
            width=0.004,
        )
    limit = xy_range_m * MM
    ax.add_patch(
        plt.Rectangle((-limit, -limit), 2 * limit, 2 * limit, fill=False, ls='--', color='0.5')
    )
    ax.set_xlim(-1.15 * limit, 1.15 * limit)
    ax.set_ylim(-1.15 * limit, 1.15 * limit)
    ax.set_aspect('equal')
    ax.set_xlabel('x [mm]')
    ax.set_ylabel('y [mm]')
    ax.legend(fontsize=8, loc='upper right')
    ax.set_title('Postures used (arrows: tilt theta, -psi; 1 deg = 4 mm)')
    return _save(fig, path)


def planning_accuracy(
    ks: Sequence[int],
    curves: Mapping[str, tuple[Sequence[float] | np.ndarray, Sequence[float] | np.ndarray]],
    reference_um: float,
    reference_label: str,
    path: Path,
) -> Path:
    """
    Draw the validation position error vs number of postures.

    Planned against random (mean +- error bar over seeds).
    """
    fig, ax = plt.subplots(figsize=(7.5, 4.2))
    for label, (mean_values, spread_values) in curves.items():
        mean_um, spread_um = np.asarray(mean_values, float), np.asarray(spread_values, float)
        lower = np.minimum(spread_um, 0.9 * mean_um)  # a log axis cannot show a bar below zero
        bars = np.array([lower, spread_um])
        ax.errorbar(ks, mean_um, yerr=bars, fmt='o-', capsize=3, label=label)
    ax.axhline(reference_um, color='k', ls='--', lw=0.9, label=reference_label)
    ax.set_xlabel('postures K')
    ax.set_ylabel('mean validation position error [um]')
    ax.set_yscale('log')
    ax.set_title('Accuracy vs number of postures: planned vs random (mean +- s.e. over seeds)')
    ax.legend(fontsize=8)
    return _save(fig, path)


def verification_errors(
    nominal_m: np.ndarray,
    calibrated_m: np.ndarray,
    threshold_m: float,
    path: Path,
    kinds: np.ndarray | None = None,
    nominal_rotary_rad: np.ndarray | None = None,
    calibrated_rotary_rad: np.ndarray | None = None,
) -> Path:
    """
    Draw the verification errors per fresh posture.

    Per fresh posture, the position error |P_fk - P_measured| of the nominal (square) and the
    calibrated (circle) parameters, um on a log axis, with the verdict's threshold; below, |rotary
    error| in urad.

    NaN (forward kinematics failed) is drawn as an x on the lower edge; fixed-position postures are
    filled.
    """
    nominal_m, calibrated_m = np.asarray(nominal_m, float), np.asarray(calibrated_m, float)
    rotary = nominal_rotary_rad is not None and calibrated_rotary_rad is not None
    fig, axes = plt.subplots(
        2 if rotary else 1, 1, figsize=(11, 6.4 if rotary else 3.8), sharex=True, squeeze=False
    )
    index = np.arange(len(nominal_m))
    fixed = (
        (np.asarray(kinds).astype(str) == 'fixed')
        if kinds is not None
        else np.zeros(len(index), bool)
    )
    # (axes, nominal, calibrated, label, threshold or None)
    panels: list[tuple[Any, np.ndarray, np.ndarray, str, float | None]] = [
        (axes[0, 0], nominal_m * UM, calibrated_m * UM, 'position error [um]', threshold_m * UM)
    ]
    if rotary:
        panels.append(
            (
                axes[1, 0],
                np.abs(np.asarray(nominal_rotary_rad, float)) * UM,
                np.abs(np.asarray(calibrated_rotary_rad, float)) * UM,
                '|rotary error| [urad]',
                None,
            )
        )
    for ax, before, after, label, threshold in panels:
        finite = np.concatenate([before[np.isfinite(before)], after[np.isfinite(after)]])
        floor = max(float(np.min(finite[finite > 0])) / 3 if np.any(finite > 0) else 1e-3, 1e-6)
        for values, marker, colour, name in (
            (before, 's', 'tab:red', 'nominal'),
            (after, 'o', 'tab:blue', 'calibrated'),
        ):
            ok = np.isfinite(values)
            shown = np.maximum(values, floor)  # an exact fit (0) stays on the log axis
            ax.plot(
                index[ok & ~fixed],
                shown[ok & ~fixed],
                marker,
                mfc='none',
                color=colour,
                ms=5,
                label=f'{name} (sphere)' if fixed.any() else name,
            )
            if fixed.any():
                ax.plot(
                    index[ok & fixed],
                    shown[ok & fixed],
                    marker,
                    color=colour,
                    ms=5,
                    label=f'{name} (fixed)',
                )
            if (~ok).any():
                ax.plot(
                    index[~ok],
                    np.full(int((~ok).sum()), floor),
                    'x',
                    color=colour,
                    ms=7,
                    label=f'{name}: forward kinematics failed',
                )
        if threshold is not None:
            ax.axhline(
                threshold, color='k', ls='--', lw=0.9, label=f'threshold {threshold:.1f} um'
            )
        ax.set_yscale('log')
        ax.set_ylabel(label)
        ax.legend(fontsize=7, loc='upper left', bbox_to_anchor=(1.01, 1.0))
    axes[0, 0].set_title(
        "Verification on fresh postures: forward kinematics vs the device's measurement"
    )
    axes[-1, 0].set_xlabel('verification posture index')
    return _save(fig, path)
