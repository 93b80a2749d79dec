"""What a status report of one module shows, and how its level is decided."""
from __future__ import annotations

from dataclasses import dataclass

from ..module.model import ModuleParams


@dataclass(frozen=True)
class ModuleStatus:
    """Everything a status report of one module shows (see msg_docs/equilibrium.md).

    ``level`` is ``ok``, ``warn`` (near a jump, or tracking stopped early) or ``error``
    (not a stable equilibrium: never expected).
    """

    level: str
    message: str
    params: ModuleParams
    eq: object
    normalized: float
    num_equilibria: object
    num_stable: object
    operation_range: object
    last_jump: object
    jumps_total: int
    tracking: str
    warn_margin: float


def status_level(eq, tracking, normalized, warn_margin, margin_unit):
    """(level, message) of a module in the verified state ``eq``: an error if it is not
    stable, a warning if tracking stopped early (``tracking`` is not 'ok') or the
    ``normalized`` stability margin is below ``warn_margin``."""
    if not eq.stable:
        return 'error', 'not a stable equilibrium'
    if tracking != 'ok':
        return 'warn', f'tracking stopped early: {tracking}'
    if normalized < warn_margin:
        return 'warn', (f'stable, near a jump: stability margin {eq.stability_margin:.4g} '
                        f'{margin_unit} (normalized {normalized:.3g} '
                        f'< warn_margin {warn_margin:g})')
    return 'ok', f'stable, stability margin {eq.stability_margin:.4g}'
