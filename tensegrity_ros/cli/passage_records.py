"""The CLI's records of the branch points a tracked path passed without a jump: the
passages (a supercritical branch point: the mechanism buckled smoothly) and, among them,
the ``undecided`` ones, whose side lies below what doubles resolve (JSON and text)."""
from __future__ import annotations

import math


def _angles(theta):
    return [[float(a), float(b)] for a, b in theta]


def theta_text(theta, names):
    """Every module's angles in degrees, by name (the CLI's neck lines)."""
    return ' '.join(f'{name} ({math.degrees(t[0]):.3f}, {math.degrees(t[1]):.3f})'
                    for name, t in zip(names, theta))


def stack_passage_record(passage):
    """A supercritical branch point the stack passed continuously, as JSON."""
    head = passage.stack.modules[-1]
    return {'kind': 'branch_point', 's': float(passage.s),
            'rho': [float(m.rho) for m in passage.stack.modules],
            'theta': _angles(passage.theta), 'F3': float(head.f3y), 'F4': float(head.f4y)}


def stack_passage_line(passage, names):
    rho = ', '.join(f'{m.rho:.9g}' for m in passage.stack.modules)
    return (f'passed: branch_point at s={passage.s:.9f} rho=({rho}): theta [deg] '
            f'{theta_text(passage.theta, names)}, buckled continuously (supercritical: '
            f'no jump)\n')


def undecided_record(undecided):
    """A :class:`~.core.module.tracking.ModuleUndecided` or
    :class:`~.core.neck.stack.StackUndecided`
    as JSON: where (s, rho, the critical theta) and how uncertain (in s and in rho)."""
    doc = {'kind': 'undecided', 's': float(undecided.s),
           's_uncertainty': float(undecided.s_uncertainty)}
    stack = getattr(undecided, 'stack', None)
    if stack is None:
        return dict(doc, rho=float(undecided.params.rho),
                    rho_uncertainty=float(undecided.rho_uncertainty),
                    theta1=float(undecided.theta[0]), theta2=float(undecided.theta[1]))
    return dict(doc, rho=[float(m.rho) for m in stack.modules],
                rho_uncertainty=[float(r) for r in undecided.rho_uncertainty],
                theta=_angles(undecided.theta))


def undecided_line(undecided, names=('m0',)):
    """One line of text for :func:`undecided_record`'s record."""
    stack = getattr(undecided, 'stack', None)
    modules = (undecided.params,) if stack is None else stack.modules
    theta = [undecided.theta] if stack is None else undecided.theta
    spans = undecided.rho_uncertainty if stack is not None else (undecided.rho_uncertainty,)
    rho = ', '.join(f'{m.rho:.9g}' for m in modules)
    span = f' ({max(spans):.2g} m of rho)' if max(spans) > 0.0 else ''
    return (f'undecided: branch_point at s={undecided.s:.9f} rho=({rho}): theta [deg] '
            f'{theta_text(theta, names)}, passed continuously to one side; an imperfection '
            f'within {undecided.s_uncertainty:.2g} of the path{span} would decide which '
            f'(below what doubles resolve)\n')
