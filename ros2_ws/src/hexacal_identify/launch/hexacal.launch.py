r"""
Start the hexacal nodes (ROS 2 Jazzy install).

    ros2 launch hexacal_identify hexacal.launch.py nominal:=/path/nominal.yaml plan:=mixed

collector, identify and kinematics (unless use_kinematics:=false); the simulated
driver unless use_driver:=false (a real machine publishes); the executor when
executor_plan names a plan from `hexacal plan` (it walks the plan through the
trajectory controller on command_topic; the simulated driver then runs in
commanded mode on that topic, else it walks its own `plan` as before).
A real ros2_control machine:

    ros2 launch hexacal_identify hexacal.launch.py use_driver:=false nominal:=nominal.yaml \
        executor_plan:=plan.yaml calibrate_when_done:=true sliders_topic:=/joint_states \
        inclinometer_topic:=/joint_states encoder_topic:=/joint_states \
        inclinometer_joints:=tilt_x,tilt_y rotary_joint:=link_rotary

Without a ROS install (the PyPI venv has no `launch`), `bringup` does the same:
the arguments go through hexacal_identify.bringup.system.launches_from_arguments,
which builds the nodes (parameters and remaps) of both. The launch imports are
inside generate_launch_description() so this file still compiles and imports
where `launch` is missing.
"""

# Launch arguments: name -> (default, description). '' keeps the node's own default.
ARGUMENTS = {
    'namespace': ('', 'namespace of all the nodes, e.g. left'),
    'nominal': (
        '',
        'nominal parameters YAML for identify and the executor (required to calibrate)',
    ),
    'output_dir': ('', 'directory identify writes its calibration YAML under'),
    'bag_dir': ('bags', 'directory the collector records bags into'),
    'bag_name': ('', "the bag's directory name under bag_dir ('' = hexacal_<date>_<time>)"),
    'calibration_store': (
        '',
        "calibration store directory of identify and kinematics ('' = the machine model's "
        'store, as `hexacal history`)',
    ),
    'record': ('true', 'record from the start'),
    'plan': (
        'random',
        'driver plan when there is no executor_plan: random, fixed, mixed or a plan YAML path',
    ),
    'postures': ('50', 'postures of a generated plan'),
    'true_params': (
        '',
        'parameters YAML of the simulated machine, of either model (empty: the '
        'default machine of model; Hexa Slide: Table 1)',
    ),
    'model': (
        '',
        'machine model of driver and collector: hexa_slide, gough_stewart, rotary_hexapod or '
        "'' (that of nominal, else true_params, else hexa_slide); identify and the executor take "
        'it from the nominal file',
    ),
    'use_driver': ('true', 'start the simulated machine (false with a real one)'),
    'measuring_mode': (
        '',
        'how the drives meet the measuring link: passive_actuator, lvdt or compliant, for the '
        "simulated driver and an executor that takes it ('' = the driver's default; the "
        "executor follows the plan's mode)",
    ),
    # Plan execution and the calibrated model.
    'executor_plan': (
        '',
        "plan YAML from `hexacal plan`: the executor walks it ('' = no "
        'executor; the simulated driver walks plan)',
    ),
    'command_topic': (
        '/joint_trajectory_controller/joint_trajectory',
        'JointTrajectory command topic of the executor, kinematics and the '
        'commanded simulated driver',
    ),
    'calibrate_when_done': ('false', 'the executor calls hexacal/calibrate at the end'),
    'shutdown_when_done': ('false', 'end the launch once the executor is done'),
    'use_kinematics': ('true', 'start the kinematics node'),
    'kinematics_parameters': (
        '',
        "calibrated parameters YAML kinematics starts from ('' = "
        'the next calibration on hexacal/parameters)',
    ),
    # Where a real machine's readings come from (the collector's input mapping).
    'sliders_topic': ('hexacal/sliders', 'actuator readings (sensor_msgs/JointState)'),
    'inclinometer_topic': ('hexacal/inclinometer', 'inclinometer readings (JointState or Imu)'),
    'encoder_topic': ('hexacal/encoder', 'rotary sensor readings (JointState)'),
    'inclinometer_type': ('', "joint_state or imu ('' = joint_state)"),
    'actuator_joints': (
        '',
        "the six actuator joints in chain order, a,b,c,d,e,f ('' = the model's)",
    ),
    'inclinometer_joints': (
        '',
        "alpha, beta joints of a JointState inclinometer, x,y ('' = "
        'inclinometer_x,inclinometer_y)',
    ),
    'rotary_joint': ('', "the rotary sensor joint ('' = rotary)"),
    'inclinometer_signs': ('', "per channel 1 or -1, e.g. 1,-1 ('' = 1,1)"),
    'inclinometer_offsets_rad': ('', "per channel zero offsets (rad), e.g. 0.0,0.002 ('' = 0,0)"),
}


def node_launches(values):
    """Return the nodes (hexacal_identify.bringup.launch_spec.NodeLaunch) of argument values."""
    from hexacal_identify.bringup.system import launches_from_arguments

    return launches_from_arguments({**{n: d for n, (d, _) in ARGUMENTS.items()}, **values})


def generate_launch_description():
    """Return the launch description: the declared arguments and their nodes."""
    from hexacal_identify.bringup.launch_spec import normalize_namespace, PACKAGES
    from hexacal_identify.bringup.system import truthy
    from launch import LaunchDescription
    from launch.actions import DeclareLaunchArgument, OpaqueFunction, Shutdown
    from launch.substitutions import LaunchConfiguration
    from launch_ros.actions import Node

    declared = [
        DeclareLaunchArgument(name, default_value=default, description=description)
        for name, (default, description) in ARGUMENTS.items()
    ]

    def nodes(context):
        values = {name: LaunchConfiguration(name).perform(context) for name in ARGUMENTS}
        shutdown = truthy(values['shutdown_when_done'])
        actions = []
        for launch in node_launches(values):
            actions.append(
                Node(
                    package=PACKAGES[launch.executable],
                    executable=launch.executable,
                    name=launch.executable,
                    namespace=normalize_namespace(launch.namespace) or None,
                    output='screen',
                    parameters=[dict(launch.parameters)],
                    remappings=list(launch.remaps.items()),
                    # the executor's end (shutdown_when_done) ends the launch
                    on_exit=[Shutdown(reason='the executor is done')]
                    if shutdown and launch.executable == 'executor'
                    else None,
                )
            )
        return actions

    return LaunchDescription([*declared, OpaqueFunction(function=nodes)])
