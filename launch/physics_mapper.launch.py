"""Start the physics_mapper node: ``ros2 launch physics_mapper physics_mapper.launch.py``.

Arguments (``name:=value``): ``scene_file`` (path or ``package://`` URL), ``params_file`` (a
parameters YAML, default the shipped ``config/params/node.yaml``), ``namespace``, ``node_name``,
``detections_topic`` (the pose estimator's ``vision_msgs/Detection3DArray`` topic, remapped onto the
node's ``detections``), ``managed`` (``true`` starts the lifecycle node, which waits
unconfigured for ``ros2 lifecycle set``).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition, UnlessCondition
from launch.substitutions import LaunchConfiguration, PathJoinSubstitution
from launch_ros.actions import LifecycleNode, Node
from launch_ros.substitutions import FindPackageShare

PACKAGE = "physics_mapper"


def generate_launch_description() -> LaunchDescription:
    scene_file = LaunchConfiguration("scene_file")
    params_file = LaunchConfiguration("params_file")
    namespace = LaunchConfiguration("namespace")
    node_name = LaunchConfiguration("node_name")
    managed = LaunchConfiguration("managed")
    remappings = [("detections", LaunchConfiguration("detections_topic"))]
    parameters = [params_file, {"scene_file": scene_file}]
    # The same node either way: plain, or managed (a lifecycle node).
    node = {
        "package": PACKAGE,
        "name": node_name,
        "namespace": namespace,
        "parameters": parameters,
        "remappings": remappings,
        "output": "screen",
    }
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
            DeclareLaunchArgument("managed", default_value="false", description="start the lifecycle node"),
            Node(executable="node", condition=UnlessCondition(managed), **node),
            LifecycleNode(executable="managed_node", condition=IfCondition(managed), **node),
        ]
    )
