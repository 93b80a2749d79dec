#!/usr/bin/env python3
"""What an rclpy executor costs per received message: the events executor (the node's
default, ``rclpy.experimental.EventsExecutor``) beside ``SingleThreadedExecutor``.

One process, two contexts: a publisher sends ``--count`` serialized joint_commands (three
``m*_rho`` targets) at ``--rate`` Hz, reliable, to a raw subscription whose callback only
counts; the subscriber's executor spins in a thread of its own, whose CPU time
(``time.thread_time``) over the stream, per message, is the figure: take, dispatch and
the executor's bookkeeping, nothing of the node.  The two executors alternate
``--rounds`` times on fresh topics (a shared machine: compare them within a round).

    python benchmarks/bench_executor.py
"""
import argparse
import os
import statistics
import sys
import threading
import time

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')


def measure(kind, count, rate, topic):
    """(messages received, CPU us per message of the spinning thread) for one executor."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.experimental import EventsExecutor
    from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.serialization import serialize_message
    from sensor_msgs.msg import JointState

    qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)        # the node's command QoS
    sender, receiver = rclpy.Context(), rclpy.Context()
    rclpy.init(context=sender)
    rclpy.init(context=receiver)
    try:
        pub_node = rclpy.create_node('bench_executor_pub', context=sender)
        sub_node = rclpy.create_node('bench_executor_sub', context=receiver)
        pub = pub_node.create_publisher(JointState, topic, qos)
        received = []
        sub_node.create_subscription(JointState, topic, received.append, qos, raw=True)
        executor = (EventsExecutor(context=receiver) if kind == 'events'
                    else SingleThreadedExecutor(context=receiver))
        executor.add_node(sub_node)
        deadline = time.monotonic() + 30.0
        while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
            time.sleep(0.01)
        cpu, running = [0.0], [True]

        def spin():
            start = time.thread_time()
            while running[0]:
                executor.spin_once(timeout_sec=0.05)
            cpu[0] = time.thread_time() - start

        thread = threading.Thread(target=spin)
        thread.start()
        raw = serialize_message(JointState(name=['m0_rho', 'm1_rho', 'm2_rho'],
                                           position=[0.09, 0.085, 0.08]))
        start = time.perf_counter()
        for i in range(count):
            delay = start + i / rate - time.perf_counter()
            if delay > 0:
                time.sleep(delay)       # paces the stream
            pub.publish(raw)
        deadline = time.monotonic() + 10.0
        while len(received) < count and time.monotonic() < deadline:
            time.sleep(0.01)
        running[0] = False
        thread.join()
        executor.shutdown()
        return len(received), cpu[0] / count * 1e6
    finally:
        rclpy.try_shutdown(context=sender)
        rclpy.try_shutdown(context=receiver)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--count', type=int, default=3000)
    parser.add_argument('--rate', type=float, default=1000.0)
    parser.add_argument('--rounds', type=int, default=2)
    args = parser.parse_args(argv)
    results = {'single': [], 'events': []}
    print(f'executor CPU per received message (spinning thread), {args.count} messages at '
          f'{args.rate:g} Hz, {os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}')
    for r in range(args.rounds):
        for kind in results:
            topic = f'/bench_executor_{os.getpid()}_{r}_{kind}'
            got, us = measure(kind, args.count, args.rate, topic)
            results[kind].append(us)
            print(f'round {r} {kind:<7} received {got:>6} of {args.count}  {us:8.1f} us')
    single, events = (statistics.median(results[k]) for k in ('single', 'events'))
    print(f'median: single {single:.1f} us, events {events:.1f} us; single / events '
          f'{single / events:.2f}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
