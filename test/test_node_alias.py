"""The node's old import path, ``tensegrity_ros.node``, is a deprecated alias of
``tensegrity_ros.ros.node`` for one release (issue 42): it warns, and it still works."""
import importlib
import subprocess
import sys

import pytest

from tensegrity_ros.ros import node


def test_importing_the_old_path_warns_and_gives_the_node(monkeypatch):
    monkeypatch.delitem(sys.modules, 'tensegrity_ros.node', raising=False)
    with pytest.warns(DeprecationWarning, match='use tensegrity_ros.ros.node'):
        alias = importlib.import_module('tensegrity_ros.node')
    assert alias.TensegrityNode is node.TensegrityNode
    assert alias.main is node.main


def test_the_old_path_still_runs_as_a_program():
    result = subprocess.run([sys.executable, '-m', 'tensegrity_ros.node', '--help'],
                            capture_output=True, text=True, timeout=120)
    assert result.returncode == 0, result.stderr
    assert 'usage: tensegrity_node' in result.stdout
