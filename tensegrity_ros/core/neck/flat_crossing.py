"""A neck module's flat crossing: where the rigid landing flow stalls, and the ways out.

Module i's rods lie flat along its base line with its top chord exactly rho(i+1) long
where rho(i) + rho(i+1) = L1 + L2 (or another sum of the lengths with signs): a change
point of the module's linkage.  There chord i's gradient in the module's own two rod
angles vanishes and the chord's solution set crosses itself (c ~ x^T H x / 2, H
indefinite): four half-branches leave the crossing.  The projected (rigid) flow stalls
on the crossing, as its projection is undefined there; the tracker goes on along one of
the half-branches (``continuation.flows.through_crossing``).  Here is the geometry:
the module's flatness, the crossing next to a state, and the states a short way out
along each half-branch, all on the constraints.

Module i is moved in its own frame: its rods turn, and every rod above turns with its
top chord (the modules above are carried rigidly), so only chord i's constraint moves.
"""
import functools
import math

import numpy as np

#: A module is at a crossing if its flat configuration misses its top chord's length by
#: less than this (times l_ref): otherwise the chord's solution set does not cross itself
#: there (it turns back, a linkage limit) and the flow has no choice to make.
CROSSING_CHORD_TOL = 1e-9
#: The rounding error of a chord constraint (times l_ref): its end nodes are sums of
#: the rod vectors below (each rounded to ~1e-16 of l_ref), and the difference of the
#: squares in (|chord|^2 - l^2) / (2 l_ref) loses as much again: ~1e-15 l_ref, a few
#: units in the last place of L1 + L2 (config/neck.yaml: 1.2e-16 m against 2.8e-17 m).
#: Next to a module's flat crossing Newton's rod-angle updates stall at this over the
#: chord's gradient (see :func:`rounding`).
CHORD_ROUNDING = 1e-15
#: Farthest (rad, max over the module's two rods) a state may be from the crossing it is
#: said to be at.
CROSSING_REACH = 0.1
#: How far out along a half-branch (rad, in the module's two angles) its state is put:
#: well clear of the crossing for the projection (chord gradient ~1e-4 l_ref), close
#: enough that the descent rate is the half-branch's own.
CROSSING_PUSH = 1e-4
#: Step of the central differences for chord i's Hessian in the module's angles (rad).
_HESSIAN_STEP = 1e-5
_NEWTON_STEPS = 5
#: How far (rad, the fastest rod) the rigid flow's velocity is followed to see which
#: way it takes a module: far below CROSSING_PUSH.
_PROBE = 1e-8


def flatness(path, y, s):
    """(module index, |d chord_i / d (module i's rod angles)| / l_ref) of the flattest
    module with a chord above it; (None, inf) for one module.  (The full row of chord i
    also moves with the lower modules, through the chord below; that part hides the
    module's own rank loss from the row's norm.)"""
    n_chords = path.topology.n_chords
    if not n_chords:
        return None, math.inf
    # (each module's pair at once: the same sums as a norm each on the x86 kernels but
    # SkylakeX's, whose dot product fuses them; a landing flow asks at every step)
    pairs = path.point(y, s).constraint_jacobian(path)[_own_columns(n_chords)]
    own = np.sqrt((pairs * pairs).sum(axis=1))
    i = int(np.argmin(own))
    return i, float(own[i]) / path.l_ref


@functools.lru_cache(maxsize=16)
def _own_columns(n_chords):
    """Index arrays of every chord i's gradient in module i's two rod angles."""
    rows = np.arange(n_chords)[:, None]
    return rows, 2 * rows + np.arange(2)


def turned(path, y, s, i, angles):
    """``y`` with module i's rods at absolute ``angles`` and every rod above turned with
    module i's top chord (so only chord i's constraint changes)."""
    before = path.point(y, s).chords(path)[i]
    y = np.array(y, dtype=float)        # (a fresh array: the path's point keeps the one it saw)
    y[2 * i:2 * i + 2] = angles
    after = path.point(y, s).chords(path)[i]
    y = y.copy()
    y[2 * i + 2:path.topology.n_rods] += np.angle(after / before)
    return y


