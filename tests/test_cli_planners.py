"""Planners from the shell: ``dexplan planners``, ``--param`` on plan and bench, name hints."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from cli_contract import assert_bad_input, run_cli

from dexplan.cli.options import parse_params
from dexplan.core.errors import InvalidInputError
from dexplan.planning.ompl import available_planners

ROOT = Path(__file__).resolve().parent.parent
SCENARIO = str(ROOT / "scenarios" / "paper_sphere.toml")


def test_planners_lists_every_planner_with_family_space_and_parameters(capfd) -> None:
    code, out, _ = run_cli(capfd, "planners")
    assert code == 0
    heads = re.findall(r"^(\w+)  \((roadmap|tree|informed|batch)\)$", out, re.M)
    assert [name for name, _ in heads] == available_planners()
    bodies = re.split(r"^\w+  \(\w+\)$", out, flags=re.M)[1:]
    blocks = dict(zip([n for n, _ in heads], bodies, strict=True))
    assert "searches: GSn\n" in blocks["PRM"]
    assert "searches: the contact chart" in blocks["RRTConnect"]
    assert "why: " in blocks["KPIECE1"]
    # parameters with OMPL's declared default and suggested range
    assert re.search(r"^ +range +0 +0\.:1\.:10000\.", blocks["RRTConnect"], re.M)
    assert re.search(r"^ +num_samples +1000 +10:10:1000000$", blocks["FMT"], re.M)


def test_planners_names_one_and_hints_a_misspelt_one(capfd) -> None:
    code, out, _ = run_cli(capfd, "planners", "KPIECE1")
    assert code == 0 and out.startswith("KPIECE1  (tree)") and "BITstar" not in out
    code, _, err = run_cli(capfd, "planners", "rrtconnect")
    assert_bad_input(code, err, names=["unknown planner 'rrtconnect'", "did you mean 'RRTConnect'"])


def test_param_values_are_read_as_toml_scalars() -> None:
    assert parse_params(["range=0.25", "intermediate_states=true", "num_samples=50"]) == (
        ("range", 0.25),
        ("intermediate_states", True),
        ("num_samples", 50),
    )
    assert parse_params(["range=1", "range=2"]) == (("range", 2),)  # the last one wins
    assert parse_params(["range=abc"]) == (("range", "abc"),)  # OMPL's check says why
    for bad in ("range", "=1", "range="):
        with pytest.raises(InvalidInputError, match="--param must be NAME=VALUE"):
            parse_params([bad])


@pytest.mark.parametrize(
    ("args", "names"),
    [
        (["--param", "rnage=0.3"], ["unknown parameter 'rnage'", "did you mean 'range'"]),
        (["--param", "range=abc"], ["parameter 'range'", "must be a number, got 'abc'"]),
        (["--param", "range=-1"], ["parameter 'range'", "must be finite and >= 0"]),
        (["--param", "range"], ["--param must be NAME=VALUE, got 'range'"]),
        (["--planner", "rrtconnect"], ["did you mean 'RRTConnect'"]),
    ],
)
def test_plan_param_is_checked_before_planning(capfd, tmp_path: Path, args, names) -> None:
    out = tmp_path / "p.json"
    code, _, err = run_cli(capfd, "plan", SCENARIO, "--planner", "RRTConnect", *args, "-o", out)
    assert_bad_input(code, err, names=names, outputs=[out])


def test_bench_param_must_suit_the_baseline_it_adds(capfd, tmp_path: Path) -> None:
    args = ["bench", "paper_sphere", "--planners", "RRTConnect", "--param", "range=0.3"]
    code, _, err = run_cli(capfd, *args, "--seeds", "1", "-o", tmp_path / "o", "--no-plots")
    line = assert_bad_input(code, err, names=["unknown parameter 'range' for planner PRM"])
    assert "PRM is the baseline, added to the sweep: --baseline none leaves it out" in line
