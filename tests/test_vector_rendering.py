"""Vector envs with camera observations or rendering, in every Gymnasium vectorization mode
and SB3's SubprocVecEnv, fork and spawn (gl_fork.py, tasks/cameras.py), and the threads
contract (render_owner.py).

Each vector case runs in a fresh interpreter under a hard timeout: a GL hang in a forked
worker fails its test instead of stopping the suite.
"""

from __future__ import annotations

import ctypes.util
import json
import os
import re
import subprocess
import sys
import threading
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest

import franka_composer
from franka_composer.render_owner import RenderThreadError

ROOT = Path(__file__).resolve().parents[1]
TIMEOUT_S = 240

# Renders a single env in this process, and a vector env of two ("parent-first": the
# single one first, so the workers are forked from a process that has rendered), then
# prints whether the vector env's first sub-env saw exactly the single env's frames.
SCRIPT = r"""
import json, sys
import gymnasium as gym
import numpy as np
import franka_composer

vector, case, order = sys.argv[1:4]
if len(sys.argv) > 4:  # Stands in for a GPU's EGL: its vendor, as if this process started it.
    import os
    franka_composer.gl_fork._egl_driver = (os.getpid(), sys.argv[4])
pixels = case == "pixels"
options = (dict(observation_mode="pixels") if pixels
           else dict(render_mode="rgb_array", width=48, height=48))
actions = np.array([[0.5, -0.3, -0.2], [-0.4, 0.2, 0.1]], np.float32)


def single_frames():
    env = gym.make("FrankaPushSparse-v0", **options)
    obs, _ = env.reset(seed=3)
    frames = [obs["workspace_pixels"] if pixels else env.render()]
    for action in actions:
        obs, *_ = env.step(action)
        frames.append(obs["workspace_pixels"] if pixels else env.render())
    env.close()
    return frames


def vector_frames():
    def frame(obs, images):
        return obs["workspace_pixels"][0] if pixels else images()[0]

    if vector.startswith("gym-"):
        mode = vector[len("gym-"):]
        env = gym.make_vec("FrankaPushSparse-v0", num_envs=2,
                           vectorization_mode="sync" if mode == "sync" else "async",
                           vector_kwargs={} if mode == "sync" else {"context": mode},
                           **options)
        obs, _ = env.reset(seed=3)
        frames = [frame(obs, env.render)]
        for action in actions:
            obs, *_ = env.step(np.stack([action, action]))
            frames.append(frame(obs, env.render))
    else:
        from stable_baselines3.common.vec_env import SubprocVecEnv
        # "module:id" imports franka_composer (which registers the id) in spawned workers.
        env = SubprocVecEnv([lambda: gym.make("franka_composer:FrankaPushSparse-v0",
                                              **options)] * 2,
                            start_method=vector[len("sb3-"):])
        env.seed(3)
        obs = env.reset()
        frames = [frame(obs, env.get_images)]
        for action in actions:
            obs, *_ = env.step(np.stack([action, action]))
            frames.append(frame(obs, env.get_images))
    env.close()
    return frames


if order == "parent-first":
    reference = single_frames()
    frames = vector_frames()
else:
    frames = vector_frames()
    reference = single_frames()
print(json.dumps({
    "shape": list(np.shape(frames[0])),
    "images": bool(min(np.std(f) for f in frames) > 10),
    "equal": all(np.array_equal(a, b) for a, b in zip(frames, reference)),
}))
"""

VECTORS = ["gym-sync", "gym-fork", "gym-spawn", "gym-forkserver", "sb3-fork", "sb3-spawn"]
FORKED = ["gym-fork", "sb3-fork"]
#: Mesa's EGL (this machine's software GL) lets forked workers render; a GPU's own does not.
FORKS_RENDER = franka_composer.gl_fork.forked_children_render()
#: The vectorizations whose workers render on this machine's GL.
RENDERING = [v for v in VECTORS if FORKS_RENDER or v not in FORKED]
SPAWN_ADVICE = ("start the workers with spawn or forkserver (gym.make_vec(..., "
                "vectorization_mode='async', vector_kwargs={'context': 'spawn'}); "
                "SubprocVecEnv(..., start_method='spawn'))")


