"""The package's import arrows all point down (README, "Package layout"): no cycles, the
core imports nothing outside it, figures never import the command line, and only the
ROS layer (everything under tensegrity_ros.ros) imports rclpy or message packages, or
the ROS layer itself.  Within the core, the concept folders are layers too: a module
imports its own folder and the folders below it, never one above."""
import ast
import pathlib
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent / 'tensegrity_ros'
#: The ROS layer: this package and everything under it.
ROS_LAYER = 'tensegrity_ros.ros'
#: Deprecated aliases of ROS layer modules, kept for one release at their old paths.
ALIASES = {'tensegrity_ros.node': 'tensegrity_ros.ros.node'}


def _in_ros_layer(name):
    return name == ROS_LAYER or name.startswith(ROS_LAYER + '.')


def _is_ros(package):
    """A top-level package of ROS: rclpy, or an interface (message, service) package."""
    return package == 'rclpy' or package.endswith(('_msgs', '_srvs', '_interfaces'))


def _modules():
    out = {}
    for path in ROOT.rglob('*.py'):
        parts = path.relative_to(ROOT.parent).with_suffix('').parts
        out['.'.join(parts[:-1] if parts[-1] == '__init__' else parts)] = path
    return out


MODULES = _modules()


def _imports(name, path):
    """(package modules, top-level external packages) that ``name`` imports, anywhere in it."""
    package = name if path.name == '__init__.py' else name.rsplit('.', 1)[0]
    inside, outside = set(), set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split('.')[:len(package.split('.')) - node.level + 1]
                target = '.'.join(base + ([node.module] if node.module else []))
            else:
                target = node.module or ''
            submodules = {f'{target}.{a.name}' for a in node.names} & MODULES.keys()
            if submodules:
                inside |= submodules
            elif target in MODULES:
                inside.add(target)
            else:
                outside.add(target.split('.')[0])
        elif isinstance(node, ast.Import):
            for alias in node.names:
                (inside if alias.name in MODULES else outside).add(
                    alias.name if alias.name in MODULES else alias.name.split('.')[0])
    inside.discard(name)
    return inside, outside


GRAPH = {name: _imports(name, path) for name, path in MODULES.items()}


def _short(name):
    return name.removeprefix('tensegrity_ros.') or 'tensegrity_ros'


def test_no_import_cycles():
    done, active = set(), []

    def visit(name):
        if name in active:
            cycle = active[active.index(name):] + [name]
            pytest.fail('import cycle: ' + ' -> '.join(map(_short, cycle)))
        if name in done:
            return
        active.append(name)
        for dep in GRAPH[name][0]:
            visit(dep)
        active.pop()
        done.add(name)

    for name in sorted(GRAPH):
        visit(name)


def test_core_imports_only_core_the_standard_library_numpy_scipy():
    for name, (inside, outside) in GRAPH.items():
        if not name.startswith('tensegrity_ros.core'):
            continue
        assert all(dep.startswith('tensegrity_ros.core') for dep in inside), (name, inside)
        allowed = {'numpy', 'scipy'} | COMPILED.get(name, set())
        assert outside - sys.stdlib_module_names - {'__future__'} <= allowed, (name, outside)


#: The one module that imports numba (numba_kernels): it compiles the kernels of the neck's
#: equations of motion (the live loop's inner loop) and of its elastic gradient flow (a
#: batch question's); see their docstrings for the numpy figures.
COMPILED = {'tensegrity_ros.core.numerics.numba_kernels': {'numba'}}


#: The core's concept folders, bottom up (docs/architecture.md says why this order).
CORE_FOLDERS = ('numerics', 'continuation', 'module', 'analysis', 'neck', 'dynamics',
                'simulation', 'tolerance')


def _core_folder(name):
    """The concept folder of a core module, or None for the core's own top-level files
    (its public front door and the deprecated aliases of moved paths)."""
    parts = name.split('.')
    return parts[2] if len(parts) > 2 and parts[2] in CORE_FOLDERS else None


def test_core_folders_import_only_their_own_folder_and_those_below():
    for name, (inside, _) in GRAPH.items():
        folder = _core_folder(name)
        if not name.startswith('tensegrity_ros.core') or folder is None:
            continue
        level = CORE_FOLDERS.index(folder)
        for dep in inside:
            below = _core_folder(dep)
            assert below is not None and CORE_FOLDERS.index(below) <= level, (
                f'{_short(name)} ({folder}) imports {_short(dep)} ({below or "core top level"})')


def test_every_core_module_lives_in_a_concept_folder():
    from tensegrity_ros.core.moved_modules import MOVED
    loose = {name for name in MODULES if name.startswith('tensegrity_ros.core.')
             and _core_folder(name) is None}
    assert loose == set(MOVED) | {'tensegrity_ros.core.moved_modules'}, loose


#: The offline tools below the command line: every module of the figures package, and the
#: parameter modules the command line and the node share.
OFFLINE_TOOLS = sorted(_short(m) for m in MODULES if _short(m).split('.')[0] == 'figures') \
    + ['problem', 'params_file', 'module_parameters']


@pytest.mark.parametrize('tool', OFFLINE_TOOLS)
def test_offline_tools_never_import_the_command_line_or_ros(tool):
    inside, outside = GRAPH[f'tensegrity_ros.{tool}']
    assert not [m for m in inside if m == 'tensegrity_ros.cli'
                or m.startswith('tensegrity_ros.cli.')]
    assert not [m for m in inside if _in_ros_layer(m)]
    assert not [p for p in outside if _is_ros(p)]


def test_only_the_ros_layer_imports_the_ros_layer():
    layer = {name for name in GRAPH if _in_ros_layer(name)}
    assert {'tensegrity_ros.ros', 'tensegrity_ros.ros.node'} <= layer     # (not vacuous)
    for name, (inside, _) in GRAPH.items():
        if not _in_ros_layer(name):
            allowed = {ALIASES[name]} if name in ALIASES else set()
            assert not (inside & layer) - allowed, name


def test_only_the_ros_layer_imports_rclpy_or_message_packages():
    ros = {name: {p for p in outside if _is_ros(p)} for name, (_, outside) in GRAPH.items()}
    assert {'rclpy', 'sensor_msgs', 'rcl_interfaces'} <= set().union(*ros.values())
    assert {name for name, packages in ros.items() if packages and not _in_ros_layer(name)} \
        == set()


def test_a_deprecated_alias_imports_only_its_new_module():
    for alias, target in ALIASES.items():
        assert GRAPH[alias][0] == {target}, alias
