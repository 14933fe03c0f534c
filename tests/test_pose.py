"""The pose helpers of dexplan.core.pose against NumPy's own routines."""

import numpy as np

from dexplan.core.pose import interpolate_pose, length, quat_angle, random_quaternion


def test_length_is_numpys_norm_bit_for_bit() -> None:
    """The hot paths' length is ``np.linalg.norm``, to the last bit, for every size."""
    rng = np.random.default_rng(5)
    for k in (1, 3, 4, 7, 30):
        for scale in (1e-9, 1.0, 1e6):
            v = rng.normal(0.0, scale, size=k)
            assert length(v) == float(np.linalg.norm(v))
    assert length(np.zeros(3)) == 0.0


def test_quat_angle_and_interpolation() -> None:
    """Half-way poses are half the angle away, the double cover does not count."""
    rng = np.random.default_rng(6)
    for _ in range(20):
        a, b = random_quaternion(rng), random_quaternion(rng)
        pa = np.concatenate([rng.normal(size=3), a])
        pb = np.concatenate([rng.normal(size=3), b])
        mid = interpolate_pose(pa, pb, 0.5)
        total = quat_angle(a, b)
        assert abs(quat_angle(a, mid[3:]) - 0.5 * total) < 1e-9
        assert abs(quat_angle(a, -b) - total) < 1e-12
        np.testing.assert_allclose(mid[:3], 0.5 * (pa[:3] + pb[:3]), atol=1e-15)
        assert abs(length(mid[3:]) - 1.0) < 1e-15
