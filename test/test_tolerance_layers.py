"""Where the tolerance code sits (issue 34): only the engine imports dask; the node's
import path holds neither dask nor any tolerance module; the CLI imports dask only when
a study runs on a cluster.  (The core's numpy/scipy-only rule: test_import_layers.)"""
import subprocess
import sys

from test_import_layers import GRAPH

TOLERANCE = {'tensegrity_ros.tolerance', 'tensegrity_ros.tolerance.design',
             'tensegrity_ros.tolerance.study', 'tensegrity_ros.tolerance.result',
             'tensegrity_ros.tolerance.engine', 'tensegrity_ros.tolerance.replay',
             'tensegrity_ros.tolerance.report',
             'tensegrity_ros.cli.tolerance', 'tensegrity_ros.core.tolerance.sampling',
             'tensegrity_ros.core.tolerance.questions',
             'tensegrity_ros.core.tolerance.sample_statistics',
             'tensegrity_ros.core.tolerance.branch_batch', 'tensegrity_ros.core.tolerance.batch'}


def closure(name):
    seen, todo = set(), [name]
    while todo:
        m = todo.pop()
        if m not in seen:
            seen.add(m)
            todo.extend(GRAPH[m][0])
    return seen


def test_the_tolerance_modules_exist_and_only_the_engine_imports_dask():
    assert TOLERANCE <= GRAPH.keys()
    users = {name for name, (_, outside) in GRAPH.items() if outside & {'dask', 'distributed'}}
    assert users == {'tensegrity_ros.tolerance.engine'}


def test_the_node_imports_no_tolerance_module():
    reached = closure('tensegrity_ros.ros.node')
    assert not reached & TOLERANCE
    assert not any(GRAPH[m][1] & {'dask', 'distributed'} for m in reached)


def test_importing_the_node_and_the_cli_loads_no_dask():
    code = ('import sys, tensegrity_ros.ros.node, tensegrity_ros.cli; '
            'bad = sorted(m for m in sys.modules if m.split(".")[0] in ("dask", "distributed")'
            ' or m.startswith("tensegrity_ros.tolerance.engine")); print(bad); '
            'sys.exit(1 if bad else 0)')
    result = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                            timeout=120)
    assert result.returncode == 0, result.stdout + result.stderr
