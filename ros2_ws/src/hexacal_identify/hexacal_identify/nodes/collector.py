"""
Node `collector`: turn the three sensor streams into postures, and record everything.

Subscribes the inputs hexacal/sliders, hexacal/inclinometer, hexacal/encoder (remappable,
e.g. all to /joint_states; Imu inclinometer) as raw CDR, judges each stream on its own
readings (the settled detector), publishes one averaged posture per dwell on hexacal/posture,
records a rosbag2 MCAP bag and reports its problems on hexacal/calibration_status.  Where the
machine measures its link (lvdt mode) hexacal/link is recorded and is one more stream of the
detector (the postures carry link_length); the driver's status gives the measuring mode and
released actuator, recorded as the bag's hexacal.measuring record. Full reference: docs/nodes.md.
"""

from __future__ import annotations

from functools import partial
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from hexacal_msgs_py.cdr import header_stamp_ns
from hexacal_msgs_py.conversions import diagnostic_status, NS_PER_S
from hexacal_msgs_py.conversions import posture_reading_to_joint_state, stamp_ns, status_values
from hexacal_msgs_py.errors import HexacalContractError
from hexacal_msgs_py.models import MODELS
from hexacal_msgs_py.names import CALIBRATION_STATUS_TOPIC, JOINT_STATE_TYPE
from hexacal_msgs_py.names import DRIVER_STATUS_NAME, LINK_LENGTH_JOINT, LINK_TOPIC, POSTURE_TOPIC
from hexacal_msgs_py.node_runtime import run_node
from hexacal_msgs_py.qos import POSTURE_QOS, SENSOR_QOS, STATUS_QOS
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient
from rclpy.serialization import deserialize_message
from rclpy.task import Future
from sensor_msgs.msg import JointState
from std_srvs.srv import Trigger

from . import collector_parameters as params
from .collector_inputs import input_sources, recorded_only_sources
from .collector_inputs import InputReader, InputSource, link_source, RAW_TOPICS
from .collector_inputs import stamp_ordered, STREAM_OF_TOPIC
from .collector_parameters import CollectorConfigurationError, resolve_model
from .polled_subscriptions import deep_reader_qos, PolledGroup, PolledSubscription
from ..bag import BagError, BagWriter, naming
from ..bag.bag_recording import Recording
from ..bag.measuring import MEASURING_METADATA, MeasuringRecord
from ..bag.qos_yaml import qos_profiles_yaml
from ..core.detection import vocabulary as detection
from ..core.detection.dwell_detector import LINK_STREAM
from ..core.detection.stream_synchronizer import StreamSynchronizer
from ..core.detection.turn_history import TurnHistory
from ..core.sessions import collector_session as health

NODE_NAME = 'collector'
START_RECORDING_SERVICE = 'hexacal/start_recording'
STOP_RECORDING_SERVICE = 'hexacal/stop_recording'
INVALID_LOG_PERIOD_S = 5.0
STALE_LOG_PERIOD_S = 10.0
STATUS_NAME = 'hexacal collector'
# A stream with no message for this long (receipt time) has stopped, e.g. the driver died.
STREAM_STOPPED_S = 1.0
# The sensor publishers are best effort (SENSOR_QOS); a deep reader queue absorbs executor
# pauses (bag flushes, GC) at 1 kHz instead of overwriting samples.
SENSOR_SUBSCRIPTION_QOS = deep_reader_qos(SENSOR_QOS, 1000)
# The sensor streams are not executor callbacks (polled_subscriptions): a timer takes
# everything queued every POLL_PERIOD_S (30 messages at 3 x 1 kHz; the reader queues hold
# 1 s) and handles it in one go, so the executor wakes 100 times a second instead of 3000.
# Messages are handled in stamp order across the streams (each stream in arrival order)
# and the detector gets them as one batch.
POLL_PERIOD_S = 0.01


