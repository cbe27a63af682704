#!/usr/bin/env python3
"""
Run the real demo per measuring mode, before -> after target refinement, today's demo beside.

For each machine model (``--models``): ``hexacal demo`` (the real nodes: driver, collector,
identify, executor as processes) in each measuring mode (passive_actuator, lvdt, compliant) with
the executor refining its targets from intermediate calibrations (the default), then compliant
``--no-refine``: today's demo (six compliant servos, every target from the nominal model), the
baseline of the same run. Each demo is a subprocess in a process group of its own, on a ROS
domain claimed for it (the lock files tests/conftest.py and the demo use),
ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST; its work directory and log stay under ``--out``.

Printed per model, one row per run, from the run's summary.json (docs/formats.md): the
postures walked on nominal -> refined targets, the largest deviation of a commanded actuator
from its setpoint at rest (the simulated truth), the largest force (compliant) or link extension
(lvdt) at rest, before -> after refinement, the pose error mean / max against the truth over
the validation poses, the verification rms (calibrated, on fresh postures) with its verdict,
and the wall time. A run that fails (a drive fault: the demo exits non-zero) is a row that says
what failed. ``--json`` prints the rows.

Run: ``.venv/bin/python benchmarks/bench_demo_modes.py [--models gough_stewart]
[--modes compliant] [--postures 50] [--verify-postures 20] [--seed 0] [--json]`` (about 3 minutes per run).
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass, field
import json
import os
from pathlib import Path
import re
import signal
import subprocess
import sys
import tempfile
import time
from typing import Any

from hexacal_identify.ros_domain import claim_domain_id

MODES = ('passive_actuator', 'lvdt', 'compliant')
MODELS = ('hexa_slide', 'gough_stewart')
STOP_GRACE_S = 20.0
UM = 1e6


@dataclass(frozen=True)
class DemoRun:
    """One demo: model, measuring mode and whether the executor refines its targets."""

    model: str
    mode: str
    refine: bool

    @property
    def label(self) -> str:
        """Return the row's name: the mode, and 'today' for the unrefined baseline."""
        return self.mode if self.refine else f'{self.mode} --no-refine (today)'

    @property
    def directory(self) -> str:
        """Return the run's work directory name."""
        return f'{self.model}_{self.mode}' + ('' if self.refine else '_no_refine')


@dataclass
class RunResult:
    """What one demo gave: its summary.json (None when it failed) or what failed."""

    model: str
    mode: str
    refine: bool
    exit_code: int | None
    wall_s: float
    out: str
    failure: str = ''
    summary: dict[str, Any] | None = field(default=None, repr=False)


def runs(models: list[str], modes: tuple[str, ...] = MODES) -> list[DemoRun]:
    """Return the runs: per model the refined modes, then today's compliant demo (if asked)."""
    return [
        run
        for model in models
        for run in [DemoRun(model, mode, True) for mode in modes]
        + ([DemoRun(model, 'compliant', False)] if 'compliant' in modes else [])
    ]


def demo_command(run: DemoRun, args: argparse.Namespace, out: Path) -> list[str]:
    """Return the demo's command line for `run`."""
    command = [
        str(Path(sys.executable).parent / 'hexacal'), 'demo',
        '--model', run.model,
        '--measuring-mode', run.mode,
        '--postures', str(args.postures),
        '--verify-postures', str(args.verify_postures),
        '--seed', str(args.seed),
        '--out', str(out),
    ]
    return command + ([] if run.refine else ['--no-refine'])


def demo_env() -> dict[str, str]:
    """Return the environment of a demo: a ROS domain of its own, localhost discovery."""
    env = dict(os.environ)
    domain = str(claim_domain_id())  # held by this process until it exits
    env.update(
        ROS_DOMAIN_ID=domain,
        HEXACAL_DEMO_DOMAIN_ID=domain,  # the demo takes this one instead of claiming its own
        ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST',
        PYTHONUNBUFFERED='1',
    )
    env.pop('ROS_STATIC_PEERS', None)
    return env


def stop_group(popen: subprocess.Popen) -> int:
    """Stop the demo's process group: SIGINT (its cleanup stops the nodes), then SIGKILL."""
    for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(popen.pid, signum)
        except ProcessLookupError:
            break
        try:
            return popen.wait(timeout=STOP_GRACE_S)
        except subprocess.TimeoutExpired:
            continue
    return popen.wait()


def failure_text(log: str, code: int | None) -> str:
    """Return what failed, from the demo's output: its error line, else the exit code."""
    errors = re.findall(r'^hexacal demo: error: (.+)$', log, re.M)
    if errors:
        text = errors[0]
        if 'faulted' in text:
            return 'drive fault: ' + text
        return text
    lines = [line for line in log.splitlines() if line.strip()]
    tail = lines[-1] if lines else ''
    return f'exit {code}' + (f': {tail}' if tail else '')


def run_demo(run: DemoRun, args: argparse.Namespace, root: Path) -> RunResult:
    """Run one demo to its end (or the timeout); return its summary or what failed."""
    out = root / run.directory
    out.mkdir(parents=True, exist_ok=True)
    log_path = out.parent / f'{run.directory}.log'
    started = time.monotonic()
    with open(log_path, 'wb') as log:
        popen = subprocess.Popen(
            demo_command(run, args, out),
            stdout=log,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            env=demo_env(),
            start_new_session=True,  # a process group of its own: stopped whole
        )
        try:
            code: int | None = popen.wait(timeout=args.timeout_s)
            timed_out = False
        except subprocess.TimeoutExpired:
            code, timed_out = stop_group(popen), True
    wall = time.monotonic() - started
    text = log_path.read_text(errors='replace')
    result = RunResult(run.model, run.mode, run.refine, code, wall, str(out))
    summary_path = out / 'summary.json'
    if timed_out:
        result.failure = f'timed out after {args.timeout_s:.0f} s (log {log_path})'
    elif code != 0 or not summary_path.exists():
        result.failure = failure_text(text, code)
    else:
        result.summary = json.loads(summary_path.read_text())
    return result


