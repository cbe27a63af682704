"""Start, wait for and stop ROS node processes in system tests.

Each process runs in its own session (process group) so that stop() reaches
every child it spawns, e.g. the nodes started by `bringup`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
import os
from pathlib import Path
import signal
import subprocess
import sys
import tempfile
import time
from typing import IO, TypeVar

T = TypeVar('T')

DEFAULT_STOP_TIMEOUT_S = 10.0
# A process that outlives its stop timeout gets SIGABRT first: with PYTHONFAULTHANDLER set (as
# start_node sets it) Python writes every thread's stack to the log, which says where it hung.
ABORT_GRACE_S = 5.0


def venv_executable(name: str) -> str:
    """Path of a console script installed next to the running interpreter (.venv/bin)."""
    path = Path(sys.executable).parent / name
    if not path.exists():
        raise FileNotFoundError(f'{path} does not exist; did `make setup` install it?')
    return str(path)


@dataclass
class RosProcess:
    """A started process; its stdout and stderr go to log_path."""

    argv: list[str]
    popen: subprocess.Popen
    log_path: Path
    _log_file: IO[bytes] = field(repr=False)

    @property
    def pid(self) -> int:
        return self.popen.pid

    def running(self) -> bool:
        return self.popen.poll() is None

    def log_text(self) -> str:
        """Everything the process has written so far."""
        self._log_file.flush()
        return self.log_path.read_text(errors='replace')

    def describe(self, tail_lines: int = 40) -> str:
        """Command, state and last log lines, for failure messages."""
        state = 'running' if self.running() else f'exited with {self.popen.returncode}'
        tail = '\n'.join(self.log_text().splitlines()[-tail_lines:])
        return f'$ {" ".join(self.argv)}  [{state}, log {self.log_path}]\n{tail}'


def start_node(
    argv: Sequence[str],
    env: Mapping[str, str] | None = None,
    log_path: str | os.PathLike | None = None,
) -> RosProcess:
    """Start argv in a new session with os.environ updated by env.

    The environment carries the session's ROS_DOMAIN_ID set by conftest.py.
    Without log_path the output goes to a new temporary file.
    """
    if log_path is None:
        descriptor, name = tempfile.mkstemp(prefix='hexacal-node-', suffix='.log')
        os.close(descriptor)
        log_path = name
    log_path = Path(log_path)
    log_path.parent.mkdir(parents=True, exist_ok=True)
    log_file = open(log_path, 'wb')  # noqa: SIM115 (closed by stop())
    child_env = dict(os.environ)
    child_env.setdefault('PYTHONFAULTHANDLER', '1')
    if env:
        child_env.update(env)
    try:
        popen = subprocess.Popen(
            [os.fspath(arg) for arg in argv],
            stdin=subprocess.DEVNULL,
            stdout=log_file,
            stderr=subprocess.STDOUT,
            env=child_env,
            start_new_session=True,
        )
    except BaseException:
        log_file.close()
        raise
    return RosProcess(list(map(os.fspath, argv)), popen, log_path, log_file)


def _group_alive(pgid: int) -> bool:
    try:
        os.killpg(pgid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def _signal_group(pgid: int, signum: int) -> None:
    try:
        os.killpg(pgid, signum)
    except ProcessLookupError:
        pass


def _wait_group_gone(pgid: int, deadline: float) -> bool:
    while _group_alive(pgid):
        if time.monotonic() >= deadline:
            return False
        time.sleep(0.05)
    return True


def stop(process: RosProcess, timeout: float = DEFAULT_STOP_TIMEOUT_S) -> int:
    """SIGINT the process group, SIGABRT then SIGKILL it after `timeout` s; the exit code.

    The exit code is the leader's: 0 for a clean shutdown, -6 or -9 if it had to
    be killed (after SIGABRT the log holds the stack of each of its threads).
    Children left in the group get the same treatment.
    """
    pgid = process.popen.pid  # start_new_session: the leader's pid is the group id
    try:
        if process.popen.poll() is None:
            _signal_group(pgid, signal.SIGINT)
            try:
                process.popen.wait(timeout)
            except subprocess.TimeoutExpired:
                _signal_group(pgid, signal.SIGABRT)
                try:
                    process.popen.wait(ABORT_GRACE_S)
                except subprocess.TimeoutExpired:
                    _signal_group(pgid, signal.SIGKILL)
                    process.popen.wait()
        # Children that outlive the leader (they are not ours to wait for).
        if _group_alive(pgid):
            _signal_group(pgid, signal.SIGINT)
            if not _wait_group_gone(pgid, time.monotonic() + timeout):
                _signal_group(pgid, signal.SIGKILL)
                _wait_group_gone(pgid, time.monotonic() + timeout)
    finally:
        process._log_file.close()
    return process.popen.returncode


def wait_for(
    predicate: Callable[[], T],
    timeout: float,
    interval: float = 0.05,
    what: str = 'condition',
    details: Callable[[], str] | None = None,
) -> T:
    """Poll predicate until it returns a truthy value, which is returned.

    On timeout raise AssertionError naming `what`, plus details() (e.g. a
    process's describe()) when given.
    """
    deadline = time.monotonic() + timeout
    while True:
        result = predicate()
        if result:
            return result
        if time.monotonic() >= deadline:
            message = f'timed out after {timeout:g} s waiting for {what}'
            if details is not None:
                message += '\n' + details()
            raise AssertionError(message)
        time.sleep(interval)


class RosProcesses:
    """Processes of one test, logged under log_dir and stopped at teardown."""

    def __init__(self, log_dir: Path) -> None:
        self.log_dir = log_dir
        self.processes: list[RosProcess] = []

    def start(
        self, argv: Sequence[str], env: Mapping[str, str] | None = None, name: str | None = None
    ) -> RosProcess:
        """start_node() with the log at log_dir/<name>.log (name defaults to argv[0]'s)."""
        base = name or Path(os.fspath(argv[0])).name
        log_path = self.log_dir / f'{base}.log'
        suffix = 1
        while log_path.exists():
            suffix += 1
            log_path = self.log_dir / f'{base}-{suffix}.log'
        process = start_node(argv, env=env, log_path=log_path)
        self.processes.append(process)
        return process

    def stop(self, process: RosProcess, timeout: float = DEFAULT_STOP_TIMEOUT_S) -> int:
        self.processes.remove(process)
        return stop(process, timeout)

    def stop_all(self, timeout: float = DEFAULT_STOP_TIMEOUT_S) -> dict[str, int]:
        """Stop every process still held, newest first; argv[0] name -> exit code."""
        codes = {}
        while self.processes:
            process = self.processes.pop()
            codes[process.log_path.stem] = stop(process, timeout)
        return codes
