"""tools/slide_calibration.py: its fits and cuts turn measured strikes into the slide expert's
calibration, and one real strike moves the puck as that calibration says."""

from __future__ import annotations

import pathlib

import gymnasium as gym
import numpy as np
import pytest

from conftest import load_script
from franka_composer.adapters.registration import env_id
from franka_composer.policies import make_expert
from franka_composer.policies.slide import CALIBRATIONS

calibration = load_script(pathlib.Path(__file__).resolve().parents[1] / "tools"
                          / "slide_calibration.py")


def test_the_glide_fit_recovers_gain_and_dead_kick():
    kicks = np.array([0.2, 0.4, 0.6, 0.8, 1.0])
    gain, dead_kick = calibration.fit_glide(kicks, 1.5**2 * (kicks - 0.05) ** 2)
    assert gain == pytest.approx(1.5) and dead_kick == pytest.approx(0.05)


def test_thinning_keeps_the_corners_and_drops_what_they_interpolate():
    angles = [0.0, 1.0, 2.0, 3.0, 4.0]
    assert calibration.thin(angles, [0.0, 1.0, 2.0, 1.0, 0.0], 0.3, 1) == (
        (0.0, 2.0, 4.0), (0.0, 2.0, 0.0))
    assert calibration.thin(angles, [0.0, 0.1, 0.0, 0.1, 0.0], 0.3, 1) == (
        (0.0, 4.0), (0.0, 0.0))


def test_pieces_leave_out_strikes_that_go_either_way_and_cut_at_jumps():
    turns = np.array([[1.0, 1.2], [1.1, 1.1], [-8.0, 2.0], [5.0, 5.2], [5.1, 5.1]])
    assert calibration.pieces([0.0, 2.5, 5.0, 7.5, 10.0], turns) == [
        ((0.0, 2.5), (1.1, 1.1)), ((7.5, 10.0), (5.1, 5.1))]
    jump = np.array([[0.0, 0.0], [0.2, 0.2], [4.0, 4.0]])
    assert calibration.pieces([0.0, 2.5, 5.0], jump) == [((0.0, 2.5), (0.0, 0.2)),
                                                           ((5.0,), (4.0,))]


def test_a_kick_at_the_reference_timing_glides_as_its_calibration_says():
    env = gym.make(env_id("slide", "sparse"), timing="reference", terminate_on_success=False,
                   max_episode_steps=calibration.MAX_STEPS)
    expert = make_expert(env)
    strike = CALIBRATIONS["mocap", "reference"]
    # Kick 0.6 along +x: results/slide-calibration/mocap-reference.md measured 0.48-0.54 m.
    glide = calibration.glide(env, expert, 0, 0.0, 0.6)
    expected = strike.glide_gain**2 * (0.6 - strike.dead_kick) ** 2
    assert glide[0] == pytest.approx(0.498, abs=1e-3) and abs(glide[1]) < 0.01
    assert glide[0] == pytest.approx(expected, rel=0.1)
