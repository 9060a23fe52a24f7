"""Slide: strike a puck across a slippery floor to a goal that is often out of reach."""

from franka_composer.tasks.config import TaskConfig
from franka_composer.tasks.records import Box2D, PuckSpec, Workspace

# Low friction on both the floor and the puck (their contact takes the smaller of the two,
# `contacts.surface_friction`; the hand's contacts take the larger, MuJoCo's rule): a struck
# puck glides. Noslip would fight the intended sliding, so it stays off (the default).
SLIDE = TaskConfig(
    name="slide",
    description="Strike a puck across a slippery floor (friction 0.04) to a goal 0.1-0.4 m "
                "beyond the object square, often out of the arm's reach: the puck must glide "
                "there. The fingers are locked closed.",
    objects=(PuckSpec(),),
    floor_friction=0.04,
    workspace=Workspace(goal_box=Box2D(centre=(1.0, 0.0))),
)
