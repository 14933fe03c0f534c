"""The batched subgrasp quality (dexplan.model.grasp.batch) against the scalar one, per grasp.

The scalar method is tested against independent references in test_grasp.py;
here every batch value must be the scalar value (same decision at the margin,
same number up to rounding), on grasps chosen to reach every stage: screen
rejections, decisions by the first bounds, by the refined bounds, and grasps
only the pair solver decides.
"""

import numpy as np
import pytest

from dexplan.core.errors import InvalidInputError
from dexplan.model.grasp import (
    ForceClosure,
    exact_force_closure,
    exact_force_closure_batch,
    min_subgrasp_quality,
    min_subgrasp_quality_batch,
)

TETRA = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=float) / np.sqrt(3)


def _grasps(rng: np.random.Generator, b: int, k: int, noise: float) -> tuple:
    """B grasps of k contacts on a 4 cm sphere: spread directions plus noise, inward normals.

    Grasp i's noise is ``noise * i / B``: from nearly the spread grasp to far from it.
    """
    base = np.vstack([TETRA, -TETRA])[:k]
    scale = noise * np.arange(b)[:, None, None] / b
    d = base[None] + scale * rng.normal(size=(b, k, 3))
    d /= np.linalg.norm(d, axis=2, keepdims=True)
    return 0.04 * d, -d


@pytest.mark.parametrize(
    ("k", "model", "torsion", "mu"),
    [
        (4, "point", 0.0, 0.8),
        (5, "point", 0.0, 0.5),
        (3, "soft", 0.01, 0.8),
        (4, "soft", 0.005, 0.4),
    ],
)
@pytest.mark.parametrize("solve", [False, True])
def test_batch_equals_scalar_grasp_by_grasp(k, model, torsion, mu, solve) -> None:
    rng = np.random.default_rng(k + 10 * int(solve))
    fc = ForceClosure()
    ref = ForceClosure()
    p, n = _grasps(rng, 300, k, noise=1.5)
    # margins at the middle of the quality distribution: many grasps are close to it
    scalar0 = np.array(
        [
            ref.min_subgrasp_quality(
                p[b], n[b], mu, torque_scale=0.04, contact_model=model, torsion=torsion
            )
            for b in range(len(p))
        ]
    )
    positive = scalar0[scalar0 > 0]
    assert len(positive) >= 15 and (scalar0 == 0).sum() >= 10  # both kinds present
    for margin in (0.0, float(np.median(positive)), float(np.quantile(positive, 0.9))):
        kw = dict(
            torque_scale=0.04, margin=margin, solve=solve, contact_model=model, torsion=torsion
        )
        batch = min_subgrasp_quality_batch(p, n, mu, solver=fc, **kw)
        scalar = np.array([ref.min_subgrasp_quality(p[b], n[b], mu, **kw) for b in range(len(p))])
        np.testing.assert_array_equal(batch > margin, scalar > margin)
        # pair solves are OSQP's (tolerance 1e-7, warm-started from the solver's history)
        np.testing.assert_allclose(batch, scalar, rtol=1e-6 if solve else 1e-9, atol=1e-12)


def test_batch_reaches_the_pair_solver_and_counts_evaluations() -> None:
    rng = np.random.default_rng(3)
    p, n = _grasps(rng, 200, 4, noise=1.0)
    scalar = np.array(
        [min_subgrasp_quality(p[b], n[b], 0.8, torque_scale=0.04) for b in range(200)]
    )
    margin = float(np.median(scalar[scalar > 0]))
    fc = ForceClosure()
    out = min_subgrasp_quality_batch(p, n, 0.8, torque_scale=0.04, margin=margin, solver=fc)
    assert fc.stats["evaluations"] == 200
    assert fc.stats["pairs_solved"] > 0  # some grasps needed the exact pair solve
    np.testing.assert_array_equal(out > margin, scalar > margin)


