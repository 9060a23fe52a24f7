"""Things with bodies: the Panda, the props it moves, and the goal marker."""

from franka_composer.entities.goal_marker import GoalMarker
from franka_composer.entities.panda import Panda
from franka_composer.entities.props import Block, Prop, Puck

__all__ = ["Block", "GoalMarker", "Panda", "Prop", "Puck"]
