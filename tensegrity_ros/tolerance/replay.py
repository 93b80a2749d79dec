"""A sample of a tolerance study as the commands that reproduce it on its own.

One module: ``tensegrity range`` / ``track`` command lines with every parameter of the
sample (floats written with ``repr``: they read back exactly).  A neck: a node parameter
file (YAML text, to save as ``sample_<i>.yaml``) and ``tensegrity track --config`` lines.
A schedule of several legs gives one line per leg, each starting from the previous
leg's final angles (which this module computes by running the sample once).
"""
from __future__ import annotations

import numpy as np

from ..core.module import ModuleParams, PARAMETER_NAMES
from ..core.module.tracking import track_module
from ..core.neck.stack import Stack, track_stack
from ..core.simulation.start_state import start_state

#: ModuleParams field -> CLI option name.
CLI_NAMES = {'rho': 'rho', 'L1': 'L1', 'L2': 'L2', 'ka': 'ka', 'kb': 'kb', 'kc': 'kc',
             'f3x': 'F3x', 'f3y': 'F3', 'f4x': 'F4x', 'f4y': 'F4', 'm1': 'm1', 'm2': 'm2'}
#: Fields always written (the others only when non-zero).
_ALWAYS = ('rho', 'L1', 'L2', 'ka', 'kb', 'kc', 'f3y', 'f4y')
#: Head-load fields as the stack form of ``track`` takes them (the top module's).
_HEAD_FIELDS = ('f3x', 'f3y', 'f4x', 'f4y')


def _num(v):
    return repr(float(v))


def _yaml_num(v):
    """A float YAML 1.1 reads as a float (it needs a '.' before an exponent)."""
    text = repr(float(v))
    if 'e' in text and '.' not in text:
        mantissa, exponent = text.split('e')
        text = f'{mantissa}.0e{exponent}'
    return text


def module_flags(row):
    """``--rho R --L1 ...`` for one module's parameter vector."""
    fields = dict(zip(PARAMETER_NAMES, row.tolist()))
    return ' '.join(f'--{CLI_NAMES[f]} {_num(v)}' for f, v in fields.items()
                    if f in _ALWAYS or v != 0.0)


def _changes(a, b, prefix='--to-'):
    return ' '.join(f'{prefix}{CLI_NAMES[f]} {_num(y)}'
                    for f, x, y in zip(PARAMETER_NAMES, a.tolist(), b.tolist()) if x != y)


def _theta_flags(theta):
    t = np.asarray(theta, dtype=float).reshape(-1)
    return f'--theta1 {_num(t[0])} --theta2 {_num(t[1])}'


def replay(question, design, stops, index):
    """{'replay': [command lines], 'config': YAML text or None, 'config_file': name}."""
    if design.modules == 1:
        if question.name == 'range':
            return {'replay': _range_lines(question, stops[0, 0]), 'config': None}
        return {'replay': _module_path_lines(design, stops), 'config': None}
    name = f'sample_{index}.yaml'
    return {'replay': _neck_lines(design, stops, name), 'config': neck_config(design, stops),
            'config_file': name}


def _range_lines(question, row):
    flags = module_flags(row)
    line = f'tensegrity range {flags}'
    if question.guess is not None:
        line += ' ' + _theta_flags(question.guess)
    if question.rho_bounds is not None:
        line += f' --rho-bounds {_num(question.rho_bounds[0])} {_num(question.rho_bounds[1])}'
    solve = row.copy()
    if question.at_rho is not None:
        solve[0] = question.at_rho
    return [line, f'tensegrity solve {module_flags(solve)}']


def _module_path_lines(design, stops):
    lines = []
    params = [ModuleParams.from_vector(s[0], g=design.g) for s in stops]
    guess = None if design.guess is None else design.guess[0]
    theta, certificate = guess, ''
    try:
        state = start_state([params[0]], None if guess is None else [guess])
    except (ValueError, RuntimeError):
        state = None
    for leg, (a, b) in enumerate(zip(stops, stops[1:])):
        line = f'tensegrity track {module_flags(a[0])} {_changes(a[0], b[0])}'
        if theta is not None:
            line += ' ' + _theta_flags(theta)
        lines.append(line)
        if state is None:
            break
        track = track_module(params[leg], params[leg + 1], state.theta, certificate=certificate)
        certificate = track.certificate
        state = track.final
        theta = state.theta
        if track.status != 'ok':
            break
    return lines


def _neck_lines(design, stops, config_name):
    lines = []
    modules = [tuple(ModuleParams.from_vector(r, g=design.g) for r in s) for s in stops]
    try:
        state = start_state(modules[0], design.guess)
    except (ValueError, RuntimeError):
        state = None
    theta = None
    for leg, (a, b) in enumerate(zip(stops, stops[1:])):
        line = f'tensegrity track --config {config_name}'
        if leg > 0:
            line += ' --rhos ' + ' '.join(_num(r[0]) for r in a)
            line += ' ' + _head_changes(stops[0][-1], a[-1], '--')
        line += ' --to-rhos ' + ' '.join(_num(r[0]) for r in b)
        line += ' ' + _head_changes(a[-1], b[-1], '--to-')
        if theta is not None:
            line += ' --theta ' + ' '.join(_num(v) for v in np.reshape(theta, -1))
        lines.append(' '.join(line.split()))
        if state is None:
            break
        track = track_stack(Stack(modules[leg]), Stack(modules[leg + 1]), state)
        state = track.final
        theta = state.theta
        if track.status != 'ok':
            break
    return lines


def _head_changes(a, b, prefix):
    return ' '.join(f'{prefix}{CLI_NAMES[f]} {_num(b[PARAMETER_NAMES.index(f)])}'
                    for f in _HEAD_FIELDS
                    if a[PARAMETER_NAMES.index(f)] != b[PARAMETER_NAMES.index(f)])


def neck_config(design, stops):
    """A tensegrity_node parameter file of the sample's modules at its start."""
    rows = stops[0]
    rhos = [float(r[0]) for r in rows]
    lo, hi = 0.5 * min(float(s[0]) for st in stops for s in st), \
        2.0 * max(float(s[0]) for st in stops for s in st)
    guess = design.guess
    lines = [f'# sample of a tolerance study: {len(rows)} modules, bottom to top',
             '/**:', '  ros__parameters:',
             f'    modules: [{", ".join(design.names)}]']
    for i, (name, row) in enumerate(zip(design.names, rows)):
        f = dict(zip(PARAMETER_NAMES, row.tolist()))
        lines += [f'    {name}:',
                  f'      L1: {_yaml_num(f["L1"])}', f'      L2: {_yaml_num(f["L2"])}',
                  f'      k: {_yaml_num(f["ka"])}',
                  f'      ka: {_yaml_num(f["ka"])}', f'      kb: {_yaml_num(f["kb"])}',
                  f'      kc: {_yaml_num(f["kc"])}',
                  f'      m1: {_yaml_num(f["m1"])}', f'      m2: {_yaml_num(f["m2"])}',
                  f'      force_a3: [{_yaml_num(f["f3x"])}, {_yaml_num(f["f3y"])}]',
                  f'      force_a4: [{_yaml_num(f["f4x"])}, {_yaml_num(f["f4y"])}]',
                  f'      rho_initial: {_yaml_num(rhos[i])}',
                  f'      rho_min: {_yaml_num(lo)}',
                  f'      rho_max: {_yaml_num(max(hi, lo * 4))}']
        if guess is not None:
            lines.append(f'      initial_theta: [{_yaml_num(guess[i][0])}, '
                         f'{_yaml_num(guess[i][1])}]')
    return '\n'.join(lines) + '\n'
