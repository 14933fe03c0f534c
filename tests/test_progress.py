"""Typed statuses and progress events of a query."""

from __future__ import annotations

import json

from dexplan import bench
from dexplan.api import plan
from dexplan.model.scenario import default_scenario
from dexplan.planning.progress import PlanStatus, ProgressEvent, Stage


def test_status_is_its_string_in_json_and_comparisons():
    assert PlanStatus.SOLVED == "solved"
    assert json.dumps({"s": PlanStatus.NO_GOAL_GRASP}) == '{"s": "no_goal_grasp"}'
    assert set(bench.PLAN_STATUSES) >= {s.value for s in PlanStatus}


def test_bench_stage_names_follow_the_stage_enum():
    assert len(bench.STAGES) == len(Stage)
    assert bench.STAGES[Stage.VERIFICATION] == "verification"


def test_a_solved_query_reports_each_stage_in_order():
    events: list[ProgressEvent] = []
    res = plan(default_scenario(), seed=3, progress=events.append).result  # verified
    assert res.solved and res.status is PlanStatus.SOLVED
    stages = [e.stage for e in events]
    # modules 1 and 2 alternate (rounds, then links); otherwise stages only go forward
    search = [Stage.MODULE1 if st is Stage.MODULE2 else st for st in stages]
    assert search == sorted(search)
    rounds = [e for e in events if e.stage is Stage.MODULE1 and "rounds" in e.counts]
    assert rounds and all(e.counts["nodes"] >= 1 and e.counts["components"] >= 1 for e in rounds)
    assert [e.counts["rounds"] for e in rounds] == list(range(1, len(rounds) + 1))
    assert stages[0] is Stage.START_GRASP and stages[-1] is Stage.VERIFICATION
    assert Stage.MODULE1 in stages and Stage.REDUCTION in stages
    assert all(e.message and e.elapsed_s >= 0 for e in events)
    assert [e.elapsed_s for e in events] == sorted(e.elapsed_s for e in events)


def test_plan_stats_round_trip_and_refuse_unknown_figures():
    import pytest

    from dexplan.core.errors import DexplanError
    from dexplan.planning.stats import PlanStats

    st = PlanStats.from_mapping(
        {"planner": "PRM", "seed": 1, "time_limit": 30.0, "regrasps": 7, "local_landing_checks": 9}
    )
    assert st.regrasps == 7 and st.local == {"landing_checks": 9}
    d = st.as_dict()
    assert d["local_landing_checks"] == 9 and "verify_time_s" not in d  # None left out
    assert PlanStats.from_mapping(d) == st
    with pytest.raises(DexplanError, match="regrasp"):
        PlanStats.from_mapping({"planner": "PRM", "seed": 1, "time_limit": 1.0, "regrasp": 1})