def _chord(path, y, s, i):
    """(chord i's constraint, its gradient in module i's two rod angles)."""
    p = path.point(y, s)
    return float(p.constraints(path)[i]), np.array(p.constraint_jacobian(path)[i, 2 * i:2 * i + 2])


def _hessian(path, y, s, i):
    """Chord i's Hessian in module i's two rod angles (central differences of its
    exact gradient; chord i does not depend on the rods above)."""
    columns = []
    for e in np.eye(2):
        plus, minus = np.array(y, dtype=float), np.array(y, dtype=float)
        plus[2 * i:2 * i + 2] += _HESSIAN_STEP * e
        minus[2 * i:2 * i + 2] -= _HESSIAN_STEP * e
        columns.append((_chord(path, plus, s, i)[1] - _chord(path, minus, s, i)[1])
                       / (2.0 * _HESSIAN_STEP))
    h = np.array(columns)
    return 0.5 * (h + h.T)


def _flat_angles(path, y, s, i):
    """Module i's two rod angles flat along its base line (each rod along it or against
    it, whichever is nearer its present angle, keeping its whole turns)."""
    # the module's x axis A1(i) -> A2(i): chord i - 1 (A4(i-1) -> A3(i-1)), or the base's x
    frame = float(np.angle(path.point(y, s).chords(path)[i - 1])) if i else 0.0
    angles = np.array(y[2 * i:2 * i + 2], dtype=float)
    for k in range(2):
        # the nearest of frame and frame + pi: a multiple of pi from the frame
        offset = angles[k] - frame
        angles[k] = frame + math.pi * round(offset / math.pi)
    return angles


def _crossing(path, y, s):
    """(module index, its flat angles, crossing state, eigenpairs of chord i's Hessian
    there) if ``y`` is next to a module's flat crossing (within CROSSING_REACH), else
    None."""
    i, _ = flatness(path, y, s)
    if i is None:
        return None
    flat = _flat_angles(path, y, s, i)
    if np.max(np.abs(flat - y[2 * i:2 * i + 2])) > CROSSING_REACH:
        return None
    crossing = turned(path, y, s, i, flat)
    c, _ = _chord(path, crossing, s, i)
    if abs(c) > CROSSING_CHORD_TOL * path.l_ref:
        return None
    values, vectors = np.linalg.eigh(_hessian(path, crossing, s, i))
    if values[0] >= 0.0 or values[1] <= 0.0:
        return None
    return i, flat, crossing, values, vectors


def turned_through_base(path, a, b, s):
    """Whether a module with a chord above turned both its rods through its base line
    from state ``a`` to ``b`` (the sines of both its local angles changed sign): a flow
    step that did so may have passed its flat crossing between the two states."""
    before, after = _base_sines(path, a, s), _base_sines(path, b, s)
    return bool(np.any(np.all(before * after < 0.0, axis=1)[:-1]))


def _base_sines(path, y, s):
    """The sines of the local angles of ``y``, the last kept on the path: a flow asks
    for each state twice, as a step's end and then as the next step's start."""
    key = (s, np.asarray(y).tobytes())
    kept = getattr(path, '_kept_base_sines', None)
    if kept is None or kept[0] != key:
        kept = path._kept_base_sines = (key, np.sin(path.angles(y, s)))
    return kept[1]


