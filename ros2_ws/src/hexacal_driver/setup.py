from setuptools import find_packages, setup

package_name = 'hexacal_driver'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    # hexacal_identify, hexacal_msgs_py and the ROS packages come from the
    # workspace or the ROS install, not PyPI.
    install_requires=['setuptools', 'numpy', 'scipy', 'pyyaml'],
    # colcon test runs pytest when it is a test dependency (as ament_python packages
    # declare it); every module the tests import besides the runtime ones.
    extras_require={
        'test': [
            'pytest',
        ],
    },
    zip_safe=True,
    maintainer='hexacal developers',
    maintainer_email='hexacal@example.com',
    description='Simulated Hexa Slide manipulator and calibration device driver.',
    license='Apache-2.0',
    python_requires='>=3.10',
    entry_points={
        'console_scripts': [
            'driver = hexacal_driver.entry:driver',
        ],
    },
)
