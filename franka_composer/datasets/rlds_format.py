"""RLDS datasets through `envlogger` wrapped around the Composer (dm_env) environment, as
acme-style agents log them; `envlogger.Reader` reads them without TensorFlow.

Every step holds the dm_env timestep (the Composer observation dict: the state vector's
observables, the task's `achieved_goal` and `goal`, images in the pixel modes; reward,
discount, step type) and the action; each episode's metadata holds its reset seed, the
dataset's metadata the task, its options and who acted. Every episode ends with the
environment's LAST step: discount 0 where the goal was reached (`terminate_on_success`),
1 at the time limit.

envlogger: 1.3 needs glibc >= 2.38 and protobuf < 7 (dm_control's tested set has 7), so the
extra takes 1.2, whose wheels run here with protobuf 7; 1.2 still names `np.unicode_`
(removed in NumPy 2) when it encodes arrays, which `import_envlogger()` restores as
`np.str_`: import envlogger through it to log with `envlogger.EnvLogger` yourself.
"""

from __future__ import annotations

import json
import logging
import os
import pathlib

import numpy as np

from franka_composer import seeding
from franka_composer.atomic_files import replace_atomically, sha256
from franka_composer.datasets.folders import removed_if_it_fails
from franka_composer.environment import ended_by_divergence
from franka_composer.episodes import check_not_diverged
from franka_composer.policies.rollout import episode_limit
from franka_composer.signals import held
from franka_composer.validation import check_path


def import_envlogger():
    """envlogger, with the one NumPy 1 name it uses put back under NumPy 2 (imported
    plainly, its `EnvLogger` fails on the first step: np.unicode_ was removed), and its
    C++ writer's informational log lines off ("Empty steps, nothing to do", three to a
    recording, on stderr): glog reads `GLOG_minloglevel` as its library loads, so it is
    set for the import only, where the user has not set it. Imported with Ctrl-C and
    SIGTERM held (`held`): stopped inside its extensions' import, a rollout failed with an
    ImportError ("initialization failed") and a traceback, not as a stop."""
    if "unicode_" not in np.__dict__:
        np.unicode_ = np.str_  # What NumPy 1 had under that name.
    quiet = "GLOG_minloglevel" not in os.environ
    if quiet:
        os.environ["GLOG_minloglevel"] = "1"  # Warnings and errors.
    try:
        with held():
            import envlogger
    finally:
        if quiet:
            del os.environ["GLOG_minloglevel"]
    return envlogger


def write(env, policy, episodes: int, seed: int, root: pathlib.Path, metadata: dict) -> dict:
    """Records `episodes` episodes of `policy` (acting on goal observations) in the Composer
    environment under the Gymnasium `env`, episode i reset with seed + i and run to its
    LAST step, into the RLDS directory `root`, with its files' digests (`add_digests`);
    returns its size and success rate."""
    envlogger = import_envlogger()
    adapter = env.unwrapped
    composer_env, task = adapter.composer_env, adapter.task
    # Through gym.make the episode length is TimeLimit's, which the dm_env logged here does
    # not see: it gets that length (the shorter, where it has one of its own).
    limit = episode_limit(env)
    if limit is not None and limit != composer_env.episode_steps:
        composer_env.set_episode_steps(limit)
    episode: dict[str, int | None] = {"seed": None}
    steps = successes = 0
    # A recording cut short is no dataset: nothing of it is left behind, in a folder it made
    # or in the empty one it was given (`record` takes no other).
    with removed_if_it_fails(root):
        with envlogger.EnvLogger(
                composer_env, data_directory=str(root), metadata=metadata,
                episode_fn=lambda timestep, action, env: dict(episode)) as logged:
            for index in range(episodes):
                episode["seed"] = seed + index
                if hasattr(policy, "reset"):
                    policy.reset()
                seeding.reseed(composer_env.random_state, seed + index)  # As reset(seed=...).
                timestep = logged.reset()
                while not timestep.last():
                    timestep = logged.step(
                        policy(adapter.goal_observation(timestep.observation)))
                    steps += 1
                if ended_by_divergence(timestep, task):
                    check_not_diverged([index])
                successes += bool(task.success)
        add_digests(root)  # Of its files as closed.
    return {"episodes": episodes, "steps": steps, "success_rate": successes / episodes}


#: The file beside an RLDS dataset's own that `write` keeps the SHA-256 of each of them in.
#: A changed byte was refused by envlogger's riegeli reader, but as whatever it met next,
#: never naming the file ("TypeError: expected bytes, NoneType found"; one in an episode
#: index read as no episodes at all).
DIGESTS_FILE = "franka_composer_sha256.json"


def add_digests(root: pathlib.Path) -> None:
    """Writes `DIGESTS_FILE` in `root`: every file of the dataset by its path there, with
    its SHA-256."""
    digests = {str(path.relative_to(root)): sha256(path)
               for path in sorted(root.rglob("*.riegeli"))}
    replace_atomically(root / DIGESTS_FILE,
                       lambda partial: partial.write_text(json.dumps(digests, indent=1)))


