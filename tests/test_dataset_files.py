"""Damaged and foreign dataset files (episodes/npz_file.py, episodes/record.py,
training/demos.py): each is refused by name, saying what is wrong, before anything
trains; and recording never leaves half a dataset behind."""

from __future__ import annotations

import itertools
import json
import pathlib
import re
import zipfile

import numpy as np
import pytest
from dm_control.composer.variation import distributions

from franka_composer.cli import main
from franka_composer.datasets import record
from franka_composer.policies import Trajectories
from franka_composer.training import demos
from franka_composer.training.models import make_env


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Two-episode push datasets in each format, and others to be refused."""
    root = tmp_path_factory.mktemp("datasets")
    record("push", 2, root / "push.npz", seed=0)
    record("push", 2, root / "rlds", format="rlds", seed=0)
    record("push", 2, root / "minari", format="minari", seed=0)
    record("slide", 1, root / "slide.npz", seed=0)
    record("pick_and_place", 1, root / "pnp.npz", seed=0)
    record("push", 1, root / "osc.npz", seed=0, control="osc")
    record("reach", 1, root / "reach-rlds", format="rlds", seed=0)
    return root


@pytest.fixture(scope="module")
def push_env():
    env = make_env("push")
    yield env
    env.close()


def _copy(source, destination):
    destination.write_bytes(source.read_bytes())
    return destination


def _undigested_copy(rlds, destination):
    """A copy of the RLDS dataset `rlds` without the file digests `record` adds, as
    envlogger logs one itself: its damage is for envlogger's reader to find."""
    import shutil

    from franka_composer.datasets.rlds_format import DIGESTS_FILE

    shutil.copytree(rlds, destination)
    (destination / DIGESTS_FILE).unlink()


def _refused(path, env, message):
    with pytest.raises(ValueError, match=re.escape(message)) as error:
        demos.load_episodes(path, env)
    assert str(path) in str(error.value)
    return str(error.value)


def test_a_recorded_npz_says_what_it_was_recorded_with_and_loads_whole(recorded):
    loaded = Trajectories.load(recorded / "push.npz")
    assert len(loaded) == 2
    assert {key: loaded.metadata[key] for key in ("task", "control", "reward_type")} == {
        "task": "push", "control": "mocap", "reward_type": "sparse"}


@pytest.mark.parametrize("damage, message", [
    (lambda path: path.write_bytes(b""), "is not a readable npz file (truncated or damaged?): "
                                         "ValueError: it is empty"),
    # Not numpy's "pickled data ... load it unsafely with allow_pickle".
    (lambda path: path.write_bytes(b"garbage" * 50), "is not a readable npz file (truncated or "
                                                    "damaged?): ValueError: it is not an npz "
                                                    "(zip) archive: it begins b'garbag'"),
    (lambda path: path.write_bytes(path.read_bytes()[:2000]), "is not a readable npz file "
                                                               "(truncated or damaged?): "
                                                               "BadZipFile"),
    (lambda path: path.write_bytes(b"\x93NUMPY garbage" * 50), "is not a readable npz file"),
])
def test_a_truncated_emptied_or_garbage_npz_is_refused_by_name(recorded, push_env, tmp_path,
                                                               damage, message):
    path = _copy(recorded / "push.npz", tmp_path / "demos.npz")
    damage(path)
    _refused(path, push_env, message)


def _central_directory(content: bytes) -> dict[str, int]:
    """Each member's offset of its entry in the zip archive's central directory."""
    end = content.rindex(b"PK\x05\x06")
    offset = int.from_bytes(content[end + 16:end + 20], "little")
    entries = {}
    while content[offset:offset + 4] == b"PK\x01\x02":
        name_size, extra_size, comment_size = (
            int.from_bytes(content[offset + at:offset + at + 2], "little") for at in (28, 30, 32))
        entries[content[offset + 46:offset + 46 + name_size].decode()] = offset
        offset += 46 + name_size + extra_size + comment_size
    return entries


def _damaged_header(content: bytes, where: str) -> bytes:
    """`content` (an npz) with one field of a zip header changed, as a changed byte does."""
    content = bytearray(content)
    entries = _central_directory(bytes(content))
    names = list(entries)
    assert names[-1] == "metadata.npy"
    if where == "compression method":  # Of the first member's central directory entry.
        content[entries[names[0]] + 10] = 99
    elif where == "encryption flag":  # The same entry's.
        content[entries[names[0]] + 8] |= 1
    else:  # The comment length of the entry before metadata's: zipfile reads past it.
        content[entries[names[-2]] + 32] = 0xA0
    return bytes(content)


@pytest.mark.parametrize("where, said", [
    ("compression method", "NotImplementedError: That compression method is not supported"),
    ("encryption flag", "RuntimeError: File 'episode_length.npy' is encrypted"),
    ("directory entry", "BadZipFile: its end record counts 10 members, and its central "
                        "directory lists 9")])
def test_an_npz_whose_zip_headers_are_damaged_is_refused_by_name(recorded, push_env, tmp_path,
                                                                 where, said):
    """zipfile's NotImplementedError and RuntimeError were left to the user as they were,
    naming no file; an entry of the central directory read wrong made zipfile stop before
    metadata, and the file read as one recorded before metadata was kept."""
    path = tmp_path / "demos.npz"
    path.write_bytes(_damaged_header((recorded / "push.npz").read_bytes(), where))
    with pytest.raises(ValueError, match=re.escape(
            f"{path} is not a readable npz file (truncated or damaged?): {said}")):
        Trajectories.load(path)
    _refused(path, push_env, "is not a readable npz file")


@pytest.mark.slow
def test_every_byte_of_an_npz_changed_is_refused_by_name_or_reads_the_same(tmp_path):
    """One byte at a time, every byte of a small dataset: no other error than the one
    naming the file (numpy's tokenize.TokenError from an npy header, zipfile's
    NotImplementedError from a zip header were before), and nothing read otherwise than
    recorded (metadata lost to a damaged directory entry was before)."""
    original = tmp_path / "reach.npz"
    record("reach", 1, original, seed=0)
    recorded = Trajectories.load(original)
    content, path = original.read_bytes(), tmp_path / "changed.npz"
    refused = 0
    for position in range(len(content)):
        changed = bytearray(content)
        changed[position] ^= 0x55
        path.write_bytes(bytes(changed))
        try:
            loaded = Trajectories.load(path)
        except ValueError as error:
            assert str(path) in str(error), (position, error)
            refused += 1
            continue
        assert loaded.metadata == recorded.metadata, position
        for ours, theirs in zip(loaded.episodes, recorded.episodes, strict=True):
            assert ours.keys() == theirs.keys(), position
            for key in ours:
                np.testing.assert_array_equal(ours[key], theirs[key], err_msg=str(position))
                assert ours[key].dtype == theirs[key].dtype, (position, key)
    assert refused > len(content) / 2  # Measured: 1,658 of 2,331 bytes.


def test_a_path_that_names_no_file_is_refused_before_anything_is_read(recorded, push_env,
                                                                      tmp_path):
    """An int was taken by `open` for a file descriptor: 0 read the caller's stdin (waiting
    on a terminal), 2 closed its stderr; a FIFO's opening waits for a writer; "" was the
    working folder."""
    import os
    import signal

    from franka_composer.datasets import rlds_format

    for value, said in ((0, "got int 0"), (True, "got bool True"), (None, "got NoneType None")):
        with pytest.raises(ValueError, match=re.escape(
                f"an npz dataset's path must be a path (a str or os.PathLike), {said}")):
            Trajectories.load(value)
    with pytest.raises(ValueError, match="^an npz dataset's path is empty: give a path$"):
        Trajectories.load("")
    with pytest.raises(ValueError, match=re.escape(f"{tmp_path} is a folder, not an npz file")):
        Trajectories.load(tmp_path)
    fifo = tmp_path / "fifo.npz"
    os.mkfifo(fifo)
    previous = signal.signal(signal.SIGALRM, lambda *_: pytest.fail("waited on a FIFO"))
    signal.alarm(10)
    try:
        with pytest.raises(ValueError, match=re.escape(
                f"{fifo} is not a regular file (a device, FIFO or socket), not an npz file")):
            Trajectories.load(fifo)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    with pytest.raises(ValueError, match=re.escape(
            "a dataset's path must be a path (a str or os.PathLike), got int 2")):
        demos.load_episodes(2, push_env)
    with pytest.raises(ValueError, match="^an RLDS dataset's folder is empty: give a path$"):
        rlds_format.read("")
    with pytest.raises(ValueError, match=re.escape(
            "out must be a path (a str or os.PathLike), got int 3")):
        record("reach", 1, 3)
    os.fstat(2)  # stderr still open.


