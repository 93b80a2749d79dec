"""Deprecated alias of :mod:`tensegrity_ros.core.simulation.events` (0.3)."""
from .moved_modules import alias

alias(__name__)
