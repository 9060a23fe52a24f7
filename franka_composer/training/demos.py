"""Demonstrations in the replay buffer before learning (`train --demos`), as Nair et al.
(2018) seed HER: the recorded episodes are added transition by transition, each episode
whole, so HER relabels their goals like the agent's own.

A dataset is any of `franka_composer.datasets`' formats: a `.npz` file, a Minari dataset
folder (the one holding `data/`), or an RLDS folder (holding `metadata.riegeli`). It must
be whole (`episodes.record`) and say it was recorded with the task and controller being
trained and sparse rewards (npz files written before they recorded it are refused), and
its episodes must fit the task (the same observation shapes). They are kept:
a run whose buffer cannot hold them and every step it will take is refused, since SB3's
buffer would otherwise overwrite them first.
"""

from __future__ import annotations

import pathlib

import numpy as np

from franka_composer.adapters.goal_env import ENV_ARGUMENTS
from franka_composer.adapters.registration import ENV_IDS, other_version, split_version
from franka_composer.controllers import CONTROL_VERSIONS, DEFAULT_CONTROL
from franka_composer.episodes import OBSERVATION_KEYS, Trajectories, check_episodes
from franka_composer.tasks import TASK_CONFIGS
from franka_composer.tasks.options import OPTIONS, readable_options
from franka_composer.tasks.rewards import reward_from_distance
from franka_composer.validation import check_path
from franka_composer.wording import counted


def load_episodes(path, env) -> list[dict[str, np.ndarray]]:
    """The episodes of the dataset at `path` as goal-dict arrays (observation keys with one
    more row than `action`, `reward`, `terminated`, `truncated`, `is_success`), checked
    whole (`episodes.record`), as recorded with `env`'s task and controller and sparse
    rewards, and against its observation space: anything else is a ValueError naming the
    file and what is wrong."""
    path = check_path("a dataset's path", path)
    mode = env.unwrapped.task.config.observations.mode
    if mode != "state":
        raise ValueError(f"{path}: demonstrations go into a buffer of state observations, "
                         f"and this env observes observation_mode {mode!r}: load them for "
                         "an env of observation_mode 'state'")
    if not path.exists():
        raise ValueError(f"{path} does not exist")
    if path.is_file() and path.suffix == ".npz":
        episodes, recorded = _npz_episodes(path, env)
    elif (path / "metadata.riegeli").is_file():
        episodes, recorded = _rlds_episodes(path, env)
    elif (path / "data").is_dir() or (path / "metadata.json").is_file():
        episodes, recorded = _minari_episodes(path, env)
    else:
        inside = sorted(found.parent.parent for found in path.glob("**/data/metadata.json"))
        hint = (f"; it holds the Minari dataset(s) {', '.join(map(str, inside))}: give one "
                "of them" if inside and path.is_dir() else "")
        raise ValueError(f"{path} is not a dataset: expected a .npz file, a Minari dataset "
                         f"folder (holding data/) or an RLDS folder (holding "
                         f"metadata.riegeli){hint}")
    check_episodes(path, episodes)
    _check_episode_limit(path, recorded, episodes)
    spaces = env.observation_space.spaces
    for key in OBSERVATION_KEYS:
        if key not in episodes[0]:
            raise ValueError(f"{path} holds no {key}: recorded in a pixel observation mode? "
                             "Demonstrations go into the buffer as state observations")
        shape = episodes[0][key].shape[1:]
        if shape != spaces[key].shape:
            raise ValueError(f"{path} holds {key} of shape {shape}, but this task's is "
                             f"{spaces[key].shape}: demonstrations of another task?")
    _check_actions(path, episodes, env.action_space)
    _check_sparse_rewards(path, episodes)
    _check_rewards_are_the_tasks(path, episodes, env)
    return episodes


