"""
Supervise node child processes: start each in its own process group, stop them all.

A stop sends SIGINT (the nodes shut down cleanly, the collector closes its bag)
and escalates to SIGTERM, then SIGKILL, for a child that does not exit within
the timeout. With `die_with_parent` the children also get SIGTERM (Linux prctl)
when this process dies, so no node outlives it.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
import os
from pathlib import Path
import signal
import subprocess
from typing import IO

from .launch_spec import NodeLaunch

DEFAULT_STOP_TIMEOUT_S = 10.0
_PR_SET_PDEATHSIG = 1  # prctl option of linux/prctl.h


def _parent_death_signal() -> Callable[[], None] | None:
    """
    Return a preexec_fn giving the child SIGTERM when its parent dies (Linux prctl), or None.

    libc is loaded here, in the parent: the child only makes the call, no dlopen after fork.
    """
    try:
        import ctypes

        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None

    def set_parent_death_signal() -> None:
        prctl(_PR_SET_PDEATHSIG, signal.SIGTERM)

    return set_parent_death_signal


@dataclass
class RunningNode:
    """A started node: its launch, its process and the log file its output goes to."""

    launch: NodeLaunch
    popen: subprocess.Popen
    log_file: IO[bytes] | None = None

    @property
    def name(self) -> str:
        """Return the node's executable."""
        return self.launch.executable

    def running(self) -> bool:
        """Return whether the process has not exited yet."""
        return self.popen.poll() is None


class NodeGroup:
    """Child node processes, each in its own process group; stop() ends them all."""

    def __init__(self, die_with_parent: bool = False) -> None:
        # die_with_parent runs code between fork and exec: only for single-threaded parents.
        self.nodes: list[RunningNode] = []
        self._preexec = _parent_death_signal() if die_with_parent else None

    def start(
        self,
        launch: NodeLaunch,
        env: Mapping[str, str] | None = None,
        log_path: str | os.PathLike[str] | None = None,
    ) -> RunningNode:
        """Start a node; its output goes to log_path, else to this process's stdout/stderr."""
        log_file = None
        if log_path is not None:
            Path(log_path).parent.mkdir(parents=True, exist_ok=True)
            log_file = open(log_path, 'wb')  # noqa: SIM115 - closed by stop()
        child_env = dict(os.environ)
        child_env.update(env or {})
        child_env.setdefault('PYTHONUNBUFFERED', '1')
        try:
            popen = subprocess.Popen(
                launch.command(),
                env=child_env,
                stdin=subprocess.DEVNULL,
                stdout=log_file,
                stderr=subprocess.STDOUT if log_file else None,
                start_new_session=True,
                preexec_fn=self._preexec,
            )
        except BaseException:
            if log_file:
                log_file.close()
            raise
        node = RunningNode(launch, popen, log_file)
        self.nodes.append(node)
        return node

    def signal_all(self, signum: int) -> None:
        """Send `signum` to the process group of every running node."""
        for node in self.nodes:
            if node.running():
                try:
                    os.killpg(node.popen.pid, signum)
                except ProcessLookupError:
                    pass

    def exited(self) -> list[RunningNode]:
        """Return the nodes whose process has exited."""
        return [node for node in self.nodes if not node.running()]

    def stop(
        self, timeout: float = DEFAULT_STOP_TIMEOUT_S, order: Sequence[str] | None = None
    ) -> dict[str, int]:
        """Stop every node (those in `order` of executables first); return name -> exit code."""
        first = list(order or ())
        ranked = sorted(
            self.nodes, key=lambda n: first.index(n.name) if n.name in first else len(first)
        )
        for node in ranked:
            self._stop_one(node, timeout)
        codes = {}
        for node in self.nodes:
            codes[node.name] = node.popen.returncode
            if node.log_file:
                node.log_file.close()
        self.nodes = []
        return codes

    def stop_node(self, node: RunningNode, timeout: float = DEFAULT_STOP_TIMEOUT_S) -> int:
        """Stop one node of the group (SIGINT, escalating), take it out; return its exit code."""
        self._stop_one(node, timeout)
        self.nodes.remove(node)
        if node.log_file:
            node.log_file.close()
        return node.popen.returncode

    @staticmethod
    def _stop_one(node: RunningNode, timeout: float) -> None:
        for signum in (signal.SIGINT, signal.SIGTERM, signal.SIGKILL):
            if not node.running():
                break
            try:
                os.killpg(node.popen.pid, signum)
            except ProcessLookupError:
                break
            try:
                node.popen.wait(timeout if signum != signal.SIGKILL else None)
            except subprocess.TimeoutExpired:
                continue
        node.popen.wait()
