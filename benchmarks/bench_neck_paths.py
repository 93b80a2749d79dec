#!/usr/bin/env python3
"""CPU time of whole neck paths over issue 32's families (test/neck_path_families.py),
on two seeds drawn fresh for each run unless ``--seeds`` names them (printed either way).

Every path is settled first (not timed), then ``track_stack`` is timed on the process's
CPU clock.  Targets (issue 32): median <= 20 ms and p99 <= 500 ms per neck path on the
2-core machine, none over 1 s.  With ``--baseline DIR`` (another checkout of the
package, e.g. ``git worktree add /tmp/base 8db3247``) the same paths run there too, in
a second worker process, alternating path by path with this tree, so that both see the
same machine load; the ratio of medians is printed.  A path over ``--limit`` seconds is
stopped (SIGALRM) and counted as over.

    python benchmarks/bench_neck_paths.py [--seeds S ...] [--count 9] [--baseline DIR]
                                          [--reference] [--max-n N]
"""
import argparse
import json
import os
from pathlib import Path
import signal
import subprocess
import sys
import time

HERE = Path(__file__).resolve().parents[1]


class TooLong(Exception):
    pass


def _too_long(*_):
    raise TooLong


def worker(root, limit, reference=False):
    """Answer 'seed count index' lines with one JSON line per path (with ``reference``,
    also the verdict of bench_round_commands' comparison with the reference)."""
    sys.path.insert(0, str(root))
    sys.path.insert(1, str(HERE / 'test'))
    from neck_path_families import paths
    from tensegrity_ros.core.neck.stack import settle_stack, track_stack
    signal.signal(signal.SIGALRM, _too_long)
    if reference:
        sys.path.insert(1, str(HERE / 'benchmarks'))
        import bench_round_commands as brc
        signal.signal(signal.SIGALRM, brc._too_long)
    cache = {}
    for line in sys.stdin:
        seed, count, index = map(int, line.split())
        if (seed, count) not in cache:
            cache = {(seed, count): paths(seed, count)}
        family, start, end, theta = cache[(seed, count)][index]
        answer = {'family': family, 'n': len(start)}
        try:
            state = settle_stack(start, theta)
        except Exception as error:      # noqa: BLE001  (a start that does not settle)
            answer['skip'] = type(error).__name__
            print(json.dumps(answer), flush=True)
            continue
        signal.alarm(limit)
        began = time.process_time()
        try:
            result = track_stack(start, end, state)
            answer.update(status=result.status, jumps=[j.kind for j in result.jumps])
        except (TooLong, Exception) as error:   # noqa: BLE001  (brc's TooLong too)
            answer['status'] = 'over' if 'TooLong' in type(error).__name__ else repr(error)
        finally:
            signal.alarm(0)
        answer['cpu'] = time.process_time() - began
        if reference and answer['status'] == 'ok':
            answer['reference'] = brc.compared_with_reference(start, end, state, 20 * limit)
        print(json.dumps(answer), flush=True)


def _spawn(root, limit, reference=False):
    return subprocess.Popen([sys.executable, __file__, '--worker', str(root), '--limit',
                             str(limit)] + (['--reference'] if reference else []),
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True, env=dict(os.environ, PYTHONHASHSEED='0'))


def _ask(proc, seed, count, index):
    proc.stdin.write(f'{seed} {count} {index}\n')
    proc.stdin.flush()
    return json.loads(proc.stdout.readline())


def _quantile(values, q):
    values = sorted(values)
    return values[min(len(values) - 1, int(q * len(values)))] if values else float('nan')


def _summary(name, answers):
    times = [a['cpu'] for a in answers if 'cpu' in a]
    over = sum(a.get('status') == 'over' for a in answers)
    failed = sum(a.get('status') == 'failed' for a in answers)
    print(f'{name}: {len(times)} paths, median {1e3 * _quantile(times, 0.5):.1f} ms, '
          f'p90 {1e3 * _quantile(times, 0.9):.1f} ms, p99 {1e3 * _quantile(times, 0.99):.1f} ms, '
          f'max {1e3 * max(times, default=0):.1f} ms, over 1 s: '
          f'{sum(t > 1.0 for t in times)}, stopped at the limit: {over}, failed: {failed}')
    families = sorted({a['family'] for a in answers})
    for family in families:
        some = [a['cpu'] for a in answers if a['family'] == family and 'cpu' in a]
        print(f'    {family:10s} median {1e3 * _quantile(some, 0.5):7.1f} ms, '
              f'max {1e3 * max(some, default=0):8.1f} ms ({len(some)})')
    return _quantile(times, 0.5)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    parser.add_argument('--seeds', type=int, nargs='+',
                        help='path family seeds (default: two drawn fresh for this run, '
                             'printed: a figure that holds only on the seeds tuned on does '
                             'not hold)')
    parser.add_argument('--count', type=int, default=9, help='paths per random family')
    parser.add_argument('--baseline', help='another checkout to compare with')
    parser.add_argument('--limit', type=int, default=60, help='s per path')
    parser.add_argument('--reference', action='store_true',
                        help='compare every path of this tree with test/reference_paths.py '
                             '(slow: ~40 s for N = 5, ~2 min for N = 10)')
    parser.add_argument('--max-n', type=int, default=10, help='only necks this long or shorter')
    parser.add_argument('--worker', help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        return worker(Path(args.worker), args.limit, args.reference)
    if args.seeds is None:
        import numpy as np
        entropy = np.random.SeedSequence().entropy
        args.seeds = [int(entropy % 1_000_000), int(entropy // 1_000_000 % 1_000_000)]
    print(f'seeds: {" ".join(map(str, args.seeds))} (--seeds {" ".join(map(str, args.seeds))} '
          f'repeats this run)', flush=True)
    sys.path.insert(0, str(HERE / 'test'))
    sys.path.insert(0, str(HERE))
    from neck_path_families import paths
    trees = {'this tree': _spawn(HERE, args.limit, args.reference)}
    if args.baseline:
        trees['baseline'] = _spawn(Path(args.baseline), args.limit)
    answers = {name: [] for name in trees}
    for seed in args.seeds:
        for index, path in enumerate(paths(seed, args.count)):
            if len(path[1]) > args.max_n:
                continue
            for name, proc in trees.items():
                answers[name].append(_ask(proc, seed, args.count, index))
                if 'reference' in answers[name][-1]:
                    found = answers[name][-1]
                    print(f'  seed {seed} path {index} ({found["family"]}, N = {found["n"]}): '
                          f'{found["reference"]}', flush=True)
    print(f'load average {os.getloadavg()[0]:.2f}')
    medians = {name: _summary(name, found) for name, found in answers.items()}
    if args.reference:
        verdicts = [a['reference'].split(':')[0] for a in answers['this tree'] if 'reference' in a]
        print(f'against the reference: { {v: verdicts.count(v) for v in set(verdicts)} }')
    if args.baseline:
        print(f'median ratio baseline / this tree: '
              f'{medians["baseline"] / medians["this tree"]:.2f}')
        differ = [(i, a, b) for i, (a, b) in enumerate(zip(answers['this tree'],
                                                           answers['baseline']))
                  if (a.get('status'), a.get('jumps')) != (b.get('status'), b.get('jumps'))]
        for i, a, b in differ:
            print(f'    path {i} ({a["family"]}, N = {a["n"]}): {a.get("status")} '
                  f'{a.get("jumps")} here, {b.get("status")} {b.get("jumps")} on the baseline')
    for proc in trees.values():
        proc.stdin.close()
        proc.wait()


if __name__ == '__main__':
    main()
