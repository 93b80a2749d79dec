"""When rounding, not the model, chose a landing: ``Event.ambiguous``.

Three ways: the two sides of a branch point land apart (:func:`.lander.land_once`);
another half-branch out of a flat crossing the flow passed lands elsewhere
(:func:`lands_elsewhere`); the departure is its own mirror image and the landing is
not (:func:`mirror_lands_too`)."""
from __future__ import annotations

from .flows import slide
from .settings import ARC_RESOLUTION


def lands_elsewhere(run, alternatives, landing, s):
    """Whether a rigid flow from one of the ``alternatives`` (states out along the
    other half-branches of a flat crossing the landing flow passed) rests more than
    1e-6 from ``landing``: then the landing is ambiguous, as where the two sides of a
    branch point land differently (e.g. the mirror images of a symmetric neck, when
    the steepest half-branch wins by 3e-4 of its descent rate: config/neck.yaml,
    bench_round_commands seed 0, stream 16).  Their own crossings are not followed up."""
    for state in alternatives:
        other = slide(run, state, s, rigid_first=True)
        if other is not None and run.separation(other, landing) > 1e-6:
            return True
    return False


def mirror_lands_too(run, y_star, landing, s):
    """Whether the landing's mirror image is as good a landing: the problem is
    mirror-symmetric at s (its optional ``mirror``), the departure its own mirror
    image (to ARC_RESOLUTION) and the landing not (by more than 1e-6).  Nothing in
    the model then chooses between the two; rounding does (bench_round_commands
    seed 3, streams 1, 10 and 19: folds off a flat module of a mirror-symmetric
    neck, the lower side of the critical mode landing on one image or the other as
    the departure's last bits went)."""
    mirror = getattr(run.problem, 'mirror', None)
    image = None if mirror is None else mirror(y_star, s)
    return (image is not None and run.separation(image, y_star) <= ARC_RESOLUTION
            and run.separation(mirror(landing, s), landing) > 1e-6)
