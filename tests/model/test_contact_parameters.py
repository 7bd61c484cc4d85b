"""The contacts' friction parameters and the parameters a group of contacts shares
(`contactdiff.model.contact_parameters`): their names, values, changes and refusals, the
scene file's ``group`` key, the cube's group and the CLI's list. Their derivatives are
tested on whole runs in tests/integration/test_friction_parameters.py."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

import contactdiff as cd
from contactdiff.cli import main
from contactdiff.errors import GroupMismatchError, InvalidInputError, UnknownNameError
from contactdiff.model.objects import SceneObject, add_objects, empty_robot
from contactdiff.model.parameters import parameter_table

CORNERS = [f"cube/{sx}x{sy}y{sz}z" for sx in "+-" for sy in "+-" for sz in "+-"]


def _boxes(frictions, groups):
    """A box (edge 0.2 m, 1 kg) resting on a face at z = 0, a contact at each of four bottom
    corners with the given friction and group."""
    box = SceneObject("box", shape="box", size=(0.2, 0.2, 0.2), mass=1.0, position=(0.0, 0.0, 0.1))
    names = [f"box/{sx}x{sy}y-z" for sx in "+-" for sy in "+-"]
    contacts = [cd.Contact(n, friction=f, group=g) for n, f, g in zip(names, frictions, groups)]
    return cd.Scene(add_objects(empty_robot(), [box]), contacts, gravity=(0.0, 0.0, -9.81)), names


def test_friction_is_a_parameter_of_coulomb_contacts_only():
    """``"none"`` and ``"stick"`` have no coefficient to vary; a number μ > 0 has one. A group of
    two Coulomb contacts has a friction parameter; a group with a ``stick`` member has not."""
    scene, names = _boxes([0.4, "none", "stick", 0.7], ["a", "a", "b", "b"])
    listed = scene.parameter_names()
    friction = [n for n in listed if n.endswith(":friction")]
    assert friction == [f"contact:{names[0]}:friction", f"contact:{names[3]}:friction"]
    assert [n for n in listed if n.startswith("group:")] == [
        "group:a:restitution",
        "group:a:offset",
        "group:b:restitution",
        "group:b:offset",
    ]
    assert scene.parameter_values(friction).tolist() == [0.4, 0.7]
    with pytest.raises(UnknownNameError, match=re.escape(f"contact:{names[0]}:friction")):
        scene.parameter_values([f"contact:{names[1]}:friction"])  # the valid names are listed


def test_the_cube_shares_one_friction_restitution_and_offset():
    """`cd.cube_scene` puts its eight corners in group ``cube``; the group's values are the
    corners' (`CubeParameters` defaults: μ 0.18, e 0.125, ground 0); setting the group sets
    every corner, and the original scene is unchanged."""
    scene = cd.cube_scene()
    assert [c.group for c in scene.contact_specs] == ["cube"] * 8
    group = ["group:cube:friction", "group:cube:restitution", "group:cube:offset"]
    assert set(group) <= set(scene.parameter_names())
    assert scene.parameter_values(group).tolist() == [0.18, 0.125, 0.0]
    moved = scene.with_parameters(
        {"group:cube:friction": 0.3, "group:cube:restitution": 0.5, "group:cube:offset": -0.01}
    )
    assert [(c.friction, c.restitution, c.offset) for c in moved.contact_specs] == [(0.3, 0.5, -0.01)] * 8
    assert moved.parameter_values(group).tolist() == [0.3, 0.5, -0.01]
    assert scene.parameter_values(group).tolist() == [0.18, 0.125, 0.0]


def test_a_group_whose_members_differ_has_no_value_until_set():
    """Reading it names each member's value; the table shows None; setting it gives them all one."""
    scene = cd.cube_scene().with_parameters({f"contact:{CORNERS[0]}:friction": 0.5})
    with pytest.raises(GroupMismatchError, match=re.escape(f"{CORNERS[0]} = 0.5, {CORNERS[1]} = 0.18")):
        scene.parameter_values(["group:cube:friction"])
    rows = {row["name"]: row for row in parameter_table(scene)}
    assert rows["group:cube:friction"]["value"] is None and rows["group:cube:restitution"]["value"] == 0.125
    same = scene.with_parameters({"group:cube:friction": 0.25})
    assert same.parameter_values(["group:cube:friction"]).tolist() == [0.25]


