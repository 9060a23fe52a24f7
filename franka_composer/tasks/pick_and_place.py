"""Pick and place: grasp a light block and carry it to a goal, in the air 70 % of the time."""

from franka_composer.tasks.config import PhysicsSettings, TaskConfig

# Grasping is held by the finger contacts (friction 2, condim 4, 10 N squeeze: see
# entities/panda.py). Measured over a 0.15 m lift and 0.1 m carry, impratio 1, 3 and 10 all
# keep the block within 3 mm of the tool centre point, so the cheaper default stays; noslip
# (~30 % more per step) is not needed.
PHYSICS = PhysicsSettings(noslip_iterations=0, impratio=1.0)

PICK_AND_PLACE = TaskConfig(
    prop_kind="block",
    object_size=(0.02,),
    object_mass=0.1,
    object_friction=1.0,
    floor_friction=1.0,
    actuated_gripper=True,
    goal_centre=(0.6, 0.0),
    goal_max_height=0.2,
    goal_in_air_probability=0.7,
    physics=PHYSICS,
)
