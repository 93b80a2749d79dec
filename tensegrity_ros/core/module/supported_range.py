"""The supported range: dimensionless groups inside which the solvers are tested.

The model is scale-invariant: with lengths in units of L1, stiffnesses in units of
ka and forces in units of ka L1 only ratios remain.  Every magnitude whose ratios
lie inside the limits below is supported (tested end to end in
test/test_supported_range.py at overall scales from 1e-40 to 1e40); outside them
the stiffness matrix spans more decades than the stability test can resolve in
double precision, and the input is refused with a reason naming the group.
"""
from __future__ import annotations

from .model import InvalidParameterError, ModuleParams

#: L2/L1 and rho/L1 lie within [1/LENGTH_RATIO, LENGTH_RATIO].
LENGTH_RATIO = 1e3
#: kb/ka and kc/ka lie within [1/STIFFNESS_RATIO, STIFFNESS_RATIO].
STIFFNESS_RATIO = 1e3
#: Each load (force component, or half a rod weight) is at most LOAD_RATIO k_min L_min.
LOAD_RATIO = 1e4
#: A value at a limit stays inside it after rescaling (relative rounding slack).
_ROUNDING = 1.0 + 1e-12


class OutOfRangeError(InvalidParameterError):
    """Parameters outside the supported dimensionless range."""


def groups(params: ModuleParams) -> dict:
    """The dimensionless groups of one module, by name."""
    k_min = min(params.ka, params.kb, params.kc)
    unit_force = k_min * min(params.L1, params.L2)
    loads = (params.f3x, params.f3y, params.f4x, params.f4y,
             0.5 * params.m1 * params.g, 0.5 * params.m2 * params.g)
    return {'L2/L1': params.L2 / params.L1, 'rho/L1': params.rho / params.L1,
            'kb/ka': params.kb / params.ka, 'kc/ka': params.kc / params.ka,
            'load/(k L)': max(abs(v) for v in loads) / unit_force}


def out_of_range_reason(params: ModuleParams) -> str:
    """Why ``params`` are outside the supported range, or '' if they are inside."""
    g = groups(params)
    for name, limit in (('L2/L1', LENGTH_RATIO), ('rho/L1', LENGTH_RATIO),
                        ('kb/ka', STIFFNESS_RATIO), ('kc/ka', STIFFNESS_RATIO)):
        if not (1.0 / limit <= g[name] * _ROUNDING and g[name] <= limit * _ROUNDING):
            return (f'{name} = {g[name]:.6g} is outside the supported range '
                    f'[{1.0 / limit:g}, {limit:g}]')
    if g['load/(k L)'] > LOAD_RATIO * _ROUNDING:
        return (f'load/(k L) = {g["load/(k L)"]:.6g} (largest force over the softest spring '
                f'times the shorter rod) is above the supported {LOAD_RATIO:g}')
    return ''


def check_supported(params: ModuleParams) -> ModuleParams:
    """``params`` if inside the supported range, else :class:`OutOfRangeError`."""
    reason = out_of_range_reason(params)
    if reason:
        raise OutOfRangeError(reason)
    return params
