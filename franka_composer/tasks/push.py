"""Push (the paper's): a block along the floor to a goal on the floor, gripper locked."""

from franka_composer.tasks.config import TaskConfig

# Everything else is TaskConfig's default: a 4 cm block (1 kg, friction 1) on a floor of
# friction 1, object and goal in the 0.3 m square at (0.6, 0). Block-on-floor contacts need
# no slip correction, so noslip stays off (it costs ~30 % per step).
PUSH = TaskConfig(
    name="push",
    description="Push a 4 cm, 1 kg block along the floor to a goal on the floor, with the "
                "fingers locked closed: the hand must get behind the block and push it.",
)
