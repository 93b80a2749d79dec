"""The per-module parameters of the node and of its parameter files, ROS-free.

One table (:data:`MODULE_PARAMETERS`: name, default, type, what a runtime change does,
description) read by the node (:mod:`tensegrity_ros.ros.parameters` turns it into ROS
parameter declarations) and by the offline tools (:mod:`tensegrity_ros.params_file`),
and one way from their values to what the core simulator takes: :class:`ModuleParams`
(with the ``k`` / ``ka``-``kc`` override rule), :class:`ModuleLimits`, start angles.
"""
from __future__ import annotations

import math

from tensegrity_ros.core import InvalidParameterError, ModuleParams
from tensegrity_ros.core.module.supported_range import check_supported
from tensegrity_ros.core.simulation.simulator import ModuleLimits
from tensegrity_ros.log_text import shown

# Kinds of per-module parameters: what a runtime change does.
PHYSICAL = 'physical'    # geometry, stiffness, masses: tracked like a command
FORCE = 'force'          # force_a3/a4: tracked like a force command
INITIAL = 'initial'      # used at start-up and by reset
LIMIT = 'limit'          # rho_min/rho_max: command validation
SETTING = 'setting'      # rates and thresholds

#: Per-module parameters ``<m>.<name>``: (name, default, type, kind, description, constraints,
#: (from, to) range or None).  The README parameter table mirrors this.
MODULE_PARAMETERS = (
    ('L1', 1.0, 'double', PHYSICAL, 'Length of rod A1A3 (m).', '> 0', None),
    ('L2', 1.0, 'double', PHYSICAL, 'Length of rod A2A4 (m).', '> 0', None),
    ('k', 100.0, 'double', PHYSICAL,
     'Stiffness of all three springs a, b, c (N/m), unless ka/kb/kc override it.', '> 0', None),
    ('ka', 0.0, 'double', PHYSICAL, 'Stiffness of spring a = A2A3 (N/m); 0.0 = use k.',
     '>= 0', None),
    ('kb', 0.0, 'double', PHYSICAL, 'Stiffness of spring b = A1A4 (N/m); 0.0 = use k.',
     '>= 0', None),
    ('kc', 0.0, 'double', PHYSICAL, 'Stiffness of spring c = A3A4 (N/m); 0.0 = use k.',
     '>= 0', None),
    ('m1', 0.0, 'double', PHYSICAL,
     'Mass of rod A1A3 (kg); its weight acts along -y of the base frame; its inertia '
     'when dynamics is true.', '>= 0 (> 0 when dynamics is true)', None),
    ('m2', 0.0, 'double', PHYSICAL, 'Mass of rod A2A4 (kg).', '>= 0 (> 0 when dynamics is true)',
     None),
    ('force_a3', [0.0, 0.0], 'double_array', FORCE,
     'Force [fx, fy] at A3 (N, base frame; fy > 0 pulls up) at start-up and on reset; '
     'setting it at runtime applies it at once, tracked like a force_a3 message.',
     'two finite numbers', None),
    ('force_a4', [0.0, 0.0], 'double_array', FORCE,
     'Force [fx, fy] at A4 (N), as force_a3.', 'two finite numbers', None),
    ('rho_initial', 0.75, 'double', INITIAL,
     'Actuator length at start-up and on reset (m).', 'rho_min <= rho_initial <= rho_max', None),
    ('initial_theta', [0.7, 0.7], 'double_array', INITIAL,
     'Start guess [theta1, theta2] (rad): the node starts (and resets) in the stable '
     'equilibrium whose basin holds it; picks the branch.', 'two finite numbers', None),
    ('rho_min', 0.05, 'double', LIMIT, 'Smallest accepted actuator command (m).',
     '0 < rho_min < rho_max; current and initial rho must stay inside', None),
    ('rho_max', 1.95, 'double', LIMIT, 'Largest accepted actuator command (m).',
     'rho_max > rho_min; current and initial rho must stay inside', None),
    ('max_rho_rate', 0.0, 'double', SETTING,
     'Actuator speed limit (m/s). 0 = no limit: a command is one straight path. '
     'Otherwise the actuator moves toward the latest target at this speed, one tracked '
     'segment per timer tick (publish_rate) and per command. With dynamics true: the '
     'kinematic actuator speed.', '>= 0 (> 0 when dynamics is true)', (0.0, 100.0)),
    ('damping', 0.01, 'double', SETTING,
     'Viscous damping at each rod pivot (N m s/rad), used when dynamics is true (must be '
     '> 0 then: without it the rods never come to rest); ignored otherwise.', '>= 0', None),
    ('warn_margin', 0.05, 'double', SETTING,
     'equilibrium is WARN (near a jump) when the stability margin (smallest Hessian '
     'eigenvalue, J/rad^2) is below warn_margin * min(ka, kb, kc) * L1 * L2.', '0..1',
     (0.0, 1.0)),
)
_MODULE_SPEC = {p[0]: p for p in MODULE_PARAMETERS}

#: {name: default} of every per-module parameter.
MODULE_DEFAULTS = {p[0]: p[1] for p in MODULE_PARAMETERS}


def effective_stiffness(k, override):
    """``<m>.ka/kb/kc`` of 0.0 means "use ``<m>.k``"."""
    return override if override > 0.0 else k


def finite_pair(value):
    return (value is not None and len(value) == 2
            and all(isinstance(v, float) and math.isfinite(v) for v in value))


def kind_of(key):
    """What a runtime change of module parameter ``key`` does (PHYSICAL, FORCE ...)."""
    return _MODULE_SPEC[key][3]


