"""core/walk_device/turns.py: device turns, and the device_turn requests to the nodes (no DDS)."""

from __future__ import annotations

from concurrent.futures import Future
import math

from hexacal_identify.core.walk.messages import LogLevel
from hexacal_identify.core.walk_device.turns import (
    check_turns,
    DeviceTurnSetter,
    same_turn,
    TURN_SET_TIMEOUT_S,
    turn_text,
    TurnSetState,
)
import numpy as np
import pytest
from rcl_interfaces.msg import SetParametersResult
from rcl_interfaces.srv import SetParameters


class _Node:
    """A node's parameter services as the executor reaches them: ready or not, answers later."""

    def __init__(self, ready: bool = True):
        self.is_ready = ready
        self.requests: list[tuple[float, Future]] = []

    def ready(self) -> bool:
        return self.is_ready

    def request(self, turn: float) -> Future:
        future: Future = Future()
        self.requests.append((turn, future))
        return future

    def answer(self, successful: bool = True, reason: str = '') -> None:
        result = SetParametersResult(successful=successful, reason=reason)
        self.requests[-1][1].set_result(SetParameters.Response(results=[result]))


def test_turns_are_compared_modulo_a_full_turn():
    assert same_turn(0.0, 2.0 * math.pi) and same_turn(-math.pi, math.pi)
    assert not same_turn(0.0, math.pi) and not same_turn(0.0, 1e-6)
    assert turn_text(math.pi) == '180 deg (3.14159 rad)'
    assert check_turns(None, 3).tolist() == [0.0, 0.0, 0.0]
    assert check_turns([0, math.pi], 2).tolist() == [0.0, math.pi]
    with pytest.raises(ValueError, match='one finite angle'):
        check_turns([0.0, np.nan], 2)
    with pytest.raises(ValueError, match='one finite angle'):
        check_turns([0.0], 2)


def test_without_nodes_nothing_is_set_and_the_start_waits_for_nothing():
    setter = DeviceTurnSetter({})
    assert setter.start_done and setter.start_waiting(0.0, 0.0) is None
    assert setter.state is None and setter.messages == []


def test_the_start_waits_until_every_node_has_set_the_mounting():
    collector, driver = _Node(), _Node(ready=False)
    setter = DeviceTurnSetter({'collector': collector, 'driver': driver})
    waiting = setter.start_waiting(math.pi, 0.0)
    assert waiting == (
        'collector, driver to set device_turn 3.14159 rad (the mounting at the start)'
    )
    assert setter.messages == [
        (
            LogLevel.INFO,
            'the mounting at the start: setting device_turn 3.14159 rad on collector, driver',
        )
    ]
    assert [turn for turn, _ in collector.requests] == [math.pi] and driver.requests == []
    assert setter.state == TurnSetState.PENDING
    driver.is_ready = True
    assert setter.step(1.0) is None  # the driver's request only now goes out
    assert setter.start_waiting(math.pi, 1.0) is not None  # one round at a time
    driver.answer()
    assert setter.step(1.5) is None  # the driver answered first
    collector.answer()
    settled = setter.step(2.0)
    assert settled is not None and settled.at_start and settled.done == ['driver', 'collector']
    assert setter.start_done and setter.start_waiting(math.pi, 2.0) is None
    assert setter.state == TurnSetState.DONE
    assert setter.message == 'device_turn 3.14159 rad set on collector, driver'


def test_a_refusal_or_silence_fails_the_round_but_settles_it():
    collector, driver, absent = _Node(), _Node(), _Node(ready=False)
    setter = DeviceTurnSetter({'collector': collector, 'driver': driver, 'absent': absent})
    answer = setter.resume(math.pi, 0.0, 2, 4)
    assert answer == (
        'setting device_turn 3.14159 rad on collector, driver, absent; posture 3 of 4 begins '
        'once they answer'
    )
    assert setter.step(0.0) is None
    assert setter.resume(math.pi, 0.1, 2, 4).startswith('already resuming: waiting for')
    collector.answer(False, 'out of range')
    assert setter.step(1.0) is None  # the driver and the absent node may still answer
    settled = setter.step(TURN_SET_TIMEOUT_S + 0.5)
    assert settled is not None and not settled.at_start and settled.done == []
    assert driver.requests[0][1].cancelled()  # no answer in time: the request is dropped
    assert setter.state == TurnSetState.FAILED
    assert setter.message == (
        'collector: refused: out of range; driver: no answer within 10 s; absent: its parameter '
        'services did not appear within 10 s'
    )
    assert setter.messages[-1][0] == LogLevel.ERROR
    assert not setter.start_done  # a resume is not the start's round


def test_an_error_answer_is_named_and_a_pause_cancels_the_round():
    node = _Node()
    setter = DeviceTurnSetter({'collector': node})
    setter.resume(math.pi, 0.0, 0, 2)
    setter.step(0.0)
    assert setter.cancel() and setter.setting is None and setter.state is None
    assert setter.messages[-1] == (
        LogLevel.INFO,
        'pause: the resume after the device turn is cancelled',
    )
    assert not setter.cancel()  # nothing left to cancel
    setter.resume(math.pi, 1.0, 0, 2)  # the next resume asks again
    setter.step(1.0)
    node.requests[-1][1].set_exception(RuntimeError('service gone'))
    assert setter.step(1.5) is not None
    assert setter.message == 'collector: RuntimeError: service gone'
