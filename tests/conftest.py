"""Test set-up: Menagerie from ../shared/menagerie when offline, one thread. Headless GL is
left to the package (EGL, loaded at the first frame), so the tests run the users' default."""

from __future__ import annotations

import functools
import importlib.util
import os
import pathlib
import re
import sys
import warnings

_REPO = pathlib.Path(__file__).resolve().parents[1]
_SHARED_MENAGERIE = _REPO.parent / "shared" / "menagerie"
if "MENAGERIE_ROOT" not in os.environ and _SHARED_MENAGERIE.is_dir():
    os.environ["MENAGERIE_ROOT"] = str(_SHARED_MENAGERIE)
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402
import pytest  # noqa: E402

import franka_composer  # noqa: E402
import franka_composer.tasks  # noqa: E402
from franka_composer import fast_path  # noqa: E402


#: SPEC.md's numbers per task: observation, action and goal sizes, episode length, how
#: goals are compared and the success threshold; `version`, the ids' suffix where not 0
#: (flip's goals changed in v1; stack's guard in v1, carried blocks part of the hand).
SPEC = {
    "push": dict(observation=18, action=3, goal=3, steps=50, metric="euclidean", threshold=0.05),
    "slide": dict(observation=18, action=3, goal=3, steps=50, metric="euclidean",
                  threshold=0.05),
    "pick_and_place": dict(observation=19, action=4, goal=3, steps=50, metric="euclidean",
                           threshold=0.05),
    "reach": dict(observation=6, action=3, goal=3, steps=50, metric="euclidean",
                  threshold=0.05),
    "stack": dict(observation=31, action=4, goal=6, steps=100, metric="euclidean",
                  threshold=0.1, version=1),
    "flip": dict(observation=20, action=4, goal=4, steps=100, metric="rotation_angle",
                 threshold=0.2, version=1),
}
#: The tasks with objects (all but reach).
OBJECT_TASKS = tuple(t for t in franka_composer.ALL_TASKS
                     if franka_composer.tasks.TASK_CONFIGS[t].objects)


@pytest.fixture(autouse=True, scope="session")
def _sb3_logs_in_pytests_folder(tmp_path_factory):
    """SB3 models the tests build themselves log into pytest's folder, not into an
    SB3-<time> folder per learn() in the system's temporary directory."""
    os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3-logs"))


@pytest.fixture
def ctrl_c_reaches_the_process():
    """Ctrl-C as a terminal gives it, with Python's handler: a test run in the background
    of a shell without job control (CI's) has SIGINT ignored."""
    import signal

    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, before)


@pytest.fixture(params=franka_composer.ALL_TASKS)
def task_name(request) -> str:
    """Every registered task: a new task is tested the day it is added."""
    return request.param


@pytest.fixture(params=OBJECT_TASKS)
def object_task_name(request) -> str:
    """Every task with an object to move."""
    return request.param


def spec_distance(task: str, achieved, desired) -> np.ndarray:
    """SPEC's goal distance, written out here independently of the package."""
    achieved, desired = np.asarray(achieved), np.asarray(desired)
    if SPEC[task]["metric"] == "rotation_angle":
        return 2 * np.arccos(np.minimum(np.abs(np.sum(achieved * desired, axis=-1)), 1.0))
    return np.linalg.norm(achieved - desired, axis=-1)


def check_reward_contract(env_name: str, **options) -> None:
    """Over random play of the Gymnasium id `env_name` (made with `options`): each step's
    reward is `compute_reward`'s, success is the distance within the success radius, a
    sparse reward is 0 exactly on success, and only the time limit ends an episode. First
    at the id's own radius, where random play rarely succeeds (flip's episodes start
    solved), then, on the same play (the radius changes no dynamics), at a radius halfway
    between the nearest and the farthest distance it met, so that both outcomes occur."""
    distances = [distance for distance, _ in _play_checking_rewards(env_name, None, options)]
    halfway = (min(distances) + max(distances)) / 2
    successes = [success for _, success in _play_checking_rewards(env_name, halfway, options)]
    assert any(successes) and not all(successes)