def _check_recorded_as_trained(path, recorded: dict, env, format: str) -> None:
    """The transitions go into the buffer as they are, so they must be of the task and the
    controller being trained, with the sparse rewards training uses: `recorded`, what the
    dataset says it was recorded with, is checked before its observations are read as the
    task's."""
    config = env.unwrapped.task.config
    control = config.control.kind
    unsaid = [key for key in ("task", "control", "reward_type") if key not in recorded]
    if unsaid:
        again = (f"--out {path}" if format == "npz"
                 else f"--format {format} --out NEW_FOLDER")
        raise ValueError(f"{path} does not say which {', '.join(unsaid)} it was recorded "
                         f"with, so it cannot be checked against this run ({_UNSAID[format]}):"
                         f" record it again, e.g. franka-composer rollout --task "
                         f"{config.name} --control {control} {again}")
    _check_id_agrees(path, recorded)
    if recorded["task"] != config.name:
        raise ValueError(f"{path} holds demonstrations of {recorded['task']}, not "
                         f"{config.name}")
    if recorded["control"] != control:
        raise ValueError(f"{path} was recorded through {recorded['control']} control, and "
                         f"this run trains through {control}: its actions would mean other "
                         "motions")
    if recorded["reward_type"] != "sparse":
        raise ValueError(f"{path} was recorded with {recorded['reward_type']} rewards, not "
                         f"the sparse {_SPARSE.tolist()} that training uses")
    if "id" not in recorded and CONTROL_VERSIONS[control]:
        raise ValueError(f"{path} names no id, so it was recorded before {control} control's "
                         f"ids went to version {CONTROL_VERSIONS[control]}, whose dynamics "
                         "changed (the task's version history): its transitions are of the "
                         "dynamics before; record it again")
    mode = _recorded_options(path, recorded).get("observation_mode")
    if mode == "pixels":
        raise ValueError(f"{path} was recorded with observation_mode 'pixels' and holds no "
                         "state observations: demonstrations go into the buffer as state "
                         "observations (record them with observation_mode 'state' or "
                         "'state+pixels')")
    recorded_dynamics = _dynamics(_recorded_config(path, recorded))
    if recorded_dynamics != _dynamics(config):
        raise ValueError(f"{path} was recorded at {recorded_dynamics}, and this run trains at "
                         f"{_dynamics(config)}: its transitions are of other dynamics")
    _check_same_transitions(path, recorded, config)


def _check_id_agrees(path, recorded: dict) -> None:
    """The id a dataset names is registered, and fixes what its task, control and reward
    type say (a plain id takes any control): the two disagree only in a file edited by
    hand, and which to believe cannot be told."""
    if "id" not in recorded:
        return
    if not isinstance(recorded["id"], str):
        raise ValueError(f"{path} says it was recorded under the id {recorded['id']!r}, which "
                         "is not an env id (damaged metadata?)")
    if recorded["id"] not in ENV_IDS:
        raise _not_registered(path, recorded["id"])
    fixed = ENV_IDS[recorded["id"]]
    said = {"task": recorded["task"], "control": recorded["control"],
            "reward_type": recorded["reward_type"]}
    contradicted = [f"{key}={value!r}" for key, value in said.items()
                    if value != getattr(fixed, key)
                    and not (key == "control" and fixed.control == DEFAULT_CONTROL)]
    if contradicted:
        raise ValueError(f"{path} names the id {recorded['id']!r}, which fixes task="
                         f"{fixed.task!r}, control={fixed.control!r} and reward_type="
                         f"{fixed.reward_type!r}, but says it was recorded with "
                         f"{', '.join(contradicted)}: its metadata contradicts itself")


def _check_episode_limit(path, recorded: dict, episodes: list[dict]) -> None:
    """No episode runs past the steps at which the dataset says its episodes were cut
    (`max_episode_steps`; datasets from before it was kept say nothing), and one that was
    cut (truncated) was cut there: a truncation elsewhere would have the critic bootstrap
    where the recording did not stop."""
    limit = recorded.get("max_episode_steps")
    if limit is None:
        return
    if (isinstance(limit, (bool, np.bool_)) or not isinstance(limit, (int, np.integer))
            or limit < 1):
        raise ValueError(f"{path} says its episodes were cut at max_episode_steps="
                         f"{limit!r}, which is not a number of steps (damaged metadata?)")
    said = f"the dataset says its episodes were cut at max_episode_steps={limit}"
    for index, episode in enumerate(episodes):
        steps = len(episode["action"])
        if steps > limit:
            raise ValueError(f"{path}: episode {index} has {steps} steps, and {said}: "
                             "edited, or its metadata damaged?")
        if bool(episode["truncated"][-1]) and steps != limit:
            raise ValueError(f"{path}: episode {index} is truncated after {steps} steps, "
                             f"and {said}: edited, its metadata damaged, or the physics "
                             "diverged there (recorded before datasets refused such "
                             "episodes)?")


