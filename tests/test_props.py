"""The props' observables: the orientation as Euler angles."""

from __future__ import annotations

import numpy as np

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
