"""Coupled joints of an MJCF hand: one degree of freedom, a narrowed range, or refused.

MuJoCo hands couple joints with limited fixed tendons (the Shadow hand's
distal and middle joints: ``-0.001 <= 0.00705 q_J0 - 0.00805 q_J1 <= 0.001``)
and joint equality constraints. dexplan plans independent joints within
box limits, so each coupling, taken in file order after the locked joints'
values are substituted, becomes one of:

- **one degree of freedom** (a URDF ``<mimic>`` joint, which Pinocchio
  models exactly): a joint equality ``q_a = c0 + c1 q_b`` over two free
  joints; or a fixed tendon over two free joints of which one is *passive*
  (no actuator drives it) and whose slack leaves that joint at most
  :data:`MAX_SLACK` rad of play: the passive joint follows the other at the
  middle of the slack;
- **a narrower range**: a tendon left with one free joint (every other one
  locked or following it) bounds that joint;
- **a check**: a tendon with no free joint left must hold at the locked values;
- **refused**, with a message naming the coupling: anything else (a tendon
  over two driven joints, three or more free joints, a nonlinear equality).
  Locking one of its joints (``[hand] locked_joints``) resolves it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from dexplan.core.errors import ModelError
from dexplan.model.hand.mjcf_xml import Coupling

__all__ = ["MAX_SLACK", "Mimic", "ResolvedJoints", "resolve_couplings"]

#: Largest play (rad) of a passive joint a tendon coupling may leave for it to
#: be modelled as following the other joint (the Shadow hand's: 0.28 rad).
MAX_SLACK = 0.35


@dataclass(frozen=True)
class Mimic:
    """``q[joint] = multiplier * q[primary] + offset`` (a URDF ``<mimic>``)."""

    primary: str
    multiplier: float
    offset: float
    source: str


@dataclass
class ResolvedJoints:
    """Locked joints, joints following another, and every joint's range.

    Attributes:
        locked: joint name -> value.
        mimic: joint name -> the joint it follows.
        ranges: joint name -> (lower, upper), narrowed by the couplings.
    """

    locked: dict[str, float]
    ranges: dict[str, tuple[float, float]]
    mimic: dict[str, Mimic] = field(default_factory=dict)

    def affine(self, joint: str) -> tuple[str | None, float, float]:
        """``joint`` as ``mult * q[free] + off``: (free joint or None, mult, off)."""
        if joint in self.locked:
            return None, 0.0, self.locked[joint]
        m = self.mimic.get(joint)
        if m is not None:
            return m.primary, m.multiplier, m.offset
        return joint, 1.0, 0.0

    def narrow(self, joint: str, lo: float, hi: float, why: str, name: str) -> None:
        """Intersect ``joint``'s range with ``[lo, hi]``."""
        old = self.ranges[joint]
        new = (max(old[0], lo), min(old[1], hi))
        if new[0] > new[1]:
            raise ModelError(f"hand {name!r}: joint {joint!r} has no value left within {why}")
        self.ranges[joint] = new


def resolve_couplings(
    cups: Sequence[Coupling],
    locked: Mapping[str, float],
    ranges: Mapping[str, tuple[float, float]],
    actuated: set[str],
    name: str,
) -> ResolvedJoints:
    """Apply the module's rules to ``cups`` in order.

    Args:
        cups: the MJCF's couplings (:func:`~dexplan.model.hand.mjcf_xml.couplings`).
        locked: locked joint values by name.
        ranges: every joint's range by name.
        actuated: the joints an actuator drives.
        name: the hand's name, for messages.

    Raises:
        ModelError: a coupling the rules refuse, or locked values it forbids.
    """
    out = ResolvedJoints(dict(locked), dict(ranges))
    for cup in cups:
        if cup.kind == "equality":
            _equality(cup, out, name)
        else:
            _tendon(cup, out, actuated, name)
    for joint, m in out.mimic.items():  # the follower stays within its own range
        lo, hi = ranges[joint]
        a, b = sorted(((lo - m.offset) / m.multiplier, (hi - m.offset) / m.multiplier))
        out.narrow(m.primary, a, b, f"the range of {joint!r}, which follows it", name)
    return out


def _equality(cup: Coupling, out: ResolvedJoints, name: str) -> None:
    a, poly = cup.joints[0], cup.coefs
    b = cup.joints[1] if len(cup.joints) > 1 else None
    linear = not any(poly[2:])
    if b is None or b in out.locked:
        q_b = 0.0 if b is None else out.locked[b]
        value = sum(c * q_b**k for k, c in enumerate(poly))
        if a in out.locked and abs(out.locked[a] - value) > 1e-6:
            raise ModelError(f"hand {name!r}: the locked joint values break MJCF {cup.describe()}")
        out.locked[a] = value
    elif a in out.locked and linear and poly[1] != 0.0:
        out.locked[b] = (out.locked[a] - poly[0]) / poly[1]
    elif linear and poly[1] != 0.0 and a not in out.mimic:
        primary, mult, off = out.affine(b)
        assert primary is not None
        out.mimic[a] = Mimic(primary, poly[1] * mult, poly[0] + poly[1] * off, cup.describe())
    else:
        _refuse(cup, name)


def _tendon(cup: Coupling, out: ResolvedJoints, actuated: set[str], name: str) -> None:
    coef: dict[str, float] = {}
    rest = 0.0
    for joint, c in zip(cup.joints, cup.coefs, strict=True):
        free, mult, off = out.affine(joint)
        rest += c * off
        if free is not None:
            coef[free] = coef.get(free, 0.0) + c * mult
    coef = {j: c for j, c in coef.items() if abs(c) > 1e-12}
    lo, hi = cup.bounds[0] - rest, cup.bounds[1] - rest
    if not coef:
        if not lo - 1e-9 <= 0.0 <= hi + 1e-9:
            raise ModelError(f"hand {name!r}: the locked joint values break MJCF {cup.describe()}")
        return
    if len(coef) == 1:
        ((joint, c),) = coef.items()
        a, b = sorted((lo / c, hi / c))
        out.narrow(joint, a, b, f"MJCF {cup.describe()}", name)
        return
    passive = [j for j in coef if j not in actuated]
    if len(coef) == 2 and len(passive) == 1:
        follower = passive[0]
        primary = next(j for j in coef if j != follower)
        c_f, c_p = coef[follower], coef[primary]
        if (hi - lo) / abs(c_f) <= MAX_SLACK:
            mid = 0.5 * (lo + hi)
            out.mimic[follower] = Mimic(primary, -c_p / c_f, mid / c_f, cup.describe())
            return
    _refuse(cup, name)


def _refuse(cup: Coupling, name: str) -> None:
    example = f'[hand] locked_joints = {{"{cup.joints[0]}" = 0.0}}'
    raise ModelError(
        f"hand {name!r}: MJCF {cup.describe()} couples joints dexplan cannot plan as one "
        f"degree of freedom; lock one of them, e.g. {example}"
    )