#: The task options, besides the timing's and damping's (`_dynamics`), that change what a
#: step does, what it is rewarded or whether it ends: a dataset recorded with others holds
#: transitions of another MDP (its actions other motions, its successes others).
_TRANSITION_OPTIONS = ("object_mass", "object_friction", "block_half_size", "puck_radius",
                       "puck_half_height", "floor_friction", "actuated_gripper",
                       "max_tcp_step", "max_joint_step", "max_finger_step",
                       "guard_ignores_carried", "physics",
                       "distance_threshold", "terminate_on_success", "randomization")


def _check_same_transitions(path, recorded: dict, config) -> None:
    """A ValueError naming the first of `_TRANSITION_OPTIONS` the dataset was recorded with
    otherwise than this run's `config` sets it (compared as the metadata keeps options,
    `readable_options`; one it does not name was the task's own)."""
    given = _recorded_options(path, recorded)
    own = TASK_CONFIGS[config.name]
    for name in _TRANSITION_OPTIONS:
        option = OPTIONS[name]
        if not option.applies_to(config):
            continue
        ours = readable_options({name: option.get(config)})[name]
        # (A Minari env spec keeps them as given: read the same way.)
        theirs = readable_options({name: given.get(name, option.get(own))})[name]
        if theirs != ours:
            raise ValueError(f"{path} was recorded with {name}={theirs!r}, and this run "
                             f"trains with {name}={ours!r}: its transitions are of another "
                             "task (other motions, rewards or ends)")


#: Why a dataset of each format may not say what it was recorded with.
_UNSAID = {"npz": "an npz written before franka_composer recorded them?",
           "minari": "a Minari dataset without its env spec?",
           "rlds": "an RLDS dataset written without franka_composer's metadata?"}


#: The task options that say how long a step is and what it does (`tasks.options.TIMINGS`),
#: and how the objects move under it.
_DYNAMICS_OPTIONS = ("timing", "control_timestep", "velocity_timestep", "weld_time_constant",
                     "object_damping")


def _recorded_config(path, recorded: dict):
    """The task's config with the dynamics options the dataset was recorded with
    (`_recorded_options`); none given is the task's own, as every dataset recorded before
    they existed had."""
    given = _recorded_options(path, recorded)
    dynamics = {name: given[name] for name in _DYNAMICS_OPTIONS if given.get(name) is not None}
    try:
        return TASK_CONFIGS[recorded["task"]].replace(control=recorded["control"], **dynamics)
    except ValueError as error:
        raise ValueError(f"{path} says it was recorded with options {dynamics}, which are not "
                         f"valid: {error}") from None


def _recorded_options(path, recorded: dict) -> dict:
    """The task options the dataset was recorded with (under "options" in npz and RLDS
    metadata, and as `_recorded_by_spec` reads a Minari env spec; none in an npz from before
    they were recorded, which was recorded with the task's own). A name that is no option of
    this version's is refused: what it did to the transitions cannot be checked."""
    given = recorded.get("options") or {}
    if not isinstance(given, dict):
        raise ValueError(f"{path} says it was recorded with the options {given!r}, which "
                         "are not a mapping of option names to values (damaged metadata?)")
    unknown = sorted(set(given) - {*OPTIONS, "timing", *_ENV_ARGUMENTS}, key=repr)
    if unknown:
        raise ValueError(f"{path} says it was recorded with {', '.join(map(repr, unknown))}, "
                         "which this version of franka_composer has no task option of (a "
                         "later release's, or damaged metadata?): whether its transitions "
                         "are this run's task cannot be checked")
    return given


def _dynamics(config) -> str:
    """The timing in words, the weld only under mocap (the other controllers have none),
    and the objects' damping where they are damped."""
    words = (f"{config.control_timestep:g} s per step, velocities per "
             f"{config.velocity_period:g} s")
    if config.control.has_weld:
        words += f", weld {config.control.weld_time_constant:g} s"
    damped = sorted({spec.joint_damping for spec in config.objects} - {0.0})
    if damped:
        words += f", objects damped {', '.join(f'{value:g}' for value in damped)}"
    return words


#: The rewards training uses: -1 until the goal is reached, 0 there.
_SPARSE = np.unique(reward_from_distance(np.array([0.0, np.inf]), "sparse", 1.0))


