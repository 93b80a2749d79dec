"""Test session environment: DDS on loopback, a DDS domain of its own, checked fields.

Set before any test module imports rclpy.

Domains: the session's base domain is ROS_DOMAIN_ID from the environment (the Makefile
and .ci/run export one per run), else one drawn from the run (pytest-xdist's run id,
shared by its workers, or this process's id).  Under pytest-xdist each worker takes the
base plus its index (gw0 the base, gw1 the next, ...), so two workers' node tests never
share a domain; domains stay in 0..101, the range ROS 2 documents as safe on Linux.
"""
import os

import pytest

#: ROS 2's safe domain range on Linux is 0..101 (ports of higher ones may collide).
MAX_DOMAIN = 101


def base_domain(environ):
    """The run's base domain: ROS_DOMAIN_ID if set, else one drawn from the run (1..100)."""
    chosen = environ.get('ROS_DOMAIN_ID', '').strip()
    if chosen:
        return int(chosen)
    run = environ.get('PYTEST_XDIST_TESTRUNUID')
    return 1 + (int(run, 16) if run else os.getpid()) % 100


def worker_domain(base, worker):
    """Domain of the xdist worker named ``worker`` ('gw<i>', or None outside xdist):
    base + i, wrapped into 0..MAX_DOMAIN."""
    index = int(worker[2:]) if worker and worker.startswith('gw') else 0
    return (base + index) % (MAX_DOMAIN + 1)


os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ['ROS_DOMAIN_ID'] = str(worker_domain(base_domain(os.environ),
                                                os.environ.get('PYTEST_XDIST_WORKER')))
os.environ.setdefault('ROS_PYTHON_CHECK_FIELDS', '1')


# The node tests' fixtures, shared by their files (test_node*.py, test_msg_docs.py): rclpy
# for a test module, a harness (test_node.Harness) per test, the neck's (test_node_neck.Neck).

@pytest.fixture(scope='module')
def ros():
    """rclpy initialised for the module's tests, shut down after them."""
    import rclpy
    rclpy.init()
    yield
    rclpy.try_shutdown()


@pytest.fixture
def harness(ros):
    """make(...) -> a test_node.Harness (a node and a client, spun together), closed after."""
    from test_node import Harness
    made = []

    def make(*args, **kwargs):
        h = Harness(*args, **kwargs)
        made.append(h)
        return h

    yield make
    for h in reversed(made):
        h.close()


@pytest.fixture
def neck(harness):
    """make(...) -> a test_node_neck.Neck on config/neck.yaml."""
    from test_node_neck import Neck
    return lambda **kwargs: Neck(harness, **kwargs)