class CollectorNode(Node):
    """Synchronise, detect postures, publish them and record the bag."""

    def __init__(self) -> None:
        super().__init__(NODE_NAME)
        value = params.declare_parameters(self)  # checked by params.parameter_problem
        self.device_turn = params.checked_turn(value['device_turn'])
        self.turns = TurnHistory()  # the turns inclinometer messages carried
        self.model = resolve_model(value['model'], value['parameters_file'])
        self.actuator_names = MODELS[self.model].actuator_names
        value.update(params.declare_actuator_parameters(self, self.model))
        self.mapping = params.declare_inputs(self, self.actuator_names)
        self.synchronizer = StreamSynchronizer(max_skew_ns=int(value['max_skew_s'] * NS_PER_S))
        self.detector_settings, settings = health.detector_settings(
            value, params.DETECTOR_PARAMETERS, params.DWELL_PARAMETERS
        )
        self.detector = health.dwell_detector(value, settings)
        self.postures_published = 0
        self.counters = health.InputCounters(RAW_TOPICS)
        self.stopped_streams: tuple[str, ...] = ()
        self._reported: dict[str, object] | None = None  # problems in the last status
        self._reported_streams: dict[str, object] = {}  # stream statistics in the last status
        self.recording = Recording(on_failure=self._recording_failed)
        self._bag_counter = 0
        self._plan_recorded = False
        self._plan_request: Future | None = None
        self.measuring = MeasuringRecord()  # from the driver's status, recorded per bag
        self._driver_status: tuple[str | None, str | None, int] | None = None  # its last
        self._link_readings = health.LinkReadings()  # for the detector
        self.link_invalid = 0
        self._posture_pub = self.create_publisher(JointState, POSTURE_TOPIC, POSTURE_QOS)
        self._status_pub = self.create_publisher(
            DiagnosticArray, CALIBRATION_STATUS_TOPIC, STATUS_QOS
        )
        self.topic_names = dict(zip(RAW_TOPICS, self.mapping.topics))
        self.topic_names[POSTURE_TOPIC] = self.resolve_topic_name(POSTURE_TOPIC)
        self._stream_names: dict[str, str] = {
            STREAM_OF_TOPIC[t]: self.topic_names[t] for t in RAW_TOPICS
        }
        self.reader = InputReader(
            self.mapping, self.model, self.synchronizer, self.turns, self._invalid
        )
        group = PolledGroup()
        # One subscription per distinct input topic: inputs remapped to one topic share it.
        self._sources = input_sources(self.mapping, self.topic_names, SENSOR_QOS)
        for source in self._sources:
            on_lost, qos = partial(self._on_lost, source.key), SENSOR_SUBSCRIPTION_QOS
            source.polled = PolledSubscription(
                self, source.message_type, source.name, qos, group, on_lost=on_lost
            )
        # Recorded as received, when published; the reader's queue is deep, as for the sensors.
        self._recorded_only = recorded_only_sources(self.resolve_topic_name, self.mapping)
        for source in self._recorded_only:
            qos = deep_reader_qos(source.qos, SENSOR_SUBSCRIPTION_QOS.depth)
            source.polled = PolledSubscription(self, source.message_type, source.name, qos, group)
        # The lvdt's link length (hexacal/link): recorded, and a detector stream.
        self._link = link_source(self.resolve_topic_name(LINK_TOPIC), self.mapping, SENSOR_QOS)
        self._link.polled = PolledSubscription(
            self, JointState, self._link.name, SENSOR_SUBSCRIPTION_QOS, group
        )
        status_topic = CALIBRATION_STATUS_TOPIC
        self.create_subscription(DiagnosticArray, status_topic, self._on_status, STATUS_QOS)
        self._poll_timer = self.create_timer(POLL_PERIOD_S, self._poll)
        self.create_service(Trigger, START_RECORDING_SERVICE, self._start_recording)
        self.create_service(Trigger, STOP_RECORDING_SERVICE, self._stop_recording)
        self._driver_parameters = AsyncParameterClient(self, value['driver_node'])
        self._flush_timer = self.create_timer(value['flush_every_s'], self.recording.flush)
        self._housekeeping_timer = self.create_timer(1.0, self._housekeeping)
        self.add_post_set_parameters_callback(self._apply_parameters)

        for line in health.start_lines(
            self.topic_names[POSTURE_TOPIC], value, self.model, self.actuator_names,
            self.mapping.describe(), self.device_turn,
        ):
            self.get_logger().info(line)
        if value['record']:
            self.open_bag()

    # ------------------------------------------------------------------ parameters

    def _apply_parameters(self, parameters: list[Parameter]) -> None:
        for parameter in parameters:
            if parameter.name == 'flush_every_s':
                self._flush_timer.timer_period_ns = int(parameter.value * NS_PER_S)
            if parameter.name == 'device_turn':
                previous, self.device_turn = self.device_turn, float(parameter.value)
                line = health.turn_change_line(previous, self.device_turn)
                if line is not None:
                    self.get_logger().info(line)

    # ------------------------------------------------------------------ streams

    def _poll(self) -> None:
        """Take every queued message, handle them in stamp order, then run the detector."""
        limit = SENSOR_SUBSCRIPTION_QOS.depth
        batches = [
            [(header_stamp_ns(data), source, data, info) for data, info in taken]
            for source in self._sources
            if (taken := source.polled.take(limit))
        ]
        for _, source, data, info in stamp_ordered(batches):
            self._on_raw(source, data, info)
        for data, info in self._link.polled.take(limit):
            self._on_link(data, info)
        self._detect()
        for source in self._recorded_only:
            for data, info in source.polled.take(limit):
                self._record_received(source, data, info)

    def _on_raw(self, source: InputSource, data: bytes, info: dict) -> None:
        """Handle one message of an input topic: recorded once, each reading taken once."""
        self.counters.count_received(source.inputs, time.monotonic_ns())
        self._record_received(source, data, info)
        self.reader.read(source, data)

    def _record_received(self, source: InputSource, data: bytes, info: dict) -> None:
        """Record a message as received (recorded-only topics register on their first)."""
        if not source.inputs and not self.recording.add_topic_once(
            source.name, source.type_name, source.qos_yaml
        ):
            return
        received_ns = info.get('received_timestamp') or self.get_clock().now().nanoseconds
        self.recording.write(source.name, data, received_ns, info.get('source_timestamp') or None)

    def _on_link(self, data: bytes, info: dict) -> None:
        """Record one link length message; keep its reading for the settled detector."""
        self._record_received(self._link, data, info)
        try:
            message = deserialize_message(data, JointState)
            stamp = stamp_ns(message.header.stamp)
            problem = self._link_readings.add(message.name, message.position, stamp)
        except (ValueError, IndexError, TypeError) as error:
            problem = f'no {LINK_LENGTH_JOINT} position ({error})'
        if problem is not None:
            self._link_problem(problem)

    def _link_problem(self, problem: str) -> None:
        self.link_invalid += 1
        self.get_logger().warning(
            f'ignored an invalid message on {self._link.name} ({self.link_invalid} so far): '
            f'{problem}',
            throttle_duration_sec=INVALID_LOG_PERIOD_S,
        )

    def _on_status(self, message: DiagnosticArray) -> None:
        """Note the driver's measuring mode and released actuator (hexacal.measuring)."""
        for status in message.status:
            if status.name != DRIVER_STATUS_NAME:
                continue
            values = status_values(status)
            stamp = stamp_ns(message.header.stamp) or self.get_clock().now().nanoseconds
            mode, released = values.get('measuring_mode'), values.get('released_joint')
            self._driver_status = (mode, released, stamp)
            if self.measuring.note(*self._driver_status):
                self._record_measuring()

    def _record_measuring(self) -> None:
        if (writer := self.recording.writer) is not None:
            self.recording.write_metadata(writer, MEASURING_METADATA, self.measuring.to_metadata())

    def _detect(self) -> None:
        """Run the posture detector over the readings accepted since the last call."""
        readings = {**self.reader.take_readings(), **self._link_readings.take()}
        if readings:
            for posture in self.detector.update(readings):
                self._on_posture(posture)

    def _on_lost(self, key: str, status) -> None:  # DDS's sample-lost report
        self.counters.lost[key] = int(status.total_count)

    def _invalid(self, topic: str, problem: str) -> None:
        count = self.counters.count_invalid(topic)
        self.get_logger().warning(
            f'ignored an invalid message on {self.topic_names[topic]} ({count} so far): '
            f'{problem}',
            throttle_duration_sec=INVALID_LOG_PERIOD_S,
        )

    def _on_posture(self, posture: detection.DetectedPosture) -> None:
        reading, turn = health.turned_reading(
            posture, self.detector, self.turns, self.synchronizer.max_skew_ns, self.device_turn
        )
        message = posture_reading_to_joint_state(reading, model=self.model)
        if self.recording.writer is not None:
            # Durable before it is published: whoever received a posture finds it in the bag.
            # BagWriter.write encodes the exact wire CDR; rclpy's serialize_message appends
            # padding bytes that strict readers (rosbags) reject.
            now_ns = self.get_clock().now().nanoseconds
            self.recording.write(self.topic_names[POSTURE_TOPIC], message, now_ns)
            if self.recording.writer is not None:
                self.recording.postures += 1
                self.recording.flush()
        self._posture_pub.publish(message)
        self.postures_published += 1
        units = MODELS[self.model].actuator_quantities  # um for sliders, urad for cranks
        self.get_logger().info(health.posture_line(self.postures_published, posture, turn, units))

    # ------------------------------------------------------------------ recording

    def _recording_failed(self, error: BagError) -> None:
        """Report a bag error (e.g. disk full) that stopped recording; the bag stays readable."""
        self.get_logger().error(f'recording stopped: {error}')
        self.close_bag()
        self._publish_status()

    def open_bag(self) -> str:
        """Start recording into a new bag directory; return its path (BagError on failure)."""
        if self.recording.writer is not None:
            return str(self.recording.directory)
        self._bag_counter += 1
        directory = naming.next_bag_directory(
            self.get_parameter('output_dir').value,
            self.get_parameter('bag_name').value,
            first=self._bag_counter == 1,
        )
        # The inputs under their real topics and types (e.g. /joint_states once for all).
        topics = [(source.name, source.type_name, source.qos_yaml) for source in self._sources]
        topics.append(
            (self.topic_names[POSTURE_TOPIC], JOINT_STATE_TYPE, qos_profiles_yaml(POSTURE_QOS))
        )
        custom_data, metadata = naming.collector_records(
            self.get_fully_qualified_name(), self.get_namespace(), self.model,
            self.mapping.to_metadata(), self.detector_settings,
        )
        try:
            self.recording.start(
                directory, custom_data=custom_data, topics=topics, metadata=metadata
            )
        except BagError as error:
            self.get_logger().error(f'cannot record to {directory}: {error}')
            raise
        self._plan_recorded, self._plan_request = False, None
        # Each bag's record starts from what the driver last said.
        self.measuring = MeasuringRecord()
        if self._driver_status is not None:
            self.measuring.note(*self._driver_status)
            self._record_measuring()
        self.get_logger().info(f'recording to {directory}')
        return str(directory)

    def close_bag(self, log: bool = True) -> str | None:
        """Finish the bag (metadata.yaml); return what happened, None if not recording."""
        text = self.recording.close()
        if log and text is not None:
            self.get_logger().info(text)
        return text

    def _start_recording(self, request, response: Trigger.Response) -> Trigger.Response:
        if self.recording.writer is not None:
            response.message = f'already recording to {self.recording.directory}'
            response.success = True
            return response
        try:
            response.message, response.success = f'recording to {self.open_bag()}', True
        except BagError as error:
            response.success, response.message = False, f'cannot record: {error}'
        return response

    def _stop_recording(self, request, response: Trigger.Response) -> Trigger.Response:
        text = self.close_bag()
        response.success = text is not None
        response.message = text or 'not recording'
        return response

    def _request_plan(self) -> None:
        """Ask the driver for its plan once per bag (optional: the bag is fine without it)."""
        writer = self.recording.writer
        if writer is None or self._plan_recorded or self._plan_request is not None:
            return
        if not self._driver_parameters.services_are_ready():
            return
        self._plan_request = self._driver_parameters.get_parameters(list(naming.PLAN_PARAMETERS))
        self._plan_request.add_done_callback(lambda future: self._record_plan(writer, future))

    def _record_plan(self, writer: BagWriter, future) -> None:
        self._plan_request = None
        if writer is not self.recording.writer or future.exception() is not None:
            return
        values = map(parameter_value_to_python, future.result().values)
        plan = health.plan_record(naming.PLAN_PARAMETERS, values)
        if not plan or not self.recording.write_metadata(writer, naming.PLAN_METADATA, plan):
            return
        self._plan_recorded = True
        self.get_logger().info(f"recorded the driver's plan {plan.get('plan_name', plan)}")

    # ------------------------------------------------------------------ housekeeping

    def _housekeeping(self) -> None:
        for source in self._sources:
            source.polled.poll_lost()  # the executor does not wait on the loss reports
        now_ns = self.get_clock().now().nanoseconds
        silent = health.silent_streams(self.synchronizer, now_ns, self._stream_names)
        if silent:
            self.get_logger().warning(
                f'no recent data on {", ".join(silent)}', throttle_duration_sec=STALE_LOG_PERIOD_S
            )
        self._check_streams()
        self._publish_status()
        self._request_plan()

    def _check_streams(self) -> None:
        """Report streams that stopped; drop a posture they leave half-captured."""
        stopped = self.counters.stopped(time.monotonic_ns(), STREAM_STOPPED_S, self.topic_names)
        for level, text in health.stopped_lines(self.stopped_streams, stopped, STREAM_STOPPED_S):
            if level == health.Level.WARN:
                self.get_logger().warning(text)
            else:
                self.get_logger().info(text)
        self.stopped_streams = stopped
        if stopped:
            self._detect()  # normally nothing left: _poll runs the detector after each batch
            now_ns = time.monotonic_ns()
            ended = health.end_of_data(self.counters, self.detector, now_ns, STREAM_STOPPED_S)
            for posture in ended:
                self._on_posture(posture)
            dropped = health.dropped_line(self.detector, stopped)
            if dropped is not None:
                self.get_logger().warning(dropped)

    def problems(self) -> dict[str, object]:
        """Return the counters of everything not used, by stream and reason (the status's)."""
        counts = (self.counters, self.synchronizer, self.detector)
        return health.problems(*counts, self.stopped_streams, self.recording.error)

    def _publish_status(self) -> None:
        """Publish on hexacal/calibration_status when a problem counter or state changed."""
        problems = self.problems()
        streams = health.stream_statistics(
            self.detector, {**self._stream_names, LINK_STREAM: self._link.name}
        )
        recording, changed = self.recording.writer is not None, streams != self._reported_streams
        decision = health.decide_status(
            problems, self._reported, self.recording.error, recording, statistics_changed=changed
        )
        if decision is None:
            return
        self._reported, self._reported_streams = problems, streams
        values = health.status_values(
            decision.outcome, self.postures_published, str(self.recording.directory or ''),
            self.counters, problems, streams,
        )
        stamp, name = self.get_clock().now().nanoseconds, self.get_fully_qualified_name()
        self._status_pub.publish(diagnostic_status(
            decision.level, STATUS_NAME, decision.message, values, hardware_id=name, stamp=stamp
        ))
        if decision.to_log:
            self.get_logger().warning(
                'not used: ' + '; '.join(f'{key}: {problems[key]}' for key in decision.to_log),
                throttle_duration_sec=INVALID_LOG_PERIOD_S,
            )

    def summary(self) -> str:
        """Return the closing summary; a posture still being captured is never published."""
        self.detector.abort(detection.DropReason.END_OF_STREAM)
        counts = (self.counters, self.synchronizer, self.detector)
        return health.summary(self.postures_published, *counts)


def _finish(node: CollectorNode) -> list[str]:
    closed = node.close_bag(log=False)  # metadata.yaml and the MCAP footer: the bag is complete
    return [*([] if closed is None else [closed]), node.summary()]


def main(args: list[str] | None = None) -> int:
    """Run the collector node until it is stopped; return the exit status."""
    return run_node(
        NODE_NAME,
        CollectorNode,
        args=args,
        finish=_finish,
        startup_errors=(
            InvalidParameterValueException,
            InvalidParameterTypeException,
            BagError,
            CollectorConfigurationError,
            HexacalContractError,
        ),
    )


if __name__ == '__main__':
    sys.exit(main(sys.argv))
