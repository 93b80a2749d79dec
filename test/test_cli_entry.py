"""The ``tensegrity`` console script's entry point: a Ctrl-C while the tool imports (about a
second) ends it with one line and status 130, as a Ctrl-C later does."""
from importlib import metadata
import subprocess
import sys
import textwrap

from installed import installed_script

from tensegrity_ros import cli_entry

#: Runs the entry point with a Ctrl-C arriving while ``tensegrity_ros.cli`` is imported (an
#: import hook raises it there: what the interpreter does when SIGINT lands in the import).
INTERRUPTED_IMPORT = textwrap.dedent("""
    import sys

    class CtrlC:
        def find_spec(self, name, path=None, target=None):
            if name == 'tensegrity_ros.cli':
                raise KeyboardInterrupt
            return None

    sys.meta_path.insert(0, CtrlC())
    from tensegrity_ros import cli_entry
    sys.exit(cli_entry.main(['range', '--rho', '0.5']))
""")


def test_a_ctrl_c_while_the_tool_imports_ends_it_with_one_line():
    done = subprocess.run([sys.executable, '-c', INTERRUPTED_IMPORT], capture_output=True,
                          text=True, timeout=120)
    assert (done.returncode, done.stderr) == (130, 'tensegrity: interrupted\n'), done.stderr


def test_the_entry_point_runs_the_tool(capsys):
    assert cli_entry.main(['range', '--help']) == 0
    assert 'usage: tensegrity range' in capsys.readouterr().out


def test_the_installed_console_script_starts_at_the_entry_point():
    """pip writes the module into the script; colcon's (setuptools') script looks the
    entry point up in the installed metadata: the two ways a user's ``tensegrity`` starts."""
    script = installed_script('tensegrity').read_text()
    (entry,) = metadata.entry_points(group='console_scripts', name='tensegrity')
    assert entry.value == 'tensegrity_ros.cli_entry:main', entry
    assert 'tensegrity_ros.cli_entry' in script or 'load_entry_point' in script, script