def rounding(path, y, s):
    """(distance, radius, exact) of ``y`` and the flat crossing next to it, or None if
    ``y`` is at no crossing.  ``distance``: rad, the larger of module i's two rod angles
    measured from their flat angles.  ``radius``: how far chord i's constraint fixes the
    module's angles at all, its rounding error (CHORD_ROUNDING l_ref) over its gradient
    in them.  ``exact``: whether the crossing itself is one to rounding, its chord
    missing its length by at most half that error.

    Near the crossing the chord's constraint is c0 + x^T H x / 2 (x: the module's angles
    from flat; c0 what the chord misses at the flat configuration), so its gradient is
    ~|H| distance and the radius ~CHORD_ROUNDING l_ref / (|H| distance).  Where c0 is
    not 0, the chord's solution set does not cross itself: its two arms pass the flat
    configuration at sqrt(2 |c0| / |H|), within the radius there exactly where
    |c0| <= CHORD_ROUNDING l_ref / 2.  Then no state the model resolves tells the arms
    apart (the crossing is exact); otherwise a state within the radius is one Newton
    passes on its way (and the arms' minima lie outside it)."""
    found = _crossing(path, y, s)
    if found is None:
        return None
    i, flat, crossing, _, _ = found
    _, gradient = _chord(path, y, s, i)
    distance = float(np.max(np.abs(y[2 * i:2 * i + 2] - flat)))
    error = CHORD_ROUNDING * path.l_ref
    return (distance, error / max(float(np.linalg.norm(gradient)), 1e-300),
            abs(_chord(path, crossing, s, i)[0]) <= 0.5 * error)


def crossing_at(path, y, s):
    """(module index, crossing state, [states out along each half-branch]) if ``y`` is
    next to a module's flat crossing (within CROSSING_REACH), else None."""
    found = _crossing(path, y, s)
    if found is None:
        return None
    i, flat, crossing, values, vectors = found
    states = []
    for sign in (1.0, -1.0):
        # the two lines where x^T H x = l0 l1 - l1 l0 = 0 (H's null cone)
        line = math.sqrt(values[1]) * vectors[:, 0] + sign * math.sqrt(-values[0]) * vectors[:, 1]
        line /= np.linalg.norm(line)
        for way in (1.0, -1.0):
            states.append(_onto_chord(path, crossing, s, i, flat + way * CROSSING_PUSH * line))
    return i, crossing, states


def _onto_chord(path, crossing, s, i, angles):
    """The state with module i's rods at ``angles``, put back onto chord i's constraint
    by Newton steps along its gradient, then projected (multipliers included)."""
    y = turned(path, crossing, s, i, angles)
    for _ in range(_NEWTON_STEPS):
        c, g = _chord(path, y, s, i)
        y = turned(path, y, s, i, y[2 * i:2 * i + 2] - c * g / float(g @ g))
    return path.project(y, s)


def ways_out(path, y, s):
    """The half-branches the mechanism moves away on from the crossing next to ``y``:
    [(descent rate, state out along it)], or None if ``y`` is at no crossing.

    A half-branch is left where the rigid flow at its state takes the module's own angles
    away from the crossing (:func:`_moves_away`).  Its descent rate is the energy drop per unit
    length from the crossing, the length in the node metric of the tracker's own flow (Cartesian
    node displacements): the released mechanism leaves along the steepest."""
    found = crossing_at(path, y, s)
    if found is None:
        return None
    i, crossing, states = found
    n = path.topology.n_rods
    metric = path.point(crossing, s).metric(path)
    energy = path.energy(crossing, s)
    ways = []
    for state in states:
        if _moves_away(path, crossing, state, s, i):
            d = (state - crossing)[:n]
            ways.append(((energy - path.energy(state, s)) / math.sqrt(float(d @ metric @ d)),
                         state))
    return ways


def _moves_away(path, crossing, state, s, i):
    """Whether the rigid flow at ``state`` takes module i's own (local) angles away from
    the crossing's.  (Not the whole state's distance: the modules above turn with its
    chord, and their own relaxation can carry the state away while module i goes back in,
    config/neck.yaml, bench_round_commands seed 0, stream 10.)"""
    velocity = path.rigid_descent(state, s)
    h = _PROBE / max(float(np.max(np.abs(velocity[:path.topology.n_rods]))), 1e-300)
    centre = path.angles(crossing, s)[i]
    here, there = (np.angle(np.exp(1j * (path.angles(z, s)[i] - centre)))
                   for z in (state, state + h * velocity))
    return bool(np.linalg.norm(there) > np.linalg.norm(here))
