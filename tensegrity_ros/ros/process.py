"""Running ``tensegrity_node`` as a program: its options, the executor, signals, clean-up.

What :func:`tensegrity_ros.ros.node.main` uses around the node: the ``--executor`` option, the
``--params-file`` paths it checks before rcl parses them, the SIGINT/SIGTERM handler behind
rclpy's, and a clean-up that tolerates the handler shutting the context concurrently.
"""
import argparse

import rclpy
import rclpy.executors
import rclpy.utilities


def make_executor(kind):
    """The executor the node's ``main`` spins: ``events`` (default) or ``single``.

    ``events`` is rclpy's C++ events executor (``rclpy.experimental.EventsExecutor``,
    shipped with Jazzy's rclpy): it dispatches a callback for a fraction of the Python
    SingleThreadedExecutor's per-callback cost, which is what lets the node keep up with
    1 kHz commands.  ``single`` is the classic ``rclpy.spin`` executor.
    """
    if kind == 'events':
        try:
            from rclpy.experimental import EventsExecutor
            return EventsExecutor()
        except ImportError:           # an rclpy without it: fall back
            pass
    return rclpy.executors.SingleThreadedExecutor()


def parse_cli(argv):
    """The program's own options (``--executor``) among ``argv``, ROS arguments removed."""
    parser = argparse.ArgumentParser(
        prog='tensegrity_node',
        description='Tensegrity module node: tracks the stable equilibrium, reports jumps. '
                    'ROS arguments follow --ros-args (e.g. --params-file config/default.yaml).')
    parser.add_argument('--executor', choices=('events', 'single'), default='events',
                        help='events: rclpy EventsExecutor (fast, default); '
                             'single: SingleThreadedExecutor (rclpy.spin)')
    return parser.parse_args(rclpy.utilities.remove_ros_args(argv)[1:])


class Interrupt:
    """SIGINT/SIGTERM handler behind rclpy's (which shuts the context down, then calls
    this): while starting, stop at once (KeyboardInterrupt); once spinning, do nothing --
    the shut-down context ends the spin loop, while an exception raised here would land
    inside whatever callback is running (the events executor then logs it as FATAL)."""

    def __init__(self):
        self.spinning = False

    def __call__(self, signum, frame):
        if not self.spinning:
            raise KeyboardInterrupt


def parameter_files(argv):
    """The ``--params-file`` paths among the ROS arguments of ``argv``."""
    paths, in_ros_args = [], False
    for i, arg in enumerate(argv):
        if arg == '--ros-args':
            in_ros_args = True
        elif arg == '--':
            in_ros_args = False
        elif in_ros_args and arg == '--params-file' and i + 1 < len(argv):
            paths.append(argv[i + 1])
    return paths


def quietly(cleanup):
    """Run a clean-up step; tolerate the signal handler shutting the context concurrently.

    rclpy's SIGINT/SIGTERM handler shuts the context down from its own thread: a
    ``try_shutdown`` racing with it can raise "rcl_shutdown already called".
    """
    if cleanup is None:
        return
    try:
        cleanup()
    except Exception:
        if rclpy.ok():
            raise
