"""The neck's equations of motion per evaluation, compiled (numba): the inner loop of a live
neck, called some 2000-4000 times per simulated second (see :mod:`.dynamics.neck_snap` for the
model and its numpy evaluation; this file only evaluates it, loop by loop).

Why compiled: the integrator calls the right-hand side once per stage, one small state at
a time, so numpy's per-call overhead is the whole cost.  Measured on this project's
2-core machine: an elementwise op on 6 numbers 0.25 us, a 20 x 20 matrix-vector product
1.1 us, ``np.linalg.solve`` 5 us (LAPACK's dgesv alone 1.7 us); the node-coordinate
right-hand side in numpy 50-70 us, a reduced (rod-angle) one written for fewest numpy
calls 46-57 us, and no arrangement of the ~60 array operations it needs below ~20 us.
At ~2000-4000 evaluations per simulated second of config/neck.yaml's snap that caps a
live neck well below the real-time factor of 20 it needs; compiled, one evaluation takes
~4 us.

numba is imported only by :func:`compiled` (a live neck's first use): the quasi-static
mode never loads it.  Without numba, or with ``TENSEGRITY_NO_NUMBA=1`` in the environment,
:func:`compiled` returns None and :class:`.dynamics.neck_snap.NeckEquations` evaluates the same
equations with numpy (the same numbers to rounding, ~10 times slower).

Node coordinates (as :class:`.dynamics.neck_snap.NeckEquations`): the moving nodes' positions
and velocities; A1(0) fixed at the origin, A2(0) at (rho0(t), 0).  Rigid lengths (rods;
the chords under upper modules, whose lengths are the upper actuators' rho) are imposed
at acceleration level with a Baumgarte term; the multipliers come from the Schur complement
of the constant mass matrix (:func:`accelerations`), solved by LAPACK.
"""
from __future__ import annotations

import numpy as np

from ..numerics.numba_kernels import compile_kernels


def ramp_at(t, rho0, rho1, duration):
    """(rho, rho') of every actuator at time t of a constant-rate ramp, then held.  A
    negative ``duration`` -D is the ramp of duration D extended beyond its end at the same
    rate (the live loop integrates a segment past its end only to interpolate at it)."""
    n = rho0.shape[0]
    rho = np.empty(n)
    rate = np.zeros(n)
    if duration == 0.0 or t >= duration > 0.0:
        rho[:] = rho1
        return rho, rate
    s = max(t, 0.0) / abs(duration)
    duration = abs(duration)
    for i in range(n):
        rho[i] = rho0[i] + s * (rho1[i] - rho0[i])
        rate[i] = (rho1[i] - rho0[i]) / duration
    return rho, rate


def node_table(y, n, rho0, rho0_rate):
    """Node positions and velocities ((2 + 2N) x 2 each) of state y."""
    nodes = 2 + 2 * n
    x = np.zeros((nodes, 2))
    v = np.zeros((nodes, 2))
    x[1, 0] = rho0
    v[1, 0] = rho0_rate
    k = 4 * n
    for j in range(2 * n):
        x[2 + j, 0] = y[2 * j]
        x[2 + j, 1] = y[2 * j + 1]
        v[2 + j, 0] = y[k + 2 * j]
        v[2 + j, 1] = y[k + 2 * j + 1]
    return x, v


