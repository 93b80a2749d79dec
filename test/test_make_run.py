"""``make run`` on a terminal: Ctrl-C stops the node and make returns the node's status, 0.

README's quick start promises it. The test runs make on a pseudo-terminal (Ctrl-C is the
terminal's SIGINT to its foreground job) with this interpreter as the node's Python and a
fresh set-up stamp, so it needs no .venv and runs the same in a colcon workspace.
"""
import os
from pathlib import Path
import pty
import select
import shutil
import signal
import sys
import time

import pytest

ROOT = Path(__file__).resolve().parents[1]
TIMEOUT = float(os.environ.get('TENSEGRITY_TEST_TIMEOUT', '30'))
READY = b'stable, margin'           # the node's start-up log line


def read_until(fd, buffer, marker, timeout):
    """Read the terminal into ``buffer`` until ``marker`` shows or it closes; True if seen."""
    deadline = time.monotonic() + timeout
    while marker not in buffer and time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.2)
        if ready:
            try:
                chunk = os.read(fd, 4096)
            except OSError:             # the terminal closed: make is gone
                return marker in buffer
            if not chunk:
                return marker in buffer
            buffer += chunk
    return marker in buffer


def reaped(pid, timeout):
    """Wait status of child ``pid`` once it has exited, None if it still runs after ``timeout``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            return status
        time.sleep(0.05)            # polling a process exit: there is no event to wait on
    return None


@pytest.mark.ros
def test_ctrl_c_on_make_run_exits_zero(tmp_path):
    make = shutil.which('make')
    assert make, 'make is not installed'
    stamp = tmp_path / 'installed'
    stamp.touch()                   # newer than requirements.txt and setup.py: no set-up
    assert os.environ.get('ROS_AUTOMATIC_DISCOVERY_RANGE') == 'LOCALHOST'
    pid, fd = pty.fork()
    if pid == 0:                    # child: make on the pseudo-terminal
        try:
            signal.signal(signal.SIGINT, signal.SIG_DFL)   # as a shell starts it, even when
            os.chdir(ROOT)                                  # this test runs with SIGINT ignored
            os.execv(make, [make, '--no-print-directory', 'run', f'PY={sys.executable}',
                            f'STAMP={stamp}'])
        finally:
            os._exit(127)
    output = bytearray()
    status = None
    try:
        assert read_until(fd, output, READY, TIMEOUT), output.decode(errors='replace')
        os.write(fd, b'\x03')       # Ctrl-C
        read_until(fd, output, b'\x00never', TIMEOUT)   # until make closes the terminal
        status = reaped(pid, TIMEOUT)
    finally:
        if status is None:          # make still running: end it and the node (its session)
            os.killpg(pid, 9)
            os.waitpid(pid, 0)
        os.close(fd)
    text = output.decode(errors='replace')
    assert status is not None, f'make run still running after Ctrl-C:\n{text}'
    assert os.waitstatus_to_exitcode(status) == 0, text
    assert 'Interrupt' not in text and 'Traceback' not in text, text