@pytest.mark.parametrize("metadata, message", [
    ([1, 2], "metadata must be a dict of names to values, got [1, 2]"),
    ({1: 2}, "metadata's keys must be strings, got 1"),
    ({"a": np.float32(1)}, "metadata['a'] = np.float32(1.0) is not JSON (give str, int, float, "
                           "bool, None, and lists and dicts of them; numpy's scalars as "
                           "Python's: .item())")])
def test_metadata_a_file_cannot_give_back_is_refused_before_writing(recorded, tmp_path,
                                                                    metadata, message):
    """`save` wrote [1, 2], which `load` then refused as "not a JSON object"; {1: 2} read
    back as {"1": 2}; numpy's float32 was json's TypeError, naming no key."""
    trajectories = Trajectories.load(recorded / "push.npz")
    with pytest.raises(ValueError, match=re.escape(message)):
        trajectories.save(tmp_path / "saved.npz", metadata)
    assert not any(tmp_path.iterdir())


@pytest.mark.parametrize("recorded_id", [5, ["FrankaPushSparse-v0"]])
def test_metadata_naming_an_id_that_is_no_string_is_refused(recorded, push_env, tmp_path,
                                                            recorded_id):
    """Was Python's AttributeError ('int' object has no attribute 'rpartition') or
    TypeError (unhashable type: 'list')."""
    metadata = dict(Trajectories.load(recorded / "push.npz").metadata, id=recorded_id)
    edited = _rewrite(recorded / "push.npz", tmp_path / "edited.npz",
                      metadata=np.array(json.dumps(metadata)))
    _refused(edited, push_env, f"says it was recorded under the id {recorded_id!r}, which is "
                               "not an env id (damaged metadata?)")


def _rewrite(source, destination, **changes):
    """`source`'s arrays with `changes` (None: left out), as a new npz."""
    with np.load(source) as data:
        arrays = {key: data[key] for key in data.files}
    arrays.update(changes)
    np.savez(destination, **{key: value for key, value in arrays.items() if value is not None})
    return destination


def test_an_npz_missing_a_key_or_whose_episode_lengths_disagree_is_refused(recorded,
                                                                           push_env, tmp_path):
    source = recorded / "push.npz"
    with np.load(source) as data:
        lengths = data["episode_length"]
    assert len(lengths) == 2
    _refused(_rewrite(source, tmp_path / "no-reward.npz", reward=None), push_env,
             "is not a franka_composer npz dataset: it has no reward")
    # The same total, cut elsewhere: the first episode's end flag falls inside the second.
    moved = _rewrite(source, tmp_path / "moved.npz", episode_length=lengths + [1, -1])
    _refused(moved, push_env, f"episode 0 ({lengths[0] + 1} steps) ends at step(s) "
                              f"[{lengths[0] - 1}] by its terminated and truncated flags, not "
                              f"at its last, {lengths[0]}: its episode boundaries do not match "
                              "its arrays")
    longer = _rewrite(source, tmp_path / "longer.npz", episode_length=lengths + [2, 0])
    _refused(longer, push_env, f"its episode_length adds up to {lengths.sum() + 4} rows of "
                               f"observation, and it holds {lengths.sum() + 2}")
    none = _rewrite(source, tmp_path / "none.npz", episode_length=np.zeros(0, np.int64))
    _refused(none, push_env, "holds no episodes")
    with np.load(source) as data:
        dense = -np.linalg.norm(data["achieved_goal"] - data["desired_goal"], axis=1)[1:]
    says_sparse = _rewrite(source, tmp_path / "says-sparse.npz",
                           reward=np.delete(dense, np.cumsum(lengths + 1)[:-1] - 1))
    _refused(says_sparse, push_env, "holds rewards other than the sparse [-1.0, 0.0] that "
                                    "training uses (episode 0; recorded with --reward-type "
                                    "dense?)")


def test_an_npz_of_another_task_or_controller_is_refused(recorded, push_env, tmp_path):
    """Slide's observations have push's shapes: only what the file says tells them apart."""
    _refused(recorded / "slide.npz", push_env, "holds demonstrations of slide, not push")
    _refused(recorded / "osc.npz", push_env, "was recorded through osc control, and this run "
                                             "trains through mocap")
    # And what it holds is checked too: pick-and-place's observations, said to be push's.
    with np.load(recorded / "push.npz") as data:
        push_metadata = data["metadata"]
    _refused(_rewrite(recorded / "pnp.npz", tmp_path / "pnp.npz", metadata=push_metadata),
             push_env, "holds observation of shape (19,), but this task's is (18,): "
                       "demonstrations of another task?")


def test_demonstrations_whose_actions_the_env_cannot_take_are_refused(recorded, push_env,
                                                                        tmp_path):
    with np.load(recorded / "push.npz") as data:
        actions, first = data["action"], int(data["episode_length"][0])
    _refused(_rewrite(recorded / "push.npz", tmp_path / "cut.npz", action=actions[:, :2]),
             push_env, "holds action of shape (2,) (episode 0), but this task's is (3,): "
                       "demonstrations of another task or controller?")
    scaled = actions * 50.0
    _refused(_rewrite(recorded / "push.npz", tmp_path / "scaled.npz", action=scaled),
             push_env, f"holds actions outside the action space [-1, 1] (episode 0: "
                       f"{scaled[:first].min():g} to {scaled[:first].max():g})")


def test_non_finite_numbers_and_flags_neither_true_nor_false_are_refused(recorded, push_env,
                                                                          tmp_path):
    """A NaN observation reached the critic's targets (the run failed at its first gradient
    step, naming no file), and a NaN success flag counted as a success."""
    source = recorded / "push.npz"
    with np.load(source) as data:
        arrays = {key: data[key].copy() for key in ("observation", "desired_goal", "reward",
                                                     "is_success")}
    arrays["observation"][5, 2] = np.nan
    arrays["desired_goal"][7] = np.inf
    arrays["reward"][3] = np.nan
    success = arrays["is_success"].astype(np.float64)
    success[4] = np.nan
    _refused(_rewrite(source, tmp_path / "observation.npz", observation=arrays["observation"]),
             push_env, "episode 0 has a non-finite observation in row 5")
    _refused(_rewrite(source, tmp_path / "goal.npz", desired_goal=arrays["desired_goal"]),
             push_env, "episode 0 has a non-finite desired_goal in row 7")
    _refused(_rewrite(source, tmp_path / "reward.npz", reward=arrays["reward"]), push_env,
             "episode 0 has a non-finite reward in row 3 (nan)")
    _refused(_rewrite(source, tmp_path / "success.npz", is_success=success), push_env,
             "episode 0 has is_success values other than true and false (nan at step 4)")
    with pytest.raises(ValueError, match="non-finite observation in row 5"):
        main(["train", "--task", "push", "--demos", str(tmp_path / "observation.npz"),
              "--out", str(tmp_path / "run")])
    assert not (tmp_path / "run").exists()


def test_numbers_of_other_types_shapes_or_past_float32_and_false_terminations_are_refused(
        recorded, push_env, tmp_path):
    """Strings and complex numbers were taken as observations (a NaN inside them failing
    the run a hundred steps in, naming no file), 1e300 went into the float32 buffer as inf,
    a column of rewards ended in a TypeError traceback, and a termination where the goal
    was not reached taught the critic that the state was worth nothing more."""
    source = recorded / "push.npz"
    with np.load(source) as data:
        observation, reward = data["observation"].copy(), data["reward"].copy()
        first = int(data["episode_length"][0])
    huge = observation.copy()
    huge[5, 2] = 1e300
    for name, arrays, message in (
            ("strings", dict(observation=observation.astype(str)),
             "episode 0 has observation of type <U"),
            ("complex", dict(observation=observation.astype(complex)),
             "episode 0 has observation of type complex128, not real numbers"),
            ("huge", dict(observation=huge), "episode 0 has a non-finite observation in row 5"),
            ("column", dict(reward=reward[:, None]),
             f"episode 0 has reward of shape ({first}, 1), not one value per step")):
        _refused(_rewrite(source, tmp_path / f"{name}.npz", **arrays), push_env, message)
    # An episode of a still hand cut by its time limit, said to have ended on the goal.
    import gymnasium as gym

    from franka_composer.policies import rollout

    env = gym.make("FrankaPushSparse-v0", max_episode_steps=5)
    try:
        timed_out = rollout(env, lambda obs: np.zeros(env.action_space.shape, np.float32), 1,
                            seed=0)
    finally:
        env.close()
    timed_out.save(tmp_path / "timed-out.npz", timed_out.metadata)
    episode = timed_out.episodes[0]
    assert episode["truncated"][-1] and not episode["is_success"][-1]
    _refused(_rewrite(tmp_path / "timed-out.npz", tmp_path / "false-end.npz",
                      terminated=~episode["terminated"] & episode["truncated"],
                      truncated=np.zeros_like(episode["truncated"])), push_env,
             "holds a termination where the goal was not reached (episode 0, step 4)")