def module_getter(module, values):
    """get(key): the value of ``<module>.<key>`` in ``values`` (arrays as float lists)."""
    prefix = module + '.'

    def get(key):
        value = values[prefix + key]
        if _MODULE_SPEC[key][2] == 'double_array' and value is not None:
            return [float(v) for v in value]
        return value
    return get


def module_params(get, rho, force_a3, force_a4):
    """The :class:`ModuleParams` of the values ``get`` reads, at ``rho`` and these forces."""
    k = get('k')
    return ModuleParams(
        rho=rho, L1=get('L1'), L2=get('L2'),
        ka=effective_stiffness(k, get('ka')), kb=effective_stiffness(k, get('kb')),
        kc=effective_stiffness(k, get('kc')),
        f3x=force_a3[0], f3y=force_a3[1], f4x=force_a4[0], f4y=force_a4[1],
        m1=get('m1'), m2=get('m2'))


def initial_params(get):
    """The module at start-up and on reset: rho_initial and the force parameters."""
    return module_params(get, get('rho_initial'), get('force_a3'), get('force_a4'))


def module_limits(get):
    return ModuleLimits(rho_min=get('rho_min'), rho_max=get('rho_max'),
                        max_rho_rate=get('max_rho_rate'), warn_margin=get('warn_margin'))


#: The ModuleParams fields a runtime parameter change may set (all but rho).
DESIGN_FIELDS = ('L1', 'L2', 'ka', 'kb', 'kc', 'f3x', 'f3y', 'f4x', 'f4y', 'm1', 'm2')


def design_changes(get, live, keys):
    """{field: value} of a module whose parameters ``keys`` changed: the design from the
    parameter values; forces from them only if a force parameter is among ``keys``
    (otherwise the live forces, which force messages may have changed)."""
    f3 = get('force_a3') if 'force_a3' in keys else (live.f3x, live.f3y)
    f4 = get('force_a4') if 'force_a4' in keys else (live.f4x, live.f4y)
    end = module_params(get, live.rho, f3, f4)
    return {name: getattr(end, name) for name in DESIGN_FIELDS}


def check_module_values(m, get):
    """Why the values of module ``m``'s parameters are refused, or '' if they are fine."""
    for key in ('L1', 'L2', 'k'):
        v = get(key)
        if not (math.isfinite(v) and v > 0.0):
            return f'{m}.{key} must be finite and > 0, got {v!r}'
    for key, meaning in (('ka', '0.0 = use k'), ('kb', '0.0 = use k'),
                         ('kc', '0.0 = use k'), ('m1', 'kg'), ('m2', 'kg'),
                         ('damping', 'N m s/rad')):
        v = get(key)
        if not (math.isfinite(v) and v >= 0.0):
            return f'{m}.{key} must be finite and >= 0 ({meaning}), got {v!r}'
    for key in ('force_a3', 'force_a4', 'initial_theta'):
        v = get(key)
        if not finite_pair(v):
            return f'{m}.{key} must be two finite numbers, got {shown(v)}'
    lo, hi, initial = get('rho_min'), get('rho_max'), get('rho_initial')
    if not (math.isfinite(lo) and lo > 0.0):
        return f'{m}.rho_min must be finite and > 0, got {lo!r}'
    if not (math.isfinite(hi) and hi > lo):
        return f'{m}.rho_max must be finite and > rho_min ({lo!r}), got {hi!r}'
    if not (math.isfinite(initial) and lo <= initial <= hi):
        return f'{m}.rho_initial={initial!r} must lie in [rho_min, rho_max] = [{lo!r}, {hi!r}]'
    try:
        initial_params(get)
        for rho in (lo, hi):                # every length the actuator may reach
            check_supported(module_params(get, rho, get('force_a3'), get('force_a4')))
    except InvalidParameterError as exc:
        return f'{m}: {exc}'
    return ''


def check_dynamics_values(m, get):
    """Why module ``m`` cannot move in the dynamics mode, or '' if it can: the rods need
    masses (their inertia), the pivots damping (to come to rest), the actuator a speed."""
    for key, unit in (('m1', 'kg'), ('m2', 'kg'), ('damping', 'N m s/rad'),
                      ('max_rho_rate', 'm/s')):
        v = get(key)
        if not (math.isfinite(v) and v > 0.0):
            return f'{m}.{key} must be > 0 ({unit}) when dynamics is true, got {v!r}'
    return ''


def live_values(get, live):
    """{key: value} of the module parameters (read by ``get``) that do not say what the live
    :class:`ModuleParams` ``live`` is: after a force message, or a path stopped early.
    Springs that follow ``k`` (override 0.0) are read back through ``k`` while they agree."""
    out = {key: float(getattr(live, key)) for key in ('L1', 'L2', 'm1', 'm2')
           if get(key) != getattr(live, key)}
    for key, fields in (('force_a3', ('f3x', 'f3y')), ('force_a4', ('f4x', 'f4y'))):
        value = [float(getattr(live, f)) for f in fields]
        if get(key) != value:
            out[key] = value
    following = [key for key in ('ka', 'kb', 'kc') if not get(key) > 0.0]
    for key in ('ka', 'kb', 'kc'):
        if key not in following and get(key) != getattr(live, key):
            out[key] = float(getattr(live, key))
    stiffnesses = {float(getattr(live, key)) for key in following}
    if len(stiffnesses) == 1:
        (k,) = stiffnesses
        if get('k') != k:
            out['k'] = k
    elif stiffnesses:
        out.update({key: float(getattr(live, key)) for key in following})
    return out
