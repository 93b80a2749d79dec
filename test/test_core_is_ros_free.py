"""The core must stay importable without ROS: it is the library half of the package."""
import subprocess
import sys


def test_importing_core_does_not_import_rclpy():
    code = ('import sys, tensegrity_ros.core, tensegrity_ros.core.module.equilibria; '
            'bad = sorted(m for m in sys.modules if m.split(".")[0] in '
            '("rclpy", "std_msgs", "sensor_msgs", "geometry_msgs", "diagnostic_msgs")); '
            'print(bad); sys.exit(1 if bad else 0)')
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True)
    assert result.returncode == 0, result.stdout + result.stderr
