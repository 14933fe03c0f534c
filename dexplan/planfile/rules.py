"""The rules of plan files: their names, what each requires, and the verifier's tolerances.

:data:`RULES` is the table of ``docs/plan_format.md`` (a test checks they
agree); :mod:`dexplan.planfile.verify` records violations only under these
names.
"""

from __future__ import annotations

from dexplan.model.objects.fingertip import TIP_DISTANCE_TOL

__all__ = [
    "CONTACT_DRIFT_TOL",
    "FC_MIN",
    "FC_PASS",
    "GOAL_ANGLE_TOL",
    "GOAL_POSITION_TOL",
    "MAX_STEP_M",
    "MAX_STEP_RAD",
    "NO_SLIP_ABS",
    "NO_SLIP_REL",
    "PENETRATION_TOL",
    "RULES",
    "STILL_TOL",
    "TIP_DISTANCE_TOL",
]

#: Verification tolerances.
PENETRATION_TOL = 1e-3  # (m)
MAX_STEP_M = 0.01  # object translation between waypoints (m)
MAX_STEP_RAD = 0.05  # object rotation and joint change between waypoints (rad)
CONTACT_DRIFT_TOL = 1e-3  # transfer contact drift (m)
STILL_TOL = 1e-9  # "does not move" (m, rad)
FC_MIN = 0.0  # force-closure quality must exceed this
#: Verdicts of :func:`dexplan.model.grasp.exact_force_closure` that pass.
FC_PASS = ("fc_linear", "fc_dense")
GOAL_POSITION_TOL = 0.005  # goal.position_tol when the file has none (m)
GOAL_ANGLE_TOL = 0.05  # goal.angle_tol when the file has none (rad)
#: Rolling without slipping: over a transfer, per finger, the contact's path on
#: the fingertip and on the object have equal lengths within NO_SLIP_REL of the
#: object's plus NO_SLIP_ABS (the planner integrates the rolling in substeps of
#: second order: its paths agree within about 0.1 %; a fixed contact slides
#: 0.2-0.3 mm per degree the object turns, with no path on the object at all).
NO_SLIP_REL = 0.02
NO_SLIP_ABS = 1e-4  # (m)

#: Every rule the verifier checks, by family, name -> what it requires (one
#: line each: the rule table of docs/plan_format.md, checked by a test).
RULES: dict[str, str] = {
    # waypoint geometry
    "object_pose": "unit quaternion (within 1e-6; sizes and finite numbers are structure, above)",
    "joint_limits": "every joint within its URDF limits",
    # fingertip contacts
    "fingertip_distance": (
        "every contact finger's fingertip sphere is within 1 mm of touching the surface"
    ),
    "contact_on_surface": "every stated contact lies within 1 mm of the surface",
    "contact_matches_fingertip": (
        "the stated contact is the surface point closest to the fingertip centre "
        "(within 1 mm): where the sphere touches; force closure uses it with the normal "
        "there (at a box edge or corner, the direction from the edge or corner to the centre)"
    ),
    # collisions and penetration
    "collision": (
        "no link-link (non-adjacent, not excluded), hand-object (except contact "
        "fingertips), hand-obstacle or object-obstacle contact"
    ),
    "penetration": "no contact fingertip sinks more than 1 mm into the object",
    # force closure
    "force_closure": (
        "at least two fingers hold the object and are force closure at every waypoint, "
        "under the plan's `contact_model` (below)"
    ),
    "subgrasp_force_closure": "on transfer waypoints, every (n-1)-finger subgrasp too",
    # holds
    "holds": (
        "at every waypoint the holding contacts (all on a transfer, the n-1 holding fingers "
        "during a regrasp) balance the object's weight within the joints' effort limits, "
        "also with each contact moved `hold_shift` along the surface (torque ratio <= 1)"
    ),
    # segments and steps
    "segments": "the plan has at least one segment",
    "step": (
        "consecutive waypoints differ by at most 1 cm and 0.05 rad (object) "
        "and 0.05 rad (every joint)"
    ),
    # transfer
    "transfer_contacts": "during a transfer the set of contact fingers does not change",
    "transfer_contact_drift": (
        "with `contact_motion` fixed, during a transfer every contact stays put in the "
        "object frame (within 1 mm)"
    ),
    "transfer_no_slip": (
        "with `contact_motion` rolling, along each transfer, per finger, the path the "
        "contact travels on the fingertip (`tip_contacts`) is as long as its path on the "
        "object (`contacts`), within 2 % + 0.1 mm"
    ),
    "tip_contact": (
        "(format /2) every `tip_contacts` entry is its contact seen from the tip link: "
        "within 1 mm of the point the fingertip's pose puts there, and on the tip sphere"
    ),
    # regrasp
    "regrasp_object_still": "during a regrasp the object does not move",
    "regrasp_one_finger": (
        "during a regrasp the joints and contacts of every other finger do not move"
    ),
    "regrasp_interior": "a regrasp has at least one interior waypoint",
    "regrasp_free_finger": "the regrasping finger is free (contact `null`) at interior waypoints",
    "regrasp_clearance": "the free finger is clear of the object at interior waypoints",
    "regrasp_endpoints": "the regrasping finger is in contact at both ends of the regrasp",
    # continuity, start and goal
    "continuity": "each segment starts where the previous one ended",
    "start": "the first waypoint is the start object pose (and `start.q` when given)",
    "goal": "the last object pose is within the goal's `position_tol` and `angle_tol`",
}
