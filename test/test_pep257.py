# Copyright 2015 Open Source Robotics Foundation, Inc.
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.
"""ament_pep257, as the ament_python template ships it.

Two changes: the paths are the package's own (not a .venv or a build tree under the
current directory), and the docstring *form* codes are added to ament's ignore list:
D205/D400/D415 (a one-line summary ending in a period, then a blank line), D213/D209 (the
summary on the second line, the closing quotes on their own), D401-D403 (an imperative,
capitalised first word), D301 (a raw docstring for a backslash).  The project's ~900
multi-line docstrings open with a summary that may run over two lines; everything else
pep257 checks (whitespace, quotes, indentation, blank lines) is checked.
"""
from pathlib import Path

from ament_pep257.main import main
import pytest

ROOT = Path(__file__).resolve().parents[1]
PATHS = [str(ROOT / p) for p in ('tensegrity_ros', 'test', 'launch', 'benchmarks', 'setup.py')]
FORM = ['D205', 'D209', 'D213', 'D301', 'D400', 'D401', 'D402', 'D403', 'D415']


@pytest.mark.linter
@pytest.mark.pep257
def test_pep257():
    rc = main(argv=['--add-ignore', *FORM, '--'] + PATHS)
    assert rc == 0, 'Found code style errors / warnings'