def _check_actions(path, episodes: list[dict], space) -> None:
    """The actions must be ones the env takes: of its shape, within its bounds (the buffer
    would otherwise teach the critic actions the actor can never take)."""
    for index, episode in enumerate(episodes):
        actions = np.asarray(episode["action"])
        if actions.shape[1:] != space.shape:
            raise ValueError(f"{path} holds action of shape {actions.shape[1:]} (episode "
                             f"{index}), but this task's is {space.shape}: demonstrations "
                             "of another task or controller?")
        if not (np.isfinite(actions).all() and (actions >= space.low).all()
                and (actions <= space.high).all()):
            raise ValueError(f"{path} holds actions outside the action space "
                             f"[{space.low.min():g}, {space.high.max():g}] (episode {index}: "
                             f"{actions.min():g} to {actions.max():g})")


def _check_sparse_rewards(path, episodes: list[dict]) -> None:
    for index, episode in enumerate(episodes):
        if not np.isin(episode["reward"], _SPARSE).all():
            raise ValueError(f"{path} holds rewards other than the sparse {_SPARSE.tolist()} "
                             f"that training uses (episode {index}; recorded with "
                             "--reward-type dense?)")


def _check_rewards_are_the_tasks(path, episodes: list[dict], env) -> None:
    """Each stored reward is the one this run's task gives the step's goals (HER recomputes
    them so): a dataset recorded with another success threshold, say, would put successes
    the run's task does not count into the buffer. So is each `is_success` flag (the
    sparse reward's 0), which the buffer's infos and success rates read."""
    for index, episode in enumerate(episodes):
        rewards = env.unwrapped.compute_reward(episode["achieved_goal"][1:],
                                               episode["desired_goal"][1:], None)
        wrong = np.flatnonzero(rewards != episode["reward"])
        if wrong.size:
            step = int(wrong[0])
            raise ValueError(
                f"{path} holds rewards this task does not give its goals (episode {index}, "
                f"step {step}: {episode['reward'][step]:g} stored, {rewards[step]:g} from the "
                "goals): recorded with another distance_threshold or reward?")
        wrong = np.flatnonzero(episode["is_success"] != (rewards == 0.0))
        if wrong.size:
            step = int(wrong[0])
            raise ValueError(
                f"{path} holds is_success flags its goals do not give (episode {index}, step "
                f"{step}: {bool(episode['is_success'][step])} stored, "
                f"{bool(rewards[step] == 0.0)} from the goals): edited?")
        wrong = np.flatnonzero(np.asarray(episode["terminated"], dtype=bool) & (rewards != 0.0))
        if wrong.size:  # The task's episodes end before their time only at the goal.
            raise ValueError(
                f"{path} holds a termination where the goal was not reached (episode {index}, "
                f"step {int(wrong[0])}): only the goal ends an episode before its time limit, "
                "and the critic would learn that the state is worth nothing more: edited?")


def _npz_episodes(path: pathlib.Path, env) -> tuple[list[dict], dict]:
    """The episodes and what the file says they were recorded with."""
    trajectories = Trajectories.load(path)
    _check_recorded_as_trained(path, trajectories.metadata, env, "npz")
    return trajectories.episodes, trajectories.metadata


def _minari_episodes(path: pathlib.Path, env) -> tuple[list[dict], dict]:
    """The episodes, once the dataset's env spec says they are of this task, and what it
    says."""
    import minari

    from franka_composer.datasets import minari_format

    data = path / "data" if (path / "data").is_dir() else path
    minari_format.check_files(path, data)
    try:
        dataset = minari.MinariDataset(data)
        env_spec = dataset.spec.env_spec
    except Exception as error:  # h5py, json and Minari raise what they meet.
        raise minari_format.unreadable(path, error) from None
    if env_spec is not None and env_spec.id not in ENV_IDS:
        raise _not_registered(path, env_spec.id)
    recorded = _recorded_by_spec(env_spec)
    _check_recorded_as_trained(path, recorded, env, "minari")
    # Before any array is read: a damaged header would have it allocate what it declares.
    minari_format.check_declared_sizes(path, data)
    minari_format.check_digests(path, data)
    stored = _stored_minari_episodes(data)
    if dataset.total_episodes > stored:  # Minari would look for episodes that are not there.
        raise ValueError(f"{path}'s metadata.json counts "
                         f"{counted(dataset.total_episodes, 'episode')}, and its data holds "
                         f"{stored}: an append cut short, or hand-edited?")
    try:
        episodes = [{**{key: np.asarray(episode.observations[key]) for key in OBSERVATION_KEYS},
                     "action": np.asarray(episode.actions, dtype=np.float32),
                     "reward": np.asarray(episode.rewards, dtype=np.float64),
                     # The flags as stored: `check_episodes` refuses any but true and false.
                     "terminated": np.asarray(episode.terminations),
                     "truncated": np.asarray(episode.truncations),
                     "is_success": np.asarray(episode.infos["is_success"][1:])}
                    for episode in dataset.iterate_episodes()]
    except Exception as error:
        raise minari_format.unreadable(path, error) from None
    steps = sum(len(episode["action"]) for episode in episodes)
    if (dataset.total_episodes, dataset.total_steps) != (stored, steps):
        # Minari reads as many episodes as metadata.json counts: the others were dropped.
        raise ValueError(f"{path}'s metadata.json counts "
                         f"{counted(dataset.total_episodes, 'episode')} of "
                         f"{counted(dataset.total_steps, 'step')} in all, and its data holds "
                         f"{stored} (the first {len(episodes)}: {counted(steps, 'step')}): an "
                         "append cut short, or hand-edited?")
    return episodes, recorded


