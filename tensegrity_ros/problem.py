"""A problem as users name it: parameters by their CLI names, and one description of it.

The offline CLI, the figures and the docs name parameters the paper's way (``rho``,
``L1``, ``k`` for all three springs, ``F`` for F3 = F4 ...).  This module turns such
named values into :class:`ModuleParams` fields and describes modules in one line,
for one module and for a neck alike.  ROS-free; imported by the CLI and the figures,
never the other way round.
"""
from __future__ import annotations

#: Parameters a user can set, by CLI name: (ModuleParams fields it sets, help).
#: Group names (k, F) set several fields; the specific names override them.
PARAMETERS = {
    'rho': (('rho',), 'actuated base length A1A2 (m)'),
    'L1': (('L1',), 'length of rod A1A3 (m, default 1)'),
    'L2': (('L2',), 'length of rod A2A4 (m, default 1)'),
    'k': (('ka', 'kb', 'kc'), 'stiffness of all three springs (N/m, default 100)'),
    'ka': (('ka',), 'stiffness of spring A2A3 (N/m; overrides --k)'),
    'kb': (('kb',), 'stiffness of spring A1A4 (N/m; overrides --k)'),
    'kc': (('kc',), 'stiffness of spring A3A4 (N/m; overrides --k)'),
    'F': (('f3y', 'f4y'), 'vertical force at A3 and at A4 (N, F3 = F4 = F; + pulls up)'),
    'F3': (('f3y',), 'vertical force at A3 (N, + pulls up, - pushes down; overrides --F)'),
    'F4': (('f4y',), 'vertical force at A4 (N, + pulls up, - pushes down; overrides --F)'),
    'F3x': (('f3x',), 'horizontal force at A3 (N, + along A1->A2)'),
    'F4x': (('f4x',), 'horizontal force at A4 (N, + along A1->A2)'),
    'm1': (('m1',), 'mass of rod A1A3 (kg, weight acts along -y)'),
    'm2': (('m2',), 'mass of rod A2A4 (kg, weight acts along -y)'),
}
#: Group names are applied first so that specific names override them.
APPLY_ORDER = ('rho', 'L1', 'L2', 'k', 'F', 'ka', 'kb', 'kc', 'F3', 'F4', 'F3x', 'F4x', 'm1', 'm2')
#: Default values of the fields (the paper's normalisation L1 = 1, k = 100).
DEFAULT_FIELDS = {'L1': 1.0, 'L2': 1.0, 'ka': 100.0, 'kb': 100.0, 'kc': 100.0,
                  'f3x': 0.0, 'f3y': 0.0, 'f4x': 0.0, 'f4y': 0.0, 'm1': 0.0, 'm2': 0.0}


def resolve_fields(values):
    """ModuleParams keyword arguments from CLI-named values (scalars or arrays).

    Defaults are the paper's (L1 = L2 = 1, k = 100, no load); group names (k, F)
    are applied before the specific ones so that ``--ka`` overrides ``--k``.
    """
    fields = dict(DEFAULT_FIELDS)
    for name in APPLY_ORDER:
        if name in values and values[name] is not None:
            for field in PARAMETERS[name][0]:
                fields[field] = values[name]
    return fields


def describe(values, skip=()):
    """Compact text of the parameters, e.g. 'L1=1 L2=1 k=100 F3=F4=5' (for titles)."""
    f = resolve_fields(values)
    skip_fields = set()
    for name in skip:
        skip_fields.update(PARAMETERS[name][0])
    parts = []

    def num(v):
        return f'{v:g}'

    for field, label in (('rho', 'rho'), ('L1', 'L1'), ('L2', 'L2')):
        if field in f and field not in skip_fields and f.get(field) is not None:
            parts.append(f'{label}={num(f[field])}')
    springs = [(s, f[s]) for s in ('ka', 'kb', 'kc') if s not in skip_fields]
    if springs:
        if len(springs) == 3 and len({v for _, v in springs}) == 1:
            parts.append(f'k={num(springs[0][1])}')
        else:
            parts.extend(f'{s}={num(v)}' for s, v in springs)
    vertical = [(lab, f[fld]) for fld, lab in (('f3y', 'F3'), ('f4y', 'F4'))
                if fld not in skip_fields]
    if len(vertical) == 2 and vertical[0][1] == vertical[1][1]:
        parts.append(f'F3=F4={num(vertical[0][1])}')
    else:
        parts.extend(f'{lab}={num(v)}' for lab, v in vertical)
    for fld, lab in (('f3x', 'F3x'), ('f4x', 'F4x'), ('m1', 'm1'), ('m2', 'm2')):
        if fld not in skip_fields and f[fld] != 0.0:
            parts.append(f'{lab}={num(f[fld])}')
    return ' '.join(parts)


def named_values(p):
    """The CLI-named values of a module (``describe``'s input)."""
    return {'rho': p.rho, 'L1': p.L1, 'L2': p.L2, 'ka': p.ka, 'kb': p.kb, 'kc': p.kc,
            'F3': p.f3y, 'F4': p.f4y, 'F3x': p.f3x, 'F4x': p.f4x, 'm1': p.m1, 'm2': p.m2}


def describe_modules(modules, names=None):
    """One line describing a mechanism: for one module its parameters
    ('rho=0.5 L1=1 L2=1 k=100 F3=F4=5'); for a neck the modules, every rho, the
    geometry (shared or per module) and the loads."""
    modules = tuple(modules)
    if len(modules) == 1:
        return describe(named_values(modules[0]))
    names = list(names) if names is not None else [f'm{i}' for i in range(len(modules))]
    parts = [f'{len(modules)} modules {", ".join(names)} (bottom to top)']
    parts.append('rho = ' + ', '.join(f'{m.rho:g}' for m in modules) + ' m')
    loads = ('rho', 'F3', 'F4', 'F3x', 'F4x')
    geometry = [describe(named_values(m), skip=loads) for m in modules]
    if len(set(geometry)) == 1:
        parts.append(geometry[0])
    else:
        parts.append('; '.join(f'{name} {g}' for name, g in zip(names, geometry)))
    loaded = []
    for name, m in zip(names, modules):
        if any((m.f3x, m.f3y, m.f4x, m.f4y)):
            text = describe(named_values(m), skip=('rho', 'L1', 'L2', 'k', 'm1', 'm2'))
            loaded.append(f'{name} {text}')
    parts.append('loads: ' + ('; '.join(loaded) if loaded else 'none'))
    return '; '.join(parts)