def check_digests(root: pathlib.Path) -> None:
    """A ValueError naming the first file of the dataset under `root` that is not what
    `write` recorded: changed, missing, or a riegeli file it did not write. A dataset
    without `DIGESTS_FILE` passes (logged by envlogger itself, or by a version that wrote
    none)."""
    listing = root / DIGESTS_FILE
    if not listing.exists():
        return
    if not listing.is_file():
        raise ValueError(f"{listing} is not a file: it should list the SHA-256 of each file "
                         "of the dataset (damaged?)")
    try:
        digests = json.loads(listing.read_text())
        if not (isinstance(digests, dict)
                and all(isinstance(digest, str) for digest in digests.values())):
            raise ValueError("not a mapping of file names to digests")
    except (ValueError, UnicodeDecodeError) as error:
        raise ValueError(f"{listing} is damaged ({error}): it should list the SHA-256 of "
                         "each file of the dataset") from None
    for name, digest in digests.items():
        path = root / name
        if not path.is_file():
            raise ValueError(f"{path} is missing: {DIGESTS_FILE} lists it as part of the "
                             "dataset (damaged, or not copied whole?)")
        if sha256(path) != digest:
            raise ValueError(f"{path} is not what was recorded: its SHA-256 differs from "
                             f"the one {DIGESTS_FILE} keeps (damaged or edited since?): "
                             "record the dataset again")
    for path in sorted(root.rglob("*.riegeli")):
        if str(path.relative_to(root)) not in digests:
            raise ValueError(f"{path} was not part of the recording ({DIGESTS_FILE} does "
                             "not list it): envlogger would read its episodes as the "
                             "dataset's")


def read(root: pathlib.Path) -> dict:
    """The dataset under `root`: its metadata, and per episode its seed, observations (the
    reset's first), actions, rewards and whether it ended on the goal (`terminated`: its
    LAST step's discount is 0) rather than at the time limit (discount 1). A file that is
    not what `write` recorded (`check_digests`) is a ValueError naming it; a dataset
    envlogger cannot read, that holds no episodes (its step files emptied or cut short
    read as none), or an episode that is not one FIRST step, MID steps and one LAST step
    (its index files cut short join or split episodes), is a ValueError naming `root`."""
    root = check_path("an RLDS dataset's folder", root)
    envlogger = import_envlogger()
    from envlogger.backends.riegeli_backend_reader import RiegeliBackendReader

    if not root.is_dir():
        raise ValueError(f"{root} does not exist" if not root.exists()
                         else f"{root} is a file, and an RLDS dataset is a folder")
    check_digests(root)
    logged = _LoggedErrors()
    absl_logger = logging.getLogger("absl")
    absl_logger.addFilter(logged)
    try:
        # The backend first: a Reader whose backend fails to open is left without one,
        # and says so again (AttributeError) when it is collected.
        backend = RiegeliBackendReader(data_directory=str(root))
        with envlogger.Reader(backend=backend) as reader:
            metadata = reader.metadata()
            read_episodes = [(list(steps), info) for steps, info in
                             zip(reader.episodes, reader.episode_metadata())]
        if logged.errors:  # It read on past a damaged file.
            raise RuntimeError(logged.errors[0])
    except Exception as error:  # envlogger's riegeli reader raises what it meets.
        said = logged.errors[0] if logged.errors else f"{type(error).__name__}: {error}"
        raise ValueError(f"{root} is not a readable RLDS dataset (damaged?): envlogger "
                         f"says {(said.splitlines() or [''])[0]}") from None
    finally:
        absl_logger.removeFilter(logged)
    if not read_episodes:
        raise ValueError(f"{root} holds no episodes (its step files empty or damaged?)")
    if isinstance(metadata, dict) and metadata.get("options", {}) is None:
        metadata["options"] = {}  # The task's own options: envlogger keeps {} as None.
    episodes = []
    for index, (steps, info) in enumerate(read_episodes):
        _check_episode(root, index, [step.timestep for step in steps])
        episodes.append({
            "seed": _episode_seed(root, index, info),
            "observations": [step.timestep.observation for step in steps],
            "actions": [step.action for step in steps[1:]],
            "rewards": [step.timestep.reward for step in steps[1:]],
            "terminated": bool(steps[-1].timestep.discount == 0),
        })
    return {"metadata": metadata, "episodes": episodes}


class _LoggedErrors(logging.Filter):
    """Keeps the errors envlogger logs (through absl), instead of printing them: opening a
    dataset with an emptied or cut step index, it logs the error that names the file
    ("NOT_FOUND: Empty steps in .../step_offsets.riegeli") under a banner saying the env
    was not closed, reads on, and fails on something else ("expected bytes, NoneType
    found")."""

    def __init__(self) -> None:
        super().__init__()
        self.errors: list[str] = []

    def filter(self, record: logging.LogRecord) -> bool:
        if record.levelno < logging.ERROR:
            return True
        error = record.exc_info[1] if record.exc_info else None
        self.errors.append(str(error) if error is not None else record.getMessage())
        return False


def _episode_seed(root: pathlib.Path, index: int, info) -> int:
    """The seed `write` keeps in each episode's metadata; a ValueError naming `root` where
    there is none (a dataset logged by envlogger without this package's `write`, or its
    episode metadata file damaged: envlogger then reads None)."""
    seed = info.get("seed") if isinstance(info, dict) else None
    if isinstance(seed, (bool, np.bool_)) or not isinstance(seed, (int, np.integer)):
        raise ValueError(f"{root}: episode {index} has no seed in its episode metadata "
                         f"(found {info!r}): a dataset this package's rlds writer did not "
                         "write, or its episode_metadata file damaged?")
    return int(seed)


def _check_episode(root: pathlib.Path, index: int, timesteps: list) -> None:
    """A ValueError naming `root` unless the episode is whole: a FIRST step, MID steps, a
    LAST step."""
    whole = (len(timesteps) >= 2 and timesteps[0].first() and timesteps[-1].last()
             and all(timestep.mid() for timestep in timesteps[1:-1]))
    if not whole:
        raise ValueError(f"{root}: episode {index} is not whole (a FIRST step, then steps, "
                         "then a LAST one; damaged, or a recording cut short?)")
