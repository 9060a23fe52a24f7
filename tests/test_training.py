"""Training, evaluation and plotting through the command line, on tiny runs."""

from __future__ import annotations

import json
import os
import pathlib
import re
import signal
import warnings
import shutil
import tempfile

import numpy as np
import pytest

import franka_composer
from franka_composer import cli
from franka_composer.training import ALGOS, TABLE_I, hyperparameters, machine
from franka_composer.training.callbacks import LatestCheckpoint
from franka_composer.training.loop import EVAL_SEED_OFFSET, FRESH_STREAM_SEED_OFFSET
from franka_composer.training.models import build_model, load_model, make_env
from franka_composer.training.run_config import RunConfig
from franka_composer.training.runs import RunDir, read_eval_rows

pytestmark = pytest.mark.slow  # Trains networks (and JAX), a few seconds each.

#: Small enough for seconds per run; learning starts after two 50-step episodes.
TINY = ["--net-arch", "16,16", "--batch-size", "32", "--buffer-size", "2000",
        "--learning-starts", "100", "--eval-every", "100", "--eval-episodes", "2",
        "--threads", "1", "--no-progress", "--device", "cpu"]


def _train(out, algo, steps, *extra, task="push"):
    return cli.main(["train", "--task", task, "--algo", algo, "--seed", "1",
                     "--out", str(out), "--total-steps", str(steps), *TINY, *extra])


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """One 300-step push run per algorithm."""
    root = tmp_path_factory.mktemp("runs")
    dirs = {}
    for algo in ALGOS:
        dirs[algo] = root / algo
        assert _train(dirs[algo], algo, 300) == 0
    return dirs


def test_table_i_is_the_papers():
    for (task, algo), hp in TABLE_I.items():
        wide = task == "slide"
        assert hp.net_arch == ((512,) * 3 if wide else (256,) * 3)
        assert hp.batch_size == (2048 if wide else 512)
        assert hp.total_steps == (1_000_000 if wide else 500_000)
        assert (hp.buffer_size, hp.learning_rate, hp.tau, hp.gamma) == (1_000_000, 1e-3,
                                                                         0.05, 0.95)
        assert (hp.eval_every, hp.eval_episodes) == (2000, 15)
        assert (hp.her_goal_selection_strategy, hp.her_n_sampled_goal) == ("future", 4)
        assert hp.action_noise_std == (None if algo == "tqc" else 0.2)
        assert hp.ent_coef == (None if algo == "ddpg" else "auto")
        assert hp.update_schedule == "step"
    tqc = hyperparameters("push", "tqc")
    assert (tqc.n_critics, tqc.n_quantiles, tqc.top_quantiles_to_drop_per_net) == (2, 25, 2)


def test_bad_names_are_value_errors_listing_choices(capsys):
    with pytest.raises(ValueError, match="ddpg, sac, tqc"):
        hyperparameters("push", "ppo")
    with pytest.raises(ValueError, match="push, slide, pick_and_place, reach, stack, flip"):
        hyperparameters("lift", "sac")
    with pytest.raises(ValueError, match="valid hyperparameters: .*batch_size"):
        hyperparameters("push", "sac").replace(batchsize=3)
    with pytest.raises(SystemExit) as exit:
        cli.main(["train", "--algo", "ppo"])
    assert exit.value.code == 2
    assert capsys.readouterr().err.endswith(
        "argument --algo: invalid choice: 'ppo' (choose from 'ddpg', 'sac', 'tqc')\n")


def test_built_model_has_table_i_settings():
    env = make_env("push")
    tqc = build_model("tqc", hyperparameters("push", "tqc"), env, seed=0, device="cpu")
    assert tqc.batch_size == 512 and tqc.tau == 0.05 and tqc.gamma == 0.95
    assert tqc.top_quantiles_to_drop_per_net == 2 and tqc.critic.n_quantiles == 25
    assert len(tqc.critic.q_networks) == 2 and tqc.critic.n_critics == 2
    assert [m.out_features for m in tqc.actor.latent_pi if hasattr(m, "out_features")] == [256] * 3
    assert tqc.replay_buffer.n_sampled_goal == 4 and tqc.action_noise is None
    sac = build_model("sac", hyperparameters("push", "sac").replace(
        update_schedule="episode", buffer_size=1000), env, seed=0, device="cpu")
    assert sac.action_noise._sigma.tolist() == [0.2] * 3
    assert (sac.train_freq.frequency, sac.train_freq.unit.value, sac.gradient_steps) == (
        1, "episode", -1)
    ddpg = build_model("ddpg", hyperparameters("push", "ddpg").replace(
        train_every=4, buffer_size=1000), env, seed=0, device="cpu")
    assert (ddpg.train_freq.frequency, ddpg.train_freq.unit.value, ddpg.gradient_steps) == (
        4, "step", 1)
    with pytest.raises(ValueError, match="train_every"):
        hyperparameters("push", "ddpg").replace(update_schedule="episode", train_every=4)
    env.close()


@pytest.mark.parametrize("algo", ALGOS)
def test_tiny_run_logs_evaluations_and_saves_model(runs, algo):
    run = RunDir(runs[algo])
    rows = read_eval_rows(run.eval_csv)
    assert [r["steps"] for r in rows] == [0, 100, 200, 300]
    assert all(0.0 <= r["success_rate"] <= 1.0 and -50 <= r["mean_reward"] <= 0 for r in rows)
    assert np.all(np.diff([r["wall_time_s"] for r in rows]) > 0)
    config = json.loads(run.config_path.read_text())
    assert (config["algo"], config["hyperparameters"]["net_arch"]) == (algo, [16, 16])
    env = make_env("push")
    assert load_model(algo, run.final_model, env=env, device="cpu").num_timesteps == 300
    env.close()
    assert 0 < run.policy_file.stat().st_size < run.final_model.stat().st_size / 2


def _committed_copy(run_root, to):
    """A run as the repository keeps it: config.json and policy.pt, nothing else."""
    to.mkdir()
    for name in ("config.json", "policy.pt"):
        (to / name).write_bytes((run_root / name).read_bytes())
    return to


@pytest.mark.parametrize("algo", ALGOS)
def test_a_policy_file_acts_as_the_trained_model_to_the_bit(runs, tmp_path, algo, capsys):
    from franka_composer.training.evaluation import measure_success
    from franka_composer.training.policy_file import ActorPolicy, load_trained

    committed = _committed_copy(runs[algo], tmp_path / "committed")
    env = make_env("push")
    full = load_trained(RunDir(runs[algo]), env, device="cpu")
    small = load_trained(RunDir(committed), env, device="cpu")
    assert isinstance(small, ActorPolicy) and small.num_timesteps == full.num_timesteps == 300
    assert not isinstance(full, ActorPolicy)  # The run's model.zip: two paths compared.
    obs, _ = env.reset(seed=3)
    for _ in range(20):
        action, _ = full.predict(obs, deterministic=True)
        np.testing.assert_array_equal(small.predict(obs, deterministic=True)[0], action)
        obs = env.step(env.action_space.sample())[0]
    assert measure_success(small, env, 3, seed=5) == measure_success(full, env, 3, seed=5)
    env.close()
    capsys.readouterr()
    reports = []  # The same final test: the same per-run line after the path, the same table.
    for root in (runs[algo], committed):
        assert cli.main(["evaluate", str(root), "--episodes", "2", "--device", "cpu"]) == 0
        reports.append(capsys.readouterr().out.replace(str(root), "RUN"))
    assert "300 steps" in reports[0] and reports[0] == reports[1]


@pytest.mark.parametrize("algo, backend", [("sac", "sb3"), ("tqc", "sbx")])
def test_a_table_i_policy_file_is_the_actor_alone(tmp_path, algo, backend):
    """Table I's push networks: a policy file is the actor's fp32 weights (under 1 MB) and a
    fraction of the model.zip (SB3's 2.3-2.9 MB, sbx's TQC 17.3 MB), so a policy per Table
    II cell stays far under 20 MB."""
    from franka_composer.training.policy_file import save_policy

    env = make_env("push")
    model = build_model(algo, hyperparameters("push", algo).replace(
        buffer_size=1000), env, seed=0, device="cpu", backend=backend)
    save_policy(model, tmp_path / "policy.pt")
    model.save(tmp_path / "model.zip")
    env.close()
    if backend == "sb3":
        actor_bytes = 4 * sum(p.numel() for p in model.actor.parameters())
    else:
        import jax

        actor_bytes = 4 * sum(leaf.size for leaf in
                              jax.tree_util.tree_leaves(model.policy.actor_state.params))
    assert actor_bytes < (tmp_path / "policy.pt").stat().st_size < actor_bytes + 20_000 < 10**6
    assert (tmp_path / "model.zip").stat().st_size > 4 * actor_bytes


def test_policy_files_refuse_what_they_cannot_load(runs, tmp_path):
    import torch

    from franka_composer.training.policy_file import _digest, load_trained

    env = make_env("push")
    committed = _committed_copy(runs["sac"], tmp_path / "committed")
    state = torch.load(committed / "policy.pt", weights_only=True)
    torch.save({**state, "format": 99}, committed / "policy.pt")
    with pytest.raises(ValueError, match="a policy file of format 99; this version of "
                                         "franka_composer reads format 1"):
        load_trained(RunDir(committed), env, device="cpu")
    # One flipped bit in a weight's bytes: torch's zip reader checks no checksum, and the
    # actor read was another (played without a word); so is one in the steps.
    torch.save(state, committed / "policy.pt")
    content = bytearray((committed / "policy.pt").read_bytes())
    name = sorted(state["actor"])[0]
    content[content.index(state["actor"][name].numpy().tobytes()[:64]) + 3] ^= 0x40
    (committed / "policy.pt").write_bytes(bytes(content))
    assert not torch.equal(torch.load(committed / "policy.pt", weights_only=True)["actor"][name],
                           state["actor"][name])
    for damaged in (committed / "policy.pt", {**state, "steps": state["steps"] + 1}):
        if isinstance(damaged, dict):
            torch.save(damaged, committed / "policy.pt")
        with pytest.raises(ValueError, match=re.escape(
                f"{committed / 'policy.pt'} is not the policy file its run wrote: its actor "
                "and steps do not give the SHA-256 it holds (damaged or edited since)")):
            load_trained(RunDir(committed), env, device="cpu")
    # A diverged actor (its digest its own): torch's distributions raised on its NaN, naming
    # no file.
    broken = {name: tensor.clone() for name, tensor in state["actor"].items()}
    name = sorted(broken)[-1]
    broken[name][0] = float("nan")
    torch.save({**state, "actor": broken, "sha256": _digest("sb3", state["steps"], broken)},
               committed / "policy.pt")
    with pytest.raises(ValueError, match=re.escape(
            f"{committed / 'policy.pt'}'s actor has parameters that are not finite (NaN or "
            f"inf in {name}): saved from a run that diverged?")):
        load_trained(RunDir(committed), env, device="cpu")
    for contents, message in (
            ((runs["sac"] / "policy.pt").read_bytes()[:1000],
             "is not a policy file \\(torch cannot read it: RuntimeError PytorchStreamReader"),
            (b"hello", "is not a policy file \\(torch cannot read it: "),
            # Not torch's advice to load it with weights_only=False, which runs any code in it.
            (np.random.default_rng(0).bytes(3000), "is not a policy file \\(torch cannot read "
                                                   "it: UnpicklingError Unsupported operand "
                                                   "95\\)$"),
            (None, "is not a policy file franka_composer wrote \\(no actor and steps in it")):
        if contents is None:
            torch.save([1, 2], committed / "policy.pt")
        else:
            (committed / "policy.pt").write_bytes(contents)
        with pytest.raises(ValueError, match=message):
            load_trained(RunDir(committed), env, device="cpu")
    # The SAC actor under a config.json that says DDPG: other layers.
    torch.save(state, committed / "policy.pt")
    config = json.loads((committed / "config.json").read_text())
    ddpg = json.loads((runs["ddpg"] / "config.json").read_text())
    (committed / "config.json").write_text(json.dumps({**config, "algo": "ddpg",
                                                       "hyperparameters":
                                                       ddpg["hyperparameters"]}))
    with pytest.raises(ValueError, match="its actor's parameters do not fit the network its "
                                         r"run's config.json describes \(ddpg, net_arch "
                                         r"\[16, 16\]\)"):
        load_trained(RunDir(committed), env, device="cpu")
    (committed / "policy.pt").unlink()
    with pytest.raises(ValueError, match="has no model yet \\(no model.zip, no checkpoint, "
                                         "no policy.pt\\)"):
        load_trained(RunDir(committed), env, device="cpu")
    env.close()


def test_a_run_opens_on_its_task_as_it_trained_and_its_env_closes_whatever_happens(
        runs, tmp_path):
    import gymnasium as gym

    from franka_composer.training.policy_file import ActorPolicy, trained_on_its_task

    committed = _committed_copy(runs["sac"], tmp_path / "committed")
    config = json.loads((committed / "config.json").read_text())
    (committed / "config.json").write_text(json.dumps({**config, "terminate_on_success": False}))
    opened = []
    with trained_on_its_task(committed, device="cpu",
                             wrap=lambda env: opened.append(env) or env) as (run, env, policy):
        assert run.task == "push" and env is opened[0] and isinstance(policy, ActorPolicy)
        assert env.unwrapped.task.config.terminate_on_success is False  # The run's option.
        assert policy.num_timesteps == 300
    # An actor that does not fit the network config.json describes: found loading it into
    # the env made for it, which then closes.
    hyperparameters = {**config["hyperparameters"], "net_arch": [8, 8]}
    (committed / "config.json").write_text(json.dumps({**config, "hyperparameters":
                                                       hyperparameters}))
    with pytest.raises(ValueError, match="its actor's parameters do not fit the network"):
        with trained_on_its_task(committed, wrap=lambda env: opened.append(env) or env):
            pass
    assert len(opened) == 2
    (committed / "policy.pt").write_bytes(b"")  # Not a policy file: refused before an env.
    with pytest.raises(ValueError, match="policy.pt is not a policy file"):
        with trained_on_its_task(committed, wrap=lambda env: opened.append(env) or env):
            pass
    (committed / "policy.pt").unlink()  # Nothing to load: refused before an env is made.
    with pytest.raises(ValueError, match="has no model yet"):
        with trained_on_its_task(committed, wrap=lambda env: opened.append(env) or env):
            pass
    assert len(opened) == 2
    for env in opened:
        with pytest.raises(gym.error.ClosedEnvironmentError, match="closed: make a new one"):
            env.reset(seed=0)


def test_demo_plays_a_trained_policy_on_its_task(runs, tmp_path, capsys):
    committed = _committed_copy(runs["tqc"], tmp_path / "committed")
    videos = tmp_path / "videos"
    assert cli.main(["demo", "--policy", str(committed), "--episodes", "2", "--out",
                     str(videos), "--width", "64", "--height", "48", "--video-episodes",
                     "1"]) == 0
    assert sorted(path.name for path in videos.iterdir()) == ["push.mp4", "push.png"]
    table = capsys.readouterr().out.splitlines()
    assert table[0].split()[:2] == ["task", "episodes"] and table[2].split()[:2] == ["push", "2"]
    with pytest.raises(ValueError, match="was trained on push; --tasks slide asks for others"):
        cli.main(["demo", "--policy", str(committed), "--tasks", "slide", "--no-video"])
    with pytest.raises(ValueError, match="acts through mocap control, not --control osc"):
        cli.main(["demo", "--policy", str(committed), "--control", "osc", "--no-video"])


