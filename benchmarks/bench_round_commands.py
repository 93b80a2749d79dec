#!/usr/bin/env python3
"""Round-number command streams on config/neck.yaml: how often tracking gives up, and why.

What a user types (issue 10): seeded streams of actuator targets from 0.05 to 0.15 m in
steps of 1 cm (one module, or all three at once) and head loads (-10 .. +1 N), 15
commands per stream, each from where the last one left the neck, through the core
:class:`~tensegrity_ros.core.simulation.simulator.Simulator` (no ROS) with no time budget, so every
command is one deterministic call.  A stream's commands are drawn up front, so one
stream does not depend on where an earlier one stopped.  A command that stops early is
a tracking failure (state kept, the reason in its text); they are counted by reason,
with the slowest command.  A command running longer than ``--limit`` seconds is stopped
(SIGALRM) and its stream ends there.  No target: a measurement of what is left to fix (session 9:
seed 0 gave 11 failures besides linkage limits and one command over 20 s).

With ``--reference`` every command that ends ok is also compared with the independent
quasi-static path of test/reference_paths.py (the overdamped mechanism, gradient flows
with jumps bisected), started from the same state: the same jumps (number, and s within
1e-6) and the same end state within 1e-6 rad (or its mirror image: the neck is
mirror-symmetric, and either side of a symmetric pitchfork is right).  Slow (the
reference takes seconds to a minute a command); disagreements are listed.

    python benchmarks/bench_round_commands.py [--seeds 0 1] [--streams 25] [--limit 20]
                                              [--first 0] [--reference]
"""
import argparse
import collections
import os
from pathlib import Path
import random
import re
import signal
import sys
import time

import numpy as np

from tensegrity_ros.core.neck.stack import Stack, track_stack
from tensegrity_ros.core.simulation.events import TrackingFailure
from tensegrity_ros.core.simulation.simulator import ModuleLimits, Simulator
from tensegrity_ros.params_file import load_stack_config

os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
CONFIG = Path(__file__).resolve().parents[1] / 'config' / 'neck.yaml'
TARGETS = [round(0.05 + 0.01 * i, 2) for i in range(11)]
LOADS = [0.0, -0.5, -1.0, -2.0, -5.0, 0.5, 1.0, -10.0]


class TooLong(Exception):
    """A command ran past the limit."""


def _too_long(*_):
    raise TooLong


def reason(text):
    """The kind of a failure's text: its reason without the numbers."""
    text = text.split(': ', 1)[-1]
    text = re.sub(r'stopped at m\d rho=[-0-9.e]+: ', '', text)
    return re.sub(r'[-+]?\d[\d.e+-]*', '#', text)[:70]


def commands(rng, count):
    """A stream's commands, all drawn up front (so later streams do not depend on where
    an earlier one stopped): ('rho_cmd', module, rho), ('joint_commands', {module: rho})
    or ('head load', N)."""
    drawn = []
    for _ in range(count):
        kind = rng.random()
        if kind < 0.4:
            drawn.append(('rho_cmd', rng.randrange(3), rng.choice(TARGETS)))
        elif kind < 0.7:
            drawn.append(('joint_commands', {i: rng.choice(TARGETS) for i in range(3)}))
        else:
            drawn.append(('head load', rng.choice(LOADS)))
    return drawn


def simulator(config):
    """config/neck.yaml's neck in the core simulator, with no time budget."""
    modules = [m.params for m in config.modules]
    limits = [ModuleLimits(m.rho_min, m.rho_max) for m in config.modules]
    return Simulator(modules, [m.initial_theta for m in config.modules], limits=limits,
                     time_budget=None)


def apply(sim, command):
    """Send one command to the simulator: its Outcome."""
    if command[0] == 'rho_cmd':
        return sim.command_rho(command[1], command[2], 0)
    if command[0] == 'joint_commands':
        return sim.command_rhos(command[1], 0)
    return sim.set_parameters({2: {'f3y': command[1], 'f4y': command[1]}}, 0, 'force')


