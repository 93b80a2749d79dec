"""The neck: N modules stacked chord on chord (docs/model.md section 4).  Its model
(:mod:`.model`: parameters, node graph, one evaluation per state), the path problem the
tracker follows (:mod:`.path`, with its flows :mod:`.flows` / :mod:`.flow_kernel`, its
linkage limits :mod:`.linkage` / :mod:`.flat_crossing` and what a state means to a user
:mod:`.reporting`), a small command as one step (:mod:`.fast_step`), the tracked stack
(:mod:`.stack`) and its frames on /tf (:mod:`.frames`)."""
from .frames import chord_frames, PlanarTransform
from .stack import (settle_stack, Stack, stack_equilibria, stack_equilibrium_at, StackEquilibrium,
                    StackJump, StackPassage, StackPath, StackTrack, StackUndecided, track_stack)

__all__ = ['chord_frames', 'PlanarTransform', 'settle_stack', 'Stack', 'stack_equilibria',
           'stack_equilibrium_at', 'StackEquilibrium', 'StackJump', 'StackPassage',
           'StackPath', 'StackTrack', 'StackUndecided', 'track_stack']
