"""Why a query failed: the rejection reasons of the sampler and the validity checker.

A failed query (no start grasp, no goal grasp, no GSn path, reduction failed)
is much easier to fix when the user sees what rejected the states the planner
tried: joint limits, collisions (and the pair of links that collided most
often), force closure, or inverse kinematics that found no reachable contact.
"""

from __future__ import annotations

from dataclasses import dataclass

from dexplan.planning.gsn.sampler_stats import SamplerStats
from dexplan.planning.gsn.validity import RejectedSample, ValidityStats


@dataclass(frozen=True)
class Rejections:
    """Counted rejections of one query.

    Attributes:
        attempts: sampler attempts (object pose + contacts + IK).
        ik_failures: attempts where some finger reached none of its candidate contacts.
        checked: states given to the validity checker (by the sampler and by
            the OMPL planner's motion checks).
        valid: of those, valid.
        bounds: rejected: the object outside its workspace box.
        joint_limits: rejected: a joint outside its limits.
        collision: rejected: a collision.
        force_closure: rejected: some (n-1)-finger subgrasp not force closure.
        top_pairs: ``((geometry, geometry), count)`` of the pairs that collided
            most often, most frequent first.
        samples: the first rejected states of each reason (``--debug-rrd``).
        screened: sampled poses whose every combined grasp was screened out
            (half-space test, fingertip clearance) before any check.
        screen_reason: why, when known in advance (faces only on a box).
    """

    attempts: int
    ik_failures: int
    checked: int
    valid: int
    bounds: int
    joint_limits: int
    collision: int
    force_closure: int
    top_pairs: tuple[tuple[tuple[str, str], int], ...]
    samples: tuple[RejectedSample, ...] = ()
    screened: int = 0
    screen_reason: str = ""

    @classmethod
    def from_stats(cls, sampler: SamplerStats, validity: ValidityStats) -> Rejections:
        """Gather the counters of a query's sampler and validity checker."""
        r = validity.rejected
        return cls(
            attempts=sampler.attempts,
            ik_failures=sampler.ik_failures,
            checked=validity.checked,
            valid=validity.valid,
            bounds=r.get("bounds", 0),
            joint_limits=r.get("joint_limits", 0),
            collision=r.get("collision", 0),
            force_closure=r.get("force_closure", 0),
            top_pairs=tuple(validity.top_collision_pairs(3)),
            samples=tuple(validity.samples),
            screened=sampler.screened,
            screen_reason=sampler.screen_reason,
        )

    def dominant(self) -> list[tuple[str, int]]:
        """Rejection reasons with counts, largest first (zero counts left out)."""
        reasons = {
            "inverse kinematics": self.ik_failures,
            "collision": self.collision,
            "force closure": self.force_closure,
            "joint limits": self.joint_limits,
            "workspace bounds": self.bounds,
        }
        return sorted(((k, v) for k, v in reasons.items() if v), key=lambda kv: -kv[1])

    def describe(self) -> str:
        """One line: attempts, valid states and the dominant reasons, largest first."""
        parts = []
        for reason, count in self.dominant():
            text = f"{count} {reason}"
            if reason == "collision" and self.top_pairs:
                (a, b), n = self.top_pairs[0]
                text += f" (most often {a} / {b}: {n})"
            parts.append(text)
        why = ", ".join(parts) if parts else "none"
        if self.checked == 0 and self.screened:
            # nothing reached the checker: say what stopped every grasp before it
            reason = self.screen_reason or (
                "every combination of the fingers' reachable contacts had a required "
                "subgrasp the half-space test rules out, or fingertips too close"
            )
            return (
                f"{self.attempts} sampler attempts: every grasp was screened out before any "
                f"check ({self.screened} object poses): {reason}"
            )
        return (
            f"{self.attempts} sampler attempts, {self.valid} of {self.checked} checked states "
            f"valid; rejections: {why}"
        )
