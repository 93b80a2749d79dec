"""Where the package's console scripts are installed, in a venv and in a ROS install.

pip puts them next to the interpreter (``.venv/bin``); colcon, like every ament_python
install, puts them in ``<prefix>/lib/tensegrity_ros/`` (setup.cfg), the prefix found
through the ament index (``AMENT_PREFIX_PATH``), which is how ``ros2 run`` finds them.
"""
from pathlib import Path
import sys

PACKAGE = 'tensegrity_ros'


def ament_prefix():
    """Install prefix of the package in the ament index, or None outside a ROS environment."""
    try:
        from ament_index_python.packages import get_package_prefix, PackageNotFoundError
    except ImportError:
        return None
    try:
        return Path(get_package_prefix(PACKAGE))
    except (PackageNotFoundError, OSError):    # OSError: AMENT_PREFIX_PATH not set
        return None


def script_candidates(name):
    """Paths where an install puts console script ``name``: ROS layout first, then the venv."""
    prefix = ament_prefix()
    ros = [] if prefix is None else [prefix / 'lib' / PACKAGE / name]
    return ros + [Path(sys.executable).with_name(name)]


def installed_script(name):
    """The installed console script ``name``; fails, naming every place looked at, if none."""
    candidates = script_candidates(name)
    for path in candidates:
        if path.is_file():
            return path
    raise AssertionError(f'console script {name!r} is not installed: looked at '
                         f'{", ".join(map(str, candidates))}')