def _um(value: float | None) -> str:
    return '-' if value is None else f'{value * UM:.1f}'


def _n(value: float | None) -> str:
    return '-' if value is None else f'{value:.1f}'


def _pair(refinement: dict, key: str, show) -> str:
    before, after = refinement['before'][key], refinement['after'][key]
    if after is None and not refinement['after']['rests']:
        return f'{show(before)} -> none'
    return f'{show(before)} -> {show(after)}'


def row(result: RunResult) -> dict[str, Any]:
    """Return the printed and --json row of a result (SI; None where it does not apply)."""
    base = {
        'model': result.model,
        'measuring_mode': result.mode,
        'refine': result.refine,
        'exit_code': result.exit_code,
        'wall_s': round(result.wall_s, 1),
        'out': result.out,
        'failure': result.failure or None,
    }
    summary = result.summary
    if summary is None:
        return base
    verification = summary.get('verification') or {}
    calibrated = verification.get('calibrated') or {}
    refinement = summary.get('refinement')
    return {
        **base,
        'postures': summary['postures'],
        'max_actuator_deviation_m': summary['max_actuator_deviation_m'],
        'max_force_n': summary['max_force_n'],
        'max_link_extension_m': summary['max_link_extension_m'],
        'refinement': refinement,
        'pose_error_mean_m': summary['pose_error_mean_m'],
        'pose_error_max_m': summary['pose_error_max_m'],
        'verification_rms_m': calibrated.get('position_rms_m'),
        'verdict': verification.get('verdict'),
    }


def print_table(model: str, rows: list[dict], args: argparse.Namespace) -> None:
    """Print one model's rows: before -> after refinement, accuracy, verification, wall time."""
    print(
        f'\n{model}: hexacal demo, {args.postures} postures + {args.verify_postures} '
        f'verification postures, seed {args.seed}'
    )
    print(
        f'  {"mode":<30} {"postures":>9} {"deviation um":>19} {"force N / ext um":>19} '
        f'{"pose err mean/max um":>21} {"verif rms um":>13} {"verdict":>8} {"wall s":>7}'
    )
    for item in rows:
        label = DemoRun(model, item['measuring_mode'], item['refine']).label
        if item['failure']:
            print(f'  {label:<30} FAILED ({item["wall_s"]:.0f} s): {item["failure"][:240]}')
            continue
        refinement = item['refinement']
        postures = f'{refinement["postures_on_nominal"]}->{refinement["postures_on_refined"]}'
        if item['measuring_mode'] == 'compliant':
            load = _pair(refinement, 'max_force_n', _n)
        elif item['measuring_mode'] == 'lvdt':
            load = _pair(refinement, 'max_link_extension_m', _um)
        else:
            load = '-'
        accuracy = f'{_um(item["pose_error_mean_m"])} / {_um(item["pose_error_max_m"])}'
        print(
            f'  {label:<30} {postures:>9} '
            f'{_pair(refinement, "max_actuator_deviation_m", _um):>19} {load:>19} '
            f'{accuracy:>21} {_um(item["verification_rms_m"]):>13} '
            f'{item["verdict"] or "-":>8} {item["wall_s"]:>7.0f}'
        )
    print(
        '  postures: walked on nominal -> on refined targets (calibration plan, then the '
        "verification plan, on the calibration's targets\n  when refined); deviation: the "
        'largest |true position - setpoint| of a commanded actuator at rest; force (compliant)'
        '\n  / link extension (lvdt): the largest at rest; before -> after refinement; pose '
        'error against the simulated truth;\n  verif rms: the calibrated position rms on the '
        "fresh verification postures (no truth needed). The baseline is today's demo."
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.strip().splitlines()[0])
    parser.add_argument('--models', nargs='+', choices=MODELS, default=list(MODELS))
    parser.add_argument(
        '--modes', nargs='+', choices=MODES, default=list(MODES),
        help="measuring modes (default all; compliant adds today's --no-refine demo)",
    )
    parser.add_argument('--postures', type=int, default=50, help='postures (default 50)')
    parser.add_argument(
        '--verify-postures', type=int, default=20, help='verification postures (default 20)'
    )
    parser.add_argument('--seed', type=int, default=0, help='seed of the demos (default 0)')
    parser.add_argument(
        '--timeout-s', type=float, default=1200.0, help='longest run of one demo (default 1200)'
    )
    parser.add_argument(
        '--out', type=Path, default=None, help='where the demos write (default: a temp dir)'
    )
    parser.add_argument('--json', action='store_true', help='print the rows as JSON')
    args = parser.parse_args()
    root = (args.out or Path(tempfile.mkdtemp(prefix='bench_demo_modes_'))).resolve()
    progress = sys.stderr if args.json else sys.stdout
    planned = runs(args.models, tuple(args.modes))
    print(f'{len(planned)} demos, work directories under {root}', file=progress, flush=True)
    rows = []
    for number, run in enumerate(planned, 1):
        print(f'[{number}/{len(planned)}] {run.model} {run.label}: started', file=progress,
              flush=True)
        result = run_demo(run, args, root)
        outcome = f'FAILED: {result.failure}' if result.failure else 'ok'
        print(f'[{number}/{len(planned)}] {run.model} {run.label}: {result.wall_s:.0f} s, '
              f'{outcome}', file=progress, flush=True)
        rows.append(row(result))
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    for model in args.models:
        print_table(model, [item for item in rows if item['model'] == model], args)
    return 0


if __name__ == '__main__':
    sys.exit(main())