def _play_checking_rewards(env_name: str, radius: float | None, options: dict) -> list:
    """`check_reward_contract`'s checks at one radius (None: the id's); each step's
    (distance, success)."""
    import gymnasium as gym

    task = franka_composer.ENV_IDS[env_name].task
    if radius is not None:
        options = {**options, "distance_threshold": radius}
    env = gym.make(env_name, terminate_on_success=False, **options)
    radius = SPEC[task]["threshold"] if radius is None else radius
    env.reset(seed=1)
    env.action_space.seed(1)
    steps, ends = [], []
    for _ in range(SPEC[task]["steps"] + 10):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        expected = env.unwrapped.compute_reward(obs["achieved_goal"], obs["desired_goal"], info)
        assert reward == expected and type(reward) is type(expected[()])
        distance = spec_distance(task, obs["achieved_goal"], obs["desired_goal"])
        assert info["is_success"] == (distance < radius)
        if "Sparse" in env_name:
            assert reward in (0.0, -1.0) and (reward == 0.0) == info["is_success"]
        else:
            assert reward == pytest.approx(-distance, abs=1e-12)
        assert not terminated
        steps.append((distance, info["is_success"]))
        ends.append(truncated)
        if truncated:
            env.reset()
    env.close()
    limit = SPEC[task]["steps"]
    assert ends[:limit] == [False] * (limit - 1) + [True]  # TimeLimit truncates on time.
    return steps


def near_goal_pairs(task: str, rng, count: int):
    """(achieved, desired) goal pairs, some within the task's threshold and some not."""
    size = SPEC[task]["goal"]
    if SPEC[task]["metric"] == "rotation_angle":
        achieved = rng.normal(size=(count, 4))
        achieved /= np.linalg.norm(achieved, axis=1, keepdims=True)
        desired = achieved + rng.normal(0, 0.08, (count, 4))
        desired /= np.linalg.norm(desired, axis=1, keepdims=True)
        desired[::3] *= -1  # q and -q: the same orientation.
        return achieved, desired
    achieved = rng.uniform(0.4, 0.8, (count, size))
    return achieved, achieved + rng.normal(0, 0.04 * np.sqrt(3 / size) * SPEC[task]["threshold"]
                                           / 0.05, (count, size))


def batches_substeps(env) -> bool:
    """Whether the dm_env environment `env` steps on the fast path, one MuJoCo call per
    control step (where it falls back, a fast-against-stock comparison compares stock with
    stock)."""
    return type(env) is fast_path.FastEnvironment and env._batch_substeps


@pytest.fixture(params=["fast", "stock"])
def composer_path(request, monkeypatch) -> str:
    """Runs a test on the fast path and on Composer's stock stepping (modules that use it:
    `pytestmark = pytest.mark.usefixtures("composer_path")`). On the fast path it checks
    that the path was taken: every environment `load` built is a FastEnvironment, and of
    the steps taken some batched their substeps (a silent fall back to stock stepping
    would compare stock with stock)."""
    monkeypatch.setenv(fast_path.ENV_VARIABLE, "1" if request.param == "fast" else "0")
    if request.param == "stock":
        yield request.param
        return
    import franka_composer.suite

    built, steps, make, step = [], [], franka_composer.suite.make_environment, \
        fast_path.FastEnvironment.step

    def making(*args, **kwargs):
        built.append(make(*args, **kwargs))
        return built[-1]

    def stepping(env, action):
        steps.append(not env._reset_next_step and getattr(env, "_batch_substeps", False))
        return step(env, action)

    monkeypatch.setattr(franka_composer.suite, "make_environment", making)
    monkeypatch.setattr(fast_path.FastEnvironment, "step", stepping)
    yield request.param
    assert [type(env).__name__ for env in built
            if type(env) is not fast_path.FastEnvironment] == []
    assert not steps or any(steps), "the fast path fell back to stock stepping"


