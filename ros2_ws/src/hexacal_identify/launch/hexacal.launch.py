"""Start the hexacal driver, collector and identify nodes (ROS 2 Jazzy install).

    ros2 launch hexacal_identify hexacal.launch.py nominal:=/path/nominal.yaml plan:=mixed

Without a ROS install (the PyPI venv has no `launch`), `bringup` does the same.
The launch imports are inside generate_launch_description() so this file
still compiles and imports where `launch` is missing.
"""

# Launch arguments: name -> (default, description). '' keeps the node's own default.
ARGUMENTS = {
    'namespace': ('', 'namespace of all three nodes, e.g. left'),
    'nominal': ('', 'nominal parameters YAML for identify (required to calibrate)'),
    'output_dir': ('', 'directory identify writes its calibration YAML under'),
    'bag_dir': ('bags', 'directory the collector records bags into'),
    'record': ('true', 'record from the start'),
    'plan': ('random', 'driver plan: random, fixed, mixed or a plan YAML path'),
    'postures': ('50', 'postures of a generated plan'),
    'true_params': ('', 'parameters YAML of the simulated machine, of either model (empty: the '
                    'default machine of model; Hexa Slide: Table 1)'),
    'model': ('', "machine model of driver and collector: hexa_slide, gough_stewart or '' (that "
              'of true_params, else hexa_slide); identify takes it from the nominal file'),
    'use_driver': ('true', 'start the simulated machine (false with a real one)'),
}


def generate_launch_description():
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument
    from launch.conditions import IfCondition
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node
    from launch_ros.parameter_descriptions import ParameterValue

    def argument(name):
        return LaunchConfiguration(name)

    def text(name):  # a string parameter even when empty or number-like
        return ParameterValue(LaunchConfiguration(name), value_type=str)

    declared = [DeclareLaunchArgument(name, default_value=default, description=description)
                for name, (default, description) in ARGUMENTS.items()]
    namespace = argument('namespace')
    driver = Node(
        package='hexacal_driver', executable='driver', name='driver', namespace=namespace,
        condition=IfCondition(argument('use_driver')), output='screen',
        parameters=[{
            'plan': text('plan'),
            'postures': ParameterValue(argument('postures'), value_type=int),
            'true_params': text('true_params'),
            'model': text('model'),
        }])
    collector = Node(
        package='hexacal_identify', executable='collector', name='collector',
        namespace=namespace, output='screen',
        parameters=[{
            'output_dir': text('bag_dir'),
            'record': ParameterValue(argument('record'), value_type=bool),
            'model': text('model'),
        }])
    identify = Node(
        package='hexacal_identify', executable='identify', name='identify',
        namespace=namespace, output='screen',
        # An empty output_dir means the node's working directory.
        parameters=[{'nominal': text('nominal'), 'output_dir': text('output_dir')}])
    return LaunchDescription([*declared, collector, identify, driver])
