"""The node's sensor frames: ``/tf`` and ``/tf_static`` in, inputs in another frame moved into the scene's.

:class:`SensorFrames` keeps a :class:`~physics_mapper.mapping.frames.TransformBuffer` fed by the
scene file's fixed ``frames:`` and, where tf2_msgs is installed, by ``/tf`` and ``/tf_static``. An
input whose poses are in another frame than the scene's is handed in with the frames it needs and
a completion; it completes at once when every transform is known at its stamp, or waits
(:class:`~physics_mapper.mapping.frames.TransformWait`) until the transforms arrive or
``transform_timeout`` seconds pass, and is then refused with the lookup's reason (logged, and in
the object's diagnostics). Inputs in sensor frames complete in the order they arrived: one behind
a waiting input waits too, so that older hypotheses never replace newer ones.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from rclpy.node import Node

from physics_mapper.mapping.frames import LookupFailure, Transform, TransformBuffer, TransformWait
from physics_mapper.mapping.stamps import NANOSECONDS_PER_SECOND
from physics_mapper.mapping.topics import TF_STATIC_TOPIC, TF_TOPIC
from physics_mapper.model.scene import Scene
from physics_mapper.msg_adapters.transforms import fixed_frame_transform, stamped_transforms
from physics_mapper.ros.qos import TF_QOS, TF_STATIC_QOS

#: What an input does once its frames are resolved: the transform of each frame found, and for the
#: others why there is none.
Completion = Callable[[Mapping[str, Transform], Mapping[str, str]], None]
#: Inputs waiting for transforms at most; the oldest is refused first.
MAX_WAITING_INPUTS = 100


class SensorFrames:
    """Transforms into the scene's frame for the inputs of one configured node (thread-safe)."""

    def __init__(self, node: Node, scene: Scene, log_once: Callable[[str, str], None], timeout: float) -> None:
        self._node = node
        self._target = scene.frame_id
        self._log_once = log_once
        self._lock = threading.Lock()
        self._buffer = TransformBuffer()
        self._waiting: TransformWait[Completion] = TransformWait(scene.frame_id, MAX_WAITING_INPUTS)
        self._timeout = timeout  # transform_timeout, seconds
        for problem in self._buffer.add_all((fixed_frame_transform(f) for f in scene.frames), static=True):
            log_once("frames", problem)

    def subscribe(self, callback_group: Any) -> list[Any]:
        """Subscriptions to ``/tf`` and ``/tf_static`` where tf2_msgs is installed (none elsewhere)."""
        try:
            from tf2_msgs.msg import TFMessage
        except ImportError:
            return []
        return [
            self._node.create_subscription(
                TFMessage, topic, self._on_transforms(static), qos, callback_group=callback_group
            )
            for topic, qos, static in ((TF_TOPIC, TF_QOS, False), (TF_STATIC_TOPIC, TF_STATIC_QOS, True))
        ]

    def _on_transforms(self, static: bool) -> Callable[[Any], None]:
        def on_transforms(message: Any) -> None:
            with self._lock:
                refusals = self._buffer.add_all(stamped_transforms(message), static=static)
            for refusal in refusals:
                self._log_once(TF_STATIC_TOPIC if static else TF_TOPIC, refusal)
            self.flush()

        return on_transforms

    def resolve(self, frames: Iterable[str], stamp_ns: int, received: float, complete: Completion) -> None:
        """Complete an input stamped ``stamp_ns`` in ``frames`` now if it can be, else once its transforms
        arrive or its wait (``transform_timeout`` seconds from ``received``) is over."""
        needed = {frame for frame in frames if frame not in ("", self._target)}
        if not needed:
            complete({}, {})
            return
        with self._lock:
            found = {frame: self._buffer.lookup(self._target, frame, stamp_ns) for frame in needed}
            failures = [f for f in found.values() if isinstance(f, LookupFailure)]
            # Behind inputs still waiting, so that inputs complete in the order they arrived.
            late = bool(failures) and all(f.may_arrive for f in failures)
            wait = self._timeout > 0.0 and (late or len(self._waiting) > 0)
            if wait:
                self._waiting.add(complete, needed, stamp_ns, received)
        if wait:
            self.flush()
            return
        transforms = {frame: t for frame, t in found.items() if isinstance(t, Transform)}
        unresolved = {frame: f.reason for frame, f in found.items() if isinstance(f, LookupFailure)}
        complete(transforms, unresolved)

    def flush(self, timeout: float | None = None) -> None:
        """Complete the waiting inputs whose transforms arrived or whose wait is over, now on the node's
        clock (``timeout``: a new ``transform_timeout``, seconds)."""
        now = self._now()
        with self._lock:
            self._timeout = self._timeout if timeout is None else timeout
            ready = self._waiting.ready(self._buffer, now, self._timeout)
        for resolved in ready:
            resolved.item(resolved.transforms, resolved.unresolved)

    def _now(self) -> float:
        return self._node.get_clock().now().nanoseconds / NANOSECONDS_PER_SECOND