def test_batch_edge_cases() -> None:
    p, n = _grasps(np.random.default_rng(0), 2, 4, noise=0.0)
    empty = min_subgrasp_quality_batch(p[:0], n[:0], 0.8, torque_scale=0.04, margin=0.005)
    assert empty.shape == (0,)
    # 2-contact point subgrasps are never force closure
    three = min_subgrasp_quality_batch(p[:, :3], n[:, :3], 0.8, torque_scale=0.04, margin=0.0)
    np.testing.assert_array_equal(three, [0.0, 0.0])
    with pytest.raises(InvalidInputError, match=r"shape \(B, k, 3\)"):
        min_subgrasp_quality_batch(p[0], n[0], 0.8, torque_scale=0.04, margin=0.005)
    with pytest.raises(InvalidInputError, match="normals"):
        min_subgrasp_quality_batch(p, 0 * n, 0.8, torque_scale=0.04, margin=0.005)
    with pytest.raises(InvalidInputError, match="margin"):
        min_subgrasp_quality_batch(p, n, 0.8, torque_scale=0.04, margin=-1.0)


@pytest.mark.parametrize(
    ("k", "model", "torsion", "mu"),
    [(4, "point", 0.0, 0.8), (5, "point", 0.0, 0.5), (3, "soft", 0.01, 0.8)],
)
@pytest.mark.parametrize("subgrasps", [True, False])
def test_weakest_quality_is_the_least_scalar_quality(k, model, torsion, mu, subgrasps) -> None:
    """One branch and bound over B grasps gives the least of their scalar qualities.

    With the exact (Lawson-Hanson) pair solver every solved pair has one
    value, so the least is the same number, whichever pairs the shared
    bounds spare; a cap already reached is the answer when nothing is below it.
    """
    rng = np.random.default_rng(k + 7 * int(subgrasps))
    p, n = _grasps(rng, 60, k, noise=0.4)
    ref = ForceClosure(solver="nnls")
    one = ref.min_subgrasp_quality if subgrasps else ref.quality
    kw = dict(torque_scale=0.04, contact_model=model, torsion=torsion)
    values = np.array([one(p[b], n[b], mu, **kw) for b in range(len(p))])
    fc = ForceClosure(solver="nnls")
    positive = values > 0
    assert positive.sum() >= 5
    least = float(values[positive].min())
    assert fc.weakest_quality(p[positive], n[positive], mu, subgrasps=subgrasps, **kw) == least
    assert fc.weakest_quality(p, n, mu, subgrasps=subgrasps, **kw) == float(values.min())
    for cap in (0.5 * least, 2.0 * least):
        got = fc.weakest_quality(p[positive], n[positive], mu, subgrasps=subgrasps, cap=cap, **kw)
        assert got == min(cap, least)
    assert fc.weakest_quality(p[:0], n[:0], mu, cap=0.3, **kw) == 0.3
    with pytest.raises(InvalidInputError, match=r"\(B, k, 3\)"):
        fc.weakest_quality(p[0], n[0], mu, **kw)


@pytest.mark.parametrize(
    ("k", "model", "torsion", "mu"),
    [
        (4, "point", 0.0, 0.3),
        (5, "point", 0.0, 0.5),
        (3, "soft", 0.01, 0.5),
        (4, "point", 0.0, 0.0),
    ],
)
@pytest.mark.parametrize("subgrasps", [True, False])
def test_batched_exact_verdicts_are_the_scalar_ones(k, model, torsion, mu, subgrasps) -> None:
    """Every grasp's verdict is the scalar exact_force_closure's, on grasps of every verdict."""
    rng = np.random.default_rng(3 * k + int(subgrasps))
    p, n = _grasps(rng, 150, k, noise=1.5)
    kw = dict(torque_scale=0.04, subgrasps=subgrasps, contact_model=model, torsion=torsion)
    scalar = [exact_force_closure(p[b], n[b], mu, **kw) for b in range(len(p))]
    assert exact_force_closure_batch(p, n, mu, **kw) == scalar
    if mu > 0 and not (subgrasps and k == 3):
        assert {"fc_linear", "not_fc"} <= set(scalar)  # both kinds reached
    assert exact_force_closure_batch(p[:0], n[:0], mu, **kw) == []
