"""Plan files (``dexplan-plan/2``): the document, its schema, its models, its verifier.

:mod:`~dexplan.planfile.document` builds, writes and reads documents,
:mod:`~dexplan.planfile.schema` checks their structure,
:mod:`~dexplan.planfile.models` rebuilds the hand, object and world they describe
and :mod:`~dexplan.planfile.verify` checks every rule a plan must keep.
"""

from dexplan.planfile.document import (
    FORMAT,
    PlannedPath,
    build_plan_document,
    read_plan,
    segments_from_dicts,
    write_plan,
)
from dexplan.planfile.models import (
    PlanModels,
    hand_from_plan,
    hand_table,
    models_from_document,
    shape_of,
)
from dexplan.planfile.schema import validate_plan
from dexplan.planfile.verify import (
    RULES,
    VerifyReport,
    Violation,
    fingertip_contact,
    verify_plan,
)

__all__ = [
    "FORMAT",
    "RULES",
    "PlanModels",
    "PlannedPath",
    "VerifyReport",
    "Violation",
    "build_plan_document",
    "fingertip_contact",
    "hand_from_plan",
    "hand_table",
    "models_from_document",
    "read_plan",
    "segments_from_dicts",
    "shape_of",
    "validate_plan",
    "verify_plan",
    "write_plan",
]
