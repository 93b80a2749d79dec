#!/usr/bin/env python3
"""The node's own cost per command, without the transport: its joint_commands callback
beside the simulator call inside it and beside a bare relay's callback, in one process.

``tensegrity_node`` on config/neck.yaml (``--config`` for another) is built in-process and
its ``joint_commands`` subscription callback is called directly with serialized commands,
as the executor calls it: the neck bench's stream (bench_node_latency.py --neck: every
module's ``<m>_rho`` on a small sine around its rho_initial).  Per command, side by side:

* node: the whole callback -- read the bytes, check, coalesce, track, publish joint_states;
* simulator: ``Simulator.command_rhos`` on the same targets, on a second simulator built
  from the same parameters (it follows the node's state command for command);
* relay: what a bare rclpy relay's callback does -- deserialize the JointState, build
  one with the joints, publish it.

and then the ROS layer alone: the node callback again with ``command_rhos`` answering at
once (an accepted outcome: what the node does around the tracker).  node - simulator
is larger than that (the tracker inside the callback shares caches with the rest).
Nothing subscribes, so no publication leaves the process; DDS delivery is
bench_node_latency.py's business.  Medians over ``--commands`` (default 2000) after a
warm-up.  ``PYTHONPATH=<another checkout>`` measures another version of the node.

BENCH_CLOCK=cpu times with this thread's CPU clock instead of the wall clock (a loaded
machine adds to the wall clock the time spent waiting for a CPU).  Also printed: the
Python and C function calls per command of each (cProfile's count over 200 commands):
a figure the load does not change, by area (ROS layer, simulator, stack tracker).

    python benchmarks/bench_node_command_path.py
"""
import argparse
import math
import os
from pathlib import Path
import statistics
import sys
import time

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_node_latency import NECK_AMPLITUDE, NECK_CONFIG, NECK_PERIOD  # noqa: E402

WARM_UP = 200
CLOCK = time.thread_time if os.environ.get('BENCH_CLOCK') == 'cpu' else time.perf_counter
#: Where a function lives -> the area its calls are counted in (first match wins).
AREAS = (('stack tracker', ('core/stack', 'core/continuation', 'numpy', 'scipy')),
         ('simulator', ('core/',)),
         ('ROS layer', ('tensegrity_ros/', 'rclpy', '_msgs/')))


def neck_commands(modules, start_rhos, count):
    """(serialized joint_commands, {module index: rho}) of the neck bench's stream: every
    module's rho on a small sine (phase-shifted per module) around ``start_rhos``."""
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState
    out = []
    for i in range(count):
        phase = 2 * math.pi * i / NECK_PERIOD
        rhos = [rho + NECK_AMPLITUDE * math.sin(phase + j) for j, rho in enumerate(start_rhos)]
        msg = JointState(name=[f'{m}_rho' for m in modules], position=rhos)
        out.append((serialize_message(msg), dict(enumerate(rhos))))
    return out


def relay_callback(publisher, modules):
    """A bare relay's callback: deserialize, answer with a JointState, publish."""
    from rclpy.serialization import deserialize_message
    from sensor_msgs.msg import JointState
    names = [f'{m}_{k}' for m in modules for k in ('rho', 'theta1', 'theta2')]

    def callback(raw):
        msg = deserialize_message(raw, JointState)
        rho = dict(zip(msg.name, msg.position))
        position = [v for m in modules for v in (rho.get(f'{m}_rho', 0.0), 0.0, 0.0)]
        publisher.publish(JointState(name=names, position=position, effort=[0.0] * len(names)))
    return callback


def _ros_layer_alone(node, callback, commands):
    """Per-command times (us) of the node callback with the simulator call answering at once."""
    from tensegrity_ros.core.simulation.events import Outcome
    accepted = Outcome()
    node.simulator.command_rhos = lambda *args, **kwargs: accepted   # this instance only
    try:
        times = []
        for i, (raw, _) in enumerate(commands):
            t0 = CLOCK()
            callback(raw)
            if i >= WARM_UP:
                times.append((CLOCK() - t0) * 1e6)
        return times
    finally:
        del node.simulator.command_rhos


