"""The package's import arrows all point down (README, "Package layout"): no cycles, the
core imports nothing outside it, figures never import the command line, and only the
ROS layer (node, node_parameters, parameter_handling, node_process, ros_conversions)
imports rclpy or messages.  Within the core, the concept folders are layers too: a module
imports its own folder and the folders below it, never one above."""
import ast
import pathlib
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent / 'tensegrity_ros'
ROS_LAYER = {'node', 'node_parameters', 'parameter_handling', 'node_process', 'ros_conversions'}


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
    assert not {_short(m) for m in inside} & ROS_LAYER
    assert 'rclpy' not in outside


def test_only_the_ros_layer_imports_the_ros_layer():
    for name, (inside, _) in GRAPH.items():
        if _short(name) not in ROS_LAYER:
            assert not {_short(m) for m in inside} & ROS_LAYER, name
