"""What a simulator call did, told to the ROS graph: ``~/jumps`` messages and log lines.

The core's outcome of a command, a tick or a parameter change carries its events
(:mod:`tensegrity_ros.core.simulation.events`): a jump or an undecided passage goes out on
``~/jumps`` with a WARN line; a tracking failure, a deferred command, a warning of a jump ahead are
counted in ``/diagnostics`` and logged; a continuous passage is an INFO line; the end of a
trajectory is counted, logged and republished on ``~/motion``.
"""
from __future__ import annotations

from tensegrity_ros.core.simulation.events import (Deferred, Jump, JumpAhead, Passage,
                                                   TrackingFailure, Undecided)
from tensegrity_ros.core.simulation.trajectory import ABORTED, MotionEnded
from tensegrity_ros.ros import conversions as conv
from tensegrity_ros.ros.incidents import WARN_THROTTLE_SEC


class EventReports:
    """Publish and log the events of a simulator call's outcome (:meth:`report`).

    ``node_name`` and ``hardware_id`` name the ``~/jumps`` messages, ``names`` are the
    modules (bottom to top); ``publish_statuses`` is called after a jump (the statuses
    changed at once), ``publish_motion`` when a trajectory ended.
    """

    def __init__(self, *, node_name, hardware_id, names, jumps_pub, incidents, logger,
                 publish_statuses, publish_motion):
        self._node_name = node_name
        self._hardware_id = hardware_id
        self._names = names
        self._jumps_pub = jumps_pub
        self._incidents = incidents
        self._logger = logger
        self._publish_statuses = publish_statuses
        self._publish_motion = publish_motion

    def report(self, outcome):
        """Publish and log what a simulator call did (jumps, failures, early warnings)."""
        jumped = False
        for event in outcome.events:
            if isinstance(event, Jump):
                self._report_jump(event)
                jumped = True
            elif isinstance(event, TrackingFailure):
                self._report_tracking_failure(event)
            elif isinstance(event, JumpAhead):
                self._report_jump_ahead(event)
            elif isinstance(event, Deferred):
                self._report_deferred(event)
            elif isinstance(event, Passage):
                self._report_passage(event)
            elif isinstance(event, Undecided):
                self._report_undecided(event)
            elif isinstance(event, MotionEnded):
                self._report_motion_ended(event)
        if jumped:
            self._publish_statuses()

    def _report_motion_ended(self, ended):
        self._incidents.counters[f'trajectories_{ended.state}'] += 1
        text = f'joint_trajectory {ended.number} {ended.state}: {ended.text}'
        if ended.state == ABORTED:
            self._logger.warning(text)
        else:
            self._logger.info(text)
        self._publish_motion()

    def _report_jump(self, jump):
        self._incidents.counters['jumps_total'] += 1
        m = self._names[jump.module]
        msg = conv.jump_status(name=f'{self._node_name}: {m} jump',
                               hardware_id=self._hardware_id, modules=self._names, jump=jump)
        self._jumps_pub.publish(msg)
        what = 'jump' if len(self._names) == 1 else 'stack jump'
        self._incidents.throttled('jump').warning(f'{m}: {what} ({jump.cause}): {msg.message}',
                                                  throttle_duration_sec=WARN_THROTTLE_SEC)

    def _report_passage(self, passage):
        """A continuous buckling is no jump (nothing on ``jumps``), but the state left a
        symmetric branch for one side: say so once, at INFO."""
        m = self._names[passage.module]
        rhos = ', '.join(f'{name} rho={p.rho:.6g}'
                         for name, p in zip(self._names, passage.modules))
        self._logger.info(f'{m}: passed a branch point continuously ({passage.cause}) at '
                          f'{rhos}: the mechanism buckled smoothly to one side, no jump')

    def _report_undecided(self, undecided):
        """A passage whose side doubles cannot decide: an ``undecided`` message on ``jumps``
        and a WARN line, counted in ``undecided_total``; no jump."""
        self._incidents.counters['undecided_total'] += 1
        m = self._names[undecided.module]
        msg = conv.undecided_status(name=f'{self._node_name}: {m} undecided',
                                    hardware_id=self._hardware_id, modules=self._names,
                                    undecided=undecided)
        self._jumps_pub.publish(msg)
        self._incidents.throttled('undecided').warning(
            f'{m}: {undecided.cause}: {msg.message}', throttle_duration_sec=WARN_THROTTLE_SEC)

    def _report_tracking_failure(self, failure):
        self._incidents.count_and_warn(
            'tracking_failures', 'tracking',
            f'{self._names[failure.module]}: tracking failed ({failure.text}); '
            f'holding the last verified equilibrium')

    def _report_deferred(self, deferred):
        self._incidents.count_and_warn(
            'commands_deferred', 'deferred',
            f'{self._names[deferred.module]}: {deferred.cause}: '
            f'{deferred.text}; holding the last verified equilibrium meanwhile')

    def _report_jump_ahead(self, warning):
        self._incidents.counters['jump_warnings'] += 1
        self._incidents.throttled('jump_ahead').warning(
            f'{self._names[warning.module]}: {warning.cause} to rho={warning.rho!r} leaves '
            f'the stable branch at rho={warning.end.rho!r} ({warning.end.kind}): the '
            f'mechanism will jump there', throttle_duration_sec=WARN_THROTTLE_SEC)
