"""Each pytest-xdist worker gets a DDS domain of its own (test/conftest.py): the run's
base domain (ROS_DOMAIN_ID from the environment) plus the worker's index, in 0..101.
Two workers on one domain would see each other's nodes (same node names in the graph,
cross-talk on relative topics)."""
import os
from pathlib import Path
import subprocess
import sys

import pytest

from conftest import base_domain, MAX_DOMAIN, worker_domain

HERE = Path(__file__).resolve().parent


def test_worker_domains_are_distinct_and_in_range():
    for base in range(MAX_DOMAIN + 1):
        domains = [worker_domain(base, f'gw{i}') for i in range(9)]
        assert len(set(domains)) == 9
        assert all(0 <= d <= MAX_DOMAIN for d in domains)
        assert domains[0] == base and worker_domain(base, None) == base
    assert [worker_domain(11, f'gw{i}') for i in range(9)] == list(range(11, 20))


def test_the_base_is_the_environment_s_else_one_per_run():
    assert base_domain({'ROS_DOMAIN_ID': '11'}) == 11
    run = {'PYTEST_XDIST_TESTRUNUID': 'a3f0c1'}
    assert base_domain(run) == base_domain(dict(run)) and 1 <= base_domain(run) <= 100


def test_this_session_is_on_loopback_with_a_domain_in_range():
    assert os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'LOCALHOST'
    assert 0 <= int(os.environ['ROS_DOMAIN_ID']) <= MAX_DOMAIN


def test_two_xdist_workers_run_on_two_domains(tmp_path):
    """A run of two workers (this conftest, a test per worker recording its domain)."""
    pytest.importorskip('xdist')
    (tmp_path / 'conftest.py').write_text((HERE / 'conftest.py').read_text())
    (tmp_path / 'test_record.py').write_text(
        'import os, pathlib, pytest\n'
        '@pytest.mark.parametrize("i", range(8))\n'
        'def test_record(i, tmp_path_factory):\n'
        '    worker = os.environ["PYTEST_XDIST_WORKER"]\n'
        '    out = pathlib.Path(__file__).with_name(worker)\n'
        '    out.write_text(os.environ["ROS_DOMAIN_ID"])\n')
    env = {k: v for k, v in os.environ.items() if not k.startswith('PYTEST_XDIST')}
    env['ROS_DOMAIN_ID'] = '30'             # (this run's own worker variables left out)
    done = subprocess.run([sys.executable, '-m', 'pytest', '-q', '-p', 'no:cacheprovider',
                           '-n', '2', '-c', os.devnull, '--rootdir', str(tmp_path),
                           str(tmp_path)],
                          env=env, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    assert {p.name: p.read_text() for p in tmp_path.glob('gw*')} == {'gw0': '30', 'gw1': '31'}
