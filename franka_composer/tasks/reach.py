"""Reach (panda-gym's): bring the tool centre point to a point in the air, no object."""

from franka_composer.tasks.config import TaskConfig
from franka_composer.tasks.records import Workspace

# The goal is uniform in the 0.3 m cube above the goal square: lifted from the surface
# with probability 1, up to 0.3 m. The fingers are locked (3 actions).
REACH = TaskConfig(
    name="reach",
    description="Move the tool centre point (between the fingertips) to a goal drawn "
                "uniformly in the 0.3 m cube above the goal square, from the floor up to "
                "0.3 m. No object; the fingers are locked closed.",
    objects=(),
    goal="tcp_position",
    workspace=Workspace(goal_max_height=0.3, goal_in_air_probability=1.0),
)
