"""What the node counts in ``/diagnostics`` and logs, throttled: refused input, failures.

Every callback of the node runs guarded (:meth:`Incidents.guard`): an unexpected exception
is logged and counted, never raised into the executor.  Refused input (a bad message, a
parameter set refused) is dropped and counted per reason; the events that raise the node
status to WARN or ERROR are remembered until the next ``/diagnostics`` report takes them.
"""
from __future__ import annotations

import traceback

import rclpy.logging

from tensegrity_ros.log_text import clipped

#: Rejected input and failures are logged at most once per this many seconds per reason.
WARN_THROTTLE_SEC = 2.0

#: Reasons counted in ``/diagnostics`` (``rejected_<reason>``).
REJECT_REASONS = (
    'non_finite',            # NaN or inf in a command
    'out_of_range',          # rho outside [rho_min, rho_max]
    'size_mismatch',         # JointState/JointTrajectory: no names, sizes that differ
    'unknown_joint',         # JointState/JointTrajectory: not a commandable <m>_rho
    'duplicate_joint',       # JointState/JointTrajectory: the same joint twice
    'trajectory_time',       # JointTrajectory: time_from_start < 0 or not increasing
    'parameter_type',        # parameter set with the wrong type
    'parameter_read_only',   # parameter set on a read-only parameter
    'parameter_undeclared',  # parameter set on a name the node does not have
    'parameter_delete',      # parameter delete (every parameter is declared, typed)
    'parameter_value',       # parameter value refused (range, physics, limits)
)
#: Trajectory outcomes counted in ``/diagnostics`` (``trajectories_<state>``).
TRAJECTORY_COUNTERS = ('trajectories_accepted', 'trajectories_succeeded',
                       'trajectories_aborted', 'trajectories_canceled')


class Incidents:
    """The node's counters (``/diagnostics`` values) and its throttled WARN and ERROR lines.

    ``logger`` is the node's logger, ``context`` its rclpy context (a callback that fails
    because the context was shut down under it, by Ctrl-C, reports nothing).
    """

    def __init__(self, logger, context):
        self.counters = {f'rejected_{r}': 0 for r in REJECT_REASONS}
        self.counters.update(commands_processed=0, commands_coalesced=0,
                             callback_exceptions=0, jump_warnings=0,
                             tracking_failures=0, jumps_total=0, commands_deferred=0,
                             undecided_total=0)
        self.counters.update(dict.fromkeys(TRAJECTORY_COUNTERS, 0))
        self._level_events = set()          # what happened since the last /diagnostics
        self._logger = logger
        self._context = context
        self._loggers = {}

    def take_level_events(self):
        """What raised the node status since the last call (``exception``, ``rejected``,
        ``tracking``, ``deferred``, ``behind``), forgotten for the next report."""
        events, self._level_events = self._level_events, set()
        return events

    def guard(self, callback, what):
        """Wrap a ROS callback: an unexpected exception is logged and counted, never raised."""
        def guarded(*args):
            try:
                return callback(*args)
            except Exception as exc:
                if not self._context.ok():  # shut down under it (Ctrl-C): nothing to report
                    return None
                self.exception(what, exc)
        return guarded

    def exception(self, what, exc):
        """Count an unexpected exception, raise the node status to ERROR, log it throttled."""
        self.counters['callback_exceptions'] += 1
        self._level_events.add('exception')
        self.throttled('exception').error(clipped(
            f'{what}: unexpected {type(exc).__name__}: {exc} (state unchanged; '
            f'{self.counters["callback_exceptions"]} so far)'),
            throttle_duration_sec=WARN_THROTTLE_SEC)
        self._logger.debug(traceback.format_exc())

    def throttled(self, key):
        """A logger of the node's name with its own throttle state (one per reason)."""
        logger = self._loggers.get(key)
        if logger is None:
            logger = self._loggers[key] = rclpy.logging.get_logger(self._logger.name)
        return logger

    def reject(self, reason, text):
        """Count refused input under ``rejected_<reason>`` and log it throttled; None."""
        key = f'rejected_{reason}'
        self.counters[key] += 1
        self._level_events.add('rejected')
        self.throttled(reason).warning(
            clipped(f'{text}: dropped ({key} = {self.counters[key]})'),
            throttle_duration_sec=WARN_THROTTLE_SEC)

    def count_and_warn(self, counter, event, text):
        """Count an event in diagnostics, raise the node status to WARN, log it throttled."""
        self.counters[counter] += 1
        self._level_events.add(event)
        self.throttled(event).warning(text, throttle_duration_sec=WARN_THROTTLE_SEC)
