from glob import glob

from setuptools import find_packages, setup

package_name = 'tensegrity_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'benchmarks']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
        ('share/' + package_name + '/msg_docs', glob('msg_docs/*.md')),
        ('share/' + package_name + '/launch', glob('launch/*.launch.py')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='tensegrity_ros developers',
    maintainer_email='dev@tensegrity-ros.invalid',
    description='Planar tensegrity mechanism (bird neck): exact equilibria, jump-aware tracking, ROS 2 node.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'tensegrity_node = tensegrity_ros.node:main',
            'tensegrity = tensegrity_ros.cli:main',
        ],
    },
)
