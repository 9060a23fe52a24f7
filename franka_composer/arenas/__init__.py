"""The worlds the robot works in."""

from franka_composer.arenas.floor import FloorArena

__all__ = ["FloorArena"]
