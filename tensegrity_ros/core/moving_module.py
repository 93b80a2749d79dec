"""Deprecated alias of :mod:`tensegrity_ros.core.dynamics.moving_module` (0.3)."""
from .moved_modules import alias

alias(__name__)
