"""What the node's subscriptions do with a received message: hypotheses for the mapper's inputs.

Each handler puts a message through its adapter (:mod:`physics_mapper.msg_adapters.hypotheses`;
:mod:`physics_mapper.msg_adapters.detection_array_cdr`, then :mod:`physics_mapper.mapping.detections`)
into the mapper's input tracker, stamped with the time the middleware received it, and logs what
became of a refused message once per object and note, in the words of its input (``PoseArray
refused``, ``detection refused``, ``Detection3DArray refused`` for bytes no reader takes). Poses in a sensor frame
go into the tracker once :class:`~physics_mapper.ros.node_frames.SensorFrames` has moved them
into the scene's frame, or refused when no transform came in time.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import replace
from typing import Any

from rclpy.event_handler import QoSMessageLostInfo
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray

from physics_mapper.mapping.detections import DETECTIONS_TOPIC, DetectionInputs
from physics_mapper.mapping.frames import Transform, moved_into
from physics_mapper.mapping.inputs import InputSnapshot, MessageKind, ReceivedPoses
from physics_mapper.mapping.mapper import Mapper
from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND
from physics_mapper.model.limits import clipped, printable
from physics_mapper.msg_adapters.detection_array_cdr import reads_layout_of, received_detection_array
from physics_mapper.msg_adapters.hypotheses import received_pose_array, received_weights
from physics_mapper.ros.node_frames import SensorFrames

#: Distinct input notes (object, text) logged in full before they are throttled.
MAX_LOGGED_INPUT_NOTES = 1000
#: Characters of one input note, logged and remembered: the notes remembered take at most about
#: 1000 x 200 characters, whatever the input they quote.
MAX_INPUT_NOTE_TEXT = 200


class InputNotes:
    """What became of the node's inputs, logged once per object and text: a stream of bad messages
    logs one line (the diagnostics count them all); past :data:`MAX_LOGGED_INPUT_NOTES` notes, at
    most one line per second."""

    def __init__(self, logger: Any) -> None:
        self._logger = logger
        self._logged: set[tuple[str, str]] = set()

    def log_once(self, name: str, what: str) -> None:
        """Log ``what`` of object (or topic) ``name``, unless it was logged already; ``what`` is escaped and
        clipped to :data:`MAX_INPUT_NOTE_TEXT` first (it quotes input: a class id may be 100 kB long)."""
        what = clipped(printable(what), MAX_INPUT_NOTE_TEXT)
        key = (name, what)
        if key in self._logged:
            return
        if len(self._logged) < MAX_LOGGED_INPUT_NOTES:
            self._logged.add(key)
            self._logger.warning(f"{name}: {what}")
        else:
            self._logger.warning(f"{name}: {what}", throttle_duration_sec=1.0)

    def log_tick(self, snapshot: InputSnapshot) -> None:
        """What only a tick finds about an object's hypotheses (dropped poses, uniform weights), once each."""
        for status in snapshot.objects:
            for note in status.notes:
                self.log_once(status.name, note)


class InputHandlers:
    """The subscription callbacks of ``node``, feeding ``mapper``'s inputs; each gets the message info."""

    def __init__(self, node: Node, mapper: Mapper, notes: InputNotes, frames: SensorFrames) -> None:
        self._node = node
        self._mapper = mapper
        self._notes = notes
        self._frames = frames

    def poses(self, name: str) -> Callable[[bytes, Mapping[str, Any]], None]:
        """Object ``name``'s serialised PoseArray handler."""
        scene = self._mapper.scene
        frame, workspace = scene.frame_id, scene.workspace

        def on_poses(raw: bytes, info: Mapping[str, Any]) -> None:
            received = received_pose_array(raw, expected_frame=frame, workspace=workspace, received=self.received(info))
            if received.frame_id in ("", frame):
                self._add(name, received)
                return

            def complete(transforms: Mapping[str, Transform], unresolved: Mapping[str, str]) -> None:
                transform = transforms.get(received.frame_id)
                if transform is not None:
                    self._add(name, moved_into(received, transform, frame))
                else:
                    self._add(name, replace(received, refusal=unresolved.get(received.frame_id, received.refusal)))

            self._frames.resolve({received.frame_id}, received.stamp_ns, received.received, complete)

        return on_poses

    def _add(self, name: str, received: ReceivedPoses) -> None:
        """Hand object ``name``'s poses to the tracker; log a refusal, or a frame taken for the scene's."""
        self._mapper.inputs.add_poses(name, received)
        self._log_refusal(name, received)

    def _log_refusal(self, name: str, received: ReceivedPoses) -> None:
        if received.frame_assumed:
            frame = self._mapper.scene.frame_id
            self._notes.log_once(name, f"a {received.source} without a frame_id is taken in the scene frame {frame!r}")
        if received.refusal is not None:
            self._notes.log_once(name, f"{received.source} refused: {received.refusal}")

    def weights(self, name: str) -> Callable[[Float64MultiArray, Mapping[str, Any]], None]:
        """Object ``name``'s weights handler."""

        def on_weights(msg: Float64MultiArray, info: Mapping[str, Any]) -> None:
            received = received_weights(msg, received=self.received(info))
            self._mapper.inputs.add_weights(name, received)
            if received.refusal is not None:
                self._notes.log_once(name, f"weights refused: {received.refusal}")

        return on_weights

    def detections(self, message_type: type) -> Callable[[bytes, Mapping[str, Any]], None]:
        """The serialised ``detections`` handler (``message_type``: vision_msgs' Detection3DArray): its results
        are the hypotheses of the objects their class ids name, a class of instances's detections associated
        to instances (:meth:`Mapper.add_detections`), once their frames are moved into the scene's."""
        viewable = reads_layout_of(message_type)

        def on_detections(raw: bytes, info: Mapping[str, Any]) -> None:
            received = self.received(info)
            array = received_detection_array(raw, message_type, viewable=viewable)
            if isinstance(array, str):
                self._notes.log_once(DETECTIONS_TOPIC, f"Detection3DArray refused: {array}")
                return

            def complete(transforms: Mapping[str, Transform], unresolved: Mapping[str, str]) -> None:
                detected = self._mapper.add_detections(
                    array, received=received, transforms=transforms, unresolved=unresolved
                )
                self._log_detections(detected)

            self._frames.resolve(array.frames(), array.stamp_ns, received, complete)

        return on_detections

    def _log_detections(self, detected: DetectionInputs) -> None:
        """What the mapper made of a Detection3DArray: each refusal and note, once."""
        for name, received in detected.objects.items():
            self._log_refusal(name, received)
        for note in detected.unused:
            self._notes.log_once(DETECTIONS_TOPIC, note)

    def lost(self, name: str, kind: MessageKind) -> Callable[[QoSMessageLostInfo], None]:
        """The middleware's message-lost event of object ``name``'s ``kind`` input, counted."""

        def on_lost(info: QoSMessageLostInfo) -> None:
            now = self._node.get_clock().now().nanoseconds / NANOSECONDS_PER_SECOND
            self._mapper.inputs.add_lost(name, kind, int(info.total_count_change), now)

        return on_lost

    def received(self, info: Mapping[str, Any]) -> float:
        """When the middleware received a message, on the node's clock (seconds).

        The middleware's receive stamp is system time; the node's clock may be simulated time,
        so the message's wait since then is taken from the node's clock now.
        """
        now_ns = self._node.get_clock().now().nanoseconds
        received_ns = int(info.get("received_timestamp", 0) or 0)
        waited_ns = max(0, time.time_ns() - received_ns) if received_ns else 0
        return (now_ns - waited_ns) / NANOSECONDS_PER_SECOND
