from glob import glob

from setuptools import find_packages, setup

package_name = 'tensegrity_ros'

setup(
    name=package_name,
    version='0.2.0',
    packages=find_packages(exclude=['test', 'benchmarks']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/msg_docs', glob('msg_docs/*.md')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    # What the node and the offline tool import (ROS itself: rclpy and the message packages,
    # from a ROS install or the ros-jazzy-* wheels of requirements.txt).
    # (numba compiles a live neck's equations of motion; without it they run in numpy).
    install_requires=['setuptools', 'numpy', 'scipy', 'numba', 'PyYAML'],
    extras_require={
        # the offline tool's PNG figures, progress bar and tolerance studies
        # (`pip install .[tools]`)
        'tools': ['matplotlib', 'tqdm', 'dask', 'distributed'],
        'test': ['pytest', 'hypothesis', 'matplotlib', 'tqdm', 'dask', 'distributed'],
    },
    zip_safe=True,
    # placeholders on RFC 2606's documentation domain, as in package.xml
    maintainer='tensegrity_ros maintainers',
    maintainer_email='maintainers@example.com',
    url='https://example.com/tensegrity_ros',
    description='Planar tensegrity mechanism (bird neck): exact equilibria, jump-aware '
                'tracking, trajectories and TF, ROS 2 node.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'tensegrity_node = tensegrity_ros.ros.node:main',
            'tensegrity = tensegrity_ros.cli_entry:main',
        ],
    },
)
