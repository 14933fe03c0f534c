"""The replay's grip forces: squeeze each hold as hard as it allows, never at its cost.

The fingers of a replay are position servos (gain ``KP``): a grip force is a
target offset of force / stiffness. The exporter's least forces (0.2 N, what
balances the weight with the least squeeze) are offsets of a fraction of a
millimetre, less than the object's tracking error, and a finger on the side
the object has moved away from lets go (box_roll90's rolling seed 1 dropped
the box that way). So the replay presses every loaded contact harder, with at
least one of :data:`SQUEEZE_LEVELS` newtons, but a squeeze is only worth what
it leaves of the hold's other margins. The least-norm solve with a larger
least normal force can keep a smaller cone margin (the solver trades margin
for balance) or bring a joint near its effort limit, and then the hold slips
or saturates (an Allegro three-finger hold squeezed to 2 N kept no cone
margin and 98 % of a torque limit; at 1 N it kept 10 % of ``mu`` and 93 %).
:class:`SqueezeSolver` takes, per configuration, the largest level whose
forces keep the plan's own forces' cone margin and stay within
:data:`TORQUE_HEADROOM` of every effort limit (or no closer than the plan's
own forces already are); else the plan's own forces.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from dexplan.core.typing import FloatArray
from dexplan.execution.forces import solver_from_plan
from dexplan.model.grasp.grip_forces import (
    ForceSettings,
    GripForceError,
    GripForces,
    GripForceSolver,
)
from dexplan.model.grasp.grip_program import joint_effort_limits
from dexplan.model.hand.hand import Hand

__all__ = ["SQUEEZE_LEVELS", "TORQUE_HEADROOM", "SqueezeSolver"]

#: Least normal forces (N) the replay tries on every loaded contact, hardest first.
#: 2 N is a 1-3 mm target offset on the paper hand's fingertips (650-2300 N/m).
SQUEEZE_LEVELS = (2.0, 1.0, 0.5)
#: A squeeze may bring no joint torque above this fraction of its effort limit:
#: the servo's tracking corrections and the links' gravity compensation share
#: the same limit.
TORQUE_HEADROOM = 0.8


class SqueezeSolver:
    """Grip forces for the replay: the plan's solver, squeezing where the hold allows it.

    The interface of :class:`~dexplan.model.grasp.grip_forces.GripForceSolver`
    that the replay uses (``solve``, ``obj``, ``settings``).

    Args:
        doc: a validated plan.
        settings: the replay's force settings (its own least normal force is
            the plan's: the fallback).
        hand: the plan's hand.
        base_dir: the plan's folder (mesh paths).
    """

    def __init__(
        self,
        doc: Mapping[str, Any],
        settings: ForceSettings,
        hand: Hand,
        base_dir: str | Path = ".",
    ) -> None:
        self.plain: GripForceSolver = solver_from_plan(doc, settings, hand, base_dir)
        self.obj, self.settings = self.plain.obj, settings
        levels = [x for x in SQUEEZE_LEVELS if x > settings.min_normal_force]
        self.squeezed = [
            solver_from_plan(doc, replace(settings, min_normal_force=x), hand, base_dir)
            for x in levels
        ]
        self.effort = joint_effort_limits(hand.model)

    def _ratio(self, g: GripForces) -> float:
        """The largest ``|torque| / effort limit`` of the forces (0 without limits)."""
        r = np.abs(np.asarray(g.joint_torques)) / self.effort
        return float(np.nanmax(r, initial=0.0))

    def solve(
        self,
        q: FloatArray,
        object_pose: FloatArray,
        contacts: Sequence[FloatArray | None],
        loaded: Sequence[bool] | None = None,
    ) -> GripForces:
        """The squeezing grip forces at one configuration (as ``GripForceSolver.solve``).

        Raises:
            GripForceError: not even the plan's own forces balance there.
        """
        full = self.settings.cone_margin
        base: GripForces | None = None  # the plan's own forces, solved only when needed
        for solver in self.squeezed:
            try:
                g = solver.solve(q, object_pose, contacts, loaded)
            except GripForceError:
                continue
            ratio = self._ratio(g)
            # the full margin within the headroom passes whatever the plan's forces are
            # (their margin is at most the full one): no need to solve them
            if g.margin >= full - 1e-12 and ratio <= TORQUE_HEADROOM + 1e-12:
                return g
            if base is None:
                base = self.plain.solve(q, object_pose, contacts, loaded)
            cap = max(TORQUE_HEADROOM, self._ratio(base))
            if g.margin >= base.margin - 1e-12 and ratio <= cap + 1e-12:
                return g
        return self.plain.solve(q, object_pose, contacts, loaded) if base is None else base
