"""A module's limits as a user sets them, and the checks of values against them.

:class:`ModuleLimits` holds the accepted actuator targets, the actuator's speed limit
and the status warning threshold of one module of a :class:`~.simulation.simulator.Simulator`;
the functions here say why limits, or a target, are not acceptable (never raising: a
user may send anything).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

from . import events as ev


@dataclass(frozen=True)
class ModuleLimits:
    """Per-module settings: accepted actuator targets, speed limit, warning threshold."""

    rho_min: float = 0.0
    rho_max: float = math.inf
    max_rho_rate: float = 0.0       # m/s; 0 = no limit (a command is one path)
    warn_margin: float = 0.05       # status 'warn' below this normalized margin


def limits_problem(limits):
    """Why ``limits`` are not usable limits ('' if they are)."""
    lo, hi, rate, warn = limits.rho_min, limits.rho_max, limits.max_rho_rate, limits.warn_margin
    if math.isnan(lo) or math.isnan(hi) or not lo <= hi:
        return f'rho_min={lo!r} and rho_max={hi!r} must be numbers with rho_min <= rho_max'
    if not (math.isfinite(rate) and rate >= 0.0):
        return f'max_rho_rate must be finite and >= 0, got {rate!r}'
    if not (math.isfinite(warn) and warn >= 0.0):
        return f'warn_margin must be finite and >= 0, got {warn!r}'
    return ''


def rho_refusal(limits, rho):
    """The refused :class:`~.simulation.events.Outcome` of an actuator target ``rho`` outside
    ``limits`` or not finite, or None."""
    if not math.isfinite(rho):
        return ev.refused(ev.NON_FINITE, f'{rho!r} is not finite')
    if not limits.rho_min <= rho <= limits.rho_max:
        return ev.refused(ev.OUT_OF_RANGE, f'{rho!r} outside [rho_min, rho_max] = '
                                           f'[{limits.rho_min}, {limits.rho_max}]')
    return None


def outside_new_limits(rho, target, rho_min, rho_max):
    """Why [rho_min, rho_max] cannot be a module's limits ('' if it can): the actuator
    at ``rho`` and its pending ``target`` (None: none) must stay inside."""
    if not rho_min <= rho <= rho_max:
        return (f'the actuator is at rho={rho!r}, outside the requested '
                f'[rho_min, rho_max] = [{rho_min!r}, {rho_max!r}]')
    if target is not None and not rho_min <= target <= rho_max:
        return (f'the pending target rho={target!r} is outside the requested '
                f'[rho_min, rho_max] = [{rho_min!r}, {rho_max!r}]')
    return ''
