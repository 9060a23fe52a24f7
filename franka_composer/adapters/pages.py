"""Each task's documentation page, generated from its configuration (one place per fact).

It is the docstring of the task's Gymnasium class (`help(FrankaPushEnv)`, or
`gym.spec("FrankaPushSparse-v0")` then the class), laid out as Gymnasium-Robotics documents
`FetchPush`: description, action and observation spaces, rewards, starting state, episode
end, arguments, version history.
"""

from __future__ import annotations

import textwrap

from franka_composer.arenas.floor import CAMERAS, RENDER_SIZE
from franka_composer.tasks.config import TaskConfig
from franka_composer.tasks.layout import layout_for
from franka_composer.tasks.options import OPTIONS, TIMINGS, read_with, unread_option
from franka_composer.tasks.records import (REFERENCE_CODE_OBJECT_DAMPING,
                                           REFERENCE_OBJECT_DAMPING)

#: Line width of the page.
WIDTH = 88
#: What each version changed, newest last (an id's version is bumped when its task's
#: dynamics, initial state, goals or reward change: docs/guide/quickstart.md, "Ids and their
#: versions"); a task whose goals changed adds its lines (`TaskConfig.version_history`).
VERSION_HISTORY = (
    "v0: this implementation of the paper's tasks on the Menagerie Panda, with contacts "
    "that hold when the hand presses under mocap and osc (objects cannot be pressed into "
    "the floor or launched), seeds of any size through np.random.SeedSequence, and three "
    "controllers (mocap, osc, joints).",
)
#: What each controller's version bump changed (`controllers.CONTROL_VERSIONS`), newest last,
#: after the task's own history on its page.
CONTROL_VERSION_HISTORY = (
    "Joints ids one version up from the task's (v1; flip's v2; stack's v2 since its own v1), "
    "0.4.0: the surface guard acts "
    "under joints as well, raising the servo targets near surfaces and braking a "
    "descending hand (a press in joint space had lifted objects 13 mm and shoved them up "
    "to 38 cm: docs/guide/controllers.md).",
)


def _reference_differences(config: TaskConfig) -> str:
    """What differs from the reference code's task at both timings; for a task it lacks,
    from its tasks (the arm, the guard, contacts and solver are theirs all the same)."""
    differences = ["Menagerie's Panda (no arm servos holding the neutral pose, other finger "
                   "pads)"]
    if config.control.actuated_gripper:
        differences.append("the fingers open at reset (closed there)")
    differences += ["the guard that keeps the hand's target out of surfaces",
                    "the contact parameters", "the solver's settings (an elliptic friction "
                    "cone here, a pyramidal one there)"]
    if config.objects and config.object_orientation == "euler":
        differences.append("the Euler angles of the observation's object orientation (x-y-z "
                           "extrinsic here, intrinsic there)")
    damped_there = REFERENCE_CODE_OBJECT_DAMPING.get(config.name, REFERENCE_OBJECT_DAMPING)
    if config.objects and damped_there and not config.objects[0].joint_damping:
        joints, them = (("the object's free joint", "it") if len(config.objects) == 1 else
                        ("the objects' free joints", "them"))
        differences.append(
            f"{joints}, undamped here where the reference code's block's is damped, which "
            f"keeps {them} from tipping over when pushed "
            f"(object_damping={REFERENCE_OBJECT_DAMPING:g} damps {them} so)")
    where = ("what differs from the reference code at both is"
             if config.name in REFERENCE_CODE_OBJECT_DAMPING else
             f"the reference code has no {config.name} task, and what differs from its tasks "
             "at both is")
    return f"{where} {', '.join(differences[:-1])} and {differences[-1]}."


