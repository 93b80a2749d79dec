"""What the node says of work that goes on over time (mixed into ``TensegrityNode``).

* ``joint_states``: the live state, stamped with the time it holds for -- in the dynamics
  mode the time the integrated state has reached, earlier than the tick while the
  simulation is behind the clock;
* the live state behind the node clock (dynamics mode), whatever the cause -- the
  integration could not reach the tick's time, or the tick came or ran late (the timer
  fired late, the process was starved): the lag in ``/diagnostics``; a tick with the
  integration behind, or the state more than a tick period late, counted in
  ``dynamics_behind_ticks``, the node status WARN, a throttled WARN line;
* a reset answered "under way": a ``reset done`` line and the new state published when
  it has settled.

The node supplies ``_sim``, ``_dynamics``, ``_js``, ``_js_pub``, ``_names``,
``_incidents``, ``_now_ns``, ``_publish_everything``,
``_describe_module`` and ``_tick_timer``.  No ROS import here: the node turns the values
into messages.
"""


class LiveStateReports:
    """Mixin: the live joint states and the reports of lag and of deferred resets."""

    def _init_live_state_reports(self):
        self._lag = 0.0                     # dynamics: the live state's lag (s) at the last tick
        self._lag_max = 0.0                 # dynamics: largest lag (s) since the last report
        self._state_ns = None               # dynamics: the state's time at the last tick
        self._reset_under_way = False       # a reset answered "under way", not yet done
        if self._dynamics:
            self._incidents.counters['dynamics_behind_ticks'] = 0

    def _publish_joint_states(self, now_ns=None):
        """Publish the live state, stamped with the time it holds for: ``now_ns`` (or now);
        in the dynamics mode the time the integration reached (earlier while it lags)."""
        js = self._js
        for i in range(len(self._names)):
            if self._dynamics:
                live = self._sim.live(i)
                js.set_module(i, live.rho, live.theta1, live.theta2, live.actuator_force)
                js.set_velocity(i, live.rho_dot, live.theta1_dot, live.theta2_dot)
            else:
                p, eq = self._sim.module(i)
                js.set_module(i, p.rho, eq.theta1, eq.theta2, eq.actuator_force)
        stamp = self._now_ns() if now_ns is None else now_ns
        if self._dynamics and self._sim.state_time_ns is not None:
            stamp = min(stamp, self._sim.state_time_ns)
        self._js_pub.publish(js.stamped(stamp))

    def _report_progress(self):
        """After a tick's simulator call: the lag (dynamics mode), a deferred reset done."""
        lag, behind = self._live_lag() if self._dynamics else (0.0, False)
        self._lag = lag
        self._lag_max = max(self._lag_max, lag)
        if behind:
            self._incidents.count_and_warn('dynamics_behind_ticks', 'behind', (
                f'dynamics: the simulation is {lag:.3f} s behind the clock (it integrates at '
                f'most {self._sim.time_budget * 1e3:g} ms per call, at ticks that come late '
                f'on a busy machine); joint_states carry the time their state holds for; '
                f'catching up'))
        if self._reset_under_way and not self._sim.pending:
            self._reset_under_way = False
            self._last_stable = None
            self._publish_everything()
            self.get_logger().info('reset done: ' + '; '.join(
                self._describe_module(i) for i in range(len(self._names))))

    def _live_lag(self):
        """(lag, behind): how far (s) the live state is behind the node clock now, beyond
        the tick period it is published at -- whatever the cause: the integration did not
        reach the tick's time (the simulator's lag), or the clock moved on more than a
        period since the last tick's state (the timer fired late, the tick's work was
        slow: a starved process).  ``behind`` if the integration is behind or the state
        is more than a whole period late (a sample missed)."""
        state_ns, previous = self._sim.state_time_ns, self._state_ns
        self._state_ns = None if self._sim.pending else state_ns   # (a reset settles)
        lag = self._sim.lag
        if state_ns is None or previous is None or self._sim.pending:
            return lag, lag > 0.0
        period = self._tick_timer.timer_period_ns
        late = (self._now_ns() - previous - period) * 1e-9
        lag = max(lag, late, 0.0)
        return lag, self._sim.lag > 0.0 or late > period * 1e-9

    def _progress_summary(self, events):
        """(message part or None, extra /diagnostics values) since the last report."""
        if not self._dynamics:
            return None, []
        part = (f'the simulation fell behind the clock (up to {self._lag_max:.3g} s)'
                if 'behind' in events else None)
        values = [('dynamics_lag', self._lag), ('dynamics_lag_max', self._lag_max)]
        self._lag_max = self._lag
        return part, values
