"""Counters of the GSn sampler (:class:`~dexplan.planning.gsn.sampler.GraspSampler`)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["SamplerStats"]


@dataclass
class SamplerStats:
    """Counters of the sampler: attempts, valid samples, IK failures, time.

    With per-finger pools an attempt is one combined grasp (or one pose whose
    pools came out empty); ``pools`` counts the poses pools were built at and
    ``finger_rejections`` the per-finger IK solutions dropped for a collision.
    """

    attempts: int = 0
    valid: int = 0
    ik_failures: int = 0
    time_s: float = 0.0
    pools: int = 0
    finger_rejections: int = 0
    #: poses whose every combined grasp was screened out before any check, and why
    screened: int = 0
    screen_reason: str = ""

    @property
    def valid_fraction(self) -> float:
        """Fraction of attempts that gave a valid state."""
        return self.valid / self.attempts if self.attempts else 0.0

    @property
    def samples_per_second(self) -> float:
        """Valid samples per second of sampling time."""
        return self.valid / self.time_s if self.time_s > 0 else 0.0

    def as_dict(self) -> dict[str, float]:
        """Plain-dict view for statistics output."""
        return {
            "attempts": self.attempts,
            "valid": self.valid,
            "ik_failures": self.ik_failures,
            "pools": self.pools,
            "finger_rejections": self.finger_rejections,
            "screened": self.screened,
            "valid_fraction": self.valid_fraction,
            "samples_per_second": self.samples_per_second,
        }