def test_resume_continues_step_count_buffer_and_csv(tmp_path, monkeypatch):
    out = tmp_path / "run"
    assert _train(out, "sac", 200, "--checkpoint-every", "100") == 0
    state = RunDir(out).read_state()
    assert state["steps"] == 200 and state["checkpoint_every"] == 100
    assert RunDir(out).read_outcome()["steps"] == 200
    saved_at, outcomes, save = [], [], LatestCheckpoint.save

    def spy(self, *, exact):
        saved_at.append((self.model.num_timesteps, exact, self.episode_ended))
        outcomes.append(RunDir(out).read_outcome())
        save(self, exact=exact)

    monkeypatch.setattr(LatestCheckpoint, "save", spy)
    assert _train(out, "sac", 400, "--resume") == 0
    # The run's own cadence after a resume, not the default's: at the first episode end at
    # or after 300 (its episodes end at steps 250, 251, 301, 351), exact; then where it
    # ended, inside an episode: not exact.
    assert saved_at == [(301, True, True), (400, False, False)]
    assert outcomes == [{}, {}]  # Going on, it has not ended: no outcome until it does.
    rows = read_eval_rows(RunDir(out).eval_csv)
    assert [r["steps"] for r in rows] == [0, 100, 200, 300, 400]
    assert rows[3]["wall_time_s"] > state["wall_time_s"]
    env = make_env("push")
    model = load_model("sac", RunDir(out).final_model, env=env, device="cpu")
    model.load_replay_buffer(RunDir(out).checkpoint_buffer)
    assert model.num_timesteps == 400
    assert model.replay_buffer.size() == 400  # The first 200 came back from the checkpoint.
    env.close()
    # CPU seconds (the training process's) add up across the resume, as wall seconds do.
    outcome = RunDir(out).read_outcome()
    assert 0 < state["cpu_time_s"] < outcome["cpu_time_s"]
    assert state["wall_time_s"] < outcome["wall_time_s"]


def test_a_run_and_its_resume_leave_nothing_in_the_temporary_directory(tmp_path,
                                                                      monkeypatch):
    # SB3's default logger makes an empty SB3-<time> folder there on every learn(); torch
    # keeps its one compile cache there, made once.
    temporary = tmp_path / "temporary"
    temporary.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temporary))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    out = tmp_path / "run"
    assert _train(out, "sac", 150, "--checkpoint-every", "100") == 0
    assert _train(out, "sac", 250, "--resume") == 0
    assert RunDir(out).read_outcome()["steps"] == 250
    assert [path.name for path in temporary.iterdir()
            if not path.name.startswith("torchinductor_")] == []


def _stop_asked_at(monkeypatch, steps: int) -> None:
    """SIGTERM's effect on the run's checkpoint callback, from its step `steps` on."""
    on_step = LatestCheckpoint._on_step

    def asked(self):
        if self.num_timesteps >= steps:
            self.stop_requested_by = signal.SIGTERM
        return on_step(self)

    monkeypatch.setattr(LatestCheckpoint, "_on_step", asked)


def _trained_state(out, algo, backend):
    """Everything a run's outcome is made of: its evaluations, the final model's
    parameters and the replay buffer's contents."""
    env = make_env(RunDir(out).read_config().task)
    model = load_model(algo, RunDir(out).final_model, env=env, device="cpu", backend=backend)
    model.load_replay_buffer(RunDir(out).checkpoint_buffer)
    buffer = model.replay_buffer
    stored = {name: getattr(buffer, name)[:buffer.pos].copy()
              for name in ("actions", "rewards", "dones")}
    stored.update({f"obs.{k}": v[:buffer.pos].copy() for k, v in buffer.observations.items()})
    if backend == "sbx":
        import jax

        states = {name: state.params for name, state in vars(model.policy).items()
                  if name.endswith("_state")}  # The actor's and the critics' TrainStates.
        assert "actor_state" in states and len(states) >= 2
        parameters = [np.asarray(leaf) for leaf in jax.tree_util.tree_leaves(states)]
    else:
        parameters = [p.detach().numpy().copy() for p in model.policy.parameters()]
    env.close()
    return read_eval_rows(RunDir(out).eval_csv), parameters, stored


def _assert_trained_alike(whole, resumed, algo, backend):
    """The resumed run trained, evaluated and stored what the uninterrupted run did, to the
    bit, and its outcome says it is that run (no fresh episode stream); returns the whole
    run's `_trained_state`."""
    # Resumed on the machine it began on: one machine, as the uninterrupted run's.
    assert (RunDir(resumed).read_outcome()["machines"] == RunDir(whole).read_outcome()["machines"]
            == [{"from_steps": 0, **machine.fingerprint()}])
    whole, resumed_state = (_trained_state(out, algo, backend) for out in (whole, resumed))
    for row in (*whole[0], *resumed_state[0]):
        del row["wall_time_s"]
    assert resumed_state[0] == whole[0]
    assert RunDir(resumed).read_outcome()["fresh_streams"] == []
    assert len(resumed_state[1]) == len(whole[1]) > 0
    for a, b in zip(resumed_state[1], whole[1]):
        np.testing.assert_array_equal(a, b)
    assert resumed_state[2].keys() == whole[2].keys()
    for name in whole[2]:
        np.testing.assert_array_equal(resumed_state[2][name], whole[2][name])
    return whole


@pytest.mark.parametrize("algo, backend, schedule, learning_starts, stop_at", [
    *((algo, backend, "step", 100, 160) for backend in ("sb3", "sbx") for algo in ALGOS),
    ("sac", "sb3", "episode", 100, 160),
    # Among its random steps (issue 37's checks take 1e5; one was stopped at 96,415): it
    # resumes drawing the actions the uninterrupted run draws.
    ("tqc", "sbx", "step", 300, 60), ("sac", "sb3", "step", 300, 60)])
def test_a_stopped_run_resumes_as_the_uninterrupted_run_to_the_bit(
        tmp_path, monkeypatch, algo, backend, schedule, learning_starts, stop_at):
    """Stopped (SIGTERM, Ctrl-C) inside an episode, a run checkpoints at that episode's end
    and exits; resumed, it trains, evaluates and stores what the uninterrupted run does."""
    options = ["--backend", backend, "--checkpoint-every", "100000",
               "--update-schedule", schedule, "--learning-starts", str(learning_starts)]
    assert _train(tmp_path / "whole", algo, 400, *options) == 0
    with monkeypatch.context() as patch:
        _stop_asked_at(patch, stop_at)  # Asked inside an episode; it ends by stop_at + 40.
        assert _train(tmp_path / "stopped", algo, 400, *options) == 143  # 128 + SIGTERM.
    state = RunDir(tmp_path / "stopped").read_state()
    assert state["exact"] and stop_at < state["steps"] <= stop_at + 40
    assert RunDir(tmp_path / "stopped").checkpoint_generators.is_file()
    resume = ["--resume", "--learning-starts", str(learning_starts)]  # TINY's says 100.
    assert _train(tmp_path / "stopped", algo, 400, *resume) == 0
    whole = _assert_trained_alike(tmp_path / "whole", tmp_path / "stopped", algo, backend)
    # The episode schedule trains on whole episodes: its run ends with its episode, at 401.
    ended = {"step": 400, "episode": 401}[schedule]
    assert [r["steps"] for r in whole[0]] == sorted({0, 100, 200, 300, 400, ended})
    assert len(whole[2]["actions"]) == ended


def test_a_campaign_cell_stopped_and_resumed_is_the_uninterrupted_run_to_the_bit(
        tmp_path, monkeypatch):
    """Issue 37's SAC cells, small: pick-and-place at the reference timing, its gradient
    steps in bf16. (Their runs begun again on another machine left the kept evaluations:
    a machine can change a course; on one machine a resume does not.)"""
    options = ["--precision", "bf16", "--timing", "reference"]
    assert _train(tmp_path / "whole", "sac", 400, *options, task="pick_and_place") == 0
    with monkeypatch.context() as patch:
        _stop_asked_at(patch, 160)
        assert _train(tmp_path / "stopped", "sac", 400, *options,
                      task="pick_and_place") == 143
    assert RunDir(tmp_path / "stopped").read_state()["exact"]
    assert cli.main(["train", "--out", str(tmp_path / "stopped"), "--resume",
                     "--learning-starts", "100", "--no-progress"]) == 0
    _assert_trained_alike(tmp_path / "whole", tmp_path / "stopped", "sac", "sb3")


def test_a_stopped_run_closes_its_progress_bar(tmp_path, monkeypatch):
    """Stopped by SIGTERM, a run with its progress bar closes the bar: one left open is
    closed by the garbage collector, at interpreter shutdown, where rich's close fails
    ("Exception ignored in tqdm.__del__ ... sys.meta_path is None")."""
    import gc

    from tqdm.std import tqdm

    _stop_asked_at(monkeypatch, 160)
    made, init = [], tqdm.__init__

    def recorded(bar, *args, **kwargs):  # Each bar, and whether it was shown when made.
        init(bar, *args, **kwargs)
        made.append((bar, not bar.disable))

    monkeypatch.setattr(tqdm, "__init__", recorded)
    options = [o for o in TINY if o != "--no-progress"]  # The bar is on by default.
    gc.disable()  # Nothing closes a bar that was left open before the test looks.
    try:
        assert cli.main(["train", "--task", "push", "--algo", "sac", "--seed", "1", "--out",
                         str(tmp_path / "run"), "--total-steps", "400", *options]) == 143
        assert RunDir(tmp_path / "run").read_state()["steps"] >= 160
        shown = [bar for bar, was_shown in made if was_shown]
        assert shown  # The run had a bar to close.
        assert [bar for bar in shown if not bar.disable] == []  # close() disables a bar.
    finally:
        gc.enable()


def _evaluations(out) -> list[tuple]:
    """A run's eval.csv rows without their wall-clock times: what a rerun gives again."""
    return [(r["steps"], r["success_rate"], r["mean_reward"])
            for r in read_eval_rows(RunDir(out).eval_csv)]


def _stopped_at_once_in(monkeypatch, callback, steps: int) -> None:
    """A stop at once (a second signal) in `callback`'s step at step `steps`."""
    on_step = callback._on_step

    def interrupted(self):
        if self.num_timesteps == steps:
            raise KeyboardInterrupt("signal 15, again")
        return on_step(self)

    monkeypatch.setattr(callback, "_on_step", interrupted)


def _stop_at_once(out, steps: int, monkeypatch) -> None:
    """A SAC run of 400 steps into `out`, stopped at once (a second SIGTERM) at `steps`: its
    checkpoint there is not at an episode's end."""
    with monkeypatch.context() as patch:
        _stopped_at_once_in(patch, LatestCheckpoint, steps)
        assert _train(out, "sac", 400) == 143


def test_a_run_stopped_at_once_resumes_with_a_fresh_episode_stream(tmp_path, monkeypatch):
    """A checkpoint that is not at an episode's end (a second signal, checkpoints written
    before resumes were exact) resumes with episodes seeded by the run's seed and step."""
    out = tmp_path / "run"
    _stop_at_once(out, 130, monkeypatch)
    assert RunDir(out).read_state() == {**RunDir(out).read_state(), "steps": 130,
                                        "exact": False}
    assert not RunDir(out).checkpoint_generators.exists()
    seeds, threads = [], []
    with monkeypatch.context() as patch:
        from stable_baselines3 import SAC

        from franka_composer.cli import train as train_command

        set_random_seed = SAC.set_random_seed
        patch.setattr(SAC, "set_random_seed",
                      lambda self, seed: seeds.append(seed) or set_random_seed(self, seed))
        limit_threads = train_command._limit_threads
        patch.setattr(train_command, "_limit_threads",
                      lambda count, backend: threads.append(count) or limit_threads(count,
                                                                                  backend))
        # Without --threads: the run's own (TINY's 1), which its checkpoint recorded.
        with pytest.warns(RuntimeWarning, match=re.escape(
                "its checkpoint at step 130 was not written where a resume goes on exactly "
                "(an episode's end, with the random generators saved); the run goes on with "
                "a fresh episode stream and from here is not the run an uninterrupted one "
                "would be")) as warned:
            assert cli.main(["train", "--resume", "--out", str(out), "--total-steps", "200",
                             "--no-progress", "--device", "cpu"]) == 0
        # That warning alone: not SB3's advice to pass an option train does not have.
        assert not [w for w in warned if "truncate_last_trajectory" in str(w.message)]
    # The run's seed and step, above the evaluation's seed: at step 10,000 they met.
    assert seeds[-1] == 1 + FRESH_STREAM_SEED_OFFSET + 130
    assert FRESH_STREAM_SEED_OFFSET > EVAL_SEED_OFFSET
    assert threads == [1] and RunDir(out).read_state()["threads"] == 1
    assert [r["steps"] for r in read_eval_rows(RunDir(out).eval_csv)] == [0, 100, 200]
    # Where it left the uninterrupted run's course, in its last checkpoint and its outcome.
    assert RunDir(out).read_state()["fresh_streams"] == [130]
    assert RunDir(out).read_outcome()["fresh_streams"] == [130]
    # Carried on by a later resume, which adds its own: the run ended at its budget, 200,
    # inside an episode, so the raised budget goes on with a fresh stream there too.
    assert not RunDir(out).read_state()["exact"]
    assert _train(out, "sac", 300, "--resume") == 0
    assert RunDir(out).read_outcome()["fresh_streams"] == [130, 200]


def test_a_resume_at_its_checkpoints_step_ends_with_the_evaluation_there(tmp_path,
                                                                        monkeypatch):
    """Stopped at once at step 130 and resumed with --total-steps 130: nothing is left to
    train, and the run ends as the uninterrupted run of 130 steps does, with an evaluation
    at its last step, the same to the digit (it ended without one), on no fresh stream and
    without the warning that it goes on with one (it recorded one, training nothing)."""
    out = tmp_path / "run"
    _stop_at_once(out, 130, monkeypatch)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        assert _train(out, "sac", 130, "--resume") == 0
    assert _train(tmp_path / "whole", "sac", 130) == 0

    assert [row[0] for row in _evaluations(out)] == [0, 100, 130]
    assert _evaluations(out) == _evaluations(tmp_path / "whole")
    outcome = RunDir(out).read_outcome()
    assert outcome["steps"] == 130 and outcome["fresh_streams"] == []


def _evaluation_cut_short_at(monkeypatch, steps: int) -> None:
    """A stop at once (a second signal) inside the evaluation at step `steps`, before its
    row is written."""
    from franka_composer.training.callbacks import RecordEvaluation

    _stopped_at_once_in(monkeypatch, RecordEvaluation, steps)


def test_an_evaluation_cut_short_by_a_stop_at_once_is_made_on_resume(tmp_path, monkeypatch):
    """A second signal inside the evaluation at step 200 leaves a checkpoint there without
    its row in eval.csv: the resume evaluates there first, as the uninterrupted run did, to
    the digit (the same model, on the same evaluation episodes)."""
    out = tmp_path / "run"
    with monkeypatch.context() as patch:
        _evaluation_cut_short_at(patch, 200)
        assert _train(out, "sac", 300) == 143
    assert RunDir(out).read_state()["steps"] == 200
    assert [r["steps"] for r in read_eval_rows(RunDir(out).eval_csv)] == [0, 100]
    with pytest.warns(RuntimeWarning, match="fresh episode stream"):
        assert _train(out, "sac", 300, "--resume") == 0
    assert _train(tmp_path / "whole", "sac", 300) == 0

    assert [row[0] for row in _evaluations(out)] == [0, 100, 200, 300]
    assert _evaluations(out)[:3] == _evaluations(tmp_path / "whole")[:3]


