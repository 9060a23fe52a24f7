"""The props' observables: the orientation as Euler angles."""

from __future__ import annotations

import numpy as np
from dm_control.utils.transformations import quat_mul

from franka_composer.entities.props import quat_to_euler


def test_quat_to_euler_matches_the_numpy_formula_to_a_few_ulp():
    """Two implementations of one formula (scalar `math` against vectorised NumPy): NumPy's
    vectorised arctan2 takes a different SIMD path on AVX-512 CPUs and may differ in the
    last bit, so equality is to a few units in the last place, not bit for bit."""
    rng = np.random.default_rng(0)
    quats = rng.normal(size=(2000, 4))
    quats[::3] = [1, 0, 0, 0] + 1e-4 * quats[::3]  # Near identity: small angles.
    quats /= np.linalg.norm(quats, axis=1, keepdims=True)
    w, x, y, z = quats.T
    expected = np.stack([np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y)),
                         np.arcsin(np.clip(2 * (w * y - z * x), -1, 1)),
                         np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))], axis=1)
    actual = np.array([quat_to_euler(q) for q in quats])
    np.testing.assert_array_max_ulp(actual, expected, maxulp=4)


def test_quat_to_euler_reads_extrinsic_xyz_angles_not_gymnasium_robotics_intrinsic_ones():
    """Roll about x, then pitch about y, then yaw about z, all world axes: the stated
    convention (docs/guide/physics.md). A block yawed 45 degrees and then tipped 10 about its
    own x axis reads (10, 0, 45) degrees; Gymnasium-Robotics' `quat2euler` (the reference
    code's, x-y-z intrinsic) reads (7.1, 7.1, 44.6)."""
    def about(axis, degrees):
        half = np.radians(degrees) / 2
        return np.concatenate([[np.cos(half)], np.sin(half) * np.eye(3)[axis]])

    rng = np.random.default_rng(1)
    for roll, pitch, yaw in rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], (50, 3)):
        quat = quat_mul(about(2, np.degrees(yaw)),
                        quat_mul(about(1, np.degrees(pitch)), about(0, np.degrees(roll))))
        np.testing.assert_allclose(quat_to_euler(quat), [roll, pitch, yaw], atol=1e-12)
    tipped = quat_mul(about(2, 45.0), about(0, 10.0))
    np.testing.assert_allclose(np.degrees(quat_to_euler(tipped)), [10.0, 0.0, 45.0],
                               atol=1e-12)
