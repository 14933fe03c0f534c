from pathlib import Path

import numpy as np
import pytest

from dexplan.core.errors import ScenarioError
from dexplan.model.scenario import builtin_scenario_path, default_scenario, load_scenario

GOOD = """
name = "t"
[hand]
builtin = "paper"
[object]
shape = "sphere"
radius = 0.04
[contact]
mu = 0.8
[start]
object_pose_xyzquat = [0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]
[goal]
object_pose_xyzquat = [0.0, 0.0, 0.1, 0.0, 0.0, 1.0, 0.0]
[planner]
name = "RRTConnect"
seed = 3
"""


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "s.toml"
    p.write_text(text)
    return p


def test_default_scenario_is_the_papers() -> None:
    s = default_scenario()
    assert s.name == "paper_sphere"
    assert s.hand.builtin == "paper"
    assert s.object == {"shape": "sphere", "radius": 0.04}
    assert s.planner.name == "PRM"
    np.testing.assert_allclose(s.goal.object_pose_xyzquat, [0, 0, 0.1, 0, 0, 1, 0])
    assert len(s.obstacles) == 1


def test_repo_scenarios_all_load() -> None:
    folder = builtin_scenario_path().parent
    names = sorted(p.stem for p in folder.glob("*.toml"))
    assert "paper_sphere" in names and "cube_obstacle" in names
    for p in folder.glob("*.toml"):
        load_scenario(p)


def test_good_scenario(tmp_path: Path) -> None:
    s = load_scenario(_write(tmp_path, GOOD))
    assert s.planner.name == "RRTConnect" and s.planner.seed == 3
    assert s.mu == 0.8 and s.friction_edges == 8
    assert s.obstacles == ()


@pytest.mark.parametrize(
    ("old", "new", "needle"),
    [
        ("radius = 0.04", "radius = -0.04", "radius"),
        ("radius = 0.04", 'radius = "big"', "radius"),
        ("mu = 0.8", "mu = -1.0", "contact.mu"),
        ("mu = 0.8", "mu = nan", "contact.mu"),
        ("mu = 0.8", "mu = 0.8\nfriction = 2", "contact.friction"),
        ('shape = "sphere"', 'shape = "torus"', "torus"),
        ('builtin = "paper"', 'builtin = "shadow"', "hand.builtin"),
        ("seed = 3", "seed = -2", "planner.seed"),
        ("seed = 3", "seed = 3\ntime_limit = 0", "planner.time_limit"),
        ("[0.0, 0.0, 0.1, 0.0, 0.0, 0.0, 1.0]", "[0.0, 0.0, 0.1]", "start.object_pose_xyzquat"),
        ("[0.0, 0.0, 0.1, 0.0, 0.0, 1.0, 0.0]", "[0.0, 0.0, 0.1, 0.0, 0.0, 3.0, 0.0]", "goal"),
        ('name = "t"', 'name = "t"\nbogus = 1', "bogus"),
    ],
)
def test_bad_fields_name_field_and_value(tmp_path: Path, old: str, new: str, needle: str) -> None:
    assert old in GOOD
    with pytest.raises(ScenarioError, match=needle):
        load_scenario(_write(tmp_path, GOOD.replace(old, new, 1)))


def test_missing_and_malformed_files(tmp_path: Path) -> None:
    with pytest.raises(ScenarioError, match="not found"):
        load_scenario(tmp_path / "nope.toml")
    with pytest.raises(ScenarioError, match="TOML"):
        load_scenario(_write(tmp_path, "name = [unclosed"))
    with pytest.raises(ScenarioError, match="start"):
        load_scenario(_write(tmp_path, GOOD.split("[start]")[0]))
    mesh = GOOD.replace('shape = "sphere"\nradius = 0.04', 'shape = "mesh"\npath = "missing.obj"')
    with pytest.raises(ScenarioError, match=r"missing\.obj"):
        load_scenario(_write(tmp_path, mesh))


def test_one_identity_ignores_cosmetic_fields_and_models_only_the_query(tmp_path):
    from dexplan.model.scenario import builtin_scenario_path, load_scenario, scenario_hash

    text = builtin_scenario_path().read_text()
    base = load_scenario(builtin_scenario_path())
    renamed = tmp_path / "other.toml"
    renamed.write_text(
        text.replace('name = "paper_sphere"', 'name = "renamed"').replace(
            "[[obstacles]]   # the table under the palm", '[[obstacles]]\nname = "table"'
        )
    )
    assert scenario_hash(load_scenario(renamed)) == scenario_hash(base)  # names are cosmetic
    moved_goal = tmp_path / "goal.toml"
    moved_goal.write_text(text.replace("position_tol = 0.005", "position_tol = 0.004"))
    other = load_scenario(moved_goal)
    assert scenario_hash(other) != scenario_hash(base)  # another query ...
    assert scenario_hash(other, models_only=True) == scenario_hash(base, models_only=True)
    softer = tmp_path / "mu.toml"
    softer.write_text(text.replace("mu = 0.8", "mu = 0.7"))
    assert scenario_hash(load_scenario(softer), models_only=True) != scenario_hash(
        base, models_only=True
    )  # ... on the same models; friction is a model