def _add_pivot_damping(force, x, v, frames, damping):
    """force -= J^T c J v: viscous torques c theta' on every local angle (t1 of A1A3 from
    A1A2, t2 of A2A4 from -A1A2), as forces on the nodes that define the angles."""
    for i in range(frames.shape[1]):
        a1, a2, a3, a4 = frames[0, i], frames[1, i], frames[2, i], frames[3, i]
        c = damping[i]
        if c == 0.0:
            continue
        # perp(d) / |d|^2 of A1A3, A1A2, A2A4
        d0x, d0y = x[a3, 0] - x[a1, 0], x[a3, 1] - x[a1, 1]
        d1x, d1y = x[a2, 0] - x[a1, 0], x[a2, 1] - x[a1, 1]
        d2x, d2y = x[a4, 0] - x[a2, 0], x[a4, 1] - x[a2, 1]
        q0, q1, q2 = d0x * d0x + d0y * d0y, d1x * d1x + d1y * d1y, d2x * d2x + d2y * d2y
        p0x, p0y = -d0y / q0, d0x / q0
        p1x, p1y = -d1y / q1, d1x / q1
        p2x, p2y = -d2y / q2, d2x / q2
        r0 = p0x * (v[a3, 0] - v[a1, 0]) + p0y * (v[a3, 1] - v[a1, 1])
        r1 = p1x * (v[a2, 0] - v[a1, 0]) + p1y * (v[a2, 1] - v[a1, 1])
        r2 = p2x * (v[a4, 0] - v[a2, 0]) + p2y * (v[a4, 1] - v[a2, 1])
        tau1 = c * (r0 - r1)            # theta1' = phi(A1A3)' - phi(A1A2)'
        tau2 = c * (r1 - r2)            # theta2' = phi(A1A2)' - phi(A2A4)'
        force[a3, 0] -= tau1 * p0x
        force[a3, 1] -= tau1 * p0y
        force[a1, 0] += tau1 * p0x
        force[a1, 1] += tau1 * p0y
        force[a2, 0] += (tau1 - tau2) * p1x
        force[a2, 1] += (tau1 - tau2) * p1y
        force[a1, 0] -= (tau1 - tau2) * p1x
        force[a1, 1] -= (tau1 - tau2) * p1y
        force[a4, 0] += tau2 * p2x
        force[a4, 1] += tau2 * p2y
        force[a2, 0] -= tau2 * p2x
        force[a2, 1] -= tau2 * p2y


def node_forces(x, v, loads, springs, spring_k, frames, damping, imperfection):
    """Springs, loads and weights, pivot damping and the built-in imperfection (a torque on
    rod A1(0)A3(0)) as forces on every node ((2 + 2N) x 2)."""
    force = loads.copy()
    for e in range(springs.shape[0]):
        a, b = springs[e, 0], springs[e, 1]
        k = spring_k[e]
        fx, fy = k * (x[a, 0] - x[b, 0]), k * (x[a, 1] - x[b, 1])
        force[a, 0] -= fx
        force[a, 1] -= fy
        force[b, 0] += fx
        force[b, 1] += fy
    _add_pivot_damping(force, x, v, frames, damping)
    rx, ry = x[2, 0] - x[0, 0], x[2, 1] - x[0, 1]
    scale = imperfection / (rx * rx + ry * ry)
    force[2, 0] -= scale * ry
    force[2, 1] += scale * rx
    return force


