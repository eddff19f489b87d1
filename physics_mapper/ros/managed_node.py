"""The node as a managed (lifecycle) node: ``ros2 run physics_mapper managed_node``."""

from __future__ import annotations

from typing import cast

from rclpy.exceptions import ParameterException
from rclpy.lifecycle import LifecycleNode, LifecycleState, TransitionCallbackReturn
from rclpy.lifecycle.publisher import LifecyclePublisher
from rclpy.publisher import Publisher
from rclpy.qos import QoSProfile

from physics_mapper.model.errors import InputError
from physics_mapper.model.scene_files import SceneError
from physics_mapper.ros.node import MapperNodeBase
from physics_mapper.ros.qos import MAP_QOS


class ManagedPhysicsMapperNode(MapperNodeBase, LifecycleNode):
    """The same node as a managed (lifecycle) node: it starts unconfigured and follows its transitions.

    ``configure`` reads the parameters and the scene and creates the subscriptions and (inactive)
    publishers; ``activate`` starts ticking and publishing; ``deactivate`` stops both (inputs are
    still collected); ``cleanup`` destroys what ``configure`` made; ``shutdown`` stops everything.
    A scene or parameters that cannot be used fail ``configure`` with the reason in the log, and
    the node stays unconfigured.
    """

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