#: Options under which the push expert's noisy episodes diverge: a hand step of 1 m.
_UNSTABLE = dict(max_tcp_step=1.0, action_noise=1.0, terminate_on_success=False)


@pytest.mark.parametrize("format, out, refused", [("npz", "push.npz", "episodes 0, 1 "),
                                                  ("minari", "minari", "episode 0 "),
                                                  ("rlds", "rlds", "episode 0 ")])
def test_a_recording_whose_physics_diverges_is_refused_and_leaves_nothing(tmp_path, format,
                                                                         out, refused):
    """An episode that ends where MuJoCo reset a diverged simulation: npz and RLDS kept it
    (the npz's early truncation was then refused as damage, RLDS read its discount 0 as the
    goal reached), and Minari failed with a "pytree structure error"."""
    with pytest.raises(ValueError, match=re.escape(
            f"{refused}ended where the physics diverged (MuJoCo found the simulation "
            "unstable and reset it): a dataset keeps no transition into such a reset")):
        record("push", 2, tmp_path / "new" / out, format=format, seed=0, **_UNSTABLE)
    assert list(tmp_path.iterdir()) == []


def test_an_npz_dataset_there_is_replaced_whole_once_recorded_and_kept_if_it_fails(tmp_path):
    """As `rollout --out` and the datasets guide say: numpy's savez would replace it too, but
    only once the new episodes are whole; a recording that fails leaves the old file."""
    out = tmp_path / "push.npz"
    record("push", 1, out, seed=0)
    record("push", 2, out, seed=5)
    replaced = Trajectories.load(out)
    assert len(replaced) == 2 and replaced.metadata["seed"] == 5
    before = out.read_bytes()
    with pytest.raises(ValueError, match="ended where the physics diverged"):
        record("push", 2, out, seed=0, **_UNSTABLE)
    assert out.read_bytes() == before and list(tmp_path.iterdir()) == [out]


def test_a_rollout_names_its_diverged_episodes_and_they_are_not_saved(push_env, tmp_path):
    import gymnasium as gym

    from franka_composer.policies import make_expert, rollout

    env = gym.make("FrankaPushSparse-v0", **{key: value for key, value in _UNSTABLE.items()
                                            if key != "action_noise"})
    try:
        calm = rollout(env, make_expert(env), 1, seed=0)  # Noiseless: no step of 1 m.
        steps = itertools.count(1)
        # The hand flung 1 m to and fro along x (back first): the simulation breaks on the
        # 7th step.
        flung = rollout(env, lambda obs: np.array([(-1) ** next(steps), 0, 0], np.float32),
                        1, seed=0)
    finally:
        env.close()
    assert calm.diverged == [] and calm.lengths.tolist() == [50]
    assert flung.diverged == [0] and flung.lengths.tolist() == [7]
    assert flung.episodes[0]["truncated"][-1] and not flung.episodes[0]["terminated"][-1]
    with pytest.raises(ValueError, match=re.escape("episode 0 ended where the physics "
                                                   "diverged")):
        flung.save(tmp_path / "flung.npz")
    assert list(tmp_path.iterdir()) == []
    # Saved before datasets refused them, the loader names divergence among the causes
    # (its options said to be the run's, which takes no max_tcp_step).
    flung.diverged = []
    flung.save(tmp_path / "flung.npz", dict(flung.metadata, options={}))
    _refused(tmp_path / "flung.npz", push_env,
             "episode 0 is truncated after 7 steps, and the dataset says its "
             "episodes were cut at max_episode_steps=50: edited, its metadata damaged, or "
             "the physics diverged there")


def test_a_dataset_that_is_not_there_or_whose_options_are_no_mapping_is_refused(
        recorded, push_env, tmp_path):
    _refused(tmp_path / "missing.npz", push_env, "missing.npz does not exist")
    _refused(tmp_path / "missing-folder", push_env, "missing-folder does not exist")
    metadata = dict(Trajectories.load(recorded / "push.npz").metadata, options="x")
    listed = _rewrite(recorded / "push.npz", tmp_path / "options.npz",
                      metadata=np.array(json.dumps(metadata)))
    _refused(listed, push_env, "says it was recorded with the options 'x', which are not a "
                               "mapping of option names to values (damaged metadata?)")


def test_a_dataset_recorded_with_an_option_this_version_has_not_is_refused(
        recorded, push_env, tmp_path):
    """An option it does not know was passed over: the dataset trained as the task's own,
    whatever that option did to its transitions. The env's own arguments beside the options
    in a Minari env spec are read as before."""
    import shutil

    metadata = Trajectories.load(recorded / "push.npz").metadata
    listed = _rewrite(recorded / "push.npz", tmp_path / "options.npz", metadata=np.array(
        json.dumps(dict(metadata, options={"bogus_option": 3}))))
    message = ("says it was recorded with 'bogus_option', which this version of "
               "franka_composer has no task option of (a later release's, or damaged "
               "metadata?): whether its transitions are this run's task cannot be checked")
    _refused(listed, push_env, message)
    # Recorded before options were (no "options"): the task's own, its other entries not
    # read as options.
    unsaid = _rewrite(recorded / "push.npz", tmp_path / "unsaid.npz", metadata=np.array(
        json.dumps({key: value for key, value in metadata.items() if key != "options"})))
    assert {"source", "seed"} <= metadata.keys()
    assert len(demos.load_episodes(unsaid, push_env)) == 2
    # 0.3.0 kept the env's own arguments given to gym.make among the options.
    given = _rewrite(recorded / "push.npz", tmp_path / "given.npz", metadata=np.array(
        json.dumps(dict(metadata, options={"time_limit": 2.5, "render_mode": None}))))
    assert len(demos.load_episodes(given, push_env)) == 2
    path = tmp_path / "minari"
    shutil.copytree(recorded / "minari" / "franka_composer" / "push" / "expert-v0", path)
    spec_file = path / "data" / "metadata.json"
    metadata = json.loads(spec_file.read_text())
    spec = json.loads(metadata["env_spec"])
    # As 0.4.0's ids wrote their spec (registered_id), with gym.make's own arguments.
    spec["kwargs"].update(registered_id="FrankaPushSparse-v0", render_mode=None, width=84,
                          height=84, camera="workspace")
    metadata["env_spec"] = json.dumps(spec)
    spec_file.write_text(json.dumps(metadata))
    assert len(demos.load_episodes(path, push_env)) == 2
    spec["kwargs"]["bogus_option"] = 1
    metadata["env_spec"] = json.dumps(spec)
    spec_file.write_text(json.dumps(metadata))
    _refused(path, push_env, message)


def test_an_npz_from_before_metadata_is_refused_saying_how_to_record_it_again(recorded,
                                                                              push_env,
                                                                              tmp_path):
    old = _rewrite(recorded / "push.npz", tmp_path / "old.npz", metadata=None)
    assert len(Trajectories.load(old)) == 2  # Still a readable file,
    _refused(old, push_env,  # but not one a run can check.
             f"does not say which task, control, reward_type it was recorded with, so it "
             f"cannot be checked against this run (an npz written before franka_composer "
             f"recorded them?): record it again, e.g. franka-composer rollout --task push "
             f"--control mocap --out {old}")


