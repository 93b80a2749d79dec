"""``tensegrity tolerance``: the command-line face of :mod:`..tolerance` (issue 34).

    tensegrity tolerance range     [module options] --tol NAME=SPREAD ... [--at-rho R]
    tensegrity tolerance path      [module options | --config FILE] --to NAME=V[,NAME=V] ...
    tensegrity tolerance head-load [module options | --config FILE] --to F=-20 ...

Common: ``--samples N --seed S --sampler sobol|lhs|mc``, the engine (``--processes P``,
default a LocalCluster of every core, 1 = in this process without dask; ``--scheduler
tcp://HOST:8786``), ``--json/--csv FILE`` ('-' for stdout), ``--plot PREFIX`` (PNG),
``--replay-dir DIR`` (the worst samples' parameter files), ``--worst K``.
"""
from __future__ import annotations

import argparse
import os
import sys

from .common import (add_parameter_options, check_output, finite_float, parameter_values,
                     positive_int)
from ..core.tolerance.sample_statistics import INTERVALS
from ..core.tolerance.sampling import SAMPLERS
from ..tolerance import (module_design, neck_design, QUESTIONS, tolerance_study, ToleranceError,
                         write_text_file)

_HELP = {
    'range': 'one module: the stable rho interval through the working point (as `tensegrity '
             'range`) and whether the module is bistable (at --at-rho, default its own rho)',
    'path': 'a planned path (legs given by --to, as `tensegrity track`; a neck from '
            '--config): does it jump, where, where does it land',
    'head-load': 'a growing head load (--to F=LOAD, or F3/F4): the load at which the neck '
                 '(or module) first jumps',
}


def add_parser(subparsers):
    """Register ``tolerance`` and its questions on the CLI's subparsers: the design's
    options as the other commands take them, and :func:`run` as the command."""
    p = subparsers.add_parser(
        'tolerance', help='design under tolerances: sample a toleranced module or neck',
        description='Sample a design whose parameters scatter by the given tolerances '
                    '(--tol), ask every sample one question, and report quantiles (1, 5, 50, '
                    '95, 99 %), event probabilities with confidence intervals, rank '
                    'correlations of every figure with every tolerance, and the worst samples '
                    'as command lines that replay them. Runs on dask.distributed: a '
                    'LocalCluster of all cores by default, --processes 1 in this process, '
                    '--scheduler ADDRESS on a running cluster. See docs/tolerance.md.')
    questions = p.add_subparsers(dest='question', metavar='QUESTION', required=True)
    for name in QUESTIONS:
        q = questions.add_parser(name, help=_HELP[name], description=_HELP[name])
        add_parameter_options(q)
        _add_common(q, finite_float, positive_int, name)
        q.set_defaults(func=run)
    return p


def run(args, out):
    """``tensegrity tolerance QUESTION``: the design's options read back, checked."""
    return run_tolerance(args, out, parameter_values(args), finite_float)


def _add_common(q, finite_float, positive_int, question):
    _add_design(q, finite_float, question)
    _add_sampling(q, finite_float, positive_int)
    _add_engine(q, positive_int)
    _add_output(q)


def _add_design(q, finite_float, question):
    design = q.add_argument_group('design')
    design.add_argument('--theta1', type=finite_float, metavar='RAD',
                        help='one module: start guess theta1 (with --theta2; default: the '
                             'upper stable equilibrium)')
    design.add_argument('--theta2', type=finite_float, metavar='RAD')
    if question != 'range':
        design.add_argument('--config', metavar='FILE.yaml',
                            help='a neck (or module) from a tensegrity_node parameter file, '
                                 'as `track --config`; module options override it')
        design.add_argument('--node', metavar='NAME', help='node entry of --config')
        design.add_argument('--theta', type=finite_float, nargs='+', metavar='RAD',
                            help='neck start guess: theta1 theta2 of every module (default: '
                                 'the initial_theta of --config)')
        design.add_argument('--to', action='append', metavar='NAME=V[,NAME=V]', default=[],
                            help='one leg of the path: the values at its end (e.g. rho=0.1, '
                                 'F3=6,F4=6, m1.rho=0.08; loads go to the head); repeat for '
                                 'a schedule')
    else:
        design.add_argument('--at-rho', type=finite_float, metavar='R',
                            help='count the stable equilibria at this rho (default: the '
                                 "sample's own rho)")
        design.add_argument('--rho-bounds', type=finite_float, nargs=2, metavar=('MIN', 'MAX'),
                            help='search interval in rho (default 0 .. 2 (L1 + L2))')


def _add_sampling(q, finite_float, positive_int):
    t = q.add_argument_group('tolerances and sampling')
    t.add_argument('--tol', action='append', metavar='NAME=SPREAD', default=[],
                   help='a tolerance: NAME=[uniform:|normal:]SPREAD[%%][:CUT], e.g. k=5%% '
                        '(uniform +-5 %%), L1=0.001 (+-1 mm), F3=normal:0.2 (sigma 0.2 N), '
                        'L2=normal:0.5%%:3 (truncated at 3 sigma); k and F tolerate each of '
                        'their springs / loads independently; m1.k names one module')
    t.add_argument('--samples', type=positive_int, default=1024, metavar='N',
                   help='number of samples (default 1024; Sobol: a power of 2 is best)')
    t.add_argument('--seed', type=int, default=0, metavar='S', help='random seed (default 0)')
    t.add_argument('--sampler', choices=SAMPLERS, default='sobol',
                   help='scrambled Sobol (default), Latin hypercube, or plain Monte Carlo')
    t.add_argument('--interval', choices=tuple(INTERVALS), default='clopper-pearson',
                   help='confidence interval of probabilities (default clopper-pearson, exact)')
    t.add_argument('--confidence', type=finite_float, default=0.95, metavar='C',
                   help='confidence level of the intervals (default 0.95)')
    t.add_argument('--exact', action='store_true',
                   help='solve every sample with the scalar functions (`range`/`track` '
                        'themselves) instead of the vectorised branch follower: the reference')