def run_python(code: str, *args: str, timeout: float = TIMEOUT_S,
               **environment: str) -> subprocess.CompletedProcess:
    """`code` run by a fresh interpreter on this checkout; past `timeout` the test fails."""
    # EGL unless a test says otherwise: what is tested is the package's default backend.
    env = {**os.environ, "PYTHONPATH": str(ROOT), "MUJOCO_GL": "egl", **environment}
    env.pop("PYOPENGL_PLATFORM", None)  # dm_control sets it for this process's backend.
    try:
        return subprocess.run([sys.executable, "-c", code, *args], cwd=ROOT, env=env,
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        pytest.fail(f"{' '.join(args) or 'the script'}: no result within {timeout} s (a hang)")


def run_case(vector: str, case: str, order: str, **environment: str):
    """The script's result for one case, or its stderr's last lines when it failed."""
    done = run_python(SCRIPT, vector, case, order, **environment)
    if done.returncode != 0:
        return "\n".join(done.stderr.strip().splitlines()[-6:])
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.slow
@pytest.mark.parametrize("vector", RENDERING)
def test_pixel_observations_of_a_vector_env_equal_a_single_envs(vector):
    # The workers are forked from a process that built an env (Gymnasium builds one for
    # the spaces) but never rendered: they render, the same frames as a single env.
    result = run_case(vector, "pixels", "vector-first")
    assert result == {"shape": [84, 84, 3], "images": True, "equal": True}


@pytest.mark.slow
@pytest.mark.parametrize("vector", RENDERING)
def test_rendering_vector_env_works_after_the_parent_rendered(vector):
    result = run_case(vector, "rgb_array", "parent-first")
    assert result == {"shape": [48, 48, 3], "images": True, "equal": True}


def assert_refused_for(vendor: str, done: subprocess.CompletedProcess) -> None:
    """A forked worker's first render raised ForkedGLError naming the driver (the parent
    raises it again, Gymnasium, or sees its worker gone, SB3)."""
    assert done.returncode != 0
    error = done.stderr.split("ForkedGLError: ", 1)[-1]
    assert re.match(r"this process \(\d+\) was forked from process \d+, where the EGL driver "
                    rf"of '{vendor}' had been initialised \(dm_control opens its display on "
                    r"import\), and that driver cannot make GL contexts in a forked child "
                    r"\(its eglCreateContext fails, or the render never returns\): ", error)
    assert SPAWN_ADVICE in error


@pytest.mark.slow
@pytest.mark.parametrize("vector", FORKED)
@pytest.mark.parametrize("case, order", [("pixels", "vector-first"),
                                         ("rgb_array", "parent-first")])
def test_forked_workers_of_a_gpu_egl_refuse_clearly(vector, case, order):
    # NVIDIA's EGL, once dm_control has initialised it (on import), makes no context in a
    # forked child: EGL_BAD_ALLOC, or a worker that never answers (measured on an H100 and
    # an H200). Here the vendor stands in; on such a GPU the driver itself is refused.
    vendor = "NVIDIA" if FORKS_RENDER else franka_composer.gl_fork._egl_driver[1]
    extra = ("NVIDIA",) if FORKS_RENDER else ()
    assert_refused_for(vendor, run_python(SCRIPT, vector, case, order, *extra))
    spawned = run_python(SCRIPT, vector.replace("fork", "spawn"), case, order, *extra)
    assert json.loads(spawned.stdout.strip().splitlines()[-1])["equal"]


osmesa = pytest.mark.skipif(ctypes.util.find_library("OSMesa") is None,
                            reason="no libOSMesa on this machine (Debian: libosmesa6)")


@pytest.mark.slow
@osmesa
def test_osmesa_pixel_workers_forked_before_any_render_work():
    result = run_case("gym-fork", "pixels", "vector-first", MUJOCO_GL="osmesa")
    assert result == {"shape": [84, 84, 3], "images": True, "equal": True}


@pytest.mark.slow
@osmesa
def test_osmesa_workers_forked_after_the_parent_rendered_refuse_clearly():
    result = run_case("gym-fork", "rgb_array", "parent-first", MUJOCO_GL="osmesa")
    assert "ForkedGLError: MUJOCO_GL=osmesa cannot render in this process" in result
    assert "vector_kwargs={'context': 'spawn'}" in result
    result = run_case("gym-spawn", "rgb_array", "parent-first", MUJOCO_GL="osmesa")
    assert result == {"shape": [48, 48, 3], "images": True, "equal": True}


# Renders, then (with "fork") forks a child that renders too, refused under OSMesa after the
# parent rendered; the child exits as a process does (its garbage collected, no atexit).
EXIT_SCRIPT = r"""
import gc, os, sys
import franka_composer

env = franka_composer.load("reach")
env.reset()
env.physics.render(32, 32)
if sys.argv[1:] == ["fork"]:
    pid = os.fork()
    if pid == 0:
        child = franka_composer.load("reach")
        child.reset()
        try:
            child.physics.render(32, 32)
        except franka_composer.gl_fork.ForkedGLError:
            print("refused", flush=True)
        del child
        gc.collect()
        sys.stderr.flush()
        os._exit(0)
    os.waitpid(pid, 0)
print("rendered")
"""


@pytest.mark.parametrize("gl", ["egl", pytest.param("osmesa", marks=osmesa)])
@pytest.mark.parametrize("fork", [(), ("fork",)])
def test_a_process_that_rendered_exits_without_a_traceback(gl, fork):
    """dm_control frees its GL contexts in an atexit callback, after Python has stopped the
    thread pools OSMesa's calls run on: every script that rendered under OSMesa ended with
    three tracebacks, and a child refused a context one more (its __del__ found no
    executor)."""
    done = run_python(EXIT_SCRIPT, *fork, MUJOCO_GL=gl)
    refused = fork and (gl == "osmesa" or not FORKS_RENDER)  # A GPU's EGL refuses forks.
    assert done.returncode == 0 and done.stdout.split() == (
        ["refused", "rendered"] if refused else ["rendered"])
    assert done.stderr == ""


# ----- Threads ------------------------------------------------------------------------------


def _on_thread(function):
    """What `function()` returned or raised on a new thread."""
    outcome = []

    def run():
        try:
            outcome.append(function())
        except Exception as error:  # noqa: BLE001 - the outcome under test
            outcome.append(error)

    thread = threading.Thread(target=run, name="other")
    thread.start()
    thread.join()
    return outcome[0]


def test_an_env_rendered_on_one_thread_closes_on_another():
    env = gym.make("FrankaPushSparse-v0", render_mode="rgb_array", width=32, height=32)
    env.reset(seed=0)
    assert _on_thread(env.render).shape == (32, 32, 3)
    assert env.close() is None  # On the main thread, which never rendered it.
    with pytest.raises(gym.error.ClosedEnvironmentError):
        env.render()
    # And the other way round: rendered here, closed on another thread.
    env = gym.make("FrankaPushSparse-v0", render_mode="rgb_array", width=32, height=32)
    env.reset(seed=0)
    env.render()
    assert _on_thread(env.close) is None


def test_closing_on_another_thread_leaves_nothing_to_fail_at_exit():
    # dm_control frees a context at exit and in garbage collection; for one current on
    # another thread that raised EGLError tracebacks after the program's own output.
    code = ("import threading, gymnasium as gym, franka_composer\n"
            "env = gym.make('FrankaPushSparse-v0', render_mode='rgb_array', width=32, "
            "height=32)\n"
            "env.reset(seed=0)\n"
            "thread = threading.Thread(target=env.render); thread.start(); thread.join()\n"
            "env.close(); del env\n"
            "import gc; gc.collect(); print('closed')\n")
    done = run_python(code)
    assert (done.returncode, done.stdout.strip(), done.stderr.strip()) == (0, "closed", "")


def test_an_env_rendered_on_another_thread_and_dropped_unclosed_is_collected_quietly():
    """Collected on the main thread, its context current on the (finished) thread that
    rendered it: dm_control's frees raised EGLError tracebacks ("Exception ignored in")."""
    code = ("import gc, threading, gymnasium as gym, franka_composer\n"
            "held = {}\n"
            "def render():\n"
            "    env = gym.make('FrankaPushSparse-v0', render_mode='rgb_array', width=32, "
            "height=32)\n"
            "    env.reset(seed=0); env.render(); held['env'] = env\n"
            "thread = threading.Thread(target=render); thread.start(); thread.join()\n"
            "held.clear(); gc.collect(); print('collected')\n"
            "import os; os._exit(0)\n")  # (Left to the exit, dm_control still prints them.)
    done = run_python(code)
    assert (done.returncode, done.stdout.strip(), done.stderr.strip()) == (0, "collected", "")


def test_a_pixel_step_on_another_thread_is_refused_before_the_physics_moves():
    env = gym.make("FrankaPushSparse-v0", observation_mode="pixels")
    obs, _ = env.reset(seed=0)
    before = env.unwrapped.composer_env.physics.data.time
    action = np.array([0.5, 0.0, 0.0], np.float32)
    for call in (lambda: env.step(action), lambda: env.reset(seed=1)):
        error = _on_thread(call)
        assert isinstance(error, RenderThreadError)
        assert str(error) == (
            "this environment renders on thread 'MainThread', which rendered it first (its "
            "GL context is current there), and cannot render or step its camera "
            "observations on thread 'other': call render(), reset() and step() from that "
            "thread, or make one environment per thread (close() works from any thread)")
    assert env.unwrapped.composer_env.physics.data.time == before
    obs, *_ = env.step(action)  # The rendering thread still steps.
    assert obs["workspace_pixels"].std() > 10
    env.close()


def test_a_state_env_steps_on_any_thread():
    env = franka_composer.load("push", seed=0)
    env.reset()
    timestep = _on_thread(lambda: env.step(np.zeros(3)))
    assert timestep.observation["achieved_goal"].shape == (3,)
    env.close()


def test_building_a_pixel_env_renders_nothing_until_its_first_episode():
    # Composer reads every observable as it builds the env; a render there would start GL
    # in Gymnasium's async parent, which never observes an episode.
    env = franka_composer.load("push", seed=0, observation_mode="pixels")
    assert env.physics._contexts is None  # pylint: disable=protected-access
    assert env.reset().observation["workspace_pixels"].std() > 10
    env.close()


# ----- Forked processes ---------------------------------------------------------------------

# Renders an env here, then in a chain of forked descendants, each rendering the env it
# inherited and a new one; prints what each descendant saw (or the error it met).
FORK_CHAIN = r"""
import json, os, sys
import gymnasium as gym
import numpy as np
import franka_composer

generations = int(sys.argv[1])
options = dict(render_mode="rgb_array", width=48, height=48)
env = gym.make("FrankaPushSparse-v0", **options)
env.reset(seed=3)
reference = env.render()


def descend(generation):
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:
        os.close(read)
        try:
            fresh = gym.make("FrankaPushSparse-v0", **options)
            fresh.reset(seed=3)
            report = [{"inherited": bool(np.array_equal(env.render(), reference)),
                       "fresh": bool(np.array_equal(fresh.render(), reference))}]
            if generation < generations:
                report += descend(generation + 1)
        except Exception as error:
            report = [f"{type(error).__name__}: {error}"]
        os.write(write, json.dumps(report).encode())
        os._exit(0)
    os.close(write)
    data = b""
    while chunk := os.read(read, 65536):
        data += chunk
    os.waitpid(pid, 0)
    return json.loads(data)


print(json.dumps(descend(1)))
"""


@pytest.mark.slow
@pytest.mark.skipif(not FORKS_RENDER, reason="Mesa's EGL: a GPU's refuses forked children")
def test_forked_descendants_render_inherited_and_new_envs_until_displays_run_out():
    done = run_python(FORK_CHAIN, "4")
    reports = json.loads(done.stdout.strip().splitlines()[-1])
    # Each generation opens a display of its own; Mesa has four (the first is the parent's).
    assert reports[:3] == [{"inherited": True, "fresh": True}] * 3
    assert reports[3].startswith("ForkedGLError: this process (")
    assert reports[3].endswith("no EGL display of its own is left to open (each forked "
                               "generation that renders takes one, and Mesa offers four): "
                               + SPAWN_ADVICE)


@pytest.mark.skipif(not FORKS_RENDER, reason="a GPU's EGL: the child must leave through "
                    "os._exit (test_a_child_leaving_through_os_exit_leaves_the_parent_rendering)")
def test_a_child_forked_after_rendering_exits_normally():
    # Its inherited GL contexts and display are the parent's: freeing them at exit (as
    # dm_control does) waited forever for the parent's render threads.
    code = ("import os, sys, gymnasium as gym, franka_composer\n"
            "env = gym.make('FrankaPushSparse-v0', render_mode='rgb_array', width=32, "
            "height=32)\n"
            "env.reset(seed=0); env.render()\n"
            "pid = os.fork()\n"
            "if pid == 0:\n"
            "    sys.exit(3)\n"
            "print(os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]))\n")
    assert run_python(code, timeout=60).stdout.strip() == "3"


def test_a_child_leaving_through_os_exit_leaves_the_parent_rendering():
    # What multiprocessing's fork workers do, and what a GPU's EGL needs: a child that exits
    # normally there runs NVIDIA's driver teardown on state it shares with its parent, whose
    # next render, close or exit then never returns (measured on an H200).
    code = ("import os, gymnasium as gym, numpy as np, franka_composer\n"
            "env = gym.make('FrankaPushSparse-v0', render_mode='rgb_array', width=32, "
            "height=32)\n"
            "env.reset(seed=0); before = env.render()\n"
            "pid = os.fork()\n"
            "if pid == 0:\n"
            "    os._exit(3)\n"
            "code = os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1])\n"
            "same = np.array_equal(env.render(), before) and before.std() > 10\n"
            "env.close(); print(code, same)\n")
    done = run_python(code, timeout=60)
    assert (done.returncode, done.stdout.strip()) == (0, "3 True")
