"""The core's module paths of 0.2 that moved into concept folders in 0.3 (CHANGELOG.rst).

docs/python_api.md promised these paths; each old path stays importable for one release as
an alias of the module's new place that warns (:func:`alias`), so ``mock.patch`` and
``isinstance`` see one module, not a copy.
"""
import importlib
import sys
import warnings

#: old path -> new path, for the paths docs/python_api.md named in 0.2.
MOVED = {
    'tensegrity_ros.core.stack': 'tensegrity_ros.core.neck.stack',
    'tensegrity_ros.core.frames': 'tensegrity_ros.core.neck.frames',
    'tensegrity_ros.core.simulator': 'tensegrity_ros.core.simulation.simulator',
    'tensegrity_ros.core.events': 'tensegrity_ros.core.simulation.events',
    'tensegrity_ros.core.trajectory': 'tensegrity_ros.core.simulation.trajectory',
    'tensegrity_ros.core.neck_dynamics': 'tensegrity_ros.core.dynamics.neck_snap',
    'tensegrity_ros.core.moving_module': 'tensegrity_ros.core.dynamics.moving_module',
    'tensegrity_ros.core.moving_neck': 'tensegrity_ros.core.dynamics.moving_neck',
}


def alias(old):
    """Make the module ``old`` (being imported) its new module, with a DeprecationWarning."""
    new = MOVED[old]
    warnings.warn(f'{old} moved to {new} in tensegrity_ros 0.3; the old path goes in 0.4',
                  DeprecationWarning, stacklevel=3)
    sys.modules[old] = importlib.import_module(new)
