"""The design of a tolerance study and its tolerances, by the CLI's parameter names.

A :class:`Design` is the nominal mechanism (one module, or a neck from a node parameter
file) at each waypoint of its command schedule; :func:`parse_tolerances` turns specs
``'k=5%'`` into :class:`~..core.tolerance.sampling.Tolerance` objects on its fields.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..core.module import InvalidParameterError, PARAMETER_NAMES, STANDARD_GRAVITY
from ..core.tolerance.sampling import parse_spread, Tolerance
from ..problem import APPLY_ORDER, DEFAULT_FIELDS, PARAMETERS

#: Names that load the head of a neck (as the CLI's load options).
HEAD_NAMES = ('F', 'F3', 'F4', 'F3x', 'F4x')


class ToleranceError(InvalidParameterError):
    """A study that cannot be set up (bad tolerance, design, or question): the reason.
    (An InvalidParameterError, which the command line reports as a usage error.)"""


# ---------------------------------------------------------------------------
# The design: nominal modules at each waypoint of a command schedule

@dataclass(frozen=True)
class Design:
    """The nominal mechanism: ``stops`` (K, N, 12) parameter vectors of N modules at K
    waypoints (K = 1: no motion), module ``names``, the start ``guess`` (N x 2 angles
    or None: a module's upper stable equilibrium, a neck's upright configuration),
    ``config``: the parameter file a neck came from, if any."""

    stops: np.ndarray
    names: tuple
    guess: tuple | None = None
    g: float = STANDARD_GRAVITY
    config: str | None = None

    @property
    def modules(self):
        return len(self.names)

    def fields(self, stop=0):
        """The ModuleParams fields of every module at waypoint ``stop`` (dicts)."""
        return [dict(zip(PARAMETER_NAMES, row.tolist())) for row in self.stops[stop]]


def _vector(fields):
    return np.array([float(fields[n]) for n in PARAMETER_NAMES])


def _apply_named(fields, values, module, top):
    """Fields of one module with CLI-named ``values`` applied (loads only on the head)."""
    out = dict(fields)
    for name in APPLY_ORDER:
        if values.get(name) is None:
            continue
        if name in HEAD_NAMES and module != top:
            continue
        for f in PARAMETERS[name][0]:
            out[f] = float(values[name])
    return out


def _leg_values(leg, names):
    """A leg's changes as {module index or None (all): {CLI name: value}}."""
    out = {}
    for key, value in leg.items():
        module, name = _split_name(key, names)
        out.setdefault(module, {})[name] = float(value)
    return out


def _split_name(key, names):
    """(module index or None, CLI name) of ``key`` ('k', 'm1.k'), names case-insensitive."""
    module = None
    if '.' in key:
        prefix, key = key.split('.', 1)
        if prefix not in names:
            raise ToleranceError(f'unknown module {prefix!r} (modules: {", ".join(names)})')
        module = names.index(prefix)
    for known in PARAMETERS:
        if known.lower() == key.lower():
            return module, known
    raise ToleranceError(f'unknown parameter {key!r} (choose from {", ".join(PARAMETERS)})')


def _stops(first, legs, names):
    """The waypoints: ``first`` (N field dicts), then each leg's changes applied to the
    previous waypoint (a leg dict maps CLI names, optionally 'm1.'-prefixed, to values;
    unprefixed loads go to the head, anything else to every module)."""
    top = len(first) - 1
    stops = [list(first)]
    for leg in legs:
        changes = _leg_values(leg, names)
        prev = stops[-1]
        new = []
        for i, fields in enumerate(prev):
            f = _apply_named(fields, changes.get(None, {}), i, top)
            f = _apply_named(f, changes.get(i, {}), i, i)
            new.append(f)
        stops.append(new)
    return stops


def _check_stops(stops, g):
    from ..core.module import InvalidParameterError, ModuleParams
    for k, stop in enumerate(stops):
        for i, f in enumerate(stop):
            try:
                ModuleParams(**f, g=g)
            except InvalidParameterError as exc:
                where = 'the start' if k == 0 else f'waypoint {k}'
                raise ToleranceError(f'module {i} at {where}: {exc}') from None