def test_an_interrupt_in_the_evaluation_at_a_resumes_end_leaves_its_exact_checkpoint(
        tmp_path, monkeypatch):
    """Resumed at its checkpoint's step, a run only evaluates: stopped at once there, its
    exact checkpoint was written over as one that is not (and its generators lost)."""
    from franka_composer.training.callbacks import Evaluation

    out = tmp_path / "run"
    with monkeypatch.context() as patch:
        _stop_asked_at(patch, 110)  # Off the evaluations' grid: its end is evaluated.
        assert _train(out, "sac", 400) == 143
    steps = RunDir(out).read_state()["steps"]
    assert RunDir(out).read_state()["exact"] and steps % 100

    def interrupted(self):
        raise KeyboardInterrupt("signal 2, again")

    with monkeypatch.context() as patch:
        patch.setattr(Evaluation, "_evaluate_now", interrupted)
        assert _train(out, "sac", steps, "--resume") == 130  # A second Ctrl-C's.
    assert RunDir(out).read_state()["exact"] and RunDir(out).read_state()["steps"] == steps
    assert RunDir(out).checkpoint_generators.is_file()


def test_a_checkpoint_whose_env_does_not_come_back_resumes_with_a_warning(tmp_path,
                                                                          monkeypatch):
    """An exact checkpoint whose rebuilt env differs from the one it saw (here: its episode
    stream's seed altered) is not resumed as if it were exact."""
    import pickle

    from franka_composer.training.run_files import file_digests

    out = tmp_path / "run"
    with monkeypatch.context() as patch:
        _stop_asked_at(patch, 160)
        assert _train(out, "sac", 400) == 143
    generators = RunDir(out).checkpoint_generators
    state = pickle.loads(generators.read_bytes())
    state["stream"]["seed"] = 99
    generators.write_bytes(pickle.dumps(state))
    checkpoint = RunDir(out).read_state()  # Its digest, of the file as it now is.
    digest = file_digests(RunDir(out).checkpoint)[generators.name]
    RunDir(out).checkpoint_state.write_text(json.dumps(
        {**checkpoint, "sha256": {**checkpoint["sha256"], generators.name: digest}}))
    steps = checkpoint["steps"]
    with pytest.warns(RuntimeWarning, match="did not come back as its checkpoint saw it; the "
                                            "run goes on with a fresh episode stream"):
        assert _train(out, "sac", steps + 50, "--resume") == 0
    assert RunDir(out).read_outcome()["steps"] == steps + 50
    assert RunDir(out).read_outcome()["fresh_streams"] == [steps]


def test_cpu_time_stays_unknown_after_a_checkpoint_that_did_not_record_it(tmp_path):
    out = tmp_path / "run"
    assert _train(out, "ddpg", 100, "--checkpoint-every", "100") == 0
    state = RunDir(out).read_state()
    assert state["cpu_time_s"] > 0 and RunDir(out).read_outcome()["cpu_time_s"] > 0
    del state["cpu_time_s"]  # As checkpoints written before CPU time was recorded.
    RunDir(out).checkpoint_state.write_text(json.dumps(state))
    assert _train(out, "ddpg", 200, "--resume") == 0
    assert RunDir(out).read_outcome()["cpu_time_s"] is None
    assert RunDir(out).read_state()["cpu_time_s"] is None


def test_fresh_streams_stay_unknown_after_a_checkpoint_that_did_not_record_them(tmp_path):
    """A run resumed from a checkpoint written before fresh streams were recorded may have
    left its course before: its outcome says unknown (null), not [] (the uninterrupted
    run)."""
    out = tmp_path / "run"
    assert _train(out, "ddpg", 100, "--checkpoint-every", "100") == 0
    state = RunDir(out).read_state()
    assert state["fresh_streams"] == [] and RunDir(out).read_outcome()["fresh_streams"] == []
    del state["fresh_streams"]
    RunDir(out).checkpoint_state.write_text(json.dumps(state))
    assert _train(out, "ddpg", 200, "--resume") == 0
    assert RunDir(out).read_outcome()["fresh_streams"] is None
    assert RunDir(out).read_state()["fresh_streams"] is None


def test_a_resume_on_another_machine_says_what_differs_and_records_it(tmp_path):
    """The checkpoint's machine had other vector instructions and another torch: the resume
    goes on, warns naming both, and the run's outcome lists both machines, each from the
    step it began there."""
    out = tmp_path / "run"
    assert _train(out, "ddpg", 100, "--checkpoint-every", "100") == 0
    here = machine.fingerprint()
    state = RunDir(out).read_state()
    assert state["machines"] == RunDir(out).read_outcome()["machines"] == [
        {"from_steps": 0, **here}]
    there = json.loads(json.dumps(here))
    there["vector_isa"] = [*(there["vector_isa"] or []), "avx10_2"]
    there["libraries"]["torch"] = "2.12.0"
    state["machines"] = [{"from_steps": 0, **there}]
    RunDir(out).checkpoint_state.write_text(json.dumps(state))
    with pytest.warns(RuntimeWarning, match=re.escape(
            "resumed from its checkpoint at step 100 on another machine (vector instruction "
            f"sets without avx10_2 now; torch 2.12.0 then, {here['libraries']['torch']} "
            "now): a resume there is exact, but from there a run's floating-point results, "
            "and so its course, can differ from the ones the machine before would have "
            "computed (recorded as machines")):
        assert _train(out, "ddpg", 200, "--resume") == 0
    assert RunDir(out).read_outcome()["machines"] == [{"from_steps": 0, **there},
                                                      {"from_steps": 100, **here}]
    assert RunDir(out).read_state()["machines"] == RunDir(out).read_outcome()["machines"]


def test_machines_start_at_the_resume_after_a_checkpoint_that_did_not_record_them(tmp_path):
    """Where the checkpoint predates the record, the list starts at its step: the machines
    before it are unknown, not this one."""
    out = tmp_path / "run"
    assert _train(out, "ddpg", 100, "--checkpoint-every", "100") == 0
    state = RunDir(out).read_state()
    del state["machines"]
    RunDir(out).checkpoint_state.write_text(json.dumps(state))
    assert _train(out, "ddpg", 200, "--resume") == 0
    assert RunDir(out).read_outcome()["machines"] == [
        {"from_steps": 100, **machine.fingerprint()}]


def test_a_run_stopped_while_writing_a_checkpoint_resumes_from_the_one_before(tmp_path,
                                                                            monkeypatch):
    """The second checkpoint fails halfway (a full disk): the first stays whole, and the
    resume goes on from it and clears what the failure left."""
    from franka_composer.training import exact_resume

    out, calls, save = tmp_path / "run", [], exact_resume.save

    def failing(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise OSError("No space left on device")
        return save(*args, **kwargs)

    monkeypatch.setattr(exact_resume, "save", failing)
    with pytest.raises(OSError, match="No space left on device"):
        _train(out, "sac", 300, "--checkpoint-every", "100")
    run = RunDir(out)
    first = run.read_state()["steps"]
    assert 100 <= first < 200 and (run.checkpoint_model.is_file()
                                   and run.checkpoint_buffer.is_file())
    assert len(list(run.root.glob("checkpoint-*"))) == 2  # The latest, and the failed one.
    monkeypatch.setattr(exact_resume, "save", save)
    assert _train(out, "sac", 300, "--resume") == 0
    assert run.read_state()["steps"] >= 300 and len(list(run.root.glob("checkpoint-*"))) == 1
    assert [r["steps"] for r in read_eval_rows(run.eval_csv)] == [0, 100, 200, 300]


def test_existing_run_needs_resume_and_resume_needs_checkpoint(runs, tmp_path):
    with pytest.raises(ValueError, match=re.escape(
            f"{runs['ddpg']} already holds a run; pass --resume to continue it")):
        _train(runs["ddpg"], "ddpg", 300)
    RunDir(tmp_path / "bare").write_config(RunDir(runs["ddpg"]).read_config())
    with pytest.raises(ValueError, match="no complete checkpoint"):
        _train(tmp_path / "bare", "ddpg", 300, "--resume")
    # Its checkpoint's folder removed: the link named, not "delete it to start again",
    # which would have lost the finished model.
    lost = RunDir(shutil.copytree(runs["ddpg"], tmp_path / "lost", symlinks=True))
    target = os.readlink(lost.checkpoint)
    shutil.rmtree(lost.root / target)
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{lost.checkpoint} links to {target}, which is missing (removed?): put it back "
            "to resume; the run's other files are as they were") + "$"):
        _train(lost.root, "ddpg", 400, "--resume")
    assert lost.final_model.is_file() and lost.checkpoint.is_symlink()


@pytest.mark.parametrize("argv, sizes, allocation", [
    (["--buffer-size", "1000000000000"], ("1,000,000,000,000", "16,16"),
     "Unable to allocate 21.8 TiB for an array with shape (1000000000000, 1, 3) and data type "
     "float64"),
    # More elements than numpy's index type counts: its ValueError named no option. (Past
    # int64 the count is refused as parsed.)
    (["--buffer-size", "4e18"], ("4,000,000,000,000,000,000", "16,16"),
     "array is too big"),
    # Found before anything is built: sbx's networks are allocated by JAX at their first
    # use, later, where it ended in JAX's traceback.
    *[(["--backend", backend, "--net-arch", "10000000,10000000"],
       ("2,000", "10000000,10000000"), "the weights of one actor and one critic alone take "
       "745,059.2 GiB (float32), and the machine has ") for backend in ("sb3", "sbx")],
    # Past that check (a machine said to have more), torch's allocator's refusal.
    (["--net-arch", "10000000,10000000", "more memory"], ("2,000", "10000000,10000000"),
     "DefaultCPUAllocator: can't allocate memory: you tried to allocate 400000000000000 "
     "bytes")])
def test_a_model_too_large_for_the_memory_is_one_line_naming_its_options(
        tmp_path, capsys, monkeypatch, argv, sizes, allocation):
    """numpy's MemoryError, torch's allocator's RuntimeError and JAX's came as tracebacks."""
    if argv[-1] == "more memory":
        from franka_composer.training import models

        monkeypatch.setattr(models, "_physical_memory_bytes", lambda: 2**62)
        argv = argv[:-1]
    if "sbx" in argv:
        pytest.importorskip("sbx")
    out = tmp_path / "run"
    assert cli.console(["train", "--task", "reach", "--algo", "sac", "--out", str(out),
                        "--total-steps", "200", *TINY, *argv]) == 1
    error = capsys.readouterr().err
    assert error.startswith(
        f"franka-composer: error: the replay buffer (--buffer-size {sizes[0]}) and networks "
        f"(--net-arch {sizes[1]}) do not fit in this machine's memory: ") and allocation in error
    assert len(error.splitlines()) == 1 and not out.exists()


def test_a_run_that_cannot_train_is_refused_before_its_folder_is_made(tmp_path):
    """Thousands of threads or a batch larger than the buffer would stall the run (past
    SIGTERM's stop at an episode's end) or exhaust memory: refused first."""
    cpus = len(os.sched_getaffinity(0))
    out = tmp_path / "run"
    with pytest.raises(ValueError, match=re.escape(
            f"--threads {cpus + 1} is more than the {cpus} CPUs this process may use")):
        _train(out, "sac", 100, "--threads", str(cpus + 1))
    with pytest.raises(ValueError, match=re.escape(
            "--batch-size 4000 is larger than the replay buffer (--buffer-size 2000) it is "
            "sampled from")):
        _train(out, "sac", 100, "--batch-size", "4000")
    with pytest.raises(ValueError, match=re.escape(
            "the scripted experts act on dx, dy, dz, which the joints controller does not "
            "take: use control='mocap' or 'osc'")):
        _train(out, "sac", 100, "--control", "joints", "--expert-demos", "2")
    assert not out.exists()
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    with pytest.raises(ValueError, match=re.escape(
            f"{out} is not empty and holds no run: give a new or empty folder as --out")):
        _train(out, "sac", 100)
    assert [path.name for path in out.iterdir()] == ["notes.txt"]


def test_a_new_run_that_fails_before_its_first_checkpoint_leaves_nothing(tmp_path,
                                                                          monkeypatch):
    from franka_composer.training import loop

    def failing(*args, **kwargs):
        raise RuntimeError("the model could not be built")

    monkeypatch.setattr(loop, "build_model", failing)
    made, given, nested = tmp_path / "made", tmp_path / "given", tmp_path / "new" / "a" / "b"
    given.mkdir()
    for out in (made, given, nested):
        with pytest.raises(RuntimeError, match="the model could not be built"):
            _train(out, "sac", 100)
    assert not made.exists() and list(given.iterdir()) == []  # The folder given stays.
    # The folders made on the way go with it (an empty new/a stayed).
    assert sorted(path.name for path in tmp_path.iterdir()) == ["given"]
    # Through `..`: the folder given stays, and none is made on the way (by the path's
    # text, `x/..` was taken for a folder made, and given removed).
    with pytest.raises(RuntimeError, match="the model could not be built"):
        _train(tmp_path / "x" / ".." / "given" / "run", "sac", 100)
    assert sorted(path.name for path in tmp_path.iterdir()) == ["given"]
    assert list(given.iterdir()) == []


@pytest.mark.parametrize("signum, status", [(signal.SIGTERM, 143), (signal.SIGINT, 130)],
                         ids=["SIGTERM", "SIGINT"])
def test_a_new_run_stopped_before_its_first_checkpoint_leaves_nothing_and_says_so(
        tmp_path, monkeypatch, capsys, ctrl_c_reaches_the_process, signum, status):
    """SIGTERM while the run records its expert's demonstrations (before training) killed
    it and left config.json and the lock: a folder that could be neither started again
    nor resumed. Ctrl-C there said a checkpoint was saved. Each exits with its signal's
    status, 128 + its number (both were 130)."""
    from franka_composer.training import demos

    def stopped(*args, **kwargs):
        os.kill(os.getpid(), signum)
        raise AssertionError(f"{signal.Signals(signum).name} did not stop the run")

    def unhandled(received, frame):
        raise AssertionError("the run left SIGTERM to the default, which kills the process")

    monkeypatch.setattr(demos, "record_expert", stopped)
    out = tmp_path / "run"
    previous = signal.signal(signal.SIGTERM, unhandled)
    try:
        assert _train(out, "sac", 200, "--expert-demos", "2") == status
        assert signal.getsignal(signal.SIGTERM) is unhandled  # Restored after the run.
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert not out.exists()
    assert capsys.readouterr().out == ("interrupted before its first checkpoint: nothing of "
                                       "the run is kept; the same command starts it again\n")
    monkeypatch.undo()
    assert _train(out, "sac", 200, "--expert-demos", "2") == 0  # Starts again.


