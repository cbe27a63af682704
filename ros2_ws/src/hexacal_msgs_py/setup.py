from setuptools import find_packages, setup

package_name = 'hexacal_msgs_py'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    # ROS packages (rclpy, message packages) come from the ROS install, not PyPI.
    install_requires=['setuptools', 'numpy', 'pyyaml'],
    # colcon test runs pytest when it is a test dependency (as ament_python packages
    # declare it); every module the tests import besides the runtime ones.
    extras_require={
        'test': [
            'pytest',
            'hypothesis',
        ],
    },
    zip_safe=True,
    maintainer='hexacal developers',
    maintainer_email='hexacal@example.com',
    description='Interface contract of hexacal (names, QoS, readings, conversions, '
    'parameter files).',
    license='Apache-2.0',
    python_requires='>=3.10',
)