def _stored_minari_episodes(data: pathlib.Path) -> int:
    """How many episodes a Minari dataset's data holds: in its hdf5 file (the groups
    episode_0, ...; what `record` writes) or, in Minari's arrow format, its episode
    folders (0/, 1/, ...)."""
    from franka_composer.datasets.minari_format import HDF5_FILE, episode_groups

    if not (data / HDF5_FILE).is_file():
        return sum(path.is_dir() and path.name.isdigit() for path in data.iterdir())
    import h5py

    with h5py.File(data / HDF5_FILE, "r") as file:
        return len(episode_groups(file))


def _recorded_by_spec(env_spec) -> dict:
    """What a Minari dataset's env spec says its env was: its id, what the id fixes (the
    plain ids' mocap control among it), the options it was made with, and its
    `max_episode_steps` where that alone cut episodes (an env made with a `time_limit` of
    its own may have cut them sooner)."""
    if env_spec is None:
        return {}
    registered = ENV_IDS.get(env_spec.id)
    kwargs = env_spec.kwargs
    limit = env_spec.max_episode_steps if kwargs.get("time_limit") is None else None
    said = {name: kwargs[name] for name in ("task", "reward_type", "control") if name in kwargs}
    return {"id": env_spec.id, **(registered._asdict() if registered else {}), **said,
            "options": {name: value for name, value in kwargs.items()
                        if name not in _ENV_ARGUMENTS},
            "max_episode_steps": limit}


#: The arguments of an env beside its task options: `FrankaGoalEnv`'s own and `load`'s
#: `time_limit` (`ENV_ARGUMENTS`), and the `registered_id` that 0.4.0's ids passed. A Minari
#: env spec holds them beside the options, and 0.3.0's datasets kept those given to
#: `gym.make` among them.
_ENV_ARGUMENTS = (*ENV_ARGUMENTS, "registered_id")


def _not_registered(path, recorded_id: str) -> ValueError:
    """A dataset recorded under an id this version does not register: an older version of
    one (dynamics since changed), or none of franka_composer's."""
    registered = other_version(recorded_id)
    if registered is None:
        return ValueError(f"{path} was recorded under {recorded_id}, not a franka_composer id")
    if split_version(recorded_id)[1] > split_version(registered)[1]:
        return ValueError(f"{path} was recorded under {recorded_id}, a newer version than "
                          f"this franka_composer's {registered}: by a later release, whose "
                          "dynamics this one does not have; train with that release")
    return ValueError(f"{path} was recorded under {recorded_id}, an older version of "
                      f"{registered}: its transitions are of dynamics since changed (the "
                      "task's version history); record it again")


