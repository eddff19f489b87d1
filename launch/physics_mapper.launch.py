"""Start the physics_mapper node: ``ros2 launch physics_mapper physics_mapper.launch.py``.

Arguments (``name:=value``): ``scene_file`` (path or ``package://`` URL), ``params_file`` (a
parameters YAML, default the shipped ``config/params/node.yaml``), ``namespace``, ``node_name``,
``detections_topic`` (the pose estimator's ``vision_msgs/Detection3DArray`` topic, remapped onto the
node's ``detections``), ``use_sim_time`` (``true``: the node's clock is ``/clock``), ``log_level``
(``debug``, ``info``, ``warn``, ``error``, ``fatal``), ``managed`` (``true`` starts the lifecycle
node) and ``autostart`` (with ``managed:=true``: configure it, then activate it once it is
inactive, as nav2's lifecycle manager does; ``false`` leaves it unconfigured for ``ros2 lifecycle set``).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, EmitEvent, RegisterEventHandler
from launch.conditions import IfCondition, UnlessCondition
from launch.events import matches_action
from launch.substitutions import AndSubstitution, LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import LifecycleNode, Node
from launch_ros.descriptions import ParameterValue
from launch_ros.event_handlers import OnStateTransition
from launch_ros.events.lifecycle import ChangeState
from launch_ros.substitutions import FindPackageShare
from lifecycle_msgs.msg import Transition

PACKAGE = "physics_mapper"


def generate_launch_description() -> LaunchDescription:
    scene_file = LaunchConfiguration("scene_file")
    params_file = LaunchConfiguration("params_file")
    namespace = LaunchConfiguration("namespace")
    node_name = LaunchConfiguration("node_name")
    managed = LaunchConfiguration("managed")
    autostart = AndSubstitution(managed, LaunchConfiguration("autostart"))
    remappings = [("detections", LaunchConfiguration("detections_topic"))]
    use_sim_time = ParameterValue(LaunchConfiguration("use_sim_time"), value_type=bool)
    parameters = [params_file, {"scene_file": scene_file, "use_sim_time": use_sim_time}]
    # The same node either way: plain, or managed (a lifecycle node).
    node = {
        "package": PACKAGE,
        "name": node_name,
        "namespace": namespace,
        "parameters": parameters,
        "remappings": remappings,
        "ros_arguments": ["--log-level", LaunchConfiguration("log_level")],
        "output": "screen",
    }
    managed_node = LifecycleNode(executable="managed_node", condition=IfCondition(managed), **node)
    return LaunchDescription(
        [
            DeclareLaunchArgument(
                "scene_file",
                default_value="package://physics_mapper/config/scenes/pyramid.yaml",
                description="scene YAML: a path or a package:// URL",
            ),
            DeclareLaunchArgument(
                "params_file",
                default_value=PathJoinSubstitution([FindPackageShare(PACKAGE), "config", "params", "node.yaml"]),
                description="node parameters YAML (--params-file)",
            ),
            DeclareLaunchArgument("namespace", default_value="", description="namespace of the node and its topics"),
            DeclareLaunchArgument("node_name", default_value="physics_mapper", description="name of the node"),
            DeclareLaunchArgument(
                "detections_topic", default_value="detections", description="the estimator's Detection3DArray topic"
            ),
            DeclareLaunchArgument("use_sim_time", default_value="false", description="true: the clock is /clock"),
            DeclareLaunchArgument(
                "log_level", default_value="info", description="debug, info, warn, error or fatal"
            ),
            DeclareLaunchArgument("managed", default_value="false", description="start the lifecycle node"),
            DeclareLaunchArgument(
                "autostart",
                default_value="true",
                description="with managed:=true, configure and activate the lifecycle node",
            ),
            Node(executable="node", condition=UnlessCondition(managed), **node),
            managed_node,
            # autostart: configure once the process is up, activate once configured (nav2's lifecycle manager's order).
            RegisterEventHandler(
                OnStateTransition(
                    target_lifecycle_node=managed_node,
                    start_state="configuring",  # not after a deactivate: the user's, kept
                    goal_state="inactive",
                    entities=[
                        EmitEvent(
                            event=ChangeState(
                                lifecycle_node_matcher=matches_action(managed_node),
                                transition_id=Transition.TRANSITION_ACTIVATE,
                            )
                        )
                    ],
                ),
                condition=IfCondition(autostart),
            ),
            EmitEvent(
                event=ChangeState(
                    lifecycle_node_matcher=matches_action(managed_node),
                    transition_id=Transition.TRANSITION_CONFIGURE,
                ),
                condition=IfCondition(autostart),
            ),
        ]
    )