def hand_tilt_degrees(env) -> float:
    """Angle (degrees) between the hand's approach axis and straight down; `env` a dm_env
    of this suite or a Gymnasium env of it."""
    env = getattr(getattr(env, "unwrapped", env), "composer_env", env)
    axis = env.physics.bind(env.task.panda.tcp_site).xmat.reshape(3, 3)[:, 2]
    return float(np.degrees(np.arccos(np.clip(-axis[2], -1, 1))))


@functools.lru_cache
def controller_press():
    """`experiments/controller_press.py`, whose press the contact tests run."""
    return load_script(pathlib.Path(__file__).resolve().parents[1] / "experiments"
                       / "controller_press.py")


def cartesian_action(env, move, gripper=None) -> np.ndarray:
    """`experiments/controller_press.py`'s action that moves the tool centre point by `move`
    (m) under any controller, the gripper (where actuated) at `gripper` (None: 0)."""
    return controller_press().cartesian_action(env, move, 0.0 if gripper is None else gripper)


def move_tcp_to(env, timestep, target, gripper=None, max_steps=30, tolerance=0.004):
    """`experiments/controller_press.py`'s drive of the tool centre point to `target` (any
    controller), the gripper (where actuated) at `gripper` (None: 0); returns the last
    timestep. Used by physical tests that need the hand somewhere first."""
    return controller_press().move_tcp_to(env, timestep, target,
                                          0.0 if gripper is None else gripper,
                                          steps=max_steps, tolerance=tolerance)


def grasp_block(env):
    """Resets `env` (pick and place) and grasps its block; returns the last timestep."""
    timestep = env.reset()
    block = timestep.observation["block/position"].copy()
    timestep = move_tcp_to(env, timestep, block + [0, 0, 0.08], gripper=1)
    timestep = move_tcp_to(env, timestep, block, gripper=1)
    for _ in range(4):
        timestep = env.step(np.array([0, 0, 0, -1], np.float32))
    return timestep


def contact_frictions(env, first, second) -> list[float]:
    """The sliding friction of each contact between the MJCF geoms `first` and `second` of
    the dm_env `env` now, as MuJoCo holds it in the contact (both sliding components)."""
    physics = env.physics
    pair = {int(physics.bind(first).element_id), int(physics.bind(second).element_id)}
    frictions = []
    for contact in physics.data.contact[:physics.data.ncon]:
        if {int(contact.geom1), int(contact.geom2)} == pair:
            assert contact.friction[0] == contact.friction[1]
            frictions.append(float(contact.friction[0]))
    return frictions


def her_samples(env, steps: int, count: int = 512):
    """(next achieved goals, desired goals, rewards) of `count` transitions SB3's
    `HerReplayBuffer` relabels ("future", 4 goals per transition) after `steps` random steps
    of `env`: what HER trains on."""
    from stable_baselines3 import SAC, HerReplayBuffer

    model = SAC("MultiInputPolicy", env, replay_buffer_class=HerReplayBuffer,
                replay_buffer_kwargs=dict(n_sampled_goal=4, goal_selection_strategy="future"),
                learning_starts=10_000, buffer_size=1000, seed=0,
                policy_kwargs=dict(net_arch=[8]), device="cpu")
    model.learn(total_timesteps=steps)  # Random actions only.
    samples = model.replay_buffer.sample(count)
    return (samples.next_observations["achieved_goal"].numpy(),
            samples.observations["desired_goal"].numpy(),
            samples.rewards.numpy().squeeze(-1))


#: The pages whose commands a reader copies: the README, RESULTS.md, BENCHMARKS.md, the docs
#: site's pages and the notes beside the committed results.
COMMAND_PAGES = (_REPO / "README.md", _REPO / "RESULTS.md", _REPO / "BENCHMARKS.md",
                 *sorted((_REPO / "docs").rglob("*.md")),
                 *sorted((_REPO / "results").rglob("*.md")))


