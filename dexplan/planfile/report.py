"""What ``dexplan verify`` finds: the broken rules of a plan and its hold figures."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["VerifyReport", "Violation"]


@dataclass(frozen=True)
class Violation:
    """One broken rule: where (segment, waypoint; -1 for the whole plan) and what."""

    segment: int
    waypoint: int
    rule: str
    message: str

    def __str__(self) -> str:
        where = "plan" if self.segment < 0 else f"segment {self.segment}"
        if self.waypoint >= 0:
            where += f", waypoint {self.waypoint}"
        return f"{where}: {self.rule}: {self.message}"


@dataclass(frozen=True)
class VerifyReport:
    """Result of :func:`~dexplan.planfile.verify.verify_plan`.

    Attributes:
        violations: every broken rule.
        waypoints: waypoints checked.
        segments: segments checked.
        weakest_hold: the least force-closure quality of a hold of the plan
            (transfer waypoints: the weakest (n-1)-finger subgrasp; regrasps:
            the n-1 holding fingers), per unit contact force; None without holds.
        worst_torque_ratio: the largest torque ratio of a hold
            (:mod:`dexplan.model.grasp.holds`: the share of the effort limits
            the joints need, each contact moved the plan's ``hold_shift``);
            ``inf`` where a hold cannot balance the weight; None without holds.
    """

    violations: tuple[Violation, ...]
    waypoints: int
    segments: int
    weakest_hold: float | None = None
    worst_torque_ratio: float | None = None

    @property
    def ok(self) -> bool:
        """True when no rule is broken."""
        return not self.violations