def page(config: TaskConfig, ids: tuple[str, ...]) -> str:
    """The documentation page of the task `config` describes, registered as `ids`."""
    layout = layout_for(config)
    control = config.control
    max_episode_steps = config.max_episode_steps
    gripper = (f"The last (the 4th; under joints the 8th) moves the fingers' target opening "
               f"by up to {control.max_finger_step:g} m (-1 and +1 set it fully closed and "
               "fully open in one step; the fingers follow it)." if control.actuated_gripper
               else "The fingers are locked closed.")
    goals, start, unit = _goal_words(config)
    # `timing` names a set of the options below (or none of its names, when they were set
    # one by one).
    timing = (f"timing = {config.timing_name!r}" if config.timing_name else
              "# timing: none of its names (control_timestep, velocity_timestep and "
              "weld_time_constant, below, were set otherwise)")
    options = [timing] + option_lines(config)
    cameras = " | ".join(f'"{name}"' for name in CAMERAS)
    default, reference = TIMINGS["default"], TIMINGS["reference"]
    sections = [
        ("Action space", [
            "Box(-1, 1, (n,), float32), by controller (the control option; the ids with Osc "
            "or Joints in their names fix it). "
            f"mocap (the default, n = {3 + int(control.actuated_gripper)}): the first three "
            f"components move the tool centre point's target by up to "
            f"{control.max_tcp_step:g} m per step along x, y, z; a mocap weld drags the hand "
            "there, held top-down, and the target never runs into the surface beneath the "
            "hand beyond a press the arm's joint torques allow. "
            f"osc (n = {3 + int(control.actuated_gripper)}): the same target; joint torques "
            "within the real Panda's limits (87 N m on joints 1-4, 12 N m on 5-7) from an "
            "operational-space law move the hand towards it, held top-down. "
            f"joints (n = {7 + int(control.actuated_gripper)}): the first seven components "
            f"move each arm joint's servo target by up to {control.max_joint_step:g} rad from "
            "its present angle, and the observation ends with the seven joint angles "
            f"(rad). {gripper}"]),
        ("Observation space", [
            f"Dict(observation=Box({layout.size},), achieved_goal=Box({_goal_size(config)},), "
            f"desired_goal=Box({_goal_size(config)},)), float64. {goals} `observation`, "
            f"velocities multiplied by {config.velocity_period:g} s (as Fetch's velp * dt):",
            layout.markdown_table()]),
        ("Rewards", [
            f"sparse: 0 if the achieved goal is within {config.distance_threshold:g} {unit} of "
            f"the desired goal, else -1. dense: minus that distance ({unit}). "
            "env.unwrapped.compute_reward(achieved, "
            "desired, info) gives the same reward for any batch of goals (HER); "
            'info["is_success"] is the success.']),
        ("Starting state", [
            f"The arm at its neutral pose {tuple(config.neutral_arm_qpos)}; {start} "
            "reset(seed=s) takes any non-negative int."]),
        ("Episode end", [
            f"Truncated after {max_episode_steps} steps: Gymnasium's TimeLimit "
            "(gym.make(id, max_episode_steps=N) sets another length), the dm_env "
            "environment's time limit under franka_composer.load (a LAST step with discount "
            "1); truncated "
            "too if the physics diverges (with a warning and info[\"diverged\"]). Terminated "
            "on success when terminate_on_success is True (the paper's default; False gives "
            "Fetch semantics, for which HER relabelling is exact)."]),
        ("Timing", [
            f"{config.control_timestep:g} s of physics per step "
            f"({round(config.control_timestep / config.physics.timestep)} MuJoCo steps of "
            f"{config.physics.timestep * 1000:g} ms); velocities multiplied by "
            f"{config.velocity_period:g} s. The paper's reference code (panda_mujoco_gym) "
            "runs 0.5 s of physics per step (ten mj_step calls of 25 steps) while its dt "
            "says 0.05 s, so each action lands with the arm at rest: timing=\"reference\" "
            f"reproduces it ({reference['control_timestep']:g} s per step, velocities "
            f"multiplied by {reference['velocity_timestep']:g} s, and the reference code's "
            f"weld, time constant {reference['weld_time_constant']:g} s, which moves the "
            "hand about as fast as the reference's); timing=\"default\" is "
            f"{default['control_timestep']:g} s with velocities multiplied by the period and "
            f"a stiffer weld ({default['weld_time_constant']:g} s) that tracks within the "
            "step. The action "
            "law and the observation layout are those above at either timing; "
            + _reference_differences(config)]),
        ("Arguments", [
            f'gym.make(id, render_mode=None | "rgb_array" | "human", width={RENDER_SIZE}, '
            f'height={RENDER_SIZE}, camera={cameras}, **options) '
            "(width, height and camera with a render mode only); the options, with this "
            "task's values:",
            "\n".join(options)]),
        ("Version history", [*VERSION_HISTORY, *config.version_history,
                             *CONTROL_VERSION_HISTORY]),
    ]
    lines = [textwrap.fill(config.description, WIDTH), "",
             textwrap.fill(f"Ids: {', '.join(ids)} (sparse and dense reward), "
                           f"max_episode_steps={max_episode_steps}; "
                           f'franka_composer.load("{config.name}") for dm_env.', WIDTH)]
    for title, paragraphs in sections:
        lines += ["", title]
        for paragraph in paragraphs:
            if "\n" in paragraph or paragraph.startswith("|"):  # Tables and lists as they are.
                lines += ["", textwrap.indent(paragraph, "    ")]
            else:
                lines += [textwrap.fill(paragraph, WIDTH, initial_indent="    ",
                                        subsequent_indent="    ")]
    return "\n".join(lines) + "\n"


