"""Test session environment: DDS on loopback, a DDS domain of its own, checked fields.

Set before any test module imports rclpy.

Domains: the session's base domain is ROS_DOMAIN_ID from the environment (the Makefile
and .ci/run export one per run), else one drawn from the run (pytest-xdist's run id,
shared by its workers, or this process's id).  Under pytest-xdist each worker takes the
base plus its index (gw0 the base, gw1 the next, ...), so two workers' node tests never
share a domain; domains stay in 0..101, the range ROS 2 documents as safe on Linux.
"""
import os

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