def _rlds_episodes(path: pathlib.Path, env) -> tuple[list[dict], dict]:
    """The episodes, once the dataset's metadata says they are of this task (its
    observations are read as this task's), and what it says."""
    from franka_composer.datasets import rlds_format

    adapter = env.unwrapped
    task, episodes = adapter.task, []
    dataset = rlds_format.read(path)
    recorded = dict(dataset["metadata"] or {})
    _check_recorded_as_trained(path, recorded, env, "rlds")
    for episode in dataset["episodes"]:
        observations = [adapter.goal_observation(o) for o in episode["observations"]]
        steps = len(episode["actions"])
        goals = {key: np.array([o[key] for o in observations]) for key in OBSERVATION_KEYS}
        success = task.is_success(goals["achieved_goal"][1:], goals["desired_goal"][1:])
        # The LAST step's discount: 0 where the episode ended on the goal, 1 at the time
        # limit (a truncation, from which the critic bootstraps).
        end = np.arange(steps) == steps - 1
        episodes.append({**goals, "action": np.array(episode["actions"], dtype=np.float32),
                         "reward": np.array(episode["rewards"], dtype=np.float64),
                         "terminated": end & episode["terminated"],
                         "truncated": end & (not episode["terminated"]),
                         "is_success": np.asarray(success, dtype=bool)})
    return episodes, recorded


def record_expert(path: pathlib.Path, config) -> pathlib.Path:
    """Records `config.expert_demos` episodes of its task's scripted expert in the run's
    own environment (controller, dynamics, termination, randomisation), so that they are
    transitions the run could have collected, to `path` (an npz, written whole; seeded
    from `RunConfig.expert_demo_seed`); returns `path`."""
    from franka_composer.datasets import record
    from franka_composer.atomic_files import replace_atomically

    options = {name: value for name, value in (
        *config.dynamics_options.items(),
        ("terminate_on_success", config.terminate_on_success),
        ("randomization", config.randomization)) if value is not None}
    replace_atomically(path, lambda temporary: record(
        config.task, config.expert_demos, temporary, seed=config.expert_demo_seed,
        control=config.control, **options))
    return path


def transitions(task: str, expert_demos: int | None, dataset, demo_episodes: int | None,
                env_options: dict) -> int:
    """How many transitions a run's demonstrations put in its replay buffer: the expert's
    `expert_demos` episodes at most (each as long as the task's horizon), or the first
    `demo_episodes` of `dataset`, loaded (and so checked) in an env made with
    `env_options`; 0 without either. One count for a run's start and its resumes."""
    if expert_demos is not None:
        return expert_demos * TASK_CONFIGS[task].max_episode_steps
    if dataset is None:
        return 0
    from franka_composer.training.models import make_env

    env = make_env(task, **env_options)
    try:
        episodes = load_episodes(dataset, env)
    finally:
        env.close()
    if demo_episodes is not None and demo_episodes > len(episodes):
        raise ValueError(f"--demo-episodes {demo_episodes}, but {dataset} holds "
                         f"{counted(len(episodes), 'episode')}")
    return int(sum(len(episode["action"]) for episode in episodes[:demo_episodes]))


def check_capacity(episodes: list[dict], buffer_size: int, total_steps: int) -> int:
    """How many transitions `episodes` hold; a ValueError if a buffer of `buffer_size`
    cannot keep them through `total_steps` steps of training."""
    transitions = int(sum(len(e["action"]) for e in episodes))
    check_room(transitions, buffer_size, total_steps)
    return transitions


def check_room(transitions: int, buffer_size: int, total_steps: int) -> None:
    """A ValueError if a buffer of `buffer_size` cannot keep `transitions` of
    demonstrations through `total_steps` steps of training (SB3's buffer would overwrite
    them first)."""
    if transitions + total_steps > buffer_size:
        raise ValueError(f"the replay buffer holds {buffer_size} transitions: {transitions} "
                         f"of demonstrations and {total_steps} steps would overwrite "
                         f"demonstrations; raise --buffer-size or take fewer episodes "
                         "(--demo-episodes, --expert-demos)")


def prefill(model, episodes: list[dict], total_steps: int) -> int:
    """Adds `episodes` to `model`'s replay buffer, transition by transition; returns how many
    (`check_capacity` first)."""
    buffer = model.replay_buffer
    transitions = check_capacity(episodes, buffer.buffer_size, total_steps)
    for episode in episodes:
        for t in range(len(episode["action"])):
            obs = {key: episode[key][t][None] for key in OBSERVATION_KEYS}
            next_obs = {key: episode[key][t + 1][None] for key in OBSERVATION_KEYS}
            terminated, truncated = bool(episode["terminated"][t]), bool(episode["truncated"][t])
            buffer.add(obs, next_obs, episode["action"][t][None],
                       np.array([episode["reward"][t]]), np.array([terminated or truncated]),
                       [{"is_success": bool(episode["is_success"][t]),
                         "TimeLimit.truncated": truncated and not terminated}])
    return transitions