def _goal_size(config: TaskConfig) -> int:
    return {"stacked": 6, "orientation": 4}.get(config.goal, 3)


def _goal_words(config: TaskConfig) -> tuple[str, str, str]:
    """What the goals are, how an episode starts, and the distance's unit, for the task's
    kind of goal (`goals.GOALS`)."""
    workspace = config.workspace
    objects = (f"the object at rest, upright, at a uniform point of the "
               f"{_square(workspace.object_box)}" if len(config.objects) == 1 else
               f"the {len(config.objects)} objects at rest, upright, at uniform points of the "
               f"{_square(workspace.object_box)}, apart from each other")
    lifted = (f"lifted uniformly in [0, {workspace.goal_max_height:g}] m"
              + ("" if workspace.goal_in_air_probability == 1 else
                 f" with probability {workspace.goal_in_air_probability:g}, else on the floor")
              if workspace.goal_max_height > 0 else "on the floor")
    if config.goal == "tcp_position":
        return ("achieved_goal is the tool centre point's position, desired_goal the goal "
                "(m, world frame).",
                f"no object; the goal's (x, y) uniform in the {_square(workspace.goal_box)}, "
                f"its height above the floor {lifted}.", "m")
    if config.goal == "stacked":
        return ("achieved_goal is both blocks' positions (block 1, then block 2), "
                "desired_goal block 1 resting on the floor at the goal and block 2 on top of "
                "it (m, world frame).",
                f"{objects}; the goal's (x, y) uniform in the {_square(workspace.goal_box)}.",
                "m")
    if config.goal == "orientation":
        settings = config.orientation_goal
        assert settings is not None  # An orientation goal's config has its settings.
        goal = ("uniformly random (orientation_goal='uniform', panda-gym's: 94 % of such "
                "goals are more than 0.2 rad from every orientation of a cube resting on a "
                "face, out of a top-down hand's reach)" if settings.kind == "uniform" else
                "one of the six faces up, drawn uniformly, turned a uniform yaw in "
                f"[-{settings.yaw_range:g}, {settings.yaw_range:g}] rad about the vertical "
                "from the heading the fewest tips give it (orientation_goal='face_up', "
                "goal_yaw_range); the start's face stays up in one goal in six, and "
                f"{_starts_solved(config):.1%} of episodes start solved, a yaw within "
                f"{config.distance_threshold:g} rad of the start's among those (what a "
                "policy that never moves the cube scores)")
        return ("achieved_goal is the cube's orientation, desired_goal the goal orientation "
                "(unit quaternions w, x, y, z; q and -q are the same orientation, and the "
                "distance is the rotation angle between them; compute_reward refuses "
                "quaternions that are not unit).",
                f"{objects}; the goal orientation {goal}.", "rad")
    return ("achieved_goal is the object's position, desired_goal the goal (m, world frame).",
            f"{objects}; the goal's (x, y) uniform in the {_square(workspace.goal_box)}, "
            f"{lifted}.", "m")


def _starts_solved(config) -> float:
    """The share of face-up goals a cube at rest, upright at a yaw of 0, already meets: the
    upright face drawn (1 in 6) at a yaw within the success angle of 0."""
    yaw_range = config.orientation_goal.yaw_range
    return (min(1.0, config.distance_threshold / yaw_range) if yaw_range > 0 else 1.0) / 6


def _square(box) -> str:
    return (f"{box.size[0]:g} x {box.size[1]:g} m square centred at "
            f"({box.centre[0]:g}, {box.centre[1]:g})")


def option_lines(config: TaskConfig) -> list[str]:
    """`name = value` for each option the task reads as configured (`TaskConfig.options`;
    not reward_type: the id fixes it), and, marked, those it reads under another setting
    (`read_with`); those no setting of the task reads are left out (reach's object_range)."""
    lines = []
    for name, option in OPTIONS.items():
        if name == "reward_type" or not option.applies_to(config):
            continue
        line = f"{name} = {option.get(config)!r}"
        if unread_option(config, name) is None:
            lines.append(line)
        elif read_with(config, name) is not None:
            lines.append(f"{line}  # read with {read_with(config, name)}")
    return lines
