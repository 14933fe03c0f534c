import numpy as np
import pytest

from dexplan.core.errors import InvalidInputError
from dexplan.core.pose import random_quaternion
from dexplan.model.hand.hand import Hand
from dexplan.model.objects import Box, Sphere
from dexplan.planning.gsn.space import GraspSubspace


def _gsn(hand: Hand, obj, mask=None) -> GraspSubspace:
    return GraspSubspace(
        hand,
        obj,
        mask,
        workspace_center=np.array([0.0, 0.0, 0.1]),
        workspace_half_extent=np.full(3, 0.02),
    )


def _fd_jacobian(f, x, eps=1e-7):
    f0 = f(x)
    J = np.empty((len(f0), len(x)))
    for j in range(len(x)):
        xp, xm = x.copy(), x.copy()
        xp[j] += eps
        xm[j] -= eps
        J[:, j] = (f(xp) - f(xm)) / (2 * eps)
    return J


@pytest.mark.parametrize("obj", [Sphere(0.04), Box([0.06, 0.05, 0.07])], ids=["sphere", "box"])
def test_jacobian_matches_finite_differences(paper_hand: Hand, obj) -> None:
    rng = np.random.default_rng(0)
    gsn = _gsn(paper_hand, obj, [True, True, False, True])
    for _ in range(15):
        quat = random_quaternion(rng) * rng.uniform(0.9, 1.1)  # off the unit sphere too
        pose = np.concatenate([np.array([0, 0, 0.1]) + rng.uniform(-0.02, 0.02, 3), quat])
        q = rng.uniform(paper_hand.lower, paper_hand.upper)
        x = gsn.join(pose, q)
        J = gsn.jacobian(x)
        assert J.shape == (4, 19)
        np.testing.assert_allclose(J, _fd_jacobian(gsn.function, x), atol=2e-6, rtol=1e-5)
        # free finger 2's joints do not enter the constraint
        assert np.all(J[:, 7 + 6 : 7 + 9] == 0)


def test_constraint_zero_on_exact_grasp(paper_hand: Hand) -> None:
    obj = Sphere(0.04)
    gsn = _gsn(paper_hand, obj)
    pose = np.array([0.0, 0.0, 0.1, 0, 0, 0, 1.0])
    q = paper_hand.neutral.copy()
    for i in range(4):
        az = np.deg2rad(45 + 90 * i)
        t = pose[:3] + 0.052 * np.array([np.cos(az), np.sin(az), -0.2])
        t = pose[:3] + 0.052 * (t - pose[:3]) / np.linalg.norm(t - pose[:3])
        res = paper_hand.finger_ik(i, t, q)
        assert res.success
        q[paper_hand.finger_q_index[i]] = res.q_finger
    x = gsn.join(pose, q)
    assert gsn.residual(x) < 1e-9
    p, n = gsn.contacts(x)
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), 0.04, atol=1e-9)
    np.testing.assert_allclose(n, -p / 0.04, atol=1e-9)  # inward normals


def test_bad_inputs(paper_hand: Hand) -> None:
    with pytest.raises(InvalidInputError, match="contact_fingers"):
        _gsn(paper_hand, Sphere(0.04), [True, False])
    gsn = _gsn(paper_hand, Sphere(0.04))
    with pytest.raises(InvalidInputError, match="state"):
        gsn.check_state(np.zeros(5))