@pytest.mark.parametrize("where", ["checks", "threads"])
def test_a_new_run_stopped_in_its_checks_or_while_its_threads_are_limited_leaves_nothing(
        tmp_path, monkeypatch, capsys, where):
    """SIGTERM while the checks load --demos printed a KeyboardInterrupt traceback; while
    the threads were limited (sbx starts JAX there) it left config.json behind."""
    import contextlib

    from franka_composer.cli import train

    if where == "checks":
        def stopped(args):
            os.kill(os.getpid(), signal.SIGTERM)
        monkeypatch.setattr(train, "check_new_run", stopped)
        said = "interrupted before training: nothing was written\n"
    else:
        @contextlib.contextmanager
        def stopped(threads, backend):
            os.kill(os.getpid(), signal.SIGTERM)
            yield
        monkeypatch.setattr(train, "_limit_threads", stopped)
        said = ("interrupted before its first checkpoint: nothing of the run is kept; the "
                "same command starts it again\n")
    out = tmp_path / "run"
    assert _train(out, "sac", 200) == 143
    assert not out.exists()
    assert capsys.readouterr().out == said


def test_a_resume_of_a_run_training_before_its_first_checkpoint_says_it_is_training(
        tmp_path):
    """It said the run had stopped before its first checkpoint: delete it."""
    from franka_composer.training.run_config import RunConfig

    out = tmp_path / "run"
    run = RunDir(out)
    run.write_config(RunConfig("push", "sac", 1, hyperparameters("push", "sac")))  # As begun.
    with run.training_lock():
        with pytest.raises(ValueError, match=re.escape(
                f"{out} is being trained by process {os.getpid()} on ")):
            cli.main(["train", "--resume", "--out", str(out)])
    with pytest.raises(ValueError, match=re.escape(
            f"{out} has no complete checkpoint to resume from (it stopped before its first "
            "one): delete it to start again")):
        cli.main(["train", "--resume", "--out", str(out)])


def test_a_resume_keeps_what_the_run_trained_and_its_evaluations(runs, tmp_path):
    run = RunDir(runs["sac"])
    steps, config = run.read_state()["steps"], run.config_path.read_text()
    with pytest.raises(ValueError, match=re.escape(
            f"{run.root} has trained {steps} steps already, more than --total-steps 100")):
        cli.main(["train", "--resume", "--out", str(run.root), "--total-steps", "100"])
    assert run.config_path.read_text() == config
    copy = tmp_path / "copy"
    shutil.copytree(run.root, copy)
    (copy / "eval.csv").unlink()
    (copy / "training.lock").unlink()  # Copied from the run: a refusal must not make one.
    files = {path.name: path.read_bytes() for path in copy.iterdir() if path.is_file()}
    with pytest.raises(ValueError, match=re.escape(
            f"{copy / 'eval.csv'} is missing: the run's evaluations up to its checkpoint would "
            "be lost; put it back to resume")):
        cli.main(["train", "--resume", "--out", str(copy), "--total-steps", "400"])
    # Refused before anything is written: not the raised budget into its config.json, nor a
    # lock file it did not have.
    assert {path.name: path.read_bytes() for path in copy.iterdir() if path.is_file()} == files
    kept = tmp_path / "kept"  # As results/ keeps a run: its config and evaluations alone.
    kept.mkdir()
    for name in ("config.json", "eval.csv"):
        shutil.copy(run.root / name, kept / name)
    with pytest.raises(ValueError, match=re.escape(
            f"{kept} has no complete checkpoint to resume from (it stopped before its first "
            "one): delete it to start again")):
        cli.main(["train", "--resume", "--out", str(kept), "--total-steps", "7777"])
    assert sorted(path.name for path in kept.iterdir()) == ["config.json", "eval.csv"]
    assert (kept / "config.json").read_bytes() == (run.root / "config.json").read_bytes()


def _copied_run(runs, tmp_path, name: str) -> RunDir:
    copy = RunDir(shutil.copytree(runs["sac"], tmp_path / name, symlinks=True))
    (copy.root / "training.lock").unlink()
    return copy


def _files(run: RunDir) -> dict:
    return {path.name: path.read_bytes() for path in run.root.iterdir() if path.is_file()}


@pytest.mark.parametrize("edit, problem", [
    # Read as a checkpoint at step -5: the resume dropped every evaluation above it.
    ({"steps": -5}, "its steps must be a whole number, 0 or more, got -5"),
    ({"checkpoint_every": 0}, "its checkpoint_every must be a whole number, 1 or more, got 0"),
    ({"wall_time_s": None}, "it has no wall_time_s"),
    ({"wall_time_s": "x"}, "its wall_time_s must be a number of seconds, 0 or more, got 'x'"),
    ({"threads": "1"}, "its threads must be a whole number, 1 or more, got '1'"),
    ({"machines": [1, 2]}, "its machines must be a list of objects, each with its "
                           "from_steps, got [1, 2]")])
def test_a_resume_refuses_a_damaged_checkpoint_state_by_name(runs, tmp_path, edit, problem):
    """Each was a traceback (ZeroDivisionError, KeyError, AttributeError) or, for negative
    steps, evaluations lost for good."""
    copy = _copied_run(runs, tmp_path, "copy")
    state = json.loads(copy.checkpoint_state.read_text())
    state.update(edit)
    copy.checkpoint_state.write_text(json.dumps({k: v for k, v in state.items()
                                                 if v is not None}))
    files = _files(copy)
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{copy.checkpoint_state} is not a checkpoint's state (edited or damaged?): "
            f"{problem}") + "$"):
        cli.main(["train", "--resume", "--out", str(copy.root), "--total-steps", "400"])
    assert _files(copy) == files


def test_a_resume_refuses_a_checkpoint_whose_steps_or_evaluations_do_not_add_up(runs,
                                                                               tmp_path):
    """A state.json that says other steps than its model was saved at, and an eval.csv
    lacking evaluations the checkpoint passed, were resumed without a word: the
    evaluations after it went on with other episodes than the run's (they follow the count
    of rows kept), its curve with a gap."""
    run = RunDir(runs["sac"])
    assert run.read_state()["steps"] == 300
    steps = _copied_run(runs, tmp_path, "steps")
    state = json.loads(steps.checkpoint_state.read_text())
    steps.checkpoint_state.write_text(json.dumps({**state, "steps": 9999}))
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{steps.checkpoint_state} says 9,999 steps, and the model beside it was saved at "
            "step 300: edited, or another checkpoint's?") + "$"):
        cli.main(["train", "--resume", "--out", str(steps.root), "--total-steps", "400"])
    rows = run.eval_csv.read_text().splitlines(keepends=True)
    assert [row.split(",")[0] for row in rows] == ["steps", "0", "100", "200", "300"]
    lacks = ("{csv} lacks {missing} (one every 100 steps from 0 to the checkpoint's 300): the "
             "resumed run's evaluations would go on with other episodes than the run's, and "
             "its curve with a gap; put them back (edited or cut?), or start the run again")
    # (The run has ended at 300: an eval.csv that stops before then is cut short, which is
    # said first.)
    cut = ("{csv} ends at step 0, and the run ended at step 300 (outcome.json), where it "
           "evaluated last: cut short, or another run's?")
    for kept, message, missing in (([0, 1, 3, 4], lacks, "the evaluation at step 100"),
                                   ([0, 1], cut, None)):
        copy = _copied_run(runs, tmp_path, f"rows-{len(kept)}")
        copy.eval_csv.write_text("".join(rows[i] for i in kept))
        files = _files(copy)
        with pytest.raises(ValueError, match="^" + re.escape(
                message.format(csv=copy.eval_csv, missing=missing)) + "$"):
            cli.main(["train", "--resume", "--out", str(copy.root), "--total-steps", "400"])
        assert _files(copy) == files
    # The last one may be missing where the checkpoint is, in a run that has not ended: a
    # stop at once cut it short, and the resume makes it
    # (test_an_evaluation_cut_short_by_a_stop_at_once_is_made_on_resume).
    copy.outcome_path.unlink()
    copy.eval_csv.write_text("".join(rows[:4]))
    copy.check_checkpoint_whole()
    copy.eval_csv.write_text("".join(rows[:3]))
    with pytest.raises(ValueError, match="^" + re.escape(lacks.format(
            csv=copy.eval_csv, missing="the evaluations at steps 200, 300")) + "$"):
        copy.check_checkpoint_whole()


def test_a_resume_refuses_threads_its_checkpoint_recorded_past_the_cpus(runs, tmp_path):
    """It trained with them on one CPU, silently, where a new run is refused."""
    copy = _copied_run(runs, tmp_path, "copy")
    cpus = len(os.sched_getaffinity(0))
    state = json.loads(copy.checkpoint_state.read_text())
    copy.checkpoint_state.write_text(json.dumps({**state, "threads": cpus + 1}))
    files = _files(copy)
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{copy.root} was trained with {cpus + 1} threads (its checkpoint's state.json), "
            f"more than the {cpus} CPUs this process may use: resume it where {cpus + 1} are "
            f"free, or give --threads {cpus} (the thread count changes the results' last "
            "bits)") + "$"):
        cli.main(["train", "--resume", "--out", str(copy.root), "--total-steps", "400"])
    assert _files(copy) == files


def test_a_finished_runs_copy_kept_without_its_policy_is_named_as_one(runs, tmp_path,
                                                                      capsys):
    """As results/ keeps some runs: config.json, eval.csv and outcome.json. It was told to
    be deleted ("stopped before its first checkpoint"), and to be resumed."""
    kept = tmp_path / "kept"
    kept.mkdir()
    for name in ("config.json", "eval.csv", "outcome.json"):
        shutil.copy(runs["sac"] / name, kept / name)
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{kept} is a kept copy of a finished run (its outcome.json kept, no policy.pt, no "
            "checkpoint to resume from): resume the run it was kept from, or start a new "
            "one") + "$"):
        cli.main(["train", "--resume", "--out", str(kept), "--total-steps", "400"])
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{kept} holds a kept copy of a finished run (nothing to resume): choose another "
            "--out") + "$"):
        _train(kept, "sac", 300)
    with pytest.raises(ValueError, match="^" + re.escape(
            f"{kept} has ended (outcome.json) and was kept without its model (no model.zip, "
            "no checkpoint, no policy.pt)") + "$"):
        cli.main(["evaluate", str(kept), "--episodes", "1", "--device", "cpu"])
    assert sorted(path.name for path in kept.iterdir()) == ["config.json", "eval.csv",
                                                            "outcome.json"]


def test_a_new_run_inside_another_run_or_at_an_unwritable_default_is_refused_first(
        runs, tmp_path, monkeypatch):
    """A run inside another was removed with that run's next checkpoint folder; the default
    runs/<task>-<algo>-seed<seed> under a file named runs failed after every other check,
    in the file system's words."""
    nested = runs["sac"] / "checkpoint" / "nested"
    with pytest.raises(ValueError, match="^" + re.escape(
            f"--out {nested} is inside the run {runs['sac'].resolve()}: give a folder "
            "outside it") + "$"):
        _train(nested, "sac", 300)
    assert not nested.exists()
    monkeypatch.chdir(tmp_path)
    pathlib.Path("runs").write_text("")
    with pytest.raises(ValueError, match="^" + re.escape(
            f"cannot write to runs/push-sac-seed1: {tmp_path.resolve() / 'runs'} is not a "
            "folder") + "$"):
        cli.main(["train", "--task", "push", "--algo", "sac", "--seed", "1",
                  "--total-steps", "300", *TINY])
    assert sorted(path.name for path in tmp_path.iterdir()) == ["runs"]


def test_a_resume_refuses_an_option_that_says_otherwise_than_the_run(runs):
    """Rather than go on with the run's settings and ignore the option given."""
    run = RunDir(runs["sac"])
    before = run.eval_csv.read_text()
    for extra, message in (
            (["--precision", "bf16"], "has precision fp32, not --precision's bf16"),
            (["--algo", "tqc"], "has algo sac, not --algo's tqc"),
            (["--batch-size", "64", "--stop-at-success", "0.9"],
             "has batch_size 32, not --batch-size's 64; stop_success_rate None, not "
             "--stop-at-success's 0.9"),
            (["--no-terminate-on-success"], "has terminate_on_success True, not "
                                            "--no-terminate-on-success's False")):
        with pytest.raises(ValueError, match=f"--resume goes on with the run's own settings, "
                                             f"and .* {message}: only --total-steps, "
                                             "--device, --checkpoint-every, --threads and "
                                             "--no-progress may change"):
            cli.main(["train", "--resume", "--out", str(run.root), *extra])
    assert run.eval_csv.read_text() == before


def test_a_resume_compares_the_options_given_over_the_runs_own_settings(tmp_path):
    """They were laid over the defaults: --learning-starts 10, the run's own, on a run that
    updates per episode read as an update every step from 10 steps, and was refused for
    the step schedule the run does not have."""
    out = tmp_path / "episodes"
    assert _train(out, "sac", 100, "--update-schedule", "episode", "--learning-starts",
                  "10") == 0
    resume = ["train", "--resume", "--out", str(out), "--total-steps", "200", "--no-progress"]
    assert cli.main([*resume, "--learning-starts", "10", "--task", "push"]) == 0
    assert RunDir(out).read_state()["steps"] >= 200
    with pytest.raises(ValueError, match=re.escape(
            f"{out} has learning_starts 10, not --learning-starts's 5: only")):
        cli.main([*resume, "--learning-starts", "5"])
    # A given option that no run could take with the run's others is named with why.
    with pytest.raises(ValueError, match=re.escape(
            "--resume goes on with the run's own settings, and --update-schedule would "
            f"change {out}'s into ones no run takes (--learning-starts must be >= 49")):
        cli.main([*resume, "--update-schedule", "step"])


def test_a_resume_refuses_a_config_json_edited_since_its_checkpoint(runs, tmp_path):
    """The checkpoint records the settings it was trained with: a hand edit of config.json
    is refused before anything is built or written, naming what differs (another algo ended
    in a traceback after the finished run's model, policy and outcome were deleted; another
    seed or controller trained on as the edited run, its files then disagreeing)."""
    from franka_composer.training import loop

    run = RunDir(runs["sac"])
    assert RunConfig.from_dict(run.read_state()["config"]) == run.read_config()
    for edit, differs in (({"algo": "ddpg"}, "algo: ddpg, not sac"),
                          ({"seed": 5}, "seed: 5, not 1"),
                          ({"control": "osc"}, "control: osc, not mocap")):
        copy = tmp_path / f"edited-{next(iter(edit))}"
        shutil.copytree(run.root, copy)
        (copy / "training.lock").unlink()
        config = json.loads((copy / "config.json").read_text())
        (copy / "config.json").write_text(json.dumps({**config, **edit}))
        files = {path.name: path.read_bytes() for path in copy.iterdir() if path.is_file()}
        with pytest.raises(ValueError, match=re.escape(
                f"{copy / 'config.json'} says other than the settings the run's checkpoint "
                f"at step {run.read_state()['steps']:,} was trained with ({differs}): a run "
                "goes on with its own; put them back, or start a new run with the new ones")):
            cli.main(["train", "--resume", "--out", str(copy), "--total-steps", "400"])
        # Nor is it played, kept or reported as the run (evaluate played it under osc, and
        # its table named it so; keep copied it, its policy then fitting no config; report
        # and plot filed it under the edited cell).
        for command in (["evaluate", str(copy), "--episodes", "1"],
                        ["keep", str(copy), "--into", str(tmp_path / "kept")],
                        ["report", str(copy)],
                        ["plot", str(copy), "--out", str(tmp_path / "kept" / "curves.png")]):
            with pytest.raises(ValueError, match=re.escape(f"({differs}): a run goes on")):
                cli.main(command)
        assert not (tmp_path / "kept").exists()
        assert {path.name: path.read_bytes() for path in copy.iterdir()
                if path.is_file()} == files
    # TQC under SAC's settings is no run's config at all: refused as such, first.
    tqc = tmp_path / "edited-to-tqc"
    shutil.copytree(run.root, tqc)
    (tqc / "training.lock").unlink()
    config = json.loads((tqc / "config.json").read_text())
    (tqc / "config.json").write_text(json.dumps({**config, "algo": "tqc"}))
    with pytest.raises(ValueError, match=re.escape(
            f"{tqc / 'config.json'} is not a run's config: tqc needs n_critics, n_quantiles, "
            "top_quantiles_to_drop_per_net, which the hyperparameters leave unset (None)")):
        cli.main(["train", "--resume", "--out", str(tqc), "--total-steps", "400"])
    # The loop checks too (a sweep's cells and scripts resume through it).
    with pytest.raises(ValueError, match="says other than the settings the run's checkpoint"):
        loop.train(RunDir(copy), resume=True, total_steps=400, device="cpu", progress=False)
    assert {path.name: path.read_bytes() for path in copy.iterdir() if path.is_file()} == files
    # A checkpoint written before it recorded the settings is not checked; one whose record
    # is damaged is named.
    edited = RunDir(copy)
    state = json.loads(edited.checkpoint_state.read_text())
    edited.checkpoint_state.write_text(json.dumps({**state, "config": {"task": "push"}}))
    with pytest.raises(ValueError, match=re.escape(
            f"{edited.checkpoint_state}'s config is not a run's config (damaged?)")):
        edited.check_config_checkpointed()
    del state["config"]
    edited.checkpoint_state.write_text(json.dumps(state))
    edited.check_config_checkpointed()