def test_a_damaged_rlds_dataset_is_an_error_not_zero_episodes(recorded, push_env, tmp_path,
                                                              capfd):
    for name, files, message in (
            # What envlogger reads as no episodes at all: it said so, and training went on.
            # Its step index emptied, envlogger logs the error naming it (printed, under a
            # banner saying the env was not closed) and reads on: kept, and said instead.
            ("emptied", "*/*.riegeli", "is not a readable RLDS dataset (damaged?): envlogger "
                                       "says NOT_FOUND: Empty steps in "),
            ("cut-index", "*/episode_index.riegeli", "holds no episodes"),
            ("cut-steps", "*/steps.riegeli", "is not a readable RLDS dataset (damaged?): "
                                             "envlogger says TypeError")):
        path = tmp_path / name
        _undigested_copy(recorded / "rlds", path)
        for damaged in path.glob(files):
            damaged.write_bytes(damaged.read_bytes()[:40 if name.startswith("cut") else 0])
        said = _refused(path, push_env, message)
        if name == "emptied":
            assert said.endswith("/step_offsets.riegeli") and str(path) in said
            assert "forgot" not in capfd.readouterr().err
        with pytest.raises(ValueError, match=re.escape(message)):
            main(["train", "--task", "push", "--demos", str(path), "--out",
                  str(tmp_path / "run")])
        assert not (tmp_path / "run").exists()
    # Cut to 90 %, the episode index split an episode (a 5-step stub read as one) or joined
    # two: refused, where the stub went into the buffer as an episode ending at a time-out;
    # the step offsets cut so are unreadable to envlogger (its own error, named after it).
    for index_file, message in (
            ("step_offsets.riegeli", " is not a readable RLDS dataset (damaged?): envlogger "
                                     "says "),
            ("episode_index.riegeli", ": episode 0 is not whole (a FIRST step, then steps, "
                                      "then a LAST one")):
        path = tmp_path / index_file
        _undigested_copy(recorded / "rlds", path)
        for damaged in path.glob(f"*/{index_file}"):
            damaged.write_bytes(damaged.read_bytes()[:len(damaged.read_bytes()) * 9 // 10])
        with pytest.raises(ValueError, match=f"^{re.escape(str(path) + message)}"):
            demos.load_episodes(path, push_env)
    garbage = tmp_path / "garbage"
    _undigested_copy(recorded / "rlds", garbage)
    (garbage / "metadata.riegeli").write_bytes(b"garbage" * 10)
    _refused(garbage, push_env, "is not a readable RLDS dataset (damaged?): envlogger says "
                                "RuntimeError: INTERNAL: Failed to parse riegeli record")


def test_a_changed_or_missing_rlds_file_is_refused_by_name(recorded, push_env, tmp_path):
    """envlogger's reader refused a changed byte as whatever it met next: "TypeError:
    expected bytes, NoneType found" for one in the steps, "Empty steps" for one in the step
    offsets, no episodes at all for one in the episode index; never naming the file."""
    import shutil

    from franka_composer.datasets.rlds_format import DIGESTS_FILE

    files = sorted(path.relative_to(recorded / "rlds")
                   for path in (recorded / "rlds").rglob("*.riegeli"))
    assert [file.name for file in files] == [
        "episode_index.riegeli", "episode_metadata.riegeli", "step_offsets.riegeli",
        "steps.riegeli", "metadata.riegeli"]
    for index, file in enumerate(files):
        path = tmp_path / f"changed-{index}"
        shutil.copytree(recorded / "rlds", path)
        raw = bytearray((path / file).read_bytes())
        raw[len(raw) // 3] ^= 0x10
        (path / file).write_bytes(bytes(raw))
        _refused(path, push_env, f"{path / file} is not what was recorded: its SHA-256 "
                                 f"differs from the one {DIGESTS_FILE} keeps")
    with pytest.raises(ValueError, match=re.escape(f"{path / file} is not what was")):
        main(["train", "--task", "push", "--demos", str(path), "--out", str(tmp_path / "run")])
    assert not (tmp_path / "run").exists()
    missing = tmp_path / "missing"
    shutil.copytree(recorded / "rlds", missing)
    (missing / files[0]).unlink()
    _refused(missing, push_env, f"{missing / files[0]} is missing: {DIGESTS_FILE} lists it")
    added = tmp_path / "added"  # A second recording's shard, copied in: more episodes.
    shutil.copytree(recorded / "rlds", added)
    shutil.copytree(added / files[0].parent, added / "20990101T000000000000")
    _refused(added, push_env, f"{added / '20990101T000000000000' / files[0].name} was not "
                              f"part of the recording ({DIGESTS_FILE} does not list it)")
    listing = tmp_path / "listing"
    shutil.copytree(recorded / "rlds", listing)
    (listing / DIGESTS_FILE).write_text("[1, 2]")
    _refused(listing, push_env, f"{listing / DIGESTS_FILE} is damaged (not a mapping of file "
                                "names to digests)")
    (listing / DIGESTS_FILE).unlink()  # A folder in its place was read as no listing.
    (listing / DIGESTS_FILE).mkdir()
    _refused(listing, push_env, f"{listing / DIGESTS_FILE} is not a file: it should list the "
                                "SHA-256 of each file of the dataset (damaged?)")
    assert len(demos.load_episodes(recorded / "rlds", push_env)) == 2


def test_an_unreadable_rlds_dataset_says_so_once(recorded, tmp_path, monkeypatch):
    """envlogger's Reader, its backend failing to open, was left without one and raised
    again when collected ("Exception ignored in: Reader.__del__ ... no attribute
    '_backend'") after the error."""
    import gc
    import sys

    from franka_composer.datasets import rlds_format

    ignored = []
    monkeypatch.setattr(sys, "unraisablehook", ignored.append)
    emptied = tmp_path / "emptied"
    _undigested_copy(recorded / "rlds", emptied)
    (emptied / "metadata.riegeli").write_bytes(b"")
    with pytest.raises(ValueError, match="is not a readable RLDS dataset"):
        rlds_format.read(emptied)
    with pytest.raises(ValueError, match=f"^{re.escape(str(tmp_path / 'nope'))} does not "
                                         "exist$"):
        rlds_format.read(tmp_path / "nope")
    gc.collect()
    assert ignored == []


def test_an_rlds_episode_cut_at_the_time_limit_is_a_truncation_not_a_termination(tmp_path,
                                                                                 push_env):
    """Its LAST step's discount is 1: the buffer bootstraps there (it read every LAST step
    as a termination, teaching the critic that the time limit is the end), as from npz
    and Minari. (Recorded without termination on success, for a run that trains so; a run
    that ends its episodes there refuses them: `_check_same_transitions`.)"""
    push_env.close()
    push_env = make_env("push", terminate_on_success=False)
    for format, name in (("rlds", "rlds"), ("npz", "push.npz"), ("minari", "minari")):
        out = tmp_path / name
        record("push", 2, out, format=format, seed=7, action_noise=0.5,
               terminate_on_success=False, **({"dataset_id": "franka_composer/push/cut-v0"}
                                              if format == "minari" else {}))
        if format == "minari":
            out = out / "franka_composer" / "push" / "cut-v0"
        episodes = demos.load_episodes(out, push_env)
        assert len(episodes) == 2, format
        for episode in episodes:
            assert not episode["terminated"].any(), format
            assert episode["truncated"].tolist() == [False] * 49 + [True], format
    push_env.close()


def test_every_format_says_where_its_episodes_were_cut(tmp_path, push_env):
    """The steps at which episodes were cut (`gym.make`'s max_episode_steps, or the env's
    own time limit where that is sooner) are kept as a Minari env spec keeps them: npz and
    RLDS metadata dropped them, and a dataset of 20-step episodes read as one of the
    task's 50."""
    from franka_composer.datasets import rlds_format

    record("push", 2, tmp_path / "push.npz", seed=0, max_episode_steps=20)
    assert Trajectories.load(tmp_path / "push.npz").metadata["max_episode_steps"] == 20
    record("push", 1, tmp_path / "timed.npz", seed=0, time_limit=0.5)  # 10 steps of 0.05 s.
    timed = Trajectories.load(tmp_path / "timed.npz")
    assert timed.metadata["max_episode_steps"] == 10
    assert timed.lengths.tolist() == [10] and timed.episodes[0]["truncated"][-1]
    record("push", 2, tmp_path / "rlds", format="rlds", seed=0, max_episode_steps=20)
    assert rlds_format.read(tmp_path / "rlds")["metadata"]["max_episode_steps"] == 20
    record("push", 2, tmp_path / "minari", format="minari", seed=0, max_episode_steps=20)
    minari_dataset = tmp_path / "minari" / "franka_composer" / "push" / "expert-v0"
    for path in (tmp_path / "push.npz", tmp_path / "rlds", minari_dataset):
        lengths = [len(episode["action"]) for episode in demos.load_episodes(path, push_env)]
        assert lengths == [11, 20], path  # The second cut at 20: the rule below holds.


def test_episodes_that_disagree_with_where_the_dataset_says_they_were_cut_are_refused(
        tmp_path, push_env):
    record("push", 2, tmp_path / "push.npz", seed=0, max_episode_steps=20)
    metadata = Trajectories.load(tmp_path / "push.npz").metadata

    def said(limit, name):
        return _rewrite(tmp_path / "push.npz", tmp_path / name, metadata=np.array(
            json.dumps(dict(metadata, max_episode_steps=limit))))

    said_fewer = "the dataset says its episodes were cut at max_episode_steps=15: edited"
    _refused(said(15, "fewer.npz"), push_env, f"episode 1 has 20 steps, and {said_fewer}")
    _refused(said(30, "more.npz"), push_env, "episode 1 is truncated after 20 steps, and the "
                                             "dataset says its episodes were cut at "
                                             "max_episode_steps=30")
    _refused(said("20", "text.npz"), push_env, "says its episodes were cut at "
                                               "max_episode_steps='20', which is not a number "
                                               "of steps (damaged metadata?)")
    assert len(demos.load_episodes(said(None, "unsaid.npz"), push_env)) == 2  # From before.


def test_an_npz_recording_interrupted_while_writing_leaves_the_old_file(recorded, tmp_path,
                                                                        monkeypatch):
    import shutil

    out = tmp_path / "push.npz"
    shutil.copy(recorded / "push.npz", out)
    before = out.read_bytes()
    savez = np.savez_compressed

    def interrupted(file, **arrays):
        savez(file, **dict(list(arrays.items())[:3]))  # Some of the arrays, then a stop.
        raise KeyboardInterrupt

    # A file of the user's named as the partial file was (push.partial.npz): left alone.
    theirs = tmp_path / "push.partial.npz"
    theirs.write_bytes(b"the user's")
    monkeypatch.setattr(np, "savez_compressed", interrupted)
    with pytest.raises(KeyboardInterrupt):
        record("push", 1, out, seed=3)
    assert out.read_bytes() == before
    assert sorted(path.name for path in tmp_path.iterdir()) == ["push.npz", "push.partial.npz"]
    monkeypatch.setattr(np, "savez_compressed", savez)
    record("push", 1, out, seed=3)
    assert len(Trajectories.load(out)) == 1
    assert theirs.read_bytes() == b"the user's"


def test_demonstrations_whose_rewards_the_task_does_not_give_are_refused(tmp_path, push_env):
    """Recorded with a 0.3 m success threshold: its stored successes are not the run's
    task's, and went into the buffer as they were."""
    out = tmp_path / "wide.npz"
    record("push", 2, out, seed=0, distance_threshold=0.3)
    _refused(out, push_env, "was recorded with distance_threshold=0.3, and this run trains "
                            "with distance_threshold=0.05: its transitions are of another task")
    # Its metadata edited to say nothing of it: the rewards still tell.
    wide = Trajectories.load(out)
    metadata = dict(wide.metadata, options={})
    wide.save(tmp_path / "edited.npz", metadata)
    _refused(tmp_path / "edited.npz", push_env, "holds rewards this task does not give its "
                                                "goals (episode 0, step 0: 0 stored, -1 from "
                                                "the goals)")


def test_demonstrations_whose_success_flags_the_goals_do_not_give_are_refused(recorded,
                                                                              push_env,
                                                                              tmp_path):
    """Every is_success flag inverted loaded, and the success rate read the opposite."""
    loaded = Trajectories.load(recorded / "push.npz")
    episodes = [{**episode, "is_success": ~episode["is_success"]}
                for episode in loaded.episodes]
    Trajectories(episodes).save(tmp_path / "inverted.npz", loaded.metadata)
    _refused(tmp_path / "inverted.npz", push_env, "holds is_success flags its goals do not "
                                                  "give (episode 0, step 0: True stored, "
                                                  "False from the goals): edited?")


def test_an_rlds_recording_cut_short_leaves_nothing_behind(tmp_path, monkeypatch):
    """A policy that fails on its 20th action: no folder of steps that would read as a
    dataset of two short episodes."""
    import franka_composer.datasets as datasets

    make_policy, calls = datasets.make_policy, []

    def failing(*args, **kwargs):
        policy = make_policy(*args, **kwargs)

        def act(observation):
            calls.append(observation)
            if len(calls) == 20:
                raise RuntimeError("the policy failed")
            return policy(observation)
        return act

    monkeypatch.setattr(datasets, "make_policy", failing)
    with pytest.raises(RuntimeError, match="the policy failed"):
        record("push", 3, tmp_path / "out" / "rlds", format="rlds", seed=0)
    assert list(tmp_path.iterdir()) == []  # "out" too, which it made.
    # Into an empty folder of the user's: the folder stays, empty.
    (tmp_path / "empty").mkdir()
    calls.clear()
    with pytest.raises(RuntimeError, match="the policy failed"):
        record("push", 3, tmp_path / "empty", format="rlds", seed=0)
    assert [path.name for path in tmp_path.iterdir()] == ["empty"]
    assert list((tmp_path / "empty").iterdir()) == []


def _joints_npz(path, metadata_changes: dict):
    """Two episodes of random actions on push under joints, their metadata changed."""
    import gymnasium as gym

    from franka_composer.policies import rollout

    env = gym.make("FrankaPushJointsSparse-v1")
    try:
        trajectories = rollout(env, lambda obs: env.action_space.sample(), 2, seed=0)
    finally:
        env.close()
    metadata = {key: value for key, value in {**trajectories.metadata,
                                              **metadata_changes}.items()
                if value is not None}
    trajectories.save(path, metadata)
    return path


@pytest.mark.parametrize("changes, message", [
    ({}, None),  # As recorded now: taken.
    ({"id": None}, "names no id, so it was recorded before joints control's ids went to "
                   "version 1, whose dynamics changed"),
    ({"id": "FrankaPushJointsSparse-v0"}, "was recorded under FrankaPushJointsSparse-v0, an "
                                          "older version of FrankaPushJointsSparse-v1"),
    ({"id": "FrankaPushJointsSparse-v3"}, "was recorded under FrankaPushJointsSparse-v3, a "
                                          "newer version than this franka_composer's "
                                          "FrankaPushJointsSparse-v1"),
    ({"id": "FrankaSlideJointsSparse-v1"},
     "names the id 'FrankaSlideJointsSparse-v1', which fixes task='slide', control='joints' "
     "and reward_type='sparse', but says it was recorded with task='push': its metadata "
     "contradicts itself"),
    ({"id": "FrankaPushOscSparse-v0"}, "but says it was recorded with control='joints'"),
    ({"id": "FrankaPushJointsDense-v1"}, "but says it was recorded with reward_type='sparse'"),
])
def test_demonstrations_of_dynamics_since_changed_are_refused(changes, message, tmp_path):
    """The Joints ids went up a version with the surface guard under joints: a dataset that
    names an older id, or through joints none (recorded before ids were named), holds
    transitions of the dynamics before. One whose id contradicts its own task, control or
    reward type (edited by hand) cannot be believed either way."""
    path = _joints_npz(tmp_path / "joints.npz", changes)
    env = make_env("push", control="joints")
    try:
        if message is None:
            assert len(demos.load_episodes(path, env)) == 2
        else:
            _refused(path, env, message)
    finally:
        env.close()


def test_a_minari_dataset_names_its_id_in_its_env_spec(tmp_path):
    """A Minari dataset carries its id in its env spec, not in franka_composer's metadata:
    through joints it is taken as of the present dynamics when that id is the present one."""
    import gymnasium as gym

    from franka_composer.datasets import minari_format

    env = gym.make("FrankaPushJointsSparse-v1")
    try:
        minari_format.write(env, lambda obs: env.action_space.sample(), 2, 0, tmp_path,
                            "push/joints-random-v0", "random actions")
    finally:
        env.close()
    run_env = make_env("push", control="joints")
    try:
        assert len(demos.load_episodes(tmp_path / "push" / "joints-random-v0", run_env)) == 2
    finally:
        run_env.close()


def test_the_documented_recipe_writes_demonstrations_training_takes(push_env, tmp_path):
    """`rollout(env, make_expert(env), episodes).save(path)` (the policies module's
    docstring) wrote no metadata, and `train --demos` refused the file as one from before
    datasets said what they were recorded with."""
    import gymnasium as gym

    from franka_composer.policies import make_expert, rollout

    env = gym.make("FrankaPushSparse-v0")
    try:
        rollout(env, make_expert(env), episodes=2, seed=0).save(tmp_path / "push.npz")
    finally:
        env.close()
    assert Trajectories.load(tmp_path / "push.npz").metadata == {
        "id": "FrankaPushSparse-v0", "task": "push", "control": "mocap",
        "reward_type": "sparse", "max_episode_steps": 50, "options": {}}
    assert len(demos.load_episodes(tmp_path / "push.npz", push_env)) == 2
    # What differs from the task's own is recorded, and checked against the run's env.
    env = gym.make("FrankaPushSparse-v0", timing="reference", object_damping=0.01)
    try:
        trajectories = rollout(env, make_expert(env), episodes=1, seed=0)
    finally:
        env.close()
    trajectories.save(tmp_path / "reference.npz")
    assert trajectories.metadata["options"] == {
        "object_damping": 0.01, "weld_time_constant": 0.02, "control_timestep": 0.5,
        "velocity_timestep": 0.05}
    _refused(tmp_path / "reference.npz", push_env, "was recorded at 0.5 s per step")
    with pytest.raises(ValueError, match=re.escape(
            f"no episodes to write to {tmp_path / 'none.npz'}")):
        Trajectories([]).save(tmp_path / "none.npz")  # An IndexError.
    assert not (tmp_path / "none.npz").exists()
    # A FileNotFoundError named the hidden partial file beside the one asked for.
    with pytest.raises(ValueError, match=re.escape(
            f"cannot write {tmp_path / 'no' / 'push.npz'}: {tmp_path / 'no'} is not a "
            "folder")):
        trajectories.save(tmp_path / "no" / "push.npz")
    # numpy's savez added .npz to a name without it (which `load` then did not find), and
    # wrote a folder's name plus .npz beside it; a path no file can be made at was a
    # FileNotFoundError naming the hidden partial file.
    (tmp_path / "folder.npz").mkdir()
    for path, message in ((tmp_path / "noext", f"an npz dataset's path must end in .npz, got "
                                                f"{str(tmp_path / 'noext')!r}"),
                          (tmp_path / "folder.npz", f"an npz dataset is a file, and "
                                                    f"{tmp_path / 'folder.npz'} is a folder"),
                          (pathlib.Path("/proc/x.npz"), "cannot write to /proc/x.npz: no file "
                                                        "can be made in /proc")):
        with pytest.raises(ValueError, match=re.escape(message)):
            trajectories.save(path)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["folder.npz", "push.npz",
                                                                "reference.npz"]
    # A TypeError from comparing the noise with 0 before it was checked.
    with pytest.raises(ValueError, match=re.escape("action_noise must be a finite number "
                                                   ">= 0, got '0.1'")):
        record("push", 1, tmp_path / "noisy.npz", action_noise="0.1")
    assert not (tmp_path / "noisy.npz").exists()


def test_numpy_options_are_recorded_as_the_numbers_they_hold(push_env, tmp_path):
    """Kept as their repr ('np.float32(0.01)'), the npz's own demonstrations were refused,
    and Minari refused np.False_ as not JSON."""
    import gymnasium as gym

    from franka_composer.policies import make_expert, rollout

    options = dict(object_damping=np.float32(0.01), terminate_on_success=np.False_)
    record("push", 1, tmp_path / "numpy.npz", seed=0, **options)
    recorded = Trajectories.load(tmp_path / "numpy.npz").metadata["options"]
    assert recorded == {"object_damping": float(np.float32(0.01)),
                        "terminate_on_success": False}
    assert type(recorded["terminate_on_success"]) is bool
    damped = make_env("push", object_damping=float(np.float32(0.01)),
                      terminate_on_success=False)
    try:
        assert len(demos.load_episodes(tmp_path / "numpy.npz", damped)) == 1
    finally:
        damped.close()
    record("push", 1, tmp_path / "minari", format="minari", seed=0, **options)
    # A randomisation's numpy constants too (they are valid constants there).
    record("push", 1, tmp_path / "constants.npz", seed=0,
           randomization={"object_mass": np.float32(0.5)})
    assert Trajectories.load(tmp_path / "constants.npz").metadata["options"] == {
        "randomization": "{'object_mass': 0.5}"}
    record("push", 1, tmp_path / "constants", format="minari", seed=0,
           randomization={"object_mass": np.float32(0.5)})
    # rollout's own record of its env says a preset by name, as the option takes it.
    env = gym.make("FrankaPushSparse-v0", randomization="default")
    try:
        assert rollout(env, make_expert(env), 1, seed=0).metadata["options"] == {
            "randomization": "default"}
    finally:
        env.close()


def test_rlds_episodes_without_their_seed_are_refused_by_name(recorded, push_env, tmp_path):
    """Episode metadata cut short or flipped (envlogger reads None), or a dataset logged
    by envlogger around `load` as acme logs (no episode metadata): a TypeError from deep in
    the reader, by `read` and by `train --demos`."""
    import franka_composer
    from franka_composer.datasets import rlds_format

    envlogger = rlds_format.import_envlogger()  # As a user logging with it (numpy 2).

    for name, cut in (("cut", lambda raw: raw[:64]),
                      ("flipped", lambda raw: raw[:len(raw) // 2] + bytes(
                          [raw[len(raw) // 2] ^ 0xFF]) + raw[len(raw) // 2 + 1:])):
        path = tmp_path / name
        _undigested_copy(recorded / "rlds", path)
        (damaged,) = path.glob("*/episode_metadata.riegeli")
        damaged.write_bytes(cut(damaged.read_bytes()))
        _refused(path, push_env, ": episode 0 has no seed in its episode metadata (found "
                                 "None): a dataset this package's rlds writer did not write")
    logged = tmp_path / "acme"
    logged.mkdir()
    env = franka_composer.load("push", seed=0)
    with envlogger.EnvLogger(env, data_directory=str(logged)) as logging:
        timestep = logging.reset()
        while not timestep.last():
            timestep = logging.step(np.zeros(env.action_spec().shape))
    with pytest.raises(ValueError, match=re.escape(f"{logged}: episode 0 has no seed")):
        rlds_format.read(logged)
    with pytest.raises(ValueError, match=re.escape(f"{logged}: episode 0 has no seed")):
        main(["train", "--task", "push", "--demos", str(logged), "--out",
              str(tmp_path / "run")])
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("format, name", [("npz", "pixels.npz"), ("rlds", "rlds"),
                                          ("minari", "minari")])
def test_a_dataset_of_pixels_alone_is_refused_for_holding_no_state(format, name, push_env,
                                                                    tmp_path):
    """RLDS raised a KeyError from the observation layout, Minari called itself damaged."""
    record("push", 1, tmp_path / name, format=format, seed=0, observation_mode="pixels",
           pixel_height=16, pixel_width=16)
    dataset = tmp_path / name
    if format == "minari":
        dataset = dataset / "franka_composer" / "push" / "expert-v0"
    _refused(dataset, push_env, "was recorded with observation_mode 'pixels' and holds no "
                                "state observations")


def test_demonstrations_are_loaded_for_an_env_of_state_observations_only(recorded):
    """For a pixel env the RLDS reader raised a KeyError ('observation')."""
    for mode in ("pixels", "state+pixels"):
        env = make_env("push", observation_mode=mode, pixel_height=16, pixel_width=16)
        try:
            _refused(recorded / "rlds", env, "demonstrations go into a buffer of state "
                                             f"observations, and this env observes "
                                             f"observation_mode {mode!r}")
        finally:
            env.close()


def test_an_rlds_dataset_of_another_task_is_refused_before_its_observations_are_read(
        recorded, push_env):
    _refused(recorded / "reach-rlds", push_env, "holds demonstrations of reach, not push")


def test_a_damaged_minari_dataset_is_refused_by_name(recorded, push_env, tmp_path):
    import shutil

    path = tmp_path / "minari"
    shutil.copytree(recorded / "minari", path)
    dataset = path / "franka_composer" / "push" / "expert-v0"
    assert len(demos.load_episodes(dataset, push_env)) == 2
    data = dataset / "data" / "main_data.hdf5"
    data.write_bytes(data.read_bytes()[:3000])
    _refused(dataset, push_env, "is not a readable Minari dataset (damaged?): its "
                                "main_data.hdf5: OSError: Unable to synchronously open file "
                                "(truncated file")


@pytest.mark.parametrize("missing, message", [
    ("data/metadata.json", "is not a Minari dataset: {data}/metadata.json is missing"),
    ("data/main_data.hdf5", "is not a readable Minari dataset: {data}/main_data.hdf5, which "
                            "its metadata.json says holds the episodes, is missing")])
def test_a_minari_dataset_missing_a_file_is_refused_naming_the_file(missing, message,
                                                                   recorded, push_env,
                                                                   tmp_path):
    """Minari said "No data found in data path" for either."""
    import shutil

    path = tmp_path / "minari"
    shutil.copytree(recorded / "minari" / "franka_composer" / "push" / "expert-v0", path)
    (path / missing).unlink()
    _refused(path, push_env, message.format(data=path / "data"))


def test_a_minari_dataset_whose_episode_attributes_are_damaged_is_refused_by_name(
        recorded, push_env, tmp_path):
    """A changed byte in an episode's attribute (the version of the "id" attribute's
    dataspace message) is h5py's RuntimeError when the digests are checked: it was left
    to the user as it was, naming no file."""
    import shutil

    import h5py

    dataset = tmp_path / "push"
    shutil.copytree(recorded / "minari" / "franka_composer" / "push" / "expert-v0", dataset)
    data = dataset / "data" / "main_data.hdf5"
    with h5py.File(data, "r") as file:
        header = h5py.h5o.get_info(file["episode_1"].id).addr
    content = bytearray(data.read_bytes())
    name = content.index(b"id\x00\x00\x00\x00\x00\x00", header)  # Its name, padded to 8.
    content[name + 24] = 0xC6
    data.write_bytes(bytes(content))
    _refused(dataset, push_env, "is not a readable Minari dataset (damaged?): its "
                                "main_data.hdf5: RuntimeError: Can't synchronously determine "
                                "if attribute exists by name (wrong version number in "
                                "dataspace message)")


def test_a_minari_array_whose_header_declares_more_than_its_file_is_refused_unread(
        recorded, push_env, tmp_path):
    """One flipped bit in the dimensions of episode 1's actions (25 rows, 2**28 + 25 after
    it) had h5py allocate the 3.2 GB they declare, and more, until the process ran out of
    memory (23 GB) before any check: the headers are read first, and its digest is checked
    before the arrays are read."""
    import shutil

    import h5py

    dataset = tmp_path / "push"
    shutil.copytree(recorded / "minari" / "franka_composer" / "push" / "expert-v0", dataset)
    data = dataset / "data" / "main_data.hdf5"
    with h5py.File(data, "r") as file:
        assert file["episode_1/actions"].shape == (25, 3)
        header = h5py.h5o.get_info(file["episode_1/actions"].id).addr
    content = bytearray(data.read_bytes())
    # Its dataspace message, the first in its object header: the dimensions as 8-byte ints.
    dimensions = content.index((25).to_bytes(8, "little") + (3).to_bytes(8, "little"), header)
    assert dimensions - header < 64
    content[dimensions + 3] ^= 0x10
    data.write_bytes(bytes(content))
    _refused(dataset, push_env, f"{dataset}: the array /episode_1/actions of its "
                                "main_data.hdf5 declares shape (268435481, 3) (chunks (25, 3)), "
                                f"3,221,225,772 bytes, and the file holds {data.stat().st_size:,}"
                                ": its header is damaged; record it again")


def _compressed(data):
    """`data`, an HDF5 file, with every array stored gzip-compressed in the same chunks and
    attributes (as `h5repack -f GZIP=4` stores it)."""
    import h5py

    repacked = data.with_suffix(".repacked")
    with h5py.File(data, "r") as source, h5py.File(repacked, "w") as target:
        def copy(name, item):
            if isinstance(item, h5py.Group):
                copied = target.require_group(name)
            else:
                copied = target.create_dataset(name, data=item[()], chunks=item.chunks,
                                               maxshape=item.maxshape, compression="gzip")
            copied.attrs.update(item.attrs)

        target.attrs.update(source.attrs)
        source.visititems(copy)
    repacked.replace(data)


def test_a_compressed_minari_array_whose_header_spans_more_chunks_than_stored_is_refused(
        recorded, push_env, tmp_path):
    """Compressed, its bytes bound nothing, and the same flipped bit was read: the chunks
    its shape spans are counted against those its file stores."""
    import shutil

    import h5py

    dataset = tmp_path / "push"
    shutil.copytree(recorded / "minari" / "franka_composer" / "push" / "expert-v0", dataset)
    data = dataset / "data" / "main_data.hdf5"
    _compressed(data)
    assert len(demos.load_episodes(dataset, push_env)) == 2  # Whole, it loads.
    with h5py.File(data, "r") as file:
        actions = file["episode_1/actions"]
        assert (actions.shape, actions.chunks, actions.compression) == ((25, 3), (25, 3),
                                                                       "gzip")
        header = h5py.h5o.get_info(actions.id).addr
    content = bytearray(data.read_bytes())
    dimensions = content.index((25).to_bytes(8, "little") + (3).to_bytes(8, "little"), header)
    content[dimensions + 3] ^= 0x10
    data.write_bytes(bytes(content))
    _refused(dataset, push_env, f"{dataset}: the array /episode_1/actions of its "
                                "main_data.hdf5 declares shape (268435481, 3) (chunks (25, 3)), "
                                "10,737,420 compressed chunks, and the file stores 1: its "
                                "header is damaged; record it again")


def test_minari_seeds_past_uint64_are_refused_before_recording(tmp_path):
    """Minari keeps each episode's seed as a uint64: --seed 2**64 ended in h5py's TypeError
    (Object dtype dtype('O') has no native HDF5 equivalent), and 2**64 - 1 after its first
    episode was recorded."""
    with pytest.raises(ValueError, match=re.escape(
            "a Minari dataset keeps each episode's seed as a uint64 (below 2**64), and episode "
            "1's would be 18446744073709551616: give a smaller --seed, or record as npz or "
            "rlds, which keep any")):
        record("reach", 2, tmp_path / "minari", format="minari", seed=2**64 - 1)
    assert not any(tmp_path.iterdir())


def test_a_dataset_of_the_tasks_own_options_says_so_in_every_format(recorded):
    """envlogger keeps {} as None: RLDS metadata read None where npz's gives {}."""
    from franka_composer.datasets import rlds_format

    assert rlds_format.read(recorded / "rlds")["metadata"]["options"] == {}
    assert Trajectories.load(recorded / "push.npz").metadata["options"] == {}


@pytest.mark.parametrize("counted, message", [
    (dict(total_episodes=1), "counts 1 episode of 36 steps in all, and its data holds 2 "
                             "(the first 1: 11 steps)"),  # Loaded one of two, silently.
    # Minari looked for an episode_2 there is not: "KeyError", blamed on the HDF5 file.
    (dict(total_episodes=3), "counts 3 episodes, and its data holds 2"),
    (dict(total_steps=7), "counts 2 episodes of 7 steps in all, and its data holds 2 "
                          "(the first 2: 36 steps)")])
def test_a_minari_dataset_whose_counts_disagree_with_its_data_is_refused(
        counted, message, recorded, push_env, tmp_path):
    """What an append cut short between the data and metadata.json leaves."""
    import shutil

    path = tmp_path / "minari"
    shutil.copytree(recorded / "minari" / "franka_composer" / "push" / "expert-v0", path)
    metadata = json.loads((path / "data" / "metadata.json").read_text())
    assert (metadata["total_episodes"], metadata["total_steps"]) == (2, 36)
    (path / "data" / "metadata.json").write_text(json.dumps({**metadata, **counted}))
    _refused(path, push_env, f"{path}'s metadata.json {message}: an append cut short, or "
                             "hand-edited?")


def test_minari_episodes_are_counted_in_either_of_minaris_formats(recorded, tmp_path):
    """Minari's arrow format (pyarrow, not an extra here) keeps no hdf5 file: counting only
    that, its datasets were refused as damaged."""
    import shutil

    hdf5 = recorded / "minari" / "franka_composer" / "push" / "expert-v0" / "data"
    assert demos._stored_minari_episodes(hdf5) == 2
    arrow = tmp_path / "arrow"  # What Minari's ArrowStorage writes: an episode per folder.
    for episode in ("0", "1", "2"):
        (arrow / episode).mkdir(parents=True)
        (arrow / episode / "metadata.json").write_text("{}")
    shutil.copy(hdf5 / "metadata.json", arrow / "metadata.json")
    assert demos._stored_minari_episodes(arrow) == 3


def test_a_minari_dataset_of_another_env_is_refused_by_its_id(tmp_path, push_env,
                                                               monkeypatch):
    """Not "does not say which task... (an npz written before...?)", with a command that
    would not record it."""
    import gymnasium as gym
    import minari

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path))
    env = minari.DataCollector(gym.make("Pendulum-v1", max_episode_steps=5))
    env.reset(seed=0)
    for _ in range(5):
        env.step(env.action_space.sample())
    env.create_dataset(dataset_id="pendulum/random-v0", algorithm_name="random")
    env.close()
    _refused(tmp_path / "pendulum" / "random-v0", push_env,
             "was recorded under Pendulum-v1, not a franka_composer id")


def test_a_minari_dataset_without_its_env_spec_is_refused_saying_how_to_record_it(
        recorded, push_env, tmp_path):
    """Not "(an npz written before...?)" with a command that refuses a Minari --out."""
    import shutil

    path = tmp_path / "no-spec"
    shutil.copytree(recorded / "minari" / "franka_composer" / "push" / "expert-v0", path)
    metadata = json.loads((path / "data" / "metadata.json").read_text())
    metadata["env_spec"] = None
    (path / "data" / "metadata.json").write_text(json.dumps(metadata))
    _refused(path, push_env, "does not say which task, control, reward_type it was recorded "
                             "with, so it cannot be checked against this run (a Minari dataset "
                             "without its env spec?): record it again, e.g. franka-composer "
                             "rollout --task push --control mocap --format minari --out "
                             "NEW_FOLDER")


@pytest.mark.parametrize("dataset_id", ["foo", "bad id", "push/expert"])
def test_a_minari_id_minari_would_refuse_is_refused_before_recording(tmp_path, monkeypatch,
                                                                      dataset_id):
    """Minari checks the id when it makes the dataset, after every episode was recorded."""
    import franka_composer.datasets as datasets

    def never(*args, **kwargs):
        raise AssertionError("recording began")

    monkeypatch.setattr(datasets, "make_policy", never)
    with pytest.raises(ValueError, match=re.escape(
            f"--dataset-id {dataset_id!r} is not a Minari dataset id: [namespace/]name-v"
            "<version>, e.g. franka_composer/push/expert-v0")):
        record("push", 100, tmp_path / "out", format="minari", dataset_id=dataset_id)
    assert list(tmp_path.iterdir()) == []


def test_the_folder_rollout_wrote_minari_datasets_into_names_them(recorded, push_env):
    """`rollout --format minari --out DIR` keeps its dataset under DIR/<namespace>/<id>."""
    _refused(recorded / "minari", push_env, "is not a dataset: expected a .npz file, a Minari "
             "dataset folder (holding data/) or an RLDS folder (holding metadata.riegeli); "
             f"it holds the Minari dataset(s) {recorded / 'minari/franka_composer/push/expert-v0'}"
             ": give one of them")


def test_minari_records_under_a_relative_datasets_path(tmp_path, monkeypatch):
    """Minari's collector joined a relative MINARI_DATASETS_PATH to itself once every
    episode was recorded."""
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("MINARI_DATASETS_PATH", "datasets")
    summary = record("push", 1, "out", format="minari", seed=0)
    assert summary["episodes"] == 1
    assert (tmp_path / "out" / "franka_composer" / "push" / "expert-v0" / "data" /
            "main_data.hdf5").is_file()
    assert not (tmp_path / "datasets").exists()  # Nor a temporary folder left anywhere.
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["franka_composer"]


def test_a_custom_randomisation_is_kept_readably_or_refused_before_recording(tmp_path):
    custom = {"object_mass": distributions.Uniform(low=0.8, high=1.2)}
    with pytest.raises(ValueError, match=re.escape(
            "a Minari dataset keeps its env's options as JSON (recover_environment makes the "
            "env from them), and randomization={'object_mass': Uniform(")):
        record("push", 1, tmp_path / "minari", format="minari", randomization=custom)
    assert not (tmp_path / "minari").exists()
    record("push", 1, tmp_path / "custom.npz", randomization=custom)
    options = Trajectories.load(tmp_path / "custom.npz").metadata["options"]
    assert options == {"randomization": "{'object_mass': Uniform(args=(), kwargs={'low': 0.8, "
                                        "'high': 1.2}, single_sample=False)}"}
    record("push", 1, tmp_path / "preset", format="minari", randomization="default")
    with zipfile.ZipFile(tmp_path / "custom.npz") as archive:
        assert "metadata.npy" in archive.namelist()
    assert json.loads(np.load(tmp_path / "custom.npz")["metadata"].item())["task"] == "push"


def test_a_minari_recording_that_fails_leaves_nothing_behind(tmp_path, monkeypatch):
    """Minari's collector keeps the episodes in a temporary folder until the end: a run that
    fails on the way removes it, and the dataset folder it made."""
    import gymnasium as gym

    from franka_composer.adapters.registration import env_id
    from franka_composer.datasets import minari_format

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari-home"))
    env = gym.make(env_id("push", "sparse"))
    steps = []

    def failing_policy(obs):
        steps.append(obs)
        if len(steps) == 60:  # In the second episode.
            raise RuntimeError("the policy failed")
        return env.action_space.sample()

    with pytest.raises(RuntimeError, match="the policy failed"):
        minari_format.write(env, failing_policy, 3, 0, tmp_path / "out" / "nested",
                            "franka_composer/push/expert-v0", "a test")
    env.close()
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # "out" too, which it made.


def test_a_minari_recording_stopped_while_its_collector_is_made_leaves_nothing_behind(
        tmp_path, monkeypatch):
    """Ctrl-C while Minari's collector was being made left the dataset's empty folder (seen
    by stopping `rollout --format minari` half a second in)."""
    import gymnasium as gym
    import minari

    from franka_composer.adapters.registration import env_id
    from franka_composer.datasets import minari_format

    def stopped(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(minari, "DataCollector", stopped)
    env = gym.make(env_id("push", "sparse"))
    with pytest.raises(KeyboardInterrupt):
        minari_format.write(env, lambda obs: env.action_space.sample(), 3, 0,
                            tmp_path / "out" / "nested", "franka_composer/push/expert-v0",
                            "a test")
    env.close()
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("format", ["minari", "rlds"])
def test_a_recording_stopped_in_a_folder_that_was_there_leaves_it_as_it_was(
        tmp_path, monkeypatch, format):
    """Into an existing datasets folder, a stopped Minari recording left its namespaces'
    metadata files; and a second signal during the cleanup of either format left half a
    dataset: the cleanup runs with the signals held, and what was there stays."""
    import signal

    from franka_composer.datasets import folders
    from franka_composer.signals import interrupt_on

    root = tmp_path / "datasets"
    (root / "franka_composer" / "other").mkdir(parents=True)  # Another dataset's.
    (root / "franka_composer" / "other" / "data.hdf5").write_text("kept")
    if format == "rlds":  # `record` takes an empty one.
        root = tmp_path / "empty"
        root.mkdir()
    before = sorted(tmp_path.rglob("*"))
    removing, rmtree = [], folders.shutil.rmtree

    def interrupted_again(path, *args, **kwargs):  # A second SIGTERM as it cleans up.
        if not removing:
            removing.append(path)
            signal.raise_signal(signal.SIGTERM)
        return rmtree(path, *args, **kwargs)

    monkeypatch.setattr(folders.shutil, "rmtree", interrupted_again)
    steps = []

    def stopped_policy(obs):
        steps.append(obs)
        if len(steps) == 60:  # In the second episode.
            signal.raise_signal(signal.SIGTERM)
        return np.zeros(3, np.float32)  # As every source gives it.

    import franka_composer.datasets as datasets

    monkeypatch.setattr(datasets, "make_policy", lambda env, **kwargs: stopped_policy)
    with pytest.raises(KeyboardInterrupt):
        with interrupt_on(signal.SIGTERM):
            record("push", 3, root, format=format, seed=0)
    assert removing and sorted(tmp_path.rglob("*")) == before

@pytest.mark.parametrize("recorded_with, message", [
    (dict(max_tcp_step=0.2), "was recorded with max_tcp_step=0.2, and this run trains with "
                             "max_tcp_step=0.05: its transitions are of another task (other "
                             "motions, rewards or ends)"),
    (dict(object_mass=5.0), "was recorded with object_mass=5.0, and this run trains with "
                            "object_mass=1.0"),
    (dict(floor_friction=0.05), "was recorded with floor_friction=0.05"),
    (dict(terminate_on_success=False), "was recorded with terminate_on_success=False, and "
                                       "this run trains with terminate_on_success=True"),
    (dict(randomization="default"), "was recorded with randomization='default', and this "
                                    "run trains with randomization=None"),
])
def test_demonstrations_of_another_task_setting_are_refused(recorded_with, message, push_env,
                                                            tmp_path):
    """Their metadata said so and they trained: actions of another scale (other motions),
    another block's mass or the floor's friction, episodes that go on past the goal, or
    randomised ones, put into the buffer of a run whose task is not theirs."""
    out = tmp_path / "other.npz"
    record("push", 1, out, seed=70, action_noise=0.5, **recorded_with)
    _refused(out, push_env, message)
    same = make_env("push", **recorded_with)
    try:
        assert len(demos.load_episodes(out, same)) == 1  # Taken by a run of that setting.
    finally:
        same.close()


def test_a_changed_number_in_a_minari_dataset_is_refused_by_its_episodes_digest(
        recorded, push_env, tmp_path):
    """Minari's HDF5 keeps no checksum: one byte changed inside an observation read as
    another number (-0.000150921557298 for -0.000150921557326), where npz and RLDS files
    fail to read. `record` gives each episode a SHA-256 of its arrays, which the loader
    checks; an episode without one (Minari's own, or from before) passes."""
    import shutil

    import h5py

    from franka_composer.datasets import minari_format

    dataset = tmp_path / "push"
    shutil.copytree(recorded / "minari" / "franka_composer" / "push" / "expert-v0", dataset)
    data = dataset / "data" / "main_data.hdf5"
    with h5py.File(data, "r") as file:
        digests = [file[f"episode_{i}"].attrs[minari_format.DIGEST_ATTRIBUTE] for i in (0, 1)]
        observation = file["episode_1/observations/observation"]
        offset = observation.id.get_chunk_info(0).byte_offset
        before = observation[5, 3]
        row = observation.shape[1]
    assert len(set(digests)) == 2 and all(len(d) == 64 for d in digests)
    assert len(demos.load_episodes(dataset, push_env)) == 2
    content = bytearray(data.read_bytes())
    content[offset + (5 * row + 3) * 8 + 2] ^= 0x10  # A low byte of observation[5, 3].
    data.write_bytes(bytes(content))
    with h5py.File(data, "r") as file:
        after = file["episode_1/observations/observation"][5, 3]
    assert after != before and np.isfinite(after) and abs(after - before) < 1e-9
    _refused(dataset, push_env, "the data of episode 1 is not what was recorded (its SHA-256 "
                                "differs from the one recorded in its main_data.hdf5): "
                                "damaged or edited since; record it again")
    with h5py.File(data, "r+") as file:
        del file["episode_1"].attrs[minari_format.DIGEST_ATTRIBUTE]
    assert len(demos.load_episodes(dataset, push_env)) == 2
