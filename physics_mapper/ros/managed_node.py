"""The node as a managed (lifecycle) node: ``ros2 run physics_mapper managed_node``."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, cast

from lifecycle_msgs.srv import ChangeState
from rclpy.exceptions import ParameterException
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.lifecycle.publisher import LifecyclePublisher
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile

from physics_mapper.model.errors import InputError
from physics_mapper.model.limits import MAX_QUOTED_TEXT, clipped, printable
from physics_mapper.model.scene_files import SceneError
from physics_mapper.ros.node import MapperNodeBase
from physics_mapper.ros.qos import MAP_QOS

#: A ChangeState service's handler: the request and a response to fill, the response.
ChangeStateCallback = Callable[[ChangeState.Request, ChangeState.Response], ChangeState.Response]


class ManagedPhysicsMapperNode(MapperNodeBase, LifecycleNode):
    """The same node as a managed (lifecycle) node: it starts unconfigured and follows its transitions.

    ``configure`` reads the parameters and the scene and creates the subscriptions and (inactive)
    publishers; ``activate`` starts ticking and publishing; ``deactivate`` stops both (inputs are
    still collected); ``cleanup`` destroys what ``configure`` made; ``shutdown`` stops everything.
    A scene or parameters that cannot be used fail ``configure`` with the reason in the log, and
    the node stays unconfigured.
    """

    def __init__(self, **kwargs: Any) -> None:
        super().__init__(**kwargs)
        for service in self.services:
            if service.srv_type is ChangeState:
                service.callback = self._guarded_change_state(service.callback)

    def _guarded_change_state(self, change_state: ChangeStateCallback) -> ChangeStateCallback:
        """rclpy's ChangeState handler, answering every request and logging each one it refuses.

        rclpy 7.1.6 (ros2/rclpy#1209) lets the RCLError ``Transition is not registered`` of a
        transition requested by an id the current state has no such transition for (activate while
        unconfigured, configure after finalized) escape the service callback: no response, and the
        executor's spin raised it out of the node. The state machine is unchanged by such a request.
        """

        def guarded(request: ChangeState.Request, response: ChangeState.Response) -> ChangeState.Response:
            transition = request.transition
            asked = f"'{clipped(printable(transition.label), MAX_QUOTED_TEXT)}'" if transition.label else transition.id
            try:
                answered = change_state(request, response)
            except RuntimeError as error:  # rclpy's RCLError
                self._logger.error(f"lifecycle transition {asked} refused: {str(error).split(', at ')[0]}")
                response.success = False
                return response
            if not answered.success:
                self._logger.warning(
                    f"lifecycle transition {asked} not done: not a transition from the current state, or it failed"
                )
            return answered

        return guarded

    def _map_publisher(self, msg_type: type, topic: str, qos: QoSProfile = MAP_QOS) -> Publisher:
        publisher = self.create_lifecycle_publisher(msg_type, topic, qos)  # type: ignore[no-untyped-call]
        self._entities.append(publisher)
        return cast(Publisher, publisher)

    def _destroy_publisher(self, publisher: Publisher) -> None:
        self.destroy_lifecycle_publisher(cast(LifecyclePublisher, publisher))

    def on_configure(self, state: LifecycleState) -> TransitionCallbackReturn:
        try:
            self.configure()
        except (SceneError, InputError, ParameterException) as error:
            self._logger.error(f"configure failed: {error}")
            self.release()
            return TransitionCallbackReturn.FAILURE
        return TransitionCallbackReturn.SUCCESS

    def on_activate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.start_ticking()
        return super().on_activate(state)  # activates the publishers

    def on_deactivate(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.stop_ticking()
        return super().on_deactivate(state)

    def on_cleanup(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.release()
        return TransitionCallbackReturn.SUCCESS

    def on_shutdown(self, state: LifecycleState) -> TransitionCallbackReturn:
        self.release()
        return TransitionCallbackReturn.SUCCESS
