"""Transfer and regrasp local planners (paper, section IV) and the landing choice of regrasps."""

from dexplan.planning.local.transitions.contacts import GraspContacts
from dexplan.planning.local.transitions.counts import LocalCounts
from dexplan.planning.local.transitions.landings import LandingPool
from dexplan.planning.local.transitions.planners import Transitions
from dexplan.planning.local.transitions.settings import TransitionSettings
from dexplan.planning.local.transitions.transfer import TransferResult, TransferStop, densify_poses

__all__ = [
    "GraspContacts",
    "LandingPool",
    "LocalCounts",
    "TransferResult",
    "TransferStop",
    "TransitionSettings",
    "Transitions",
    "densify_poses",
]