def test_no_terminate_on_success_reaches_the_env(tmp_path, monkeypatch):
    """The envs the run trains and evaluates on run to the time limit, not only its
    config.json saying so."""
    from franka_composer.training import loop

    built = []
    real_make_env = loop.make_env
    monkeypatch.setattr(loop, "make_env", lambda task, **options: built.append(
        real_make_env(task, **options)) or built[-1])
    out = tmp_path / "fetch_semantics"
    assert _train(out, "ddpg", 100, "--no-terminate-on-success") == 0
    assert RunDir(out).read_config().terminate_on_success is False
    assert len(built) == 2  # The training env and the evaluation env.
    assert [env.unwrapped.task.terminate_on_success for env in built] == [False, False]


def test_a_randomised_run_trains_resumes_and_evaluates_on_randomised_envs(tmp_path, capsys,
                                                                          monkeypatch):
    import gymnasium as gym

    from franka_composer.training import loop

    made, played = [], []  # make_env's options; the randomised parameters of each episode.

    class RecordPlayedDraws(gym.Wrapper):
        """Records an episode's draw at its first step: resets nothing steps after (the
        skipping of evaluated episodes on resume, a vector env's reset after its last
        episode) play no episode."""

        def reset(self, **kwargs):
            obs, info = self.env.reset(**kwargs)
            self._draw = info["randomization"]
            return obs, info

        def step(self, action):
            if self._draw is not None:
                played.append(json.dumps(self._draw, sort_keys=True, default=repr))
                self._draw = None
            return self.env.step(action)

    real_make_env = loop.make_env
    monkeypatch.setattr(loop, "make_env", lambda task, **options: made.append(options)
                        or RecordPlayedDraws(real_make_env(task, **options)))
    out = tmp_path / "randomised"
    assert _train(out, "sac", 100, "--randomization", "default",
                  "--checkpoint-every", "100") == 0
    assert json.loads(RunDir(out).config_path.read_text())["randomization"] == "default"
    assert _train(out, "sac", 200, "--resume") == 0
    assert [options["randomization"] for options in made] == ["default"] * 4  # Train, eval.
    # Every episode played, trained on or evaluated, before and after the resume, had its
    # own draw: at least 4 training episodes (200 steps in episodes of 50) and 2 evaluation
    # episodes at each of the 3 evaluations (steps 0, 100, 200).
    assert len(played) >= 4 + 2 * 3
    assert len(set(played)) == len(played)
    from franka_composer.training import policy_file

    evaluated = []
    real_policy_env = policy_file.make_env
    monkeypatch.setattr(policy_file, "make_env", lambda task, **options: evaluated.append(
        options) or RecordPlayedDraws(real_policy_env(task, **options)))
    played.clear()
    assert cli.main(["evaluate", str(out), "--episodes", "2"]) == 0
    assert "push" in capsys.readouterr().out
    assert [options["randomization"] for options in evaluated] == ["default"]
    assert len(played) == 2 and len(set(played)) == 2  # Each evaluated episode drawn anew.
    with pytest.raises(SystemExit):
        _train(tmp_path / "bad", "sac", 100, "--randomization", "strong")
    assert "invalid choice: 'strong' (choose from 'default')" in capsys.readouterr().err
    assert not (tmp_path / "bad").exists()


def test_evaluate_prints_table_ii_layout(runs, tmp_path, capsys):
    table = tmp_path / "new folder" / "table.md"  # Made when the table is written.
    assert cli.main(["evaluate", *map(str, runs.values()), "--episodes", "2",
                     "--device", "cpu", "--out", str(table)]) == 0
    printed = capsys.readouterr().out
    lines = table.read_text().splitlines()
    assert lines[:2] == ["| Tasks | DDPG | SAC | TQC |", "|---|---|---|---|"]
    cells = lines[2].split("|")[1:-1]
    # TINY's settings are not Table I's: the row says so.
    assert cells[0].strip() == "Push (net_arch 16,16, batch_size 32, buffer_size 2000)"
    rates = [float(c.split("±")[0]) for c in cells[1:]]
    assert all(r in (0.0, 50.0, 100.0) for r in rates)  # 2 episodes, one seed each.
    assert [c.split("±")[1].strip() for c in cells[1:]] == ["0.0"] * 3
    assert printed.count("over 2 episodes") == 3


def test_plot_draws_one_line_per_algorithm(runs, tmp_path, monkeypatch, capsys):
    import matplotlib.image
    import matplotlib.pyplot as plt

    figures, close = [], plt.close
    monkeypatch.setattr(plt, "close", lambda fig=None: figures.append(fig) or close(fig))
    out = tmp_path / "curves.png"
    assert cli.main(["plot", *map(str, runs.values()), "--out", str(out)]) == 0
    assert capsys.readouterr().out == f"3 curves -> {out}\n"
    (axes,) = figures[0].axes
    lines = axes.get_lines()
    assert [line.get_label() for line in lines] == [f"{algo.upper()} (1 seed)" for algo in runs]
    assert [text.get_text() for text in axes.get_legend().get_texts()] == [
        line.get_label() for line in lines]
    for line, run in zip(lines, runs.values()):  # One seed: its median is its own curve.
        rows = read_eval_rows(RunDir(run).eval_csv)
        assert line.get_xdata().tolist() == [row["steps"] for row in rows]
        assert line.get_ydata().tolist() == [row["success_rate"] for row in rows]
    image = matplotlib.image.imread(out)
    assert image.shape[0] == 432 and image.shape[1] == 540  # One panel, 4.5 x 3.6 in.
    assert np.ptp(image[..., :3]) > 0.5  # Not blank.


def _wait_for_evaluation(out, steps, process, timeout_s=120):
    """Until the run training in `process` into `out` has logged its evaluation at `steps`
    or later; fails if the process ends first or the time runs out."""
    import time

    deadline = time.monotonic() + timeout_s
    while not any(r["steps"] >= steps for r in read_eval_rows(RunDir(out).eval_csv)):
        assert time.monotonic() < deadline and process.poll() is None
        time.sleep(0.05)


@pytest.mark.parametrize("signum", ["SIGTERM", "SIGINT"])
def test_sigterm_writes_a_checkpoint_that_resumes(tmp_path, signum):
    """And Ctrl-C, as a terminal sends it: the command line's own handler for it had
    training stop at once, at an inexact checkpoint."""
    import subprocess
    import sys

    out = tmp_path / "interrupted"
    command = [sys.executable, "-m", "franka_composer", "train", "--task", "push", "--algo",
               "ddpg", "--seed", "1", "--out", str(out), "--total-steps", "100000", *TINY]
    process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True, preexec_fn=(
        lambda: signal.signal(signal.SIGINT, signal.SIG_DFL)))
    _wait_for_evaluation(out, 200, process, timeout_s=60)
    process.send_signal(getattr(signal, signum))
    stdout, stderr = process.communicate(timeout=60)
    # 128 + the signal, as a shell reports it: 143 for SIGTERM, 130 for Ctrl-C.
    assert process.returncode == 128 + getattr(signal, signum) and "--resume" in stdout
    # Said at once (after the evaluation under way, if one was: it says so then).
    assert re.fullmatch(r"stopping at the episode's end, where its checkpoint resumes exactly"
                        r"( \(first the evaluation under way: 2 episodes at step [\d,]+\))?; "
                        r"Ctrl-C or SIGTERM again stops at once\n", stderr), stderr
    steps = RunDir(out).read_state()["steps"]
    assert steps >= 200 and RunDir(out).read_state()["exact"]  # At the episode's end.
    assert _train(out, "ddpg", steps + 100, "--resume") == 0
    evaluated = [r["steps"] for r in read_eval_rows(RunDir(out).eval_csv)]
    assert evaluated == sorted(set(evaluated)) and evaluated[-1] == steps + 100


def test_a_stop_asked_during_an_evaluation_says_at_once_that_it_waits_for_it(
        tmp_path, monkeypatch, capfd):
    """A stop waits for the evaluation under way (its row is the exact course's), which with
    many episodes or long steps takes minutes: nothing showed that the stop was heard, and
    a run under `timeout` looked hung."""

    from franka_composer.training.callbacks import Evaluation

    log, sent = Evaluation._log_success_callback, []

    def signal_once(self, locals_, globals_):  # Called at each step of an evaluation.
        if self.num_timesteps >= 200 and not sent:
            sent.append(self.num_timesteps)
            signal.raise_signal(signal.SIGTERM)
        return log(self, locals_, globals_)

    monkeypatch.setattr(Evaluation, "_log_success_callback", signal_once)
    capfd.readouterr()
    assert _train(tmp_path / "run", "sac", 400) == 143
    assert sent == [200] and capfd.readouterr().err == (
        "stopping at the episode's end, where its checkpoint resumes exactly (first the "
        "evaluation under way: 2 episodes at step 200); Ctrl-C or SIGTERM again stops at "
        "once\n")
    state = RunDir(tmp_path / "run").read_state()
    assert state["exact"] and 200 <= state["steps"] <= 250  # The episode's end (at 200).
    assert [r["steps"] for r in read_eval_rows(RunDir(tmp_path / "run").eval_csv)] == [
        0, 100, 200]


@pytest.mark.parametrize("algo, backend", [("tqc", "sbx"), ("sac", "sb3")])
def test_a_killed_run_resumes_from_its_last_checkpoint_as_the_uninterrupted_run(
        tmp_path, algo, backend):
    """SIGKILL (the kernel's out-of-memory killer, a preempted job) leaves no last
    checkpoint: the run goes on from the last one it wrote on its way, which must hold
    everything the run went on from after writing it. Each run in a process of its own,
    as a user's are: JAX sizes its threads once per process (`--threads`), and this one's
    may have been sized by another test."""
    import subprocess
    import sys

    def train(out, *extra):
        return subprocess.Popen([sys.executable, "-m", "franka_composer", "train", "--out",
                                 str(out), *extra], stdout=subprocess.DEVNULL)

    options = ["--task", "push", "--algo", algo, "--seed", "1", "--total-steps", "500",
               *TINY, "--backend", backend, "--checkpoint-every", "100"]
    assert train(tmp_path / "whole", *options).wait(timeout=300) == 0
    killed = tmp_path / "killed"
    process = train(killed, *options)
    _wait_for_evaluation(killed, 300, process)
    process.send_signal(signal.SIGKILL)
    assert process.wait(timeout=60) == -signal.SIGKILL
    steps = RunDir(killed).read_state()["steps"]
    assert 100 <= steps < 500  # Written on the way, before the end.
    assert train(killed, "--resume", "--no-progress").wait(timeout=300) == 0
    whole = _assert_trained_alike(tmp_path / "whole", killed, algo, backend)
    assert [r["steps"] for r in whole[0]] == [0, 100, 200, 300, 400, 500]


def test_sbx_model_has_table_i_settings():
    import sbx  # In the test extra: a missing sbx is a failure here, not a skip.
    env = make_env("push")
    tqc = build_model("tqc", hyperparameters("push", "tqc").replace(buffer_size=1000),
                      env, seed=0, device="cpu", backend="sbx")
    assert isinstance(tqc, sbx.TQC)
    assert (tqc.batch_size, tqc.tau, tqc.gamma, tqc.learning_rate) == (512, 0.05, 0.95, 1e-3)
    assert (tqc.qf_learning_rate, tqc.policy_delay, tqc.action_noise) == (1e-3, 1, None)
    assert (tqc.policy.n_quantiles, tqc.policy.n_target_quantiles) == (25, 46)
    assert tqc.policy.net_arch_pi == tqc.policy.net_arch_qf == [256] * 3
    assert (tqc.policy.dropout_rate, tqc.policy.layer_norm) == (0.0, False)
    assert tqc.replay_buffer.n_sampled_goal == 4 and tqc.target_entropy == -3.0
    sac = build_model("sac", hyperparameters("push", "sac").replace(
        update_schedule="episode", buffer_size=1000), env, seed=0, device="cpu", backend="sbx")
    assert sac.action_noise._sigma.tolist() == [0.2] * 3 and sac.ent_coef_init == "auto"
    assert (sac.train_freq.frequency, sac.train_freq.unit.value, sac.gradient_steps) == (
        1, "episode", -1)
    assert sac.policy.n_critics == 2 and sac.qf_learning_rate == 1e-3
    ddpg = build_model("ddpg", hyperparameters("push", "ddpg").replace(
        buffer_size=1000), env, seed=0, device="cpu", backend="sbx")
    assert ddpg.policy.n_critics == 1 and ddpg.qf_learning_rate == 1e-3  # sbx's default: 1e-3.
    assert (ddpg.policy_delay, ddpg.target_noise_clip) == (1, 0.0)  # No TD3 tricks.
    env.close()


_XLA_THREADS_PROBE = """
import os
from franka_composer.cli.train import _limit_threads
cores = os.sched_getaffinity(0)
with _limit_threads(1, "sbx"):
    import jax.numpy as jnp
    (jnp.ones((256, 256)) @ jnp.ones((256, 256))).block_until_ready()
    tasks = os.listdir("/proc/self/task")
    names = [open(f"/proc/self/task/{tid}/comm").read().strip() for tid in tasks]
    pinned = [tid for tid in tasks if os.sched_getaffinity(int(tid)) != cores]
    print(names.count("tf_XLAEigen"), len(pinned))
"""


@pytest.mark.skipif(len(os.sched_getaffinity(0)) < 2 or not os.path.isdir("/proc/self/task"),
                    reason="needs two cores and Linux's /proc")