def _add_engine(q, positive_int):
    e = q.add_argument_group('engine (dask.distributed)')
    e.add_argument('--processes', type=positive_int, metavar='P',
                   help='worker processes of the LocalCluster (default: all cores); 1 runs '
                        'in this process without dask')
    e.add_argument('--scheduler', metavar='ADDRESS',
                   help='run on a running cluster, e.g. tcp://HOST:8786 (dask scheduler + '
                        'dask worker; the package must be installed on the workers)')
    e.add_argument('--chunk', type=positive_int, metavar='C',
                   help='samples per task (default: by question; the answer does not depend '
                        'on it)')
    e.add_argument('--no-progress', action='store_true', help='no progress bar')


def _add_output(q):
    o = q.add_argument_group('output')
    o.add_argument('--json', metavar='FILE', help="write the report as JSON ('-': stdout)")
    o.add_argument('--csv', metavar='FILE', help="write every sample as CSV ('-': stdout)")
    o.add_argument('--plot', metavar='PREFIX',
                   help='write PREFIX_histograms.png and PREFIX_sensitivity.png')
    o.add_argument('--worst', type=int, default=5, metavar='K',
                   help='list the K worst samples with their replay commands (default 5)')
    o.add_argument('--replay-dir', metavar='DIR',
                   help='write the worst samples of a neck as parameter files sample_<i>.yaml '
                        'there (their replay commands read them)')


def _legs(specs, finite):
    """[{name: value}] from --to specs 'rho=0.1,F3=6'."""
    legs = []
    for spec in specs:
        leg = {}
        for item in spec.split(','):
            if '=' not in item:
                raise ToleranceError(f'--to {spec!r}: expected NAME=VALUE[,NAME=VALUE]')
            name, text = (x.strip() for x in item.split('=', 1))
            try:
                leg[name] = finite(text)
            except argparse.ArgumentTypeError as exc:
                raise ToleranceError(f'--to {spec!r}: {name}: {exc}') from None
        legs.append(leg)
    return legs


def design_from_args(args, values, finite):
    """The :class:`.tolerance.Design` of the command line."""
    if (args.theta1 is None) != (args.theta2 is None):
        raise ToleranceError('give both --theta1 and --theta2, or neither')
    legs = _legs(getattr(args, 'to', []), finite)
    config = getattr(args, 'config', None)
    if config is None:
        if getattr(args, 'node', None) is not None:
            raise ToleranceError('--node selects an entry of --config: give --config too')
        if getattr(args, 'theta', None) is not None:
            raise ToleranceError('--theta is for a neck (--config); one module takes '
                                 '--theta1/--theta2')
        guess = None if args.theta1 is None else (args.theta1, args.theta2)
        return module_design(values, legs=legs, guess=guess)
    if not os.path.isfile(config):
        raise ToleranceError(f'--config: no such file {config!r}')
    guess = args.theta
    if args.theta1 is not None:
        if guess is not None:
            raise ToleranceError('give --theta or --theta1/--theta2, not both')
        guess = [args.theta1, args.theta2]
    return neck_design(config, args.node, values, legs=legs, guess=guess)


def run_tolerance(args, out, values, finite):
    """``tensegrity tolerance QUESTION``: returns the exit status."""
    if args.scheduler is not None and args.processes is not None:
        raise ToleranceError('give --processes (a LocalCluster, or 1: in this process) or '
                             '--scheduler (a running cluster), not both')
    if not 0.0 < args.confidence < 1.0:
        raise ToleranceError(f'--confidence must be between 0 and 1, got {args.confidence:g}')
    if args.worst < 0:
        raise ToleranceError(f'--worst must be >= 0, got {args.worst}')
    for option, path in (('--json', args.json), ('--csv', args.csv)):
        check_output(path, option)
    if args.json == '-' and args.csv == '-':
        raise ToleranceError('--json and --csv cannot both go to stdout')
    if args.plot is not None:
        check_output(args.plot + '_histograms.png', '--plot')
    design = design_from_args(args, values, finite)
    progress = not args.no_progress and sys.stderr.isatty()
    result = tolerance_study(
        design, args.question, args.tol, samples=args.samples, seed=args.seed,
        sampler=args.sampler, processes=args.processes, scheduler=args.scheduler,
        chunk=args.chunk, progress=progress, at_rho=getattr(args, 'at_rho', None),
        rho_bounds=getattr(args, 'rho_bounds', None), exact=args.exact,
        confidence=args.confidence, interval=args.interval, worst=args.worst)
    to_stdout = '-' in (args.json, args.csv)
    messages = sys.stderr if to_stdout else out
    if args.json == '-':
        result.write_json(out)
    elif args.json:
        with open(args.json, 'w', encoding='utf-8') as f:
            result.write_json(f)
    if args.csv == '-':
        result.write_csv(out)
    elif args.csv:
        with open(args.csv, 'w', encoding='ascii') as f:
            result.write_csv(f)
    if not to_stdout:
        out.write(result.text())
    if args.replay_dir:
        for w in result.summary()['worst']:
            if w.get('config'):
                path = os.path.join(args.replay_dir, w['config_file'])
                write_text_file(path, w['config'])
                messages.write(f'wrote {path}\n')
    for path in (args.json, args.csv):
        if path and path != '-':
            messages.write(f'wrote {path}\n')
    if args.plot:
        for path in result.plot(args.plot):
            messages.write(f'wrote {path}\n')
    return 0
