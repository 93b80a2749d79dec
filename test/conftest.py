"""Test session environment: DDS on loopback, a DDS domain of its own, checked fields.

Set before any test module imports rclpy.
"""
import os

import pytest

os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'LOCALHOST'
os.environ.setdefault('ROS_DOMAIN_ID', str(1 + os.getpid() % 100))
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