def test_sbx_threads_1_sizes_xla_to_one_thread_and_leaves_every_core():
    """Pinned for its whole run, every sbx run of a machine sat on the first core: two sweep
    cells ran at half speed, the second core idle."""
    import subprocess
    import sys

    result = subprocess.run([sys.executable, "-c", _XLA_THREADS_PROBE], capture_output=True,
                            text=True, timeout=120, check=False)
    assert result.returncode == 0, result.stderr[-2000:]
    assert result.stdout.split() == ["1", "0"]  # One XLA pool thread; no thread pinned.


@pytest.mark.parametrize("algo", ALGOS)
def test_sbx_run_trains_resumes_and_evaluates(tmp_path, algo, capsys):
    import sbx  # In the test extra: a missing sbx is a failure here, not a skip.

    out = tmp_path / algo
    cores = os.sched_getaffinity(0)
    assert _train(out, algo, 200, "--backend", "sbx", "--checkpoint-every", "100") == 0
    assert os.sched_getaffinity(0) == cores  # --threads 1 pinned the run, not the caller.
    assert RunDir(out).read_config().backend == "sbx"
    assert RunDir(out).read_state()["steps"] == 200
    assert _train(out, algo, 300, "--resume") == 0  # The backend comes from config.json.
    rows = read_eval_rows(RunDir(out).eval_csv)
    assert [r["steps"] for r in rows] == [0, 100, 200, 300]
    env = make_env("push")
    model = load_model(algo, RunDir(out).final_model, env=env, device="cpu", backend="sbx")
    assert isinstance(model, getattr(sbx, algo.upper())) and model.num_timesteps == 300
    model.load_replay_buffer(RunDir(out).checkpoint_buffer)
    assert model.replay_buffer.size() == 300  # The first 200 came back from the checkpoint.
    # Its policy file (the flax actor's parameters) acts as the model, to the bit.
    from franka_composer.training.policy_file import ActorPolicy, load_trained

    committed = RunDir(_committed_copy(out, tmp_path / "committed"))
    small = load_trained(committed, env, device="cpu")
    assert isinstance(small, ActorPolicy) and small.num_timesteps == 300
    assert RunDir(out).policy_file.stat().st_size < RunDir(out).final_model.stat().st_size / 2
    obs, _ = env.reset(seed=3)
    for _ in range(20):
        action, _ = model.predict(obs, deterministic=True)
        np.testing.assert_array_equal(small.predict(obs, deterministic=True)[0], action)
        obs = env.step(env.action_space.sample())[0]
    env.close()
    capsys.readouterr()
    reports = []
    for root in (out, committed.root):
        assert cli.main(["evaluate", str(root), "--episodes", "1", "--device", "cpu"]) == 0
        reports.append(capsys.readouterr().out.replace(str(root), "RUN"))
    assert "300 steps" in reports[0] and reports[0] == reports[1]
    # A policy file is loaded by the library its run's config.json names, or refused.
    config = json.loads(committed.config_path.read_text())
    committed.config_path.write_text(json.dumps({**config, "backend": "sb3"}))
    env = make_env("push")
    with pytest.raises(ValueError, match="holds an actor of sbx, and its run's config.json "
                                         "says sb3"):
        load_trained(committed, env, device="cpu")
    committed.config_path.write_text(json.dumps({**config, "hyperparameters": {
        **config["hyperparameters"], "net_arch": [16, 8]}}))
    with pytest.raises(ValueError, match="its actor's parameters do not fit the network its "
                                         "run's config.json describes"):
        load_trained(committed, env, device="cpu")
    env.close()


def test_sbx_backend_without_sbx_is_a_value_error(tmp_path, monkeypatch):
    import sys

    monkeypatch.setitem(sys.modules, "sbx", None)  # `import sbx` raises ImportError.
    with pytest.raises(ValueError, match="pip install sbx-rl"):
        _train(tmp_path / "run", "sac", 100, "--backend", "sbx")
    assert not (tmp_path / "run").exists()  # Refused before the run directory was made.


def test_config_without_backend_resumes_as_sb3(tmp_path):
    from stable_baselines3 import SAC

    out = tmp_path / "old"
    assert _train(out, "sac", 100, "--checkpoint-every", "100") == 0
    config = json.loads(RunDir(out).config_path.read_text())
    assert config.pop("backend") == "sb3"
    RunDir(out).config_path.write_text(json.dumps(config))  # As written before --backend.
    assert RunDir(out).read_config().backend == "sb3"
    assert _train(out, "sac", 200, "--resume") == 0
    assert [r["steps"] for r in read_eval_rows(RunDir(out).eval_csv)] == [0, 100, 200]
    env = make_env("push")
    assert type(load_model("sac", RunDir(out).final_model, env=env, device="cpu")) is SAC
    env.close()


def _scripted_evaluations(monkeypatch, rates) -> None:
    """Each evaluation scores the next of `rates` (SB3's evaluate_policy as EvalCallback calls
    it: episode rewards and lengths, and each episode's last step reported to `callback`)."""
    from stable_baselines3.common import callbacks as sb3_callbacks

    rates = iter(rates)

    def evaluate(model, env, n_eval_episodes, callback=None, **kwargs):
        successes = int(next(rates) * n_eval_episodes)
        for episode in range(n_eval_episodes):
            callback({"done": True, "info": {"is_success": episode < successes}}, {})
        return [-10.0] * n_eval_episodes, [50] * n_eval_episodes

    monkeypatch.setattr(sb3_callbacks, "evaluate_policy", evaluate)


def test_the_early_stopping_rule_ends_a_run_and_resume_keeps_it_ended(tmp_path, monkeypatch):
    """5 consecutive evaluations at >= 95 % (here 3 at 100 %) end the run before its budget;
    outcome.json records it, and --resume does not train it further."""
    _scripted_evaluations(monkeypatch, [0.5, 1.0, 0.5, 1.0, 1.0, 1.0] + [0.0] * 50)
    out = tmp_path / "early"
    run = RunDir(out)
    assert _train(out, "ddpg", 2000, "--stop-at-success", "0.95", "--stop-after", "3") == 0
    rows = read_eval_rows(run.eval_csv)
    assert [r["steps"] for r in rows] == [0, 100, 200, 300, 400, 500]
    outcome = run.read_outcome()
    assert outcome["steps"] == 500 and outcome["stopped_early"] is True
    config = run.read_config().hyperparameters
    assert (config.stop_success_rate, config.stop_after_evaluations) == (0.95, 3)
    ended = run.outcome_path.read_bytes()
    assert _train(out, "ddpg", 3000, "--resume") == 0
    # Nothing trained, nothing recorded: no fresh episode stream, no added wall time.
    assert run.outcome_path.read_bytes() == ended
    assert len(read_eval_rows(run.eval_csv)) == 6
    # Stopped after the rule was met and before its outcome was written: a resume ends it
    # there, as it would have ended, and trains nothing.
    for path in (run.outcome_path, run.final_model, run.policy_file):
        path.unlink()
    assert _train(out, "ddpg", 3000, "--resume") == 0
    outcome = run.read_outcome()
    assert (outcome["steps"], outcome["stopped_early"]) == (500, True)
    assert outcome["fresh_streams"] == run.read_state()["fresh_streams"]
    assert run.final_model.is_file() and run.policy_file.is_file()
    assert len(read_eval_rows(run.eval_csv)) == 6


def test_an_evaluation_made_on_resume_that_meets_the_rule_ends_the_run_there(tmp_path,
                                                                            monkeypatch):
    """The rule met by the evaluation a resume makes first (one a stop at once cut short)
    ends the run at that step, as the uninterrupted run ended: it trained on, and ended a
    step of the grid later, or never if that evaluation failed."""
    rule = ("--stop-at-success", "0.95", "--stop-after", "3")
    _scripted_evaluations(monkeypatch, [1.0] * 3)
    assert _train(tmp_path / "whole", "sac", 600, *rule) == 0
    out = tmp_path / "run"
    with monkeypatch.context() as patch:
        _evaluation_cut_short_at(patch, 200)
        _scripted_evaluations(patch, [1.0] * 3)
        assert _train(out, "sac", 600, *rule) == 143
    _scripted_evaluations(monkeypatch, [1.0, 0.0])
    with pytest.warns(RuntimeWarning, match="fresh episode stream"):
        assert _train(out, "sac", 600, "--resume") == 0
    for run in (RunDir(tmp_path / "whole"), RunDir(out)):
        assert [r["steps"] for r in read_eval_rows(run.eval_csv)] == [0, 100, 200]
        outcome = run.read_outcome()
        assert (outcome["steps"], outcome["stopped_early"]) == (200, True)
        assert run.read_state()["steps"] == 200


def test_an_evaluation_off_the_grid_neither_stops_a_run_nor_survives_a_raised_budget(
        tmp_path, monkeypatch):
    """A budget between two evaluations ends with one at the last step: success there is
    not the stopping rule's (the run reached its budget), and a raised budget drops it, as
    the uninterrupted run at that budget has none there. While the raised run trains, it
    has no final model or policy: `evaluate` plays its newest checkpoint, not the model it
    ended with before."""
    _scripted_evaluations(monkeypatch, [0.0] * 6 + [1.0] + [0.0] * 50)  # Success at 550 only.
    out = tmp_path / "off-grid"
    run = RunDir(out)
    assert _train(out, "sac", 550, "--stop-at-success", "0.95", "--stop-after", "1") == 0
    assert [r["steps"] for r in read_eval_rows(run.eval_csv)][-2:] == [500, 550]
    outcome = run.read_outcome()
    assert (outcome["steps"], outcome["stopped_early"]) == (550, False)
    _stop_asked_at(monkeypatch, 700)
    assert _train(out, "sac", 1000, "--resume") == 143
    assert not run.final_model.exists() and not run.policy_file.exists()
    assert not run.outcome_path.exists() and run.read_state()["steps"] >= 700
    steps = [r["steps"] for r in read_eval_rows(run.eval_csv)]
    assert 550 not in steps and steps[-1] == 700


def test_a_run_without_the_rule_records_that_it_went_the_distance(runs):
    outcome = RunDir(runs["sac"]).read_outcome()
    assert outcome["steps"] == 300 and outcome["stopped_early"] is False


def test_a_resume_of_a_run_that_has_ended_says_it_trained_nothing(runs, tmp_path, capsys):
    """It printed "trained 300 steps -> model.zip", as if it had."""
    import shutil

    out = tmp_path / "ended"
    shutil.copytree(runs["sac"], out)
    (out / "training.lock").unlink(missing_ok=True)
    files = {path.name: path.read_bytes() for path in out.iterdir() if path.is_file()}
    capsys.readouterr()
    assert _train(out, "sac", 300, "--resume") == 0
    assert capsys.readouterr().out.splitlines()[-1] == (
        f"{out} had ended at 300 steps: nothing to train (a larger --total-steps goes on)")
    assert {path.name: path.read_bytes() for path in out.iterdir()
            if path.is_file() and path.name != "training.lock"} == files
    # Ended by the success rule: no budget goes on, and it is not told one does.
    outcome = json.loads((out / "outcome.json").read_text())
    (out / "outcome.json").write_text(json.dumps({**outcome, "stopped_early": True}))
    assert _train(out, "sac", 5000, "--resume") == 0
    assert capsys.readouterr().out.splitlines()[-1] == (
        f"{out} had ended at 300 steps (stopped early: the success rule was met): nothing "
        "to train")


def _ended_run_resumed_and_interrupted(runs, tmp_path, monkeypatch, capsys, stage: str,
                                       steps: int) -> tuple[pathlib.Path, str]:
    """A copy of the ended 300-step SAC run resumed to `steps`, interrupted in `loop`'s
    function `stage`: the copy, and the last line train printed."""
    from franka_composer.training import loop

    out = tmp_path / "ended"
    shutil.copytree(runs["sac"], out)
    (out / "training.lock").unlink(missing_ok=True)

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(loop, stage, interrupted)
    capsys.readouterr()
    assert _train(out, "sac", steps, "--resume") == 130
    return out, capsys.readouterr().out.splitlines()[-1]


def test_an_interrupted_resume_of_a_run_that_has_ended_says_so(runs, tmp_path, monkeypatch,
                                                                 capsys):
    """Stopped while it loads the ended run's model, it said "continue with franka-composer
    train --resume", which trains nothing."""
    out, said = _ended_run_resumed_and_interrupted(runs, tmp_path, monkeypatch, capsys,
                                                   "_trained_model", 300)
    assert said == (f"interrupted: {out} had ended at 300 steps: nothing to train (a larger "
                    "--total-steps goes on)")


