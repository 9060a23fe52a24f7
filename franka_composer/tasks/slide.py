"""Slide: strike a puck across a slippery floor to a goal that is often out of reach."""

from franka_composer.tasks.config import PhysicsSettings, TaskConfig

# Low friction on both the floor and the puck (MuJoCo takes the larger of the two): a struck
# puck glides. Noslip would fight the intended sliding, so it stays off.
PHYSICS = PhysicsSettings(noslip_iterations=0, impratio=1.0)

SLIDE = TaskConfig(
    prop_kind="puck",
    object_size=(0.03, 0.03),
    object_mass=1.0,
    object_friction=0.04,
    floor_friction=0.04,
    actuated_gripper=False,
    goal_centre=(1.0, 0.0),
    physics=PHYSICS,
)
