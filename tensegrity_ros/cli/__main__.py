"""``python -m tensegrity_ros.cli``: the ``tensegrity`` command line."""
import sys

from . import main

sys.exit(main())