def test_a_run_interrupted_once_it_has_ended_says_so(tmp_path, monkeypatch, capsys):
    """Stopped after it wrote its outcome, it said "continue with ... --resume", which
    trains nothing: it says where it ended."""
    from franka_composer.training import loop

    finish = loop._finish

    def finished_then_interrupted(*args, **kwargs):
        finish(*args, **kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(loop, "_finish", finished_then_interrupted)
    capsys.readouterr()
    assert _train(tmp_path / "run", "sac", 200) == 130
    assert capsys.readouterr().out.splitlines()[-1] == (
        f"interrupted as it ended: trained 200 steps -> {tmp_path / 'run' / 'model.zip'}")


def test_a_raised_budget_interrupted_before_it_is_saved_says_to_resume_with_it(
        runs, tmp_path, monkeypatch, capsys):
    """Stopped while it loads the ended run's checkpoint, before config.json takes the new
    budget, it said to resume without it, which then trains nothing."""
    out, said = _ended_run_resumed_and_interrupted(runs, tmp_path, monkeypatch, capsys,
                                                   "_resume", 400)
    assert said == ("interrupted: its checkpoint at step 300 is kept; continue with "
                    f"franka-composer train --resume --out {out} --total-steps 400")


def test_stop_at_success_refuses_a_rate_outside_zero_to_one(capsys):
    with pytest.raises(SystemExit):
        cli.main(["train", "--stop-at-success", "1.5"])
    assert "must be a success rate in (0, 1], got '1.5'" in capsys.readouterr().err


#: CUDA only where torch sees a GPU (CI has none; a GPU machine runs this file as it is).
DEVICES_HERE = ["cpu", pytest.param("cuda", marks=pytest.mark.skipif(
    not __import__("torch").cuda.is_available(), reason="torch sees no CUDA GPU"))]


@pytest.mark.parametrize("device", DEVICES_HERE)
@pytest.mark.parametrize("precision", ["fp32", "bf16"])
def test_precision_sets_the_gradient_steps_and_nothing_else(tmp_path, monkeypatch, precision,
                                                           device):
    """bf16: every network pass of the gradient steps (batches of 32) in bfloat16, the
    rollouts' and evaluations' (one observation) in float32, the saved weights float32, and
    autocast off again afterwards; fp32: float32 throughout. The same on either device."""
    import torch

    from franka_composer.training import loop

    seen = set()  # (network, batch size, output dtype)
    build = loop.build_model

    def build_and_watch(*args, **kwargs):
        model = build(*args, **kwargs)
        for name, module in (("actor", model.actor.latent_pi[0]),
                             ("critic", model.critic.q_networks[0][0]),
                             ("target", model.critic_target.q_networks[0][0])):
            module.register_forward_hook(lambda module, inputs, output, name=name: seen.add(
                (name, output.shape[0], output.dtype)))
        return model

    monkeypatch.setattr(loop, "build_model", build_and_watch)
    monkeypatch.setattr(machine, "bf16_units", lambda: False)  # As on an AVX2 CPU.
    out = tmp_path / precision
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert _train(out, "sac", 300, "--precision", precision, "--device", device) == 0
    # Emulated bf16 (17x fp32's step there) is said, on the CPU only.
    emulated = [str(w.message) for w in caught if "this CPU has no bf16 units" in str(w.message)]
    assert len(emulated) == (precision == "bf16" and device == "cpu")
    assert all("--precision fp32 trains the same settings in fp32" in m for m in emulated)
    assert not torch.is_autocast_enabled(device)
    assert RunDir(out).read_config().precision == precision
    assert json.loads(RunDir(out).config_path.read_text())["precision"] == precision
    trained = torch.bfloat16 if precision == "bf16" else torch.float32
    assert seen == {("actor", 32, trained), ("critic", 32, trained), ("target", 32, trained),
                    ("actor", 1, torch.float32)}
    assert len(read_eval_rows(RunDir(out).eval_csv)) == 4
    env = make_env("push")
    model = load_model("sac", RunDir(out).final_model, env=env, device="cpu")
    assert {p.dtype for p in model.policy.parameters()} == {torch.float32}
    env.close()


def test_bf16_needs_the_torch_backend(tmp_path, capsys):
    with pytest.raises(ValueError, match="--precision bf16 runs the networks under "
                                         "torch.autocast: it needs --backend sb3, not sbx"):
        _train(tmp_path / "run", "sac", 100, "--backend", "sbx", "--precision", "bf16")
    assert not (tmp_path / "run").exists()  # Refused before the run directory was made.
    with pytest.raises(SystemExit):
        _train(tmp_path / "run", "sac", 100, "--precision", "fp16")
    assert "invalid choice: 'fp16'" in capsys.readouterr().err
    assert not (tmp_path / "run").exists()


def _critic_values(critic, obs, actions) -> "np.ndarray":
    values = critic(obs, actions)
    return np.concatenate([v.detach().numpy().ravel() for v in (
        values if isinstance(values, tuple) else (values,))])


@pytest.mark.parametrize("algo", ALGOS)
def test_clipped_q_targets_bound_the_target_critic_and_nothing_else(algo):
    """Critics made to output exactly `value` (zero weights, the output layer's bias set):
    the target critic's values come out clamped to [-1/(1-gamma), 0], every critic (SAC's
    two, TQC's quantiles) alike; the critic that is trained is left alone; and removing
    the hook restores the target critic."""
    import torch

    from franka_composer.training.target_bounds import clip_target_critic

    env = make_env("push")
    model = build_model(algo, hyperparameters("push", algo).replace(
        net_arch=(16, 16), buffer_size=1000), env, seed=0, device="cpu")
    obs = model.policy.obs_to_tensor(env.observation_space.sample())[0]
    actions = torch.zeros((1,) + env.action_space.shape)

    def set_output(value):
        with torch.no_grad():
            for critic in (model.critic, model.critic_target):
                for layer in critic.modules():
                    if isinstance(layer, torch.nn.Linear):
                        layer.weight.zero_()
                        layer.bias.fill_(0.0 if layer.out_features == 16 else value)

    handle = clip_target_critic(model, 0.95)
    lowest = np.float32(-1 / (1 - 0.95))
    for value, clamped in ((1000.0, 0.0), (-1000.0, lowest), (-5.0, -5.0), (0.0, 0.0)):
        set_output(value)
        target = _critic_values(model.critic_target, obs, actions)
        assert target.size == {"tqc": 50, "sac": 2, "ddpg": 1}[algo]
        assert np.all(target == np.float32(clamped)), (value, target)
        assert np.all(_critic_values(model.critic, obs, actions) == np.float32(value))
    handle.remove()
    set_output(1000.0)
    assert np.all(_critic_values(model.critic_target, obs, actions) == 1000.0)
    env.close()


def test_clip_q_targets_is_recorded_clips_again_on_resume_and_needs_sb3(tmp_path,
                                                                       monkeypatch):
    from franka_composer.training import loop

    clipped = []  # (gamma, the model's target critic) per clip_target_critic call
    clip = loop.clip_target_critic
    monkeypatch.setattr(loop, "clip_target_critic", lambda model, gamma: clipped.append(
        (gamma, model.critic_target)) or clip(model, gamma))
    out = tmp_path / "run"
    assert _train(out, "sac", 200, "--checkpoint-every", "100", "--clip-q-targets") == 0
    config = RunDir(out).read_config()
    assert config.hyperparameters.clip_q_targets is True
    assert "clip_q_targets True" in config.variant
    assert _train(out, "sac", 300, "--resume") == 0
    assert [gamma for gamma, _ in clipped] == [0.95, 0.95]
    assert clipped[0][1] is not clipped[1][1]  # The resumed run's own target critic.
    assert len(clipped[1][1]._forward_hooks) == 1
    assert _train(tmp_path / "plain", "sac", 100) == 0
    assert len(clipped) == 2 and not RunDir(tmp_path / "plain").read_config(
        ).hyperparameters.clip_q_targets
    with pytest.raises(ValueError, match="--clip-q-targets clamps a PyTorch target critic: "
                                         "it needs --backend sb3, not sbx"):
        _train(tmp_path / "sbx", "sac", 100, "--backend", "sbx", "--clip-q-targets")
    assert not (tmp_path / "sbx").exists()


def test_a_run_trains_and_is_evaluated_at_its_own_control_timestep(tmp_path, capsys):
    """--control-timestep 0.5 (the paper's code's 0.5 s per step): recorded, named in the
    variant, the same env for evaluate; the task's own 0.05 is the default run, not
    another; a period that is no whole number of physics steps is refused before the run
    exists."""
    from franka_composer.cli.train import run_config
    from franka_composer.training.policy_file import trained_on_its_task

    out = tmp_path / "slow"
    assert _train(out, "sac", 100, "--control-timestep", "0.5") == 0
    config = RunDir(out).read_config()
    assert config.control_timestep == 0.5 and config.variant.endswith(", 0.5 s per step")
    assert json.loads(RunDir(out).config_path.read_text())["control_timestep"] == 0.5
    with trained_on_its_task(out, device="cpu") as (_, env, _policy):
        env.reset(seed=0)
        physics = env.unwrapped.task.config.physics
        assert env.unwrapped.task.config.control_timestep == 0.5
        start = env.unwrapped._env.physics.data.time
        env.step(env.action_space.sample())
        assert env.unwrapped._env.physics.data.time - start == pytest.approx(0.5)
        assert physics.timestep == 0.002
    assert _train(tmp_path / "default", "sac", 100, "--control-timestep", "0.05") == 0
    given_none = ["train", "--task", "push", "--algo", "sac", "--seed", "1", *TINY]
    assert RunDir(tmp_path / "default").read_config().differing(run_config(
        cli.build_parser().parse_args(given_none))) == {}  # One run, given or not.
    with pytest.raises(ValueError, match="--resume goes on with the run's own settings, and "
                                         ".* has control_timestep 0.5, not "
                                         "--control-timestep's 0.05"):
        _train(out, "sac", 200, "--resume", "--control-timestep", "0.05")
    # Named by the flag the user typed (the task and Python's API name the field).
    for bad, message in (("0.051", "^--control-timestep must be a whole multiple of the "
                                   "physics timestep \\(0.002 s\\), got 0.051$"),
                         ("0", "^--control-timestep must be > 0, got 0.0$")):
        with pytest.raises(ValueError, match=message):
            _train(tmp_path / "bad", "sac", 100, "--control-timestep", bad)
        assert not (tmp_path / "bad").exists()
        with pytest.raises(ValueError, match=message.replace("--control-timestep",
                                                             "control_timestep")):
            franka_composer.load("push", control_timestep=float(bad))


def test_a_run_at_the_reference_timing_is_recorded_and_played_at_it(tmp_path, capsys):
    """--timing reference: config.json holds 0.5 s per step, velocities per 0.05 s and the
    weld's 0.02 s, the variant says "reference timing", evaluation's env is made so, a
    resume that says another timing is refused naming --timing, and a policy will not act
    at another timing or on another weld. A run recorded before the weld was a setting (no
    "weld_time_constant") had the default one, and says so."""
    from franka_composer.datasets.sources import TrainedPolicy
    from franka_composer.training.policy_file import trained_on_its_task
    from franka_composer.policies.rollout import Trajectories
    from franka_composer.training.run_config import RunConfig

    out = tmp_path / "reference"
    assert _train(out, "sac", 100, "--timing", "reference") == 0
    config = RunDir(out).read_config()
    assert config.variant.endswith(", reference timing")
    saved = json.loads(RunDir(out).config_path.read_text())
    assert (saved["control_timestep"], saved["velocity_timestep"],
            saved["weld_time_constant"]) == (0.5, 0.05, 0.02)
    with trained_on_its_task(out, device="cpu") as (_, env, _policy):
        assert env.unwrapped.task.config.control_timestep == 0.5
        assert env.unwrapped.task.config.velocity_timestep == 0.05
        assert env.unwrapped.task.config.control.weld_time_constant == 0.02
    with pytest.raises(ValueError, match="--resume goes on with the run's own settings, and "
                                         ".* has control_timestep 0.5, not --timing's 0.05; "
                                         "velocity_timestep 0.05, not --timing's None; "
                                         "weld_time_constant 0.02, not --timing's 0.01"):
        _train(out, "sac", 200, "--resume", "--timing", "default")
    with pytest.raises(ValueError, match="observes velocities per 0.05 s, not per 0.5 s"):
        TrainedPolicy(out, make_env("push", control_timestep=0.5))
    with pytest.raises(ValueError, match="moved a hand welded with a time constant of 0.02 "
                                         "s, not 0.01 s"):
        TrainedPolicy(out, make_env("push", control_timestep=0.5, velocity_timestep=0.05))
    # `rollout --policy` records at the run's own timing unless told otherwise (and refuses).
    assert cli.main(["rollout", "--task", "push", "--policy", str(out), "--episodes", "1",
                     "--out", str(tmp_path / "played.npz")]) == 0
    assert Trajectories.load(tmp_path / "played.npz").metadata["options"] == {
        "control_timestep": 0.5, "velocity_timestep": 0.05, "weld_time_constant": 0.02}
    with pytest.raises(ValueError, match="acts every 0.5 s, not every 0.05 s"):
        cli.main(["rollout", "--task", "push", "--policy", str(out), "--timing", "default",
                  "--out", str(tmp_path / "refused.npz")])
    # `demo --policy` plays it at its own timing too, and refuses another.
    capsys.readouterr()
    assert cli.main(["demo", "--policy", str(out), "--episodes", "1", "--no-video"]) == 0
    assert capsys.readouterr().out.splitlines()[2].split()[:2] == ["push", "1"]
    with pytest.raises(ValueError, match="acts every 0.5 s, not every 0.05 s"):
        cli.main(["demo", "--policy", str(out), "--timing", "default", "--no-video"])
    del saved["weld_time_constant"]
    older = RunConfig.from_dict(saved)  # As the reference timing's first campaign cells.
    assert older.weld_time_constant == 0.01
    assert older.variant.endswith(", 0.5 s per step, velocities per 0.05 s")
    with pytest.raises(ValueError, match="--timing sets the control timestep: give --timing "
                                         "or --control-timestep, not both"):
        _train(tmp_path / "both", "sac", 100, "--timing", "reference",
               "--control-timestep", "0.5")
    assert not (tmp_path / "both").exists()


def _object_damping(env) -> np.ndarray:
    """The damping of the degrees of freedom of `env`'s objects' free joints."""
    model = env.unwrapped._env.physics.model
    return np.concatenate([model.dof_damping[model.jnt_dofadr[joint]:][:6]
                           for joint in np.flatnonzero(model.jnt_type == 0)])  # mjJNT_FREE


def test_a_run_on_damped_objects_is_recorded_and_played_on_them(tmp_path):
    """--object-damping 0.01 (the reference code's block): config.json holds it, the variant
    names it, evaluation, `rollout --policy` and the run's expert demonstrations are on
    objects damped so, a resume that says otherwise is refused, and a dataset recorded on
    undamped objects is refused naming both dynamics. A run recorded before the option had
    undamped objects, and is the same run as one given none."""
    from franka_composer.cli.train import run_config
    from franka_composer.datasets import record
    from franka_composer.policies.rollout import Trajectories
    from franka_composer.training.policy_file import trained_on_its_task
    from franka_composer.training.run_config import RunConfig

    out = tmp_path / "damped"
    assert _train(out, "sac", 100, "--object-damping", "0.01", "--expert-demos", "1") == 0
    config = RunDir(out).read_config()
    assert config.object_damping == 0.01
    assert config.variant == "net_arch 16,16, batch_size 32, buffer_size 2000, object damping " \
                             "0.01, 1 expert demos"
    saved = json.loads(RunDir(out).config_path.read_text())
    assert saved["object_damping"] == 0.01
    with trained_on_its_task(out, device="cpu") as (_, env, _policy):
        env.reset(seed=0)
        np.testing.assert_array_equal(_object_damping(env), np.full(6, 0.01))
    assert Trajectories.load(RunDir(out).expert_demos).metadata["options"][
        "object_damping"] == 0.01
    assert cli.main(["rollout", "--task", "push", "--policy", str(out), "--episodes", "1",
                     "--out", str(tmp_path / "played.npz")]) == 0
    # What differs from the task's own (the run's timing is the task's: not listed).
    assert Trajectories.load(tmp_path / "played.npz").metadata["options"] == {
        "object_damping": 0.01}
    with pytest.raises(ValueError, match="--resume goes on with the run's own settings, and "
                                         ".* has object_damping 0.01, not "
                                         "--object-damping's 0.0"):
        _train(out, "sac", 200, "--resume", "--object-damping", "0")
    record("push", 1, tmp_path / "undamped.npz", seed=0)
    with pytest.raises(ValueError, match=re.escape(
            "undamped.npz was recorded at 0.05 s per step, velocities per 0.05 s, weld 0.01 s, "
            "and this run trains at 0.05 s per step, velocities per 0.05 s, weld 0.01 s, "
            "objects damped 0.01: its transitions are of other dynamics")):
        _train(tmp_path / "refused", "sac", 100, "--object-damping", "0.01", "--demos",
               str(tmp_path / "undamped.npz"))
    # `rollout --object-damping` records on other objects (the policy too), and such a
    # dataset fills a damped run's buffer.
    assert cli.main(["rollout", "--task", "push", "--policy", str(out), "--object-damping",
                     "0", "--episodes", "1", "--out", str(tmp_path / "undamped-play.npz")]) == 0
    assert "object_damping" not in Trajectories.load(
        tmp_path / "undamped-play.npz").metadata["options"]
    assert cli.main(["rollout", "--task", "push", "--object-damping", "0.01", "--episodes",
                     "1", "--out", str(tmp_path / "damped.npz")]) == 0
    assert _train(tmp_path / "on-demos", "sac", 100, "--object-damping", "0.01", "--demos",
                  str(tmp_path / "damped.npz")) == 0
    del saved["object_damping"]
    older = RunConfig.from_dict(saved)
    assert older.object_damping == 0.0 and "object damping" not in older.variant
    given_none = ["train", "--task", "push", "--algo", "sac", "--seed", "1", *TINY,
                  "--expert-demos", "1"]
    assert older.differing(run_config(cli.build_parser().parse_args(given_none))) == {}
    for task, bad, message in (
            ("push", "-1", "--object-damping must be >= 0, got -1.0"),
            ("reach", "0.01", "--object-damping does not apply to reach: it has no object")):
        with pytest.raises(ValueError, match=re.escape(message)):
            cli.main(["train", "--task", task, "--algo", "sac", "--out",
                      str(tmp_path / "refused"), "--object-damping", bad, *TINY])
    assert not (tmp_path / "refused").exists()


def test_rollout_of_a_policy_records_episodes_as_its_run_trained(tmp_path):
    """`rollout --policy` recorded a run trained without termination on success, or with
    randomisation, in terminating, unrandomised episodes: other success numbers than
    `evaluate` and `demo` gave, and a dataset `train --demos` refused for that very run."""
    from franka_composer.policies.rollout import Trajectories

    out = tmp_path / "run"
    assert _train(out, "sac", 200, "--no-terminate-on-success", "--randomization",
                  "default") == 0
    assert cli.main(["rollout", "--task", "push", "--policy", str(out), "--episodes", "2",
                     "--out", str(tmp_path / "played.npz")]) == 0
    played = Trajectories.load(tmp_path / "played.npz")
    assert played.metadata["options"] == {"terminate_on_success": False,
                                          "randomization": "default"}
    assert played.lengths.tolist() == [50, 50]
    assert _train(tmp_path / "on-demos", "sac", 100, "--no-terminate-on-success",
                  "--randomization", "default", "--demos", str(tmp_path / "played.npz")) == 0


def test_the_weld_counts_only_under_mocap_control():
    """The weld's time constant is part of a mocap run's timing (its label, a resume's
    comparison); the osc and joints controllers have no weld, so a run of theirs recorded
    before the weld was a setting (read as the default's) is the same run at the reference
    timing as one recorded with it."""
    from franka_composer.training.run_config import RunConfig

    def config(control, weld):
        return RunConfig("push", "sac", 0, hyperparameters("push", "sac"), control=control,
                         control_timestep=0.5, velocity_timestep=0.05,
                         weld_time_constant=weld)

    assert config("osc", None).differing(config("osc", 0.02)) == {}
    assert config("osc", None).timing_label == "reference timing"
    assert config("mocap", None).differing(config("mocap", 0.02)) == {
        "weld_time_constant": (0.01, 0.02)}
    assert config("mocap", None).timing_label == "0.5 s per step, velocities per 0.05 s"
    assert config("mocap", 0.02).timing_label == "reference timing"
    # A mocap run beside an osc one (a resume, keep or sweep given the other): the controller
    # differs, and only it (not a KeyError on the weld only one of them has).
    for ours, theirs in (("mocap", "osc"), ("osc", "mocap")):
        assert config(ours, 0.02).differing(config(theirs, 0.02)) == {"control": (ours, theirs)}


def test_a_run_keeps_the_surface_guard_it_trained_under(capsys):
    """Stack's v1 guard counts a carried block as part of the hand; a stack run from before
    it (its config.json names no guard setting, as issue 40's kept run) trained under v0's,
    and is remade, labelled and checked as such: played on v1's guard it would act in
    dynamics it never saw."""
    from franka_composer.datasets.sources import check_acts_in
    from franka_composer.tasks import task_config
    from franka_composer.training.run_config import RunConfig

    new = RunConfig("stack", "tqc", 0, hyperparameters("stack", "tqc"), backend="sbx")
    assert new.guard_ignores_carried is True and new.setup == ""
    assert "guard_ignores_carried" not in new.env_options
    saved = new.to_dict()
    assert saved["guard_ignores_carried"] is True
    del saved["guard_ignores_carried"]
    older = RunConfig.from_dict(saved)
    assert older.guard_ignores_carried is False
    assert older.setup == "guard_ignores_carried=False"
    assert older.differing(new) == {"guard_ignores_carried": (False, True)}
    env = make_env("stack", **older.env_options)
    try:
        assert env.unwrapped.task.config.control.guard_ignores_carried is False
    finally:
        env.close()
    kept = RunDir(pathlib.Path(__file__).resolve().parents[1] / "results" / "learnability"
                  / "stack-tqc-seed0").read_config()
    assert kept.guard_ignores_carried is False
    with pytest.raises(ValueError, match=re.escape(
            "run trained with guard_ignores_carried=False, not True: the surface guard held "
            "the hand differently wherever it carried a block")):
        check_acts_in("run", older, task_config("stack"))
    check_acts_in("run", older, task_config("stack", guard_ignores_carried=False))
    # Push's own is v0's: a push run from before names none and is the same run.
    push = RunConfig("push", "sac", 0, hyperparameters("push", "sac"))
    assert RunConfig.from_dict({k: v for k, v in push.to_dict().items()
                                if k != "guard_ignores_carried"}).differing(push) == {}
    with pytest.raises(ValueError, match=re.escape(
            "guard_ignores_carried does nothing here: reach has no object to carry")):
        RunConfig("reach", "sac", 0, hyperparameters("reach", "sac"),
                  guard_ignores_carried=True)
    # `train --guard-ignores-carried false` trains (or, in a sweep, names) such a run: a
    # campaign's stack cell from before v1 is its own run again, not "another run".
    from franka_composer.cli.train import run_config

    parsed = cli.build_parser().parse_args(["train", "--task", "stack", "--algo", "tqc",
                                            "--backend", "sbx", "--guard-ignores-carried",
                                            "FALSE"])
    assert run_config(parsed).differing(older) == {}
    capsys.readouterr()
    with pytest.raises(SystemExit):
        cli.build_parser().parse_args(["train", "--guard-ignores-carried", "no"])
    assert ("argument --guard-ignores-carried: must be true or false, got 'no'"
            in capsys.readouterr().err)


@pytest.mark.parametrize("seed", ["-1", "2147483648", "1.5"])
def test_a_seed_sb3_cannot_take_is_refused_before_the_run_exists(tmp_path, capsys, seed):
    """SB3 seeds NumPy with the seed plus the evaluation offset (and plus the steps on a
    resume), at most 2**32 - 1: a bad seed is refused by the parser, not after config.json
    was written."""
    with pytest.raises(SystemExit):
        _train(tmp_path / "run", "sac", 100, "--seed", seed)
    assert "argument --seed: must be an integer from 0 to 2147483647" in \
        capsys.readouterr().err
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("algo, format", [("ddpg", "npz"), ("sac", "minari"),
                                          ("tqc", "rlds")])
def test_demonstrations_fill_the_replay_buffer_before_learning(tmp_path, algo, format):
    """Every algorithm, every format: the buffer starts with the demonstrations, whole
    episodes, in order, and keeps them (the run writes its checkpoint's buffer)."""
    from stable_baselines3.common.save_util import load_from_pkl

    from franka_composer.datasets import record
    from franka_composer.training import demos

    path = tmp_path / ("demos.npz" if format == "npz" else "demos")
    record("push", 3, path, format=format, seed=7)
    if format == "minari":
        path = path / "franka_composer" / "push" / "expert-v0"
    env = make_env("push")
    episodes = demos.load_episodes(path, env)
    env.close()
    out = tmp_path / "run"
    assert _train(out, algo, 100, "--demos", str(path), "--demo-episodes", "2",
                  "--checkpoint-every", "100") == 0
    config = RunDir(out).read_config()
    assert (config.demos, config.demo_episodes) == (str(path.resolve()), 2)
    buffer = load_from_pkl(RunDir(out).checkpoint_buffer)
    count = sum(len(e["action"]) for e in episodes[:2])
    stored = buffer.observations["observation"][:count, 0]
    np.testing.assert_array_equal(stored, np.concatenate(
        [e["observation"][:-1] for e in episodes[:2]]))
    np.testing.assert_array_equal(buffer.actions[:count, 0],
                                  np.concatenate([e["action"] for e in episodes[:2]]))
    assert buffer.ep_length[0, 0] == len(episodes[0]["action"])  # Whole episodes for HER.
    assert buffer.pos == count + 100  # Then the run's own 100 steps.
    with pytest.raises(ValueError, match=re.escape(  # A raised budget keeps them too.
            f"holds 2000 transitions, {count} of them for its demonstrations, so at most "
            f"{2000 - count} steps keep them")):
        _train(out, algo, 2001 - count, "--resume")


def test_the_runs_expert_records_its_demonstrations_at_its_start(tmp_path):
    """--expert-demos N: the run records N expert episodes into its folder, seeded apart
    from other seeds' runs, and its buffer starts with them, whole, in order."""
    from stable_baselines3.common.save_util import load_from_pkl

    from franka_composer.datasets import record
    from franka_composer.training import demos
    from franka_composer.training.run_config import EXPERT_DEMO_SEED

    out = tmp_path / "run"
    assert _train(out, "sac", 100, "--expert-demos", "2", "--checkpoint-every", "100") == 0
    run = RunDir(out)
    config = run.read_config()
    assert (config.expert_demos, config.demos) == (2, None)
    assert config.expert_demo_seed == EXPERT_DEMO_SEED + 100_000  # The run's seed is 1.
    assert "2 expert demos" in config.variant
    # The same episodes as the expert recorded by hand from that seed.
    record("push", 2, tmp_path / "by-hand.npz", seed=config.expert_demo_seed)
    env = make_env("push")
    recorded = demos.load_episodes(run.expert_demos, env)
    by_hand = demos.load_episodes(tmp_path / "by-hand.npz", env)
    env.close()
    for ours, theirs in zip(recorded, by_hand, strict=True):
        for key in ("observation", "action", "reward"):
            np.testing.assert_array_equal(ours[key], theirs[key])
    buffer = load_from_pkl(run.checkpoint_buffer)
    count = sum(len(e["action"]) for e in recorded)
    np.testing.assert_array_equal(buffer.actions[:count, 0],
                                  np.concatenate([e["action"] for e in recorded]))
    assert buffer.pos == count + 100
    # A raised budget keeps them too: 2 episodes of up to 50 steps leave 1900 of 2000.
    config_before = run.config_path.read_bytes()
    with pytest.raises(ValueError, match=re.escape(
            f"--total-steps 1901: {out}'s replay buffer holds 2000 transitions, 100 of them "
            "for its demonstrations, so at most 1900 steps keep them")):
        _train(out, "sac", 1901, "--resume")
    assert run.config_path.read_bytes() == config_before
    # So does a budget edited into config.json: the resume trained on over them.
    edited = json.loads(config_before)
    edited["hyperparameters"]["total_steps"] = 1901
    run.config_path.write_text(json.dumps(edited))
    with pytest.raises(ValueError, match=re.escape(
            f"{run.config_path}'s total_steps 1901 (its checkpoint's: 100): {out}'s "
            "replay buffer holds 2000 transitions, 100 of them for its demonstrations, so "
            "at most 1900 steps keep them")):
        cli.main(["train", "--resume", "--out", str(out)])


def test_a_plain_resume_of_a_demos_run_does_not_count_its_dataset_again(tmp_path,
                                                                        monkeypatch):
    """Its replay buffer holds the demonstrations it began with: a resume without
    --total-steps counted the dataset now at their path, recorded again since with more
    episodes, and refused the budget that fits."""
    from franka_composer.datasets import record

    dataset = tmp_path / "push.npz"
    record("push", 2, dataset, seed=0)
    out = tmp_path / "run"
    assert _train(out, "sac", 200, "--demos", str(dataset), "--buffer-size", "300") == 0
    record("push", 10, dataset, seed=0)
    assert cli.main(["train", "--resume", "--out", str(out), "--no-progress"]) == 0
    # Its --demos given again, as a relative path, agrees: only what breaks the run is named.
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=re.escape(
            "--resume goes on with the run's own settings, and --expert-demos would change")):
        cli.main(["train", "--resume", "--out", str(out), "--demos", "push.npz",
                  "--expert-demos", "5"])


