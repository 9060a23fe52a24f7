"""Push: slide a block along the floor to a goal on the floor, gripper locked closed."""

from franka_composer.tasks.config import PhysicsSettings, TaskConfig

# Block-on-floor contacts need no slip correction: noslip is off (it costs ~30 % per step).
PHYSICS = PhysicsSettings(noslip_iterations=0, impratio=1.0)

PUSH = TaskConfig(
    prop_kind="block",
    object_size=(0.02,),
    object_mass=1.0,
    object_friction=1.0,
    floor_friction=1.0,
    actuated_gripper=False,
    goal_centre=(0.6, 0.0),
    physics=PHYSICS,
)