def _calls(callback, raws):
    """{area: function calls per call of ``callback``} over ``raws`` (cProfile's count)."""
    import cProfile
    import pstats
    profile = cProfile.Profile()
    profile.enable()
    for raw in raws:
        callback(raw)
    profile.disable()
    counts = {}
    for (filename, _, _), (_, calls, _, _, _) in pstats.Stats(profile).stats.items():
        area = next((name for name, marks in AREAS if any(m in filename for m in marks)),
                    'Python and C built-ins')
        counts[area] = counts.get(area, 0) + calls / len(raws)
    return counts


def measure(config, count):
    """Per-command times (us) of the node callback, the simulator and the relay."""
    import rclpy
    from sensor_msgs.msg import JointState

    from tensegrity_ros.core.simulation.simulator import Simulator
    from tensegrity_ros.ros.node import TensegrityNode

    rclpy.init(args=['bench', '--ros-args', '--params-file', str(config),
                     '-r', f'__ns:=/bench_path_{os.getpid()}'])
    node = TensegrityNode()
    relay = rclpy.create_node('relay', namespace=f'/bench_path_relay_{os.getpid()}')
    try:
        callback = next(s.callback for s in node.subscriptions
                        if s.topic_name.endswith('/joint_commands'))
        start_modules, start_thetas = node._initial_configuration()
        twin = Simulator(start_modules, start_thetas,
                         limits=[node.simulator.limits(i) for i in range(len(node.modules))])
        relay_cb = relay_callback(relay.create_publisher(JointState, 'joint_states', 10),
                                  node.modules)
        commands = neck_commands(node.modules, [p.rho for p in start_modules], WARM_UP + count)
        times = {'node': [], 'simulator': [], 'relay': []}
        before = node.counters['commands_processed']
        for i, (raw, targets) in enumerate(commands):
            t0 = CLOCK()
            callback(raw)
            t1 = CLOCK()
            twin.command_rhos(targets, 0)
            t2 = CLOCK()
            relay_cb(raw)
            t3 = CLOCK()
            if i >= WARM_UP:
                for key, dt in zip(times, (t1 - t0, t2 - t1, t3 - t2)):
                    times[key].append(dt * 1e6)
        times['ros layer'] = _ros_layer_alone(node, callback, commands)
        processed = node.counters['commands_processed'] - before
        if processed != 2 * (WARM_UP + count):
            raise RuntimeError(f'the node processed {processed} of {2 * (WARM_UP + count)} '
                               f'commands')
        more = neck_commands(node.modules, [p.rho for p in start_modules], 200)
        calls = {'node': _calls(callback, [raw for raw, _ in more]),
                 'relay': _calls(relay_cb, [raw for raw, _ in more])}
        return times, calls
    finally:
        relay.destroy_node()
        node.destroy_node()
        rclpy.try_shutdown()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--config', type=Path, default=NECK_CONFIG)
    parser.add_argument('--commands', type=int, default=2000)
    args = parser.parse_args(argv)
    times, calls = measure(args.config, args.commands)
    med = {k: statistics.median(v) for k, v in times.items()}
    p90 = {k: statistics.quantiles(v, n=10)[-1] for k, v in times.items()}
    import tensegrity_ros
    print(f'node command path ({args.config.name}, {args.commands} commands, in-process, '
          f'{os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}; tensegrity_ros from '
          f'{Path(tensegrity_ros.__file__).parent})')
    clock = 'CPU time of this thread' if CLOCK is time.thread_time else 'wall clock'
    print(f'per command (us, {clock})')
    print(f'{"":<36} {"median":>8} {"p90":>8}')
    for key, label in (('node', 'node: joint_commands callback'),
                       ('simulator', 'simulator.command_rhos (inside it)'),
                       ('ros layer', 'ROS layer alone (simulator stubbed)'),
                       ('relay', 'bare relay callback (baseline)')):
        print(f'{label:<36} {med[key]:>8.1f} {p90[key]:>8.1f}')
    print(f'{"node - simulator":<36} {med["node"] - med["simulator"]:>8.1f}')
    print(f'ROS layer alone / relay callback: {med["ros layer"] / med["relay"]:.2f}')
    for key in ('node', 'relay'):
        split = ', '.join(f'{area} {n:.0f}' for area, n in sorted(calls[key].items()))
        print(f'function calls per command, {key}: {sum(calls[key].values()):.0f} ({split})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