def test_expert_demonstrations_are_refused_beside_a_dataset_or_past_the_buffer(tmp_path):
    from franka_composer.datasets import record

    record("push", 1, tmp_path / "push.npz", seed=0)
    with pytest.raises(ValueError, match=re.escape(
            "a run's demonstrations come from a dataset (--demos) or are recorded by its "
            "expert (--expert-demos), not both")):
        _train(tmp_path / "run", "sac", 100, "--expert-demos", "2", "--demos",
               str(tmp_path / "push.npz"))
    # 2000 buffer transitions (TINY): 3 episodes of up to 50 steps and 1900 steps do not fit.
    with pytest.raises(ValueError, match=re.escape(
            "the replay buffer holds 2000 transitions: 150 of demonstrations and 1900 steps "
            "would overwrite demonstrations")):
        _train(tmp_path / "run", "sac", 1900, "--expert-demos", "3")
    assert not (tmp_path / "run").exists()


def test_demonstrations_are_refused_when_they_do_not_fit(tmp_path, capsys):
    from franka_composer.datasets import record

    record("pick_and_place", 2, tmp_path / "pnp.npz", seed=0)
    record("push", 2, tmp_path / "push.npz", seed=0)
    record("push", 1, tmp_path / "dense.npz", seed=0, reward_type="dense")
    record("push", 1, tmp_path / "osc", format="rlds", seed=0, control="osc")
    record("slide", 1, tmp_path / "slide", format="minari", seed=0)
    record("push", 1, tmp_path / "dense-rlds", format="rlds", seed=0, reward_type="dense")
    record("push", 1, tmp_path / "reference.npz", seed=0, timing="reference")
    record("push", 1, tmp_path / "slow", format="minari", seed=0, control_timestep=0.5)
    for extra, message in (
            (["--demos", str(tmp_path / "dense.npz")], "was recorded with dense rewards, not "
                                                       "the sparse [-1.0, 0.0] that "
                                                       "training uses"),
            (["--demos", str(tmp_path / "dense-rlds")], "was recorded with dense rewards, not "
                                                        "the sparse [-1.0, 0.0] that "
                                                        "training uses"),
            (["--demos", str(tmp_path / "osc")], "was recorded through osc control, and this "
                                                 "run trains through mocap"),
            (["--demos", str(tmp_path / "slide" / "franka_composer" / "slide" / "expert-v0")],
             "holds demonstrations of slide, not push"),
            (["--demos", str(tmp_path / "pnp.npz")], "holds demonstrations of pick_and_place, "
                                                     "not push"),
            (["--demos", str(tmp_path / "push.npz"), "--demo-episodes", "3"],
             "--demo-episodes 3, but"),
            (["--demo-episodes", "2"], "--demo-episodes takes the first episodes of --demos"),
            (["--demos", str(tmp_path)], "is not a dataset"),
            (["--demos", str(tmp_path / "reference.npz")],
             "was recorded at 0.5 s per step, velocities per 0.05 s, weld 0.02 s, and this run "
             "trains at 0.05 s per step, velocities per 0.05 s, weld 0.01 s"),
            (["--demos", str(tmp_path / "slow" / "franka_composer" / "push" / "expert-v0"),
              "--timing", "reference"],
             "was recorded at 0.5 s per step, velocities per 0.5 s, weld 0.01 s, and this run "
             "trains at 0.5 s per step, velocities per 0.05 s, weld 0.02 s")):
        with pytest.raises(ValueError, match=re.escape(message)):
            _train(tmp_path / "run", "sac", 100, *extra)
        assert not (tmp_path / "run").exists()
    with pytest.raises(ValueError, match="would overwrite demonstrations"):
        _train(tmp_path / "small", "sac", 2000, "--demos", str(tmp_path / "push.npz"))
    assert not (tmp_path / "small").exists()
    assert _train(tmp_path / "at-its-timing", "sac", 100, "--timing", "reference",
                  "--demos", str(tmp_path / "reference.npz")) == 0
