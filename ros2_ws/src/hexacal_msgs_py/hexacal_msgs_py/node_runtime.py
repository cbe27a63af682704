"""
How every hexacal node starts, spins and stops: one place for the shutdown rules.

A terminal's Ctrl-C reaches a node twice under `ros2 launch`: the terminal sends
SIGINT to the whole process group, then launch forwards another SIGINT to each
node; supervisors send SIGTERM. rclpy's own handlers turn the first signal into
a shutdown of the context, which ends spinning. They also chain to the Python
handler that was there before, which for SIGINT would raise KeyboardInterrupt
at whatever line the main thread is on - possibly in the middle of closing a
bag. So a no-op Python handler is installed before rclpy's, and once spinning
has ended SIGINT and SIGTERM are ignored: the node finishes its files,
destroys itself and exits 0 with no traceback, however many signals follow.

A node module calls `remember_termination_signals()` before its heavy imports,
so a Ctrl-C while the node is still starting is remembered and the node stops
as soon as it exists, instead of a KeyboardInterrupt traceback from an import.
This module imports rclpy only inside `run_node` for the same reason.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
import signal
from typing import TYPE_CHECKING, TypeVar

if TYPE_CHECKING:
    from rclpy.executors import Executor
    from rclpy.node import Node

TERMINATION_SIGNALS = (signal.SIGINT, signal.SIGTERM)

NodeT = TypeVar('NodeT', bound='Node')
_received: list[int] = []  # signals seen by the Python-level handler


def _noted(signum: int, frame: object) -> None:
    """
    Python-level handler under rclpy's: the context shutdown already ends spinning.

    Remembered, for a signal that arrives before rclpy.init has installed rclpy's handlers.
    """
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

    After a signal the context is shut down, and a line logged through the node's logger (or any
    logger of its name) while the node still exists fails to reach rosout with an rcl error on
    the terminal. A node's `finish` hands this to whatever may log while it stops (workers
    finishing a calibration or a report) and returns `lines`; run_node logs them at their
    severity once the node, and its rosout publisher, are gone.
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


def _stopped_during_startup() -> int:
    import rclpy

    hold_termination_signals()
    rclpy.try_shutdown()
    return 0


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
    the node is destroyed, since the context (and the node's rosout publisher) may
    already be shut down by the signal.
    """
    import rclpy
    from rclpy.executors import ExternalShutdownException

    remember_termination_signals()  # before rclpy.init, so that rclpy chains to these
    rclpy.init(args=args)
    logger = rclpy.logging.get_logger(node_name)
    try:
        node = create()
    except startup_errors as error:
        if rclpy.ok():
            logger.fatal(f'cannot start: {error}')
            rclpy.try_shutdown()
            return 2
        return _stopped_during_startup()
    except Exception:
        # A signal during start-up shuts the context down under the constructor, whose next rcl
        # call then fails ("context is not valid"): that is a stop, not a crash.
        if rclpy.ok():
            raise
        return _stopped_during_startup()
    executor = None
    lines: list[str | tuple[str, str]] = []
    try:
        if node.context.ok() and not _received:
            executor = make_executor() if make_executor is not None else None
            if executor is None:
                rclpy.spin(node)
            else:
                executor.add_node(node)
                executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        # A signal that shuts the context down while an executor is created or builds its wait
        # set surfaces as an rcl error ("context is not valid"), not as ExternalShutdownException.
        if node.context.ok():
            raise
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
