from pathlib import Path

from setuptools import find_packages, setup

package_name = 'hexacal_identify'
here = Path(__file__).resolve().parent

# Relative paths (setuptools requires them); sorted for reproducible builds.
# The launch directory may be missing or empty.
launch_files = sorted(str(p.relative_to(here)) for p in here.glob('launch/*.launch.py'))

data_files = [
    ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
    ('share/' + package_name, ['package.xml']),
]
if launch_files:
    data_files.append(('share/' + package_name + '/launch', launch_files))

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    package_data={package_name: ['data/*.yaml', 'core/data/*.yaml']},
    data_files=data_files,
    # ROS packages (rclpy, message packages, hexacal_msgs_py) come from the
    # ROS install or the workspace, not PyPI; see requirements.txt.
    install_requires=[
        'setuptools',
        'numpy',
        'scipy',
        'pyyaml',
        'mcap',
        'mcap-ros2-support',
        'matplotlib',
        'tqdm',
        'threadpoolctl',
        'lz4',
        'zstandard',
    ],
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
    description='Kinematic calibration of six-leg parallel manipulators (Hexa Slide, '
    'Gough-Stewart): identification core, nodes and CLI.',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'collector = hexacal_identify.nodes.entry:collector',
            'identify = hexacal_identify.nodes.entry:identify',
            'executor = hexacal_identify.nodes.entry:executor',
            'kinematics = hexacal_identify.nodes.entry:kinematics',
            'replay = hexacal_identify.nodes.replay:main',
            'hexacal = hexacal_identify.cli:main',
            'bringup = hexacal_identify.bringup.cli:main',
        ],
    },
)