def accelerations(t, y, n, rho0, rho1, duration, mass_inverse, loads, springs, spring_k,
                  frames, damping, imperfection, rigid, rigid_length, rigid_chord, baumgarte):
    """(free node accelerations (4N), multipliers of the rigid lengths, node forces).

    M a = f + G^T lambda, G a = gamma, with the mass matrix M constant (``mass_inverse``
    given): lambda from the Schur complement (G M^-1 G^T) lambda = gamma - G M^-1 f, whose
    entries need only the 2 x 2 blocks of M^-1 between the two nodes of each rigid length
    (a row of G has at most four entries): 3N - 1 unknowns instead of 7N - 1."""
    rho, rate = ramp_at(t, rho0, rho1, duration)
    x, v = node_table(y, n, rho[0], rate[0])
    force = node_forces(x, v, loads, springs, spring_k, frames, damping, imperfection)
    k = 4 * n
    m = rigid.shape[0]
    f = np.empty(k)
    for j in range(k):
        f[j] = force[2 + j // 2, j % 2]
    u = mass_inverse @ f
    # G's rows as (column, value) pairs: a rigid length's two nodes, x and y
    cols = np.full((m, 4), -1, dtype=np.int64)
    vals = np.zeros((m, 4))
    gamma = np.empty(m)
    for e in range(m):
        a, b = rigid[e, 0], rigid[e, 1]
        dx, dy = x[a, 0] - x[b, 0], x[a, 1] - x[b, 1]
        vx, vy = v[a, 0] - v[b, 0], v[a, 1] - v[b, 1]
        chord = rigid_chord[e]
        length = rigid_length[e] if chord < 0 else rho[chord]
        length_rate = 0.0 if chord < 0 else rate[chord]
        for slot, node, sign in ((0, a, 2.0), (2, b, -2.0)):
            if node >= 2:
                cols[e, slot], cols[e, slot + 1] = 2 * (node - 2), 2 * (node - 2) + 1
                vals[e, slot], vals[e, slot + 1] = sign * dx, sign * dy
        phi = dx * dx + dy * dy - length * length
        phi_dot = 2.0 * (dx * vx + dy * vy) - 2.0 * length * length_rate
        gamma[e] = (-2.0 * (vx * vx + vy * vy) + 2.0 * length_rate * length_rate
                    - 2.0 * baumgarte * phi_dot - baumgarte * baumgarte * phi)
    schur = np.zeros((m, m))
    for e in range(m):
        for p in range(4):
            i = cols[e, p]
            if i < 0:
                continue
            gamma[e] -= vals[e, p] * u[i]
            for g in range(m):
                total = 0.0
                for q in range(4):
                    j = cols[g, q]
                    if j >= 0:
                        total += mass_inverse[i, j] * vals[g, q]
                schur[e, g] += vals[e, p] * total
    lam = np.linalg.solve(schur, gamma)
    pull = f.copy()                                   # f + G^T lambda
    for e in range(m):
        for p in range(4):
            if cols[e, p] >= 0:
                pull[cols[e, p]] += vals[e, p] * lam[e]
    return mass_inverse @ pull, lam, force


def state_rate(t, y, n, rho0, rho1, duration, mass_inverse, loads, springs, spring_k, frames,
               damping, imperfection, rigid, rigid_length, rigid_chord, baumgarte):
    """dy/dt: (node velocities, node accelerations)."""
    acc, _, _ = accelerations(t, y, n, rho0, rho1, duration, mass_inverse, loads, springs,
                              spring_k, frames, damping, imperfection, rigid, rigid_length,
                              rigid_chord, baumgarte)
    k = 4 * n
    out = np.empty(2 * k)
    out[:k] = y[k:]
    out[k:] = acc
    return out


def actuator_forces(t, y, n, rho0, rho1, duration, mass_inverse, loads, springs, spring_k,
                    frames, damping, imperfection, rigid, rigid_length, rigid_chord, baumgarte,
                    base_mass_row):
    """Every actuator's force (N): module 0's, the x force it exerts on A2(0) (the slider
    is massless: its share of the rods' inertia, minus the forces on A2(0)); an upper
    module's, 2 lambda l along the chord that is its telescopic rod (positive pushes)."""
    acc, lam, force = accelerations(t, y, n, rho0, rho1, duration, mass_inverse, loads,
                                    springs, spring_k, frames, damping, imperfection, rigid,
                                    rigid_length, rigid_chord, baumgarte)
    rho, rate = ramp_at(t, rho0, rho1, duration)
    x, v = node_table(y, n, rho[0], rate[0])
    out = np.empty(n)
    reaction = -force[1, 0]
    for j in range(acc.shape[0]):
        reaction += base_mass_row[j] * acc[j]
    for e in range(rigid.shape[0]):
        a, b = rigid[e, 0], rigid[e, 1]
        if a == 1:
            reaction -= 2.0 * (x[a, 0] - x[b, 0]) * lam[e]
        elif b == 1:
            reaction += 2.0 * (x[a, 0] - x[b, 0]) * lam[e]
        chord = rigid_chord[e]
        if chord >= 0:
            out[chord] = 2.0 * lam[e] * rho[chord]
    out[0] = reaction
    return out


def local_angles_and_rates(t, y, n, rho0, rho1, duration, frames):
    """Every module's local angles (wrapped to [-pi, pi)) and their rates, 2N each."""
    rho, rate = ramp_at(t, rho0, rho1, duration)
    x, v = node_table(y, n, rho[0], rate[0])
    angles = np.empty(2 * n)
    rates = np.empty(2 * n)
    for i in range(n):
        a1, a2, a3, a4 = frames[0, i], frames[1, i], frames[2, i], frames[3, i]
        d0x, d0y = x[a3, 0] - x[a1, 0], x[a3, 1] - x[a1, 1]
        d1x, d1y = x[a2, 0] - x[a1, 0], x[a2, 1] - x[a1, 1]
        d2x, d2y = x[a4, 0] - x[a2, 0], x[a4, 1] - x[a2, 1]
        phi0, phi1, phi2 = np.arctan2(d0y, d0x), np.arctan2(d1y, d1x), np.arctan2(d2y, d2x)
        angles[2 * i] = (phi0 - phi1 + np.pi) % (2.0 * np.pi) - np.pi
        angles[2 * i + 1] = (2.0 * np.pi + phi1 - phi2) % (2.0 * np.pi) - np.pi
        r0 = (d0x * (v[a3, 1] - v[a1, 1]) - d0y * (v[a3, 0] - v[a1, 0])) / (d0x * d0x + d0y * d0y)
        r1 = (d1x * (v[a2, 1] - v[a1, 1]) - d1y * (v[a2, 0] - v[a1, 0])) / (d1x * d1x + d1y * d1y)
        r2 = (d2x * (v[a4, 1] - v[a2, 1]) - d2y * (v[a4, 0] - v[a2, 0])) / (d2x * d2x + d2y * d2y)
        rates[2 * i] = r0 - r1
        rates[2 * i + 1] = r1 - r2
    return angles, rates


def readings(ts, ys, n, rho0, rho1, duration, mass_inverse, loads, springs, spring_k, frames,
             damping, imperfection, rigid, rigid_length, rigid_chord, baumgarte,
             base_mass_row):
    """Local angles, their rates and the actuator forces of many states ``ys`` at times
    ``ts`` (the figures of a snap read every sample): (k, 2N), (k, 2N), (k, N)."""
    k = ts.shape[0]
    angles = np.empty((k, 2 * n))
    rates = np.empty((k, 2 * n))
    forces = np.empty((k, n))
    for j in range(k):
        y = np.ascontiguousarray(ys[j])
        angles[j], rates[j] = local_angles_and_rates(ts[j], y, n, rho0, rho1, duration, frames)
        forces[j] = actuator_forces(ts[j], y, n, rho0, rho1, duration, mass_inverse, loads,
                                    springs, spring_k, frames, damping, imperfection, rigid,
                                    rigid_length, rigid_chord, baumgarte, base_mass_row)
    return angles, rates, forces


#: The kernels, callees first (numba compiles a caller against the callees it finds).
KERNELS = ('ramp_at', 'node_table', '_add_pivot_damping', 'node_forces', 'accelerations',
           'state_rate', 'actuator_forces', 'local_angles_and_rates', 'readings')
_COMPILED = []


def compiled():
    """The kernels compiled by numba (its on-disk cache reused) as a namespace, made on the
    first call, or None where numba is not installed or TENSEGRITY_NO_NUMBA is set."""
    if not _COMPILED:
        _COMPILED.append(_compile())
    return _COMPILED[0]


def _compile():
    kernels = compile_kernels(globals(), KERNELS)
    if kernels is not None:
        _warm_up(kernels)
    return kernels


def warm_up():
    """Load (or compile) the kernels now, not inside a timed call: the first use in a
    process costs ~1 s with numba's cache (tens of seconds to fill it), later ones nothing."""
    compiled()


def _warm_up(k):
    """Call every kernel once with the argument types a live neck passes."""
    n = 1
    state_rate, actuator_forces = k.state_rate, k.actuator_forces
    local_angles_and_rates, readings = k.local_angles_and_rates, k.readings
    state_rate(0.0, np.array([1.0, 1.0, 2.0, 1.0, 0.0, 0.0, 0.0, 0.0]), n,
               np.ones(1), np.ones(1), 0.0, np.eye(4), np.zeros((4, 2)),
               np.zeros((1, 2), dtype=np.int64), np.zeros(1), np.array([[0], [1], [2], [3]]),
               np.zeros(1), 0.0, np.array([[2, 0], [3, 1]]), np.ones(2),
               np.array([-1, -1]), 20.0)
    actuator_forces(0.0, np.array([1.0, 1.0, 2.0, 1.0, 0.0, 0.0, 0.0, 0.0]), n,
                    np.ones(1), np.ones(1), 0.0, np.eye(4), np.zeros((4, 2)),
                    np.zeros((1, 2), dtype=np.int64), np.zeros(1),
                    np.array([[0], [1], [2], [3]]), np.zeros(1), 0.0,
                    np.array([[2, 0], [3, 1]]), np.ones(2), np.array([-1, -1]), 20.0,
                    np.zeros(4))
    local_angles_and_rates(0.0, np.array([1.0, 1.0, 2.0, 1.0, 0.0, 0.0, 0.0, 0.0]), 1,
                           np.ones(1), np.ones(1), 0.0, np.array([[0], [1], [2], [3]]))
    readings(np.zeros(1), np.array([[1.0, 1.0, 2.0, 1.0, 0.0, 0.0, 0.0, 0.0]]), n,
             np.ones(1), np.ones(1), 0.0, np.eye(4), np.zeros((4, 2)),
             np.zeros((1, 2), dtype=np.int64), np.zeros(1), np.array([[0], [1], [2], [3]]),
             np.zeros(1), 0.0, np.array([[2, 0], [3, 1]]), np.ones(2), np.array([-1, -1]),
             20.0, np.zeros(4))
