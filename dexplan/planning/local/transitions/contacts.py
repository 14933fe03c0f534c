"""The contacts a grasp holds, and where they put the fingertips."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dexplan.core.pose import quat_to_matrix
from dexplan.core.typing import FloatArray


@dataclass(frozen=True)
class GraspContacts:
    """Contacts of all n fingers, object frame.

    Attributes:
        points: (n, 3) contact points on the object surface.
        normals_out: (n, 3) outward unit surface normals there.
    """

    points: FloatArray
    normals_out: FloatArray

    def replace(self, finger: int, point: FloatArray, normal_out: FloatArray) -> GraspContacts:
        """Copy with finger ``finger`` moved to a new contact."""
        p, n = self.points.copy(), self.normals_out.copy()
        p[finger], n[finger] = point, normal_out
        return GraspContacts(p, n)

    def as_tuple(self) -> tuple[FloatArray, ...]:
        """Contacts as a per-finger tuple (for waypoints)."""
        return tuple(self.points[i].copy() for i in range(len(self.points)))

    def tip_centres(self, pose: FloatArray, radius: float) -> FloatArray:
        """World fingertip centres ``(n, 3)`` at object pose ``pose: (7,)`` (XYZW).

        Each centre is ``radius`` out from its contact along the outward normal.
        """
        R = quat_to_matrix(pose[3:7] / np.linalg.norm(pose[3:7]))
        return (self.points + radius * self.normals_out) @ R.T + pose[:3]