def documented_commands(program: str) -> list[tuple[str, str, list[str], bool]]:
    """Each command of `program` (a regular expression: the program and how it is called)
    that `COMMAND_PAGES` give in code: a fenced block's lines (joined at a trailing
    backslash), an inline code span (joined where the text wraps it) or an HTML comment.
    (the page's repository path, the program as written, the words after it up to a
    comment or a pipe, and whether it starts its line or span: after a prompt, `&&`, `nice`,
    variables set for it or a folder, not inside prose.)"""
    command = re.compile(r"(?:^|(?<=[\s/(]))(" + program + r")(?=\s|$)([^\n|;&#`]*)",
                         re.MULTILINE)
    begins = re.compile(r"\s*(?:\$ |.*&& |<!-- |nice -n \d+ |(?:[A-Z_]+=(?:<[^>]*>|\S+) )+)?"
                        r"(?:\S*/)?")
    fence = re.compile(r"^```[^\n]*\n(.*?)^```", re.DOTALL | re.MULTILINE)
    found = []
    for page in COMMAND_PAGES:
        text = page.read_text()
        prose = fence.sub("", text)
        pieces = [re.sub(r"\\\n\s*", " ", block) for block in fence.findall(text)]
        pieces += [span.replace("\n", " ") for span in
                   re.findall(r"`((?:[^`\n]|\n(?!\n))+)`", prose)]
        pieces += ["<!-- " + note.strip().replace("\n", " ")
                   for note in re.findall(r"<!--(.*?)-->", prose, re.DOTALL)]
        for piece in pieces:
            for match in command.finditer(piece):
                line = piece[piece.rfind("\n", 0, match.start()) + 1:match.start()]
                found.append((page.relative_to(_REPO).as_posix(), match.group(1),
                              match.group(2).split(), bool(begins.fullmatch(line))))
    return found


def doc_option(word: str) -> str | None:
    """The long option a command's word gives (`--seed`, `[--seed`, `--seed=3`), or None."""
    option = word.strip("[]").split("=", 1)[0]
    return option if re.fullmatch(r"--[a-z][\w-]*", option) else None


def load_script(path: pathlib.Path):
    """A script of the repository (benchmarks/, experiments/, tools/: not packages) as a
    module, registered under its name, where its dataclasses look their module up."""
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


#: What Gymnasium's env checker says of every env of this suite: that its state observations
#: are unbounded (positions and velocities, as Fetch's).
UNBOUNDED_OBSERVATIONS = {
    "\x1b[33mWARN: A Box observation space minimum value is -infinity. This is probably "
    "too low.\x1b[0m",
    "\x1b[33mWARN: A Box observation space maximum value is infinity. This is probably "
    "too high.\x1b[0m"}


def env_checker_findings(env, sb3: bool = False) -> set[str]:
    """What Gymnasium's env checker (and SB3's, with `sb3`) reports of `env`: they report
    most findings as warnings, not errors."""
    from gymnasium.utils.env_checker import check_env

    with warnings.catch_warnings(record=True) as found:
        warnings.simplefilter("always")
        check_env(env.unwrapped, skip_render_check=True)
        if sb3:
            from stable_baselines3.common.env_checker import check_env as sb3_check_env

            sb3_check_env(env.unwrapped, warn=True)
    return {str(warning.message) for warning in found}



def write_policy_file(path: pathlib.Path, size: int) -> None:
    """A policy file as franka_composer writes one (`read_policy_file` reads it whole), of
    an actor of `size` parameters: what a finished run keeps."""
    import torch

    from franka_composer.training.policy_file import FORMAT

    torch.save({"actor": {"weight": torch.ones(size)}, "steps": 2000, "format": FORMAT,
                "backend": "sb3"}, path)
