"""
What the walk reports (ROS-free): the status fields of its progress, its ETA, its summary.

core/walk/execution.py's `PlanExecution.progress`, `eta_s` and `summary` answer with these;
core/sessions/executor_session.py adds the executor's own fields to the status.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .platform_paths import move_duration
from .settings import ExecutionState

if TYPE_CHECKING:
    from .execution import PlanExecution

DEFAULT_OVERHEAD_S = 1.0  # ETA before any posture is done: per posture, besides moving, settle_s
UNDER_WAY = (ExecutionState.RUNNING, ExecutionState.PAUSED)  # started, not over


def eta_s(execution: PlanExecution, now: float) -> float | None:
    """Return seconds until the plan is done at the pace so far (None when over)."""
    if execution.state not in (*UNDER_WAY, ExecutionState.WAITING):
        return None
    settings = execution.settings
    done = [o for o in execution.outcomes if o.measured]
    overhead = (
        float(np.mean([o.duration_s - o.move_s for o in done]))
        if done
        else settings.settle_s + DEFAULT_OVERHEAD_S
    )
    remaining = 0.0
    latest, targets = execution.actuators.latest, execution.targets
    previous = latest if latest is not None else targets[0]
    for index in range(execution.index, execution.total):
        remaining += move_duration(
            previous, targets[index], settings.max_actuator_speed_m_s
        ) + max(overhead, 0.0)
        previous = targets[index]
    if execution.state == ExecutionState.RUNNING and execution.commanding:
        remaining -= min(now - execution.posture_start, remaining)
    return max(remaining, 0.0)


def skipped_text(execution: PlanExecution) -> str:
    """Return the postures skipped so far and why: '3: reason; 7: reason'."""
    return '; '.join(f'{o.index + 1}: {o.reason}' for o in execution.skipped)


def progress(execution: PlanExecution, now: float) -> dict[str, object]:
    """Return the status fields: state, posture k of K, measured, skipped, ETA."""
    state, total, index = execution.state, execution.total, execution.index
    values: dict[str, object] = {
        'state': state,
        'posture': min(index + 1, total) if state != ExecutionState.DONE else total,
        'postures': total,
        'measured': execution.measured,
        'skipped': len(execution.skipped),
        'corrections': execution.total_corrections,
    }
    if execution.skipped:
        values['skipped_postures'] = skipped_text(execution)
    if state in UNDER_WAY and index < total:
        values['kind'] = execution.kinds[index]
    judgement = execution.inclinometer_judgement
    if execution.commanding and judgement is not None:
        values['inclinometer'] = judgement.state  # fixed position: since the last move
    if total:
        values['device_turn_rad'] = float(execution.turns[min(index, total - 1)])
    if execution.turn_needed is not None:
        values['device_turn_needed_rad'] = execution.turn_needed
    eta = eta_s(execution, now)
    if eta is not None:
        values['eta_s'] = round(eta, 1)
    if execution.started_at is not None:
        end = execution.finished_at if execution.finished_at is not None else now
        values['elapsed_s'] = round(end - execution.started_at, 1)
        paused = execution.paused_s(now)
        if paused > 0:
            values['paused_s'] = round(paused, 1)
    return values


def summary(execution: PlanExecution) -> str:
    """Return one line: postures measured and skipped (which and why)."""
    skipped = execution.skipped
    return (
        f'{execution.measured} of {execution.total} postures measured, {len(skipped)} skipped'
        + (f' ({skipped_text(execution)})' if skipped else '')
    )


__all__ = ['eta_s', 'progress', 'summary']