def module_design(values, legs=(), guess=None):
    """One module from CLI-named values (``{'rho': 0.5, 'F': 5}``; the paper's defaults
    otherwise) and a command schedule: ``legs``, one dict of changes per leg
    (``[{'rho': 0.1}, {'rho': 0.5}]``).  ``guess``: (t1, t2) start guess or None."""
    if values.get('rho') is None:
        raise ToleranceError('the design needs rho')
    fields = dict(DEFAULT_FIELDS, rho=None)
    fields = _apply_named(fields, values, 0, 0)
    stops = _stops([fields], legs, ['m0'])
    _check_stops(stops, STANDARD_GRAVITY)
    return Design(stops=np.array([[_vector(f) for f in s] for s in stops]), names=('m0',),
                  guess=None if guess is None else (tuple(float(v) for v in guess),))


def neck_design(config, node=None, values=None, legs=(), guess=None):
    """A neck (or one module) from a node parameter file, as ``track --config`` reads it;
    ``values``: CLI-named overrides (loads to the head, the rest to every module);
    ``legs`` as :func:`module_design` ('m1.rho' commands one module, 'rho' all);
    ``guess``: N x 2 angles (default: the file's initial_theta)."""
    from ..params_file import ConfigError, load_stack_config
    try:
        cfg = load_stack_config(config, node)
    except (ConfigError, OSError) as exc:
        raise ToleranceError(str(exc)) from None
    names = tuple(cfg.names)
    first = [dict(zip(PARAMETER_NAMES, m.params.vector().tolist())) for m in cfg.modules]
    top = len(first) - 1
    first = [_apply_named(f, values or {}, i, top) for i, f in enumerate(first)]
    stops = _stops(first, legs, list(names))
    _check_stops(stops, STANDARD_GRAVITY)
    if guess is None:
        guess = cfg.initial_theta
    guess = np.asarray(guess, dtype=float).reshape(len(names), 2)
    return Design(stops=np.array([[_vector(f) for f in s] for s in stops]), names=names,
                  guess=tuple(tuple(float(v) for v in t) for t in guess), config=str(config))


# ---------------------------------------------------------------------------
# Tolerances by CLI name

def parse_tolerances(specs, design):
    """:class:`Tolerance` objects (one per toleranced field and module) from specs
    ``'NAME=SPREAD'`` (see :func:`.core.tolerance.sampling.parse_spread`)."""
    names = list(design.names)
    top = design.modules - 1
    out, seen = [], set()
    for spec in specs:
        if isinstance(spec, Tolerance):
            out.append(spec)
            continue
        if '=' not in spec:
            raise ToleranceError(f'bad tolerance {spec!r}: expected NAME=SPREAD, e.g. k=5%')
        key, text = spec.split('=', 1)
        module, name = _split_name(key.strip(), names)
        try:
            distribution, spread, relative, cut = parse_spread(text)
        except ValueError as exc:
            raise ToleranceError(str(exc)) from None
        if module is not None:
            modules = [module]
        elif name in HEAD_NAMES:
            modules = [top]
        else:
            modules = list(range(design.modules))
        for i in modules:
            for f in PARAMETERS[name][0]:
                label = f if design.modules == 1 else f'{names[i]}.{f}'
                if (i, f) in seen:
                    raise ToleranceError(f'{label} is toleranced twice (by {spec!r})')
                seen.add((i, f))
                nominal = design.stops[0, i, PARAMETER_NAMES.index(f)]
                if relative and nominal == 0.0 and spread > 0.0:
                    raise ToleranceError(f'{spec!r}: {label} is 0, a relative tolerance of '
                                         f'it is 0 too: give an absolute one')
                out.append(Tolerance(field=f, spread=spread, distribution=distribution,
                                     relative=relative, cut=cut, module=i, label=label))
    if not out:
        raise ToleranceError('give at least one tolerance (e.g. --tol k=5%)')
    return out
