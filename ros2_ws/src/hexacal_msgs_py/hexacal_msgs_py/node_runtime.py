"""
How every hexacal node starts, spins and stops: one place for the shutdown rules.

A terminal's Ctrl-C reaches a node twice under `ros2 launch`: the terminal sends
SIGINT to the whole process group, then launch forwards another SIGINT to each
node; supervisors send SIGTERM. rclpy's own handlers would shut the context down
from their signal thread while the main thread may be inside the executor's wait
on that context, a race that aborts the process now and then (rclpy issue 1453:
"Fatal Python error: Aborted" in `_wait_for_ready_callbacks`). So rclpy installs
no handler here: a Python handler notes the signal; the interpreter's wakeup fd
(`signal.set_wakeup_fd`) lets a watcher thread trigger a guard condition, which
wakes the executor's wait (a Python handler runs only once the main thread is
back from C); spinning ends, and the context is shut down on the main thread
once nothing waits on it. The executor spins as `Executor.spin` does, with no
timeout. From then on SIGINT and SIGTERM are ignored: the node finishes its
files, destroys itself and exits 0 with no traceback, however many signals follow.

A node module calls `remember_termination_signals()` before its heavy imports,
so a Ctrl-C while the node is still starting is remembered and the node stops
as soon as it exists, instead of a KeyboardInterrupt traceback from an import.
This module imports rclpy only inside `run_node` for the same reason.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
import os
import signal
import threading
from typing import TYPE_CHECKING, TypeVar

if TYPE_CHECKING:
    from rclpy.executors import Executor
    from rclpy.node import Node

TERMINATION_SIGNALS = (signal.SIGINT, signal.SIGTERM)

NodeT = TypeVar('NodeT', bound='Node')
_received: list[int] = []  # signals seen by the Python-level handler


def _noted(signum: int, frame: object) -> None:
    """Note a termination signal: `run_node` stops spinning when the executor's wait returns."""
    _received.append(signum)


def remember_termination_signals() -> None:
    """From now on SIGINT and SIGTERM are remembered, not raised: `run_node` acts on them."""
    for signum in TERMINATION_SIGNALS:
        signal.signal(signum, _noted)


def hold_termination_signals() -> None:
    """Ignore SIGINT and SIGTERM from now on: the process is already shutting down."""
    for signum in TERMINATION_SIGNALS:
        signal.signal(signum, signal.SIG_IGN)


class ShutdownLog:
    """
    A node logger's stand-in while the node stops: every line kept, logged after it is destroyed.

    After an external shutdown (a node that stops itself shuts its context down) a line logged
    through the node's logger (or any logger of its name) while the node still exists fails to
    reach rosout with an rcl error on the terminal. A node's `finish` hands this to whatever may
    log while it stops (workers finishing a calibration or a report) and returns `lines`;
    run_node logs them at their severity once the node, and its rosout publisher, are gone.
    """

    def __init__(self) -> None:
        """Start with no line."""
        self.lines: list[tuple[str, str]] = []  # (severity method name, message)

    def _keep(self, severity: str, message: str) -> bool:
        self.lines.append((severity, str(message)))
        return True

    def debug(self, message: str, **_: object) -> bool:
        """Keep a debug line."""
        return self._keep('debug', message)

    def info(self, message: str, **_: object) -> bool:
        """Keep an info line."""
        return self._keep('info', message)

    def warning(self, message: str, **_: object) -> bool:
        """Keep a warning."""
        return self._keep('warning', message)

    warn = warning

    def error(self, message: str, **_: object) -> bool:
        """Keep an error."""
        return self._keep('error', message)

    def fatal(self, message: str, **_: object) -> bool:
        """Keep a fatal line."""
        return self._keep('fatal', message)


def _log_line(logger, severity: str, text: str) -> None:
    """Log `text` at `severity`: one call site per severity (rclpy refuses a change at one)."""
    if severity == 'debug':
        logger.debug(text)
    elif severity == 'warning':
        logger.warning(text)
    elif severity == 'error':
        logger.error(text)
    elif severity == 'fatal':
        logger.fatal(text)
    else:
        logger.info(text)


def _watch_signals(wake: Callable[[], None]) -> Callable[[], None]:
    """
    Call `wake` from a thread whenever a signal arrives; return the function that stops it.

    The interpreter writes each signal's number to its wakeup fd from the C handler, even while
    the main thread is blocked in the executor's wait, where no Python handler can run.
    """
    read_fd, write_fd = os.pipe()
    os.set_blocking(write_fd, False)  # set_wakeup_fd's requirement: a signal never blocks
    previous = signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)

    def watch() -> None:
        while os.read(read_fd, 64):  # b'' once the write end is closed: stop
            try:
                wake()
            except Exception:  # a wake after the node is gone: nothing to wake
                return

    thread = threading.Thread(target=watch, name='signal watch', daemon=True)
    thread.start()

    def stop() -> None:
        signal.set_wakeup_fd(previous)
        os.close(write_fd)
        thread.join()
        os.close(read_fd)

    return stop


def _spin(node: 'Node', executor: 'Executor') -> None:
    """Spin as Executor.spin does until a noted signal or an external shutdown."""
    from rclpy.callback_groups import ReentrantCallbackGroup

    executor.add_node(node)
    # A node's guard condition, its own group never busy: the executor's wait returns for it
    # (a trigger of the executor's own guard only makes the wait start again).
    wake = node.create_guard_condition(lambda: None, callback_group=ReentrantCallbackGroup())
    stop_watching = _watch_signals(wake.trigger)
    try:
        while node.context.ok() and not _received:
            executor.spin_once()
    finally:
        stop_watching()
        node.destroy_guard_condition(wake)


def run_node(
    node_name: str,
    create: Callable[[], NodeT],
    *,
    args: list[str] | None = None,
    startup_errors: tuple[type[BaseException], ...] = (),
    make_executor: Callable[[], 'Executor'] | None = None,
    finish: Callable[[NodeT], Iterable[str | tuple[str, str]]] | None = None,
) -> int:
    """
    Run one node until a signal or an external shutdown; return the exit code.

    ``startup_errors`` raised by ``create`` are a bad configuration: logged as
    fatal, exit code 2. ``finish`` runs after spinning with the termination
    signals held (close bags, write files, wait for workers); the lines it
    returns (text, or (severity, text) as a ShutdownLog keeps them) are logged after
    the node is destroyed (a worker's line through the node's logger could race its
    rosout publisher's teardown).
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    remember_termination_signals()
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    logger = rclpy.logging.get_logger(node_name)
    try:
        node = create()
    except startup_errors as error:
        logger.fatal(f'cannot start: {error}')
        hold_termination_signals()
        rclpy.try_shutdown()
        return 2
    executor = None
    lines: list[str | tuple[str, str]] = []
    try:
        if not _received:  # a signal while the node was being built: stop before spinning
            executor = make_executor() if make_executor is not None else SingleThreadedExecutor()
            _spin(node, executor)
    except ExternalShutdownException:
        pass
    finally:
        hold_termination_signals()
        if executor is not None:
            executor.shutdown(timeout_sec=5.0)
        if finish is not None:
            lines = [line for line in finish(node) if line]
        node.destroy_node()
        for line in lines:
            _log_line(logger, *(line if isinstance(line, tuple) else ('info', line)))
        rclpy.try_shutdown()
    return 0
