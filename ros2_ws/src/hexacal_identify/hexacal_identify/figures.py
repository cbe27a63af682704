"""PNG figures of the study and the calibration report (matplotlib, headless).

Display units are labelled: parameter errors in mm (rail-direction components
as 1000 x the unit-vector component, like the paper's Table 1), pose errors in
um and deg.
"""
from __future__ import annotations

from pathlib import Path
from typing import Sequence

import matplotlib

matplotlib.use("Agg")  # no display: figures are files
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from .core.model import FIELDS_PER_CHAIN, N_CHAINS, PARAMETER_FIELDS  # noqa: E402

MM = 1e3


def _save(fig, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def parameter_errors(initial_m: np.ndarray, final_m: np.ndarray, title: str, path: Path) -> Path:
    """Figs. 4-6: initial (square) and final (circle) error of each of the 54 parameters."""
    fig, ax = plt.subplots(figsize=(10, 3.6))
    index = np.arange(1, len(initial_m) + 1)
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.plot(index, initial_m * MM, "s", mfc="none", color="tab:red", label="initial error")
    ax.plot(index, final_m * MM, "o", mfc="none", color="tab:blue", label="final error")
    for chain in range(1, N_CHAINS):
        ax.axvline(chain * FIELDS_PER_CHAIN + 0.5, color="0.85", lw=0.8)
    ax.set_xlabel("parameter (chain-major: A0x A0y A0z Bx By Bz l ax ay per chain)")
    ax.set_ylabel("error [mm]")
    ax.set_title(title)
    ax.legend(loc="upper right")
    return _save(fig, path)


def chain_errors(initial_m: np.ndarray, final_m: np.ndarray, title: str, path: Path) -> Path:
    """Figs. 7-9: per kinematic chain, each parameter's error before and after (log scale)."""
    fig, axes = plt.subplots(1, N_CHAINS, figsize=(13, 3.4), sharey=True)
    before = np.abs(initial_m.reshape(N_CHAINS, FIELDS_PER_CHAIN)) * MM
    after = np.abs(final_m.reshape(N_CHAINS, FIELDS_PER_CHAIN)) * MM
    x = np.arange(FIELDS_PER_CHAIN)
    for chain, ax in enumerate(axes):
        ax.bar(x - 0.2, np.maximum(before[chain], 1e-9), 0.4, color="tab:red", label="before")
        ax.bar(x + 0.2, np.maximum(after[chain], 1e-9), 0.4, color="tab:blue", label="after")
        ax.set_yscale("log")
        ax.set_xticks(x, PARAMETER_FIELDS, rotation=90, fontsize=7)
        ax.set_title(f"chain {chain + 1}", fontsize=9)
    axes[0].set_ylabel("|error| [mm]")
    axes[0].legend(fontsize=7)
    fig.suptitle(title)
    return _save(fig, path)


def noise_table(levels: Sequence[float], ours_um: Sequence[float], ours_spread_um: Sequence[float],
                paper_um: Sequence[float], ours_deg: Sequence[float], paper_deg: Sequence[float], path: Path) -> Path:
    """Table 3 as a picture: mean validation pose error after calibration, hexacal vs the paper."""
    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 3.6))
    x = np.arange(len(levels))
    left.bar(x - 0.2, ours_um, 0.4, yerr=ours_spread_um, label="hexacal (mean over seeds)", color="tab:blue")
    left.bar(x + 0.2, paper_um, 0.4, label="paper, Table 3", color="tab:gray")
    left.set_xticks(x, [f"+-{level:g} um" for level in levels])
    left.set_ylabel("mean position error [um]")
    left.legend(fontsize=8)
    right.bar(x - 0.2, ours_deg, 0.4, color="tab:blue")
    right.bar(x + 0.2, paper_deg, 0.4, color="tab:gray")
    right.set_xticks(x, [f"+-{level:g} um" for level in levels])
    right.set_ylabel("mean orientation error [deg]")
    fig.suptitle("Pose error after calibration, 50 validation postures")
    return _save(fig, path)


def singular_values(spectra: dict[str, np.ndarray], rank_tolerance: float, path: Path) -> Path:
    """Column-scaled singular values of the identification Jacobian, one line per cost function."""
    fig, ax = plt.subplots(figsize=(8, 3.8))
    for label, values in spectra.items():
        values = np.asarray(values)
        ax.semilogy(np.arange(1, len(values) + 1), np.maximum(values / values[0], 1e-18), ".-", label=label)
    ax.axhline(rank_tolerance, color="k", ls="--", lw=0.8, label=f"rank threshold {rank_tolerance:g}")
    ax.set_xlabel("singular value index")
    ax.set_ylabel("sigma / sigma_max")
    ax.set_title("Identifiability: singular values of the scaled identification Jacobian")
    ax.legend(fontsize=8)
    return _save(fig, path)
