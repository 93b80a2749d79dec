"""tools/same_arithmetic.py: which test-numerics configs repeat this machine's arithmetic.

make test-numerics skips a config only when it is this machine's own arithmetic; a config
that would change a kernel or a SIMD loop must never be taken for a repeat.
"""
import importlib.util
import os
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parents[1]
TOOL = ROOT / 'tools' / 'same_arithmetic.py'


def load_tool():
    spec = importlib.util.spec_from_file_location('same_arithmetic', TOOL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def run_tool(*args):
    env = {k: v for k, v in os.environ.items()
           if k not in ('OPENBLAS_CORETYPE', 'NPY_DISABLE_CPU_FEATURES')}
    return subprocess.run([sys.executable, str(TOOL), *args], env=env).returncode


def native_core():
    cores = subprocess.run(
        [sys.executable, '-c', 'import sys; sys.path.insert(0, sys.argv[1]);'
         'import same_arithmetic as s; print(*s.native_cores())', str(TOOL.parent)],
        env={k: v for k, v in os.environ.items() if k != 'OPENBLAS_CORETYPE'},
        capture_output=True, text=True, check=True).stdout.split()
    return cores


def test_the_machines_own_core_with_nothing_turned_off_is_a_repeat():
    cores = native_core()
    if len(cores) != 1:
        return  # numpy and scipy picked different cores, or none could be read: never a repeat
    assert run_tool(cores[0], '-') == 0


def test_another_core_is_not_a_repeat():
    other = 'nehalem' if native_core() != ['nehalem'] else 'sandybridge'
    assert run_tool(other, '-') == 1


def test_turning_off_a_feature_this_cpu_has_is_not_a_repeat():
    tool = load_tool()
    present = sorted(tool.present_features())
    cores = native_core()
    assert present, 'numpy reports no CPU feature at all'
    assert not tool.same_arithmetic(cores[0] if cores else 'haswell', [present[-1]])


def test_turning_off_only_features_this_cpu_lacks_is_a_repeat():
    tool = load_tool()
    absent = ['AVX512_SPR'] if 'AVX512_SPR' not in tool.present_features() else []
    cores = native_core()
    if len(cores) == 1 and absent:
        assert tool.same_arithmetic(cores[0], absent)