def compared_with_reference(start, end, held, limit):
    """'agree', 'differ: ...' or 'no reference: ...' for the command from ``held`` (a
    verified state of ``start``) to ``end``, tracked here and by the reference.

    They agree where the jumps match in s (1e-6) and landing (1e-4 rad, or the mirror
    image), and the end states to 1e-6 rad.  A landing of ours that the reference lists
    as another way out of a crossing, or, where our jump says it is ambiguous, where the
    reference's own flow from our departure rests (at a crossing the way out turns on
    the departure's last 1e-7 rad), is followed on by the reference from there."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / 'test'))
    from reference_paths import angle_distance, flow_to_rest, NeckSystem, quasi_static_path
    track = track_stack(start, end, held)
    if track.status != 'ok':
        return 'agree'                          # a stated give-up: counted as a failure
    signal.alarm(limit)
    try:
        ref = quasi_static_path(NeckSystem(start.modules, end.modules), np.ravel(held.theta))
    except TooLong:
        return 'no reference: over the limit'
    except Exception as error:                  # the reference's own give-up
        return f'no reference: {type(error).__name__}'
    finally:
        signal.alarm(0)
    system = NeckSystem(start.modules, end.modules)
    apart = lambda a, b: min(angle_distance(a, b),                         # noqa: E731
                             angle_distance(np.reshape(a, (-1, 2))[:, ::-1].ravel(), b))
    jumps, done = sorted(track.jumps, key=lambda j: j.s), 0
    differ = lambda: (f'differ: jumps at s {[round(float(j.s), 7) for j in jumps]}, '  # noqa
                      f'reference {[round(float(j.s), 7) for j in ref.jumps]}; end states '
                      f'{apart(np.ravel(track.final.theta), ref.final):.2g} rad apart')
    while True:     # as test_reference_tracking.assert_same_neck_path: where a jump of ours
        again = False   # leaves by a way out the reference lists as an alternative (an
        for theirs in ref.jumps:        # ambiguous one), the reference goes on from ours
            if done == len(jumps) or abs(jumps[done].s - theirs.s) >= 1e-6:
                return differ()
            landing = np.ravel(jumps[done].to_theta)
            done += 1
            if apart(landing, theirs.landing) <= 1e-4:
                continue
            signal.alarm(limit)
            try:
                if not (any(apart(landing, x) <= 1e-4 for x in theirs.alternatives)
                        or jumps[done - 1].ambiguous and apart(landing, flow_to_rest(
                            system, np.ravel(jumps[done - 1].from_theta),
                            theirs.s_after).state) <= 1e-4):
                    return differ()
                ref = quasi_static_path(system, landing, theirs.s_after)
            except TooLong:
                return 'no reference: over the limit (on from another way out)'
            except Exception as error:
                return f'no reference: {type(error).__name__} (on from another way out)'
            finally:
                signal.alarm(0)
            again = True
            break
        if not again:
            final = apart(np.ravel(track.final.theta), ref.final)
            return 'agree' if done == len(jumps) and final < 1e-6 else differ()


def stream(config, rng, count, limit, reference=False):
    """One stream: (failures [(reason, text, command)], slowest finished (s, command),
    the command stopped at the limit or None, reference comparisons [(verdict, command)])."""
    sim = simulator(config)
    failures, slowest, compared = [], (0.0, None), []
    for command in commands(rng, count):
        before = (Stack(tuple(sim.modules)), sim.state)
        start = time.process_time()
        signal.alarm(limit)
        try:
            outcome = apply(sim, command)
        except TooLong:
            return failures, slowest, command, compared
        finally:
            signal.alarm(0)
        spent = time.process_time() - start
        slowest = max(slowest, (spent, command), key=lambda t: t[0])
        failures += [(reason(e.text), e.text, command) for e in outcome.events
                     if isinstance(e, TrackingFailure)]
        if reference:
            end = Stack(tuple(sim.modules))
            compared.append((compared_with_reference(before[0], end, before[1], 4 * limit),
                             command))
    return failures, slowest, None, compared


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--seeds', type=int, nargs='+', default=[0])
    parser.add_argument('--streams', type=int, default=25)
    parser.add_argument('--commands', type=int, default=15)
    parser.add_argument('--limit', type=int, default=20, help='s per command')
    parser.add_argument('--first', type=int, default=0, help='skip the streams before it')
    parser.add_argument('--reference', action='store_true',
                        help='compare every command with the independent reference (slow)')
    args = parser.parse_args()
    signal.signal(signal.SIGALRM, _too_long)
    config = load_stack_config(str(CONFIG))
    for seed in args.seeds:
        rng = random.Random(seed)
        counts, examples, slow, worst = collections.Counter(), {}, [], (0.0, None)
        verdicts = collections.Counter()
        for index in range(args.streams):
            if index < args.first:
                commands(rng, args.commands)
                continue
            failures, slowest, stopped, compared = stream(config, rng, args.commands,
                                                          args.limit, args.reference)
            for verdict, command in compared:
                verdicts[verdict.split(':')[0]] += 1
                if verdict != 'agree':
                    print(f'  stream {index}, {command}: {verdict}', flush=True)
            for kind, text, command in failures:
                counts[kind] += 1
                examples.setdefault(kind, (index, command, text))
            if stopped is not None:
                slow.append((index, stopped))
            worst = max(worst, slowest, key=lambda t: t[0])
        print(f'seed {seed}: {args.streams} streams x {args.commands} commands; '
              f'{sum(counts.values())} tracking failures; over {args.limit} s: {len(slow)}; '
              f'slowest finished command {worst[0]:.2f} s {worst[1]}')
        for kind, n in counts.most_common():
            index, command, text = examples[kind]
            print(f'  {n:3d} x {kind}\n        e.g. stream {index}, {command}: {text[:160]}')
        for index, command in slow:
            print(f'  over {args.limit} s: stream {index}, {command} (the stream ends there)')
        if args.reference:
            print(f'  against the reference: {dict(verdicts)}')


if __name__ == '__main__':
    main()
