"""What the package declares it needs is what it imports (issue 33).

The node and its launch files run on the ROS message packages, numpy, scipy and PyYAML
alone; matplotlib and tqdm are the offline tool's, the ``tools`` extra; package.xml and
setup.py say so, and package.xml is a complete format-3 manifest.
"""
import ast
from pathlib import Path
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: ROS package (package.xml exec_depend) of each top-level import of the ROS layer.
ROS_PACKAGES = {'rclpy': 'rclpy', 'rcl_interfaces': 'rcl_interfaces', 'std_msgs': 'std_msgs',
                'std_srvs': 'std_srvs', 'sensor_msgs': 'sensor_msgs',
                'geometry_msgs': 'geometry_msgs', 'diagnostic_msgs': 'diagnostic_msgs',
                'visualization_msgs': 'visualization_msgs',
                'trajectory_msgs': 'trajectory_msgs', 'tf2_msgs': 'tf2_msgs',
                'numpy': 'python3-numpy', 'scipy': 'python3-scipy', 'numba': 'python3-numba',
                'yaml': 'python3-yaml',
                'ament_index_python': 'ament_index_python', 'launch': 'launch',
                'launch_ros': 'launch_ros'}


def manifest():
    return ET.parse(ROOT / 'package.xml').getroot()


def top_level_imports(path):
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names |= {a.name.split('.')[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and not node.level and node.module:
            names.add(node.module.split('.')[0])
    return names - set(sys.stdlib_module_names) - {'tensegrity_ros', '__future__'}


def test_the_node_never_loads_the_offline_tools_dependencies():
    code = ('import sys, tensegrity_ros.ros.node, tensegrity_ros.params_file; '
            'print(sorted(m for m in ("matplotlib", "tqdm", "dask", "distributed") '
            'if m in sys.modules))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         check=True, cwd=ROOT)
    assert out.stdout.strip() == '[]', out


def test_exec_depends_are_what_the_node_and_launch_files_import():
    files = sorted((ROOT / 'tensegrity_ros' / 'ros').glob('*.py'))
    files += [ROOT / 'tensegrity_ros' / f for f in (
        'params_file.py', 'module_parameters.py', 'log_text.py')]
    files += sorted((ROOT / 'tensegrity_ros' / 'core').rglob('*.py'))
    files += sorted((ROOT / 'launch').glob('*.launch.py'))
    imported = set().union(*(top_level_imports(f) for f in files))
    assert imported <= ROS_PACKAGES.keys(), imported - ROS_PACKAGES.keys()
    declared = {e.text for e in manifest().findall('exec_depend')}
    assert declared == {ROS_PACKAGES[name] for name in imported}
    assert not {'python3-matplotlib', 'python3-tqdm'} & declared


def test_the_manifest_is_complete():
    root = manifest()
    assert root.get('format') == '3'
    for tag in ('name', 'version', 'description', 'maintainer', 'license'):
        assert (root.findtext(tag) or '').strip(), tag
    email = root.find('maintainer').get('email')
    assert email and not email.endswith('.invalid')
    urls = {u.get('type') for u in root.findall('url')}
    assert urls == {'website', 'repository', 'bugtracker'}
    tests = {e.text for e in root.findall('test_depend')}
    assert {'ament_flake8', 'ament_pep257', 'python3-pytest'} <= tests
    assert root.find('export/build_type').text == 'ament_python'
    setup = (ROOT / 'setup.py').read_text()
    assert f"version='{root.findtext('version')}'" in setup


def test_setup_declares_the_tools_extra():
    tree = ast.parse((ROOT / 'setup.py').read_text())
    call = next(n for n in ast.walk(tree) if isinstance(n, ast.Call)
                and getattr(n.func, 'id', '') == 'setup')
    keywords = {k.arg: ast.literal_eval(k.value) for k in call.keywords
                if k.arg in ('install_requires', 'extras_require')}
    assert set(keywords['install_requires']) == {'setuptools', 'numpy', 'scipy', 'numba',
                                                 'PyYAML'}
    tools = set(keywords['extras_require']['tools'])
    assert tools == {'matplotlib', 'tqdm', 'dask', 'distributed'}
    pinned = {line.split('==')[0].lower() for line in
              (ROOT / 'requirements.txt').read_text().splitlines() if '==' in line}
    assert {'matplotlib', 'tqdm', 'ros-ament-flake8', 'ros-ament-pep257'} <= pinned


def test_a_figure_without_matplotlib_is_one_clear_error(tmp_path):
    code = ('import sys; sys.modules["matplotlib"] = None; '
            'from tensegrity_ros.cli import main; '
            f'sys.exit(main(["diagram", "--from-rho", "0.1", "--to-rho", "1", "--count", "5", '
            f'"--png", r"{tmp_path / "d.png"}"]))')
    out = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                         cwd=ROOT)
    assert out.returncode == 1, out
    assert out.stderr.strip().count('\n') == 0, out.stderr
    assert "error: No module named 'matplotlib" in out.stderr
    assert not (tmp_path / 'd.png').exists()


@pytest.mark.parametrize('launch_file', ['module.launch.py', 'neck.launch.py'])
def test_launch_files_are_installed(launch_file):
    assert "glob('launch/*.launch.py')" in (ROOT / 'setup.py').read_text()
    assert (ROOT / 'launch' / launch_file).exists()