def test_bad_friction_values_and_conflicting_changes_are_refused():
    """μ < 0 and a non-finite μ are refused naming the parameter; μ = 0 makes the contact
    frictionless (no friction parameter left); a contact's own and its group's value must agree
    when both are given."""
    scene = cd.cube_scene()
    for bad in (-0.1, float("inf"), float("nan")):
        with pytest.raises(InvalidInputError, match="group:cube:friction"):
            scene.with_parameters({"group:cube:friction": bad})
    frictionless = scene.with_parameters({f"contact:{CORNERS[0]}:friction": 0.0})
    assert frictionless.contact_specs[0].friction == "none"
    names = frictionless.parameter_names()
    assert f"contact:{CORNERS[0]}:friction" not in names and "group:cube:friction" not in names
    assert "group:cube:restitution" in names
    with pytest.raises(InvalidInputError, match="different values"):
        scene.with_parameters({"group:cube:friction": 0.3, f"contact:{CORNERS[2]}:friction": 0.4})
    agreed = scene.with_parameters({"group:cube:friction": 0.3, f"contact:{CORNERS[2]}:friction": 0.3})
    assert agreed.parameter_values(["group:cube:friction"]).tolist() == [0.3]
    with pytest.raises(InvalidInputError, match=r"restitution must be in \[0, 1\]"):
        scene.with_parameters({"group:cube:restitution": 1.5})


ROBOTS = Path(__file__).resolve().parents[2] / "robots"


def _ball_file(tmp_path, contacts: str) -> str:
    """A scene file on the repository's ball (one prismatic joint z, robots/ball.urdf)."""
    path = tmp_path / "ball_scene.toml"
    path.write_text(f'robot = "{ROBOTS / "ball.urdf"}"\n{contacts}[initial]\nq = {{ z = 1.0 }}\n')
    return str(path)


def test_scene_file_group_key(tmp_path):
    """``group = "feet"`` in a ``[[contact]]`` entry (a floor and a ceiling on the ball's frame); a
    group name with ':' is refused."""

    def write(group):
        return _ball_file(
            tmp_path,
            f'[[contact]]\nframe = "ball"\nname = "low"\nfriction = 0.5\ngroup = {group}\n'
            f'[[contact]]\nframe = "ball"\nname = "high"\nnormal = [0.0, 0.0, -1.0]\n'
            f"offset = -2.0\nfriction = 0.5\ngroup = {group}\n",
        )

    scene = cd.load_scene(write('"feet"'))
    assert [c.group for c in scene.contact_specs] == ["feet", "feet"]
    assert scene.parameter_values(["group:feet:friction"]).tolist() == [0.5]
    with pytest.raises(GroupMismatchError, match="low = 0.0, high = -2.0"):
        scene.parameter_values(["group:feet:offset"])
    with pytest.raises(InvalidInputError, match="group must be a non-empty name"):
        cd.load_scene(write('"a:b"'))


def test_cli_lists_the_friction_and_group_parameters(tmp_path, capsys):
    """``contactdiff simulate SCENE --param list`` prints every name, the new ones included, and
    ``--json`` their values."""
    path = _ball_file(tmp_path, '[[contact]]\nframe = "ball"\nfriction = 0.4\ngroup = "g"\n')
    assert main(["simulate", path, "--t-final", "0.1", "--param", "list"]) == 0
    names = capsys.readouterr().out.split()
    assert {"contact:ball:friction", "group:g:friction", "group:g:restitution", "group:g:offset"} <= set(names)
    assert main(["simulate", path, "--t-final", "0.1", "--param", "list", "--json"]) == 0
    rows = {row["name"]: row for row in json.loads(capsys.readouterr().out)}
    assert rows["group:g:friction"] == {
        "name": "group:g:friction",
        "kind": "group",
        "target": "g",
        "field": "friction",
        "value": 0.4,
    }


def test_cli_differentiates_a_group_whose_members_differ(tmp_path, capsys):
    """The run's parameter table shows ``(differ)`` for the value of a group whose contacts
    differ (a floor at 0 and a ceiling at -2 m along -z: offsets 0 and -2), and the column."""
    path = _ball_file(
        tmp_path,
        '[[contact]]\nframe = "ball"\nname = "low"\ngroup = "g"\n'
        '[[contact]]\nframe = "ball"\nname = "high"\nnormal = [0.0, 0.0, -1.0]\n'
        'offset = -2.0\ngroup = "g"\n',
    )
    assert main(["simulate", path, "--t-final", "0.1", "--param", "group:g:offset"]) == 0
    line = [row for row in capsys.readouterr().out.splitlines() if row.strip().startswith("group:g:offset")]
    assert len(line) == 1 and "(differ)" in line[0]
