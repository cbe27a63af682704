"""
Choose a design from a candidate set: greedy and exchange selection.

Selection: greedy (add the candidate that maximises the index, one at a time;
the information matrix gets a rank-r update per posture, and all candidates
are scored at once with batched r x r determinants or n x n eigenvalues) and
Fedorov-style exchange (from the greedy design, swap a design posture for the
candidate that improves the index most, until a whole pass swaps nothing).
While the design has fewer rows than parameters every index is zero; the D
criterion with a tiny ridge (log det(M + delta I)) then chooses, whatever index
was asked for, because it rewards each new independent direction.

The relative cost (eqs. 12, 13) differences consecutive postures of the same
kind, so a posture's rows depend on its predecessor: greedy appends in plan
order (exact), exchange swaps within a kind in place (also exact).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .candidate_set import CandidateSet, kind_neighbours
from .observability import check_index, full_rank, index_from_eigenvalues, PREDICTION
from ..machine.measurements import POSTURE_KINDS

RIDGE = 1e-8  # delta of log det(M + delta I), relative to the mean per-posture information
Progress = Callable[[str], None]


def no_progress(_: str) -> None:
    """Report nothing (the default progress callback)."""


def _score(
    base: np.ndarray,
    added: np.ndarray,
    n_postures: int,
    index: str,
    ridge: float,
    use_d_criterion: bool,
    weight: np.ndarray | None = None,
) -> np.ndarray:
    """Criterion of base + A_c^T A_c for every candidate c (higher is better)."""
    if index == PREDICTION and not use_d_criterion:
        assert weight is not None  # CandidateSet.position_weight: set for I
        # -trace(W (B + A^T A)^-1) by Woodbury: trace(W B^-1) - trace(S^-1 A B^-1 W B^-1 A^T), S =
        # I + A B^-1 A^T.
        inverse = np.linalg.inv(base + ridge * np.eye(len(base)))
        projected = added @ inverse
        inner = projected @ added.transpose(0, 2, 1) + np.eye(added.shape[1])
        weighted = projected @ weight @ projected.transpose(0, 2, 1)
        reduction = np.trace(np.linalg.solve(inner, weighted), axis1=1, axis2=2)
        return reduction - np.trace(weight @ inverse)
    if use_d_criterion or index == 'O1':
        # log det(B + A^T A) = log det B + log det(I + A B^-1 A^T): r x r determinants per
        # candidate.
        regularised = base + ridge * np.eye(len(base))
        inverse = np.linalg.inv(regularised)
        inner = (added @ inverse) @ added.transpose(0, 2, 1) + np.eye(added.shape[1])
        return np.linalg.slogdet(regularised)[1] + np.linalg.slogdet(inner)[1]
    eigenvalues = np.linalg.eigvalsh(base[None] + added.transpose(0, 2, 1) @ added)
    return index_from_eigenvalues(eigenvalues, n_postures, index)


def greedy_design(
    candidates: CandidateSet,
    n_postures: int,
    index: str = 'O1',
    progress: Progress = no_progress,
    kind_counts: dict[str, int] | None = None,
    screen: int = 300,
    excluded: np.ndarray | None = None,
) -> tuple[np.ndarray, list[float]]:
    """
    Add, one at a time, the candidate that maximises the index; return (design, history).

    The history is the D-criterion's.

    The history holds log det(M + delta I) after each pick: it never decreases.
    ``kind_counts`` caps the postures of each kind.  The relative cost needs it:
    there, a kind's first posture adds only its phi row (its differences need a
    partner), so one-step greedy would never start the fixed-position kind.
    For O2-O4 only the ``screen`` candidates with the best D-criterion gain are
    scored exactly (n x n eigenvalues each); O1 and I score every candidate.
    ``excluded``: candidate indices never chosen.
    """
    check_index(index)
    n = len(candidates)
    if n_postures > n:
        raise ValueError(f'cannot choose {n_postures} postures from {n} candidates')
    available = np.ones(n, bool)
    if excluded is not None and len(excluded):
        available[np.asarray(excluded, dtype=int)] = False
    remaining = dict(kind_counts) if kind_counts is not None else None
    ridge = RIDGE * _mean_posture_information(candidates)
    information = candidates.start_information()
    design: list[int] = []
    last_of_kind = {kind: -1 for kind in POSTURE_KINDS}
    history = []
    if remaining is not None:
        if sum(remaining.values()) < n_postures:
            raise ValueError(f'kind_counts {remaining} allow fewer than {n_postures} postures')
        available &= np.isin(candidates.kinds, [k for k, count in remaining.items() if count > 0])
    for step in range(n_postures):
        pool = np.flatnonzero(available)
        if not len(pool):
            raise ValueError(f'only {step} candidates fit the kind counts; {n_postures} requested')
        previous = np.array([last_of_kind[k] for k in candidates.kinds[pool]])
        added = candidates.slot_rows(pool, previous, np.full(len(pool), -1))
        d_phase = not full_rank(information)
        if not (d_phase or index in ('O1', PREDICTION)) and len(pool) > screen:
            keep = np.argsort(_score(information, added, step + 1, index, ridge, True))[-screen:]
            pool, added = pool[keep], added[keep]
        scores = _score(
            information, added, step + 1, index, ridge, d_phase, candidates.position_weight
        )
        best = int(np.argmax(scores))
        choice = int(pool[best])
        design.append(choice)
        available[choice] = False
        if remaining is not None:
            kind = candidates.kinds[choice]
            remaining[kind] -= 1
            if remaining[kind] <= 0:
                available &= candidates.kinds != kind
        last_of_kind[candidates.kinds[choice]] = choice
        information = information + added[best].T @ added[best]
        history.append(
            float(np.linalg.slogdet(information + ridge * np.eye(candidates.n_parameters))[1])
        )
        progress(f'greedy {index}: {step + 1}/{n_postures} postures')
    return np.array(design, dtype=int), history


def exchange_design(
    candidates: CandidateSet,
    start: np.ndarray,
    index: str = 'O1',
    max_passes: int = 10,
    progress: Progress = no_progress,
    screen: int = 300,
) -> tuple[np.ndarray, list[float]]:
    """
    Exchange from ``start`` (Fedorov-style): swap postures for better candidates while it helps.

    A plan posture is swapped for the best candidate while the index improves.

    Returns (design, criterion after each accepted swap), strictly increasing.  For
    O2-O4 each slot scores the ``screen`` candidates with the best D-criterion gain
    exactly (eigenvalues); O1 scores every candidate.  The relative cost swaps
    within a kind, in place, so each posture keeps its neighbours.
    """
    check_index(index)
    design = np.array(start, dtype=int)
    ridge = RIDGE * _mean_posture_information(candidates)
    information = candidates.information(design)
    use_d = not full_rank(information)
    current = _design_criterion(
        information, len(design), index, ridge, use_d, candidates.position_weight
    )
    history = [current]
    for sweep in range(max_passes):
        swapped = False
        for slot in range(len(design)):
            previous, following = kind_neighbours(candidates.kinds, design, slot)
            old = candidates.slot_rows(
                design[[slot]], np.array([previous]), np.array([following])
            )[0]
            base = information - old.T @ old
            pool = np.setdiff1d(np.arange(len(candidates)), design)
            if (
                candidates.relative
            ):  # keep the kind sequence: the differences stay between the same slots
                pool = pool[candidates.kinds[pool] == candidates.kinds[design[slot]]]
            if not len(pool):
                continue
            added = candidates.slot_rows(
                pool, np.full(len(pool), previous), np.full(len(pool), following)
            )
            if not (use_d or index in ('O1', PREDICTION)) and len(pool) > screen:
                d_gain = _score(base, added, len(design), index, ridge, True)
                keep = np.argsort(d_gain)[-screen:]
                pool, added = pool[keep], added[keep]
            scores = _score(
                base, added, len(design), index, ridge, use_d, candidates.position_weight
            )
            best = int(np.argmax(scores))
            if scores[best] > current + 1e-12 * max(abs(current), 1.0):
                design[slot] = pool[best]
                information = base + added[best].T @ added[best]
                current = float(scores[best])
                history.append(current)
                swapped = True
        progress(f'exchange {index}: pass {sweep + 1}, {len(history) - 1} swaps')
        if not swapped:
            break
    return design, history


def _design_criterion(
    information: np.ndarray,
    n_postures: int,
    index: str,
    ridge: float,
    use_d: bool,
    weight: np.ndarray | None = None,
) -> float:
    if index == PREDICTION and not use_d:
        assert weight is not None  # CandidateSet.position_weight: set for I
        return -float(
            np.trace(weight @ np.linalg.inv(information + ridge * np.eye(len(information))))
        )
    if use_d or index == 'O1':
        return float(np.linalg.slogdet(information + ridge * np.eye(len(information)))[1])
    return float(index_from_eigenvalues(np.linalg.eigvalsh(information), n_postures, index))


def _mean_posture_information(candidates: CandidateSet) -> float:
    """Mean eigenvalue of one posture's information: the unit of the ridge."""
    stacked = (
        candidates.rows
        if not candidates.relative
        else np.concatenate([candidates.rows, candidates.difference_rows], axis=1)
    )
    return float(
        np.einsum('nrk,nrk->', stacked, stacked) / (len(candidates) * candidates.n_parameters)
    )
