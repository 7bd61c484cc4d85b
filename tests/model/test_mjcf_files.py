"""MJCF files as untrusted input: entity expansion refused, included and asset files kept
inside the model's folder unless the caller allows otherwise."""

from __future__ import annotations

import os
import time

import pytest
from mjcf_models import FREE_XML, write

from contactdiff.errors import ModelLoadError, UnsafeModelFileError
from contactdiff.model.mjcf import load_mjcf
from contactdiff.model.mjcf_xml import MAX_INCLUDES, looks_like_mjcf
from contactdiff.model.robot_files import load_robot

BILLION_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE mujoco [
 <!ENTITY a "lol">
 <!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">
 <!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">
 <!ENTITY d "&c;&c;&c;&c;&c;&c;&c;&c;&c;&c;">
 <!ENTITY e "&d;&d;&d;&d;&d;&d;&d;&d;&d;&d;">
 <!ENTITY f "&e;&e;&e;&e;&e;&e;&e;&e;&e;&e;">
 <!ENTITY g "&f;&f;&f;&f;&f;&f;&f;&f;&f;&f;">
 <!ENTITY h "&g;&g;&g;&g;&g;&g;&g;&g;&g;&g;">
 <!ENTITY i "&h;&h;&h;&h;&h;&h;&h;&h;&h;&h;">
]>
<mujoco model="&i;"><worldbody/></mujoco>
"""


def test_billion_laughs_is_refused_quickly(tmp_path):
    """10⁹ copies of "lol" (3 GB) if expanded; refused before any expansion. The bound,
    1 s, is ~1000 times the parse of a small file, far below an expansion's minutes."""
    path = write(tmp_path, "laughs.xml", BILLION_LAUGHS)
    start = time.perf_counter()
    with pytest.raises(UnsafeModelFileError, match="laughs.xml.*refused.*(Entit|DTD)"):
        load_robot(path)
    assert time.perf_counter() - start < 1.0


def test_external_entity_is_refused(tmp_path):
    secret = write(tmp_path, "secret.txt", "secret")
    text = (
        f'<?xml version="1.0"?><!DOCTYPE mujoco [<!ENTITY x SYSTEM "file://{secret}">]>'
        '<mujoco model="&x;"><worldbody/></mujoco>'
    )
    with pytest.raises(UnsafeModelFileError):
        load_robot(write(tmp_path, "xxe.xml", text))


def _main_with_include(folder, name: str):
    return write(folder, "main.xml", f'<mujoco model="main"><include file="{name}"/></mujoco>')


def test_include_inside_the_folder_is_read(tmp_path):
    (tmp_path / "parts").mkdir()
    write(tmp_path / "parts", "body.xml", FREE_XML)
    robot = load_robot(_main_with_include(tmp_path, "parts/body.xml"))
    assert robot.floating_base and robot.nv == 6


def test_include_outside_the_folder_is_refused_unless_allowed(tmp_path):
    (tmp_path / "model").mkdir()
    write(tmp_path, "outside.xml", FREE_XML)
    main = _main_with_include(tmp_path / "model", "../outside.xml")
    with pytest.raises(
        UnsafeModelFileError,
        match=r"<include> file '../outside.xml' resolves to .*outside "
        r"the model's folder .*allow_outside=True",
    ):
        load_robot(main)
    assert load_mjcf(main, allow_outside=True).nv == 6


def test_symbolic_link_out_of_the_folder_is_refused(tmp_path):
    (tmp_path / "model").mkdir()
    write(tmp_path, "outside.xml", FREE_XML)
    os.symlink(tmp_path / "outside.xml", tmp_path / "model" / "link.xml")
    with pytest.raises(UnsafeModelFileError, match="outside the model's folder"):
        load_robot(_main_with_include(tmp_path / "model", "link.xml"))


def test_include_cycle_is_refused(tmp_path):
    write(tmp_path, "a.xml", '<mujoco><include file="main.xml"/></mujoco>')
    with pytest.raises(UnsafeModelFileError, match="includes itself"):
        load_robot(_main_with_include(tmp_path, "a.xml"))


def test_include_flood_is_refused(tmp_path):
    includes = "".join(f'<include file="p{k}.xml"/>' for k in range(MAX_INCLUDES + 1))
    for k in range(MAX_INCLUDES + 1):
        write(tmp_path, f"p{k}.xml", "<mujoco/>")
    with pytest.raises(UnsafeModelFileError, match=f"more than {MAX_INCLUDES} files"):
        load_robot(write(tmp_path, "main.xml", f"<mujoco>{includes}</mujoco>"))


@pytest.mark.parametrize("mesh", ["../../elsewhere/part.stl", "/etc/part.stl"])
def test_asset_path_outside_the_folder_is_refused(tmp_path, mesh):
    text = FREE_XML.replace(
        "<worldbody>", f'<compiler meshdir="assets"/><asset><mesh file="{mesh}"/></asset><worldbody>'
    )
    with pytest.raises(UnsafeModelFileError, match="<mesh> file .*outside the model's folder"):
        load_robot(write(tmp_path, "robot.xml", text))


def test_missing_include_is_named(tmp_path):
    with pytest.raises(ModelLoadError, match="missing.xml' does not exist"):
        load_robot(_main_with_include(tmp_path, "missing.xml"))


def test_malformed_xml_is_a_load_error(tmp_path):
    with pytest.raises(ModelLoadError, match="cannot read MJCF"):
        load_robot(write(tmp_path, "bad.xml", "<mujoco><worldbody></mujoco>"))


def test_mjcf_is_recognised_by_extension_and_root(tmp_path):
    assert looks_like_mjcf(write(tmp_path, "a.xml", '<?xml version="1.0"?>\n<!-- c --><mujoco model="a"/>'))
    assert not looks_like_mjcf(write(tmp_path, "b.xml", '<robot name="b"/>'))
    assert looks_like_mjcf(write(tmp_path, "c.mjcf", "<mujoco/>"))
    assert not looks_like_mjcf(write(tmp_path, "d.txt", "<mujoco/>"))


def test_a_file_larger_than_the_cap_is_refused(tmp_path, monkeypatch):
    from contactdiff.model import mjcf_xml

    monkeypatch.setattr(mjcf_xml, "MAX_FILE_BYTES", 100)
    with pytest.raises(UnsafeModelFileError, match=r"has \d+ bytes, more than the 100 read"):
        load_robot(write(tmp_path, "big.xml", FREE_XML))


def test_missing_meshes_load_and_the_replay_draws_spheres_and_says_so(tmp_path):
    """A body with an explicit <inertial> and a mesh geom whose file is absent: the dynamics
    needs no mesh (M = the inertial's mass, 3 kg, on the translations); the replay's geometry
    is one stand-in sphere per body, with a warning counting the missing mesh files."""
    import numpy as np
    import pinocchio as pin

    from contactdiff.model.mjcf import MJCFWarning
    from contactdiff.replay_geometry import drawn_geometry

    text = FREE_XML.replace(
        "<worldbody>", '<compiler meshdir="assets"/><asset><mesh file="hull.stl"/></asset><worldbody>'
    ).replace("<freejoint/>", '<freejoint/><geom type="mesh" mesh="hull"/>')
    robot = load_robot(write(tmp_path, "hull.xml", text))
    M = pin.crba(robot.model, robot.new_data(), robot.q_ref)
    np.testing.assert_allclose(np.diag(M)[:3], 3.0, rtol=1e-14)  # FREE_XML's mass, kg
    with pytest.warns(MJCFWarning, match=r"drawn as spheres at its bodies \(1 of its 1 mesh files are missing\)"):
        geoms = drawn_geometry(robot, 0.01)
    assert geoms.ngeoms >= 1 and all(type(g.geometry).__name__ == "Sphere" for g in geoms.geometryObjects)


def test_the_replay_command_says_once_that_it_draws_spheres(tmp_path):
    """`contactdiff simulate --html` of an MJCF robot without its meshes: one warning that
    the replay draws spheres (the command also looks for the meshes before the run)."""
    import warnings

    pytest.importorskip("meshcat", reason="the replay needs the viz extra")
    from contactdiff.cli import main
    from contactdiff.model.mjcf import MJCFWarning

    text = FREE_XML.replace(
        "<worldbody>", '<compiler meshdir="assets"/><asset><mesh file="hull.stl"/></asset><worldbody>'
    ).replace("<freejoint/>", '<freejoint/><geom type="mesh" mesh="hull"/>')
    model = write(tmp_path, "hull.xml", text)
    scene = tmp_path / "scene.toml"
    scene.write_text(f'robot = "{model.as_posix()}"\n')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert main(["simulate", str(scene), "--t-final", "0.01", "--html", str(tmp_path / "r.html")]) == 0
    drawn = [w for w in caught if issubclass(w.category, MJCFWarning) and "drawn as spheres" in str(w.message)]
    assert len(drawn) == 1


def test_a_scene_file_including_the_robot_is_the_robot(tmp_path):
    """Menagerie's ``scene.xml`` pattern: include the robot, add a <worldbody> with a floor
    and a light. MuJoCo reads the two worldbody sections as one; so does the loader."""
    write(
        tmp_path,
        "free.xml",
        FREE_XML.replace("</mujoco>", '<keyframe><key name="home" qpos="0 0 0.5 1 0 0 0"/></keyframe></mujoco>'),
    )
    scene = write(
        tmp_path,
        "scene.xml",
        '<mujoco model="scene"><include file="free.xml"/><worldbody>'
        '<light pos="0 0 1.5"/><geom name="floor" size="0 0 0.05" type="plane"/></worldbody></mujoco>',
    )
    robot = load_robot(scene)
    assert robot.floating_base and robot.nv == 6
    assert list(robot.q_ref) == [0, 0, 0.5, 0, 0, 0, 1]  # the included file's keyframe home


def test_menagerie_go2_scene_is_go2():
    from helpers import menagerie_file

    robot = load_robot(menagerie_file("unitree_go2/go2.xml"))
    scene = load_robot(menagerie_file("unitree_go2/scene.xml"))
    assert scene.nv == robot.nv and scene.feet == robot.feet
    assert list(scene.q_ref) == list(robot.q_ref)


def test_cli_refuses_an_unsafe_file_on_one_line(tmp_path, capsys):
    from contactdiff.cli import main

    assert main(["check", str(write(tmp_path, "laughs.xml", BILLION_LAUGHS))]) == 2
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "laughs.xml" in err and "refused" in err


def test_left_out_warning_is_one_line(tmp_path):
    """The warning names no Python source line: printed, it is one line."""
    import warnings

    from contactdiff.model.mjcf import MJCFWarning

    text = FREE_XML.replace("</mujoco>", "<tendon><fixed name='t'/></tendon></mujoco>")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_robot(write(tmp_path, "free.xml", text))
    (w,) = [w for w in caught if issubclass(w.category, MJCFWarning)]
    printed = warnings.formatwarning(w.message, w.category, w.filename, w.lineno, w.line)
    assert printed.count("\n") == 1 and "tendon(s) fixed 't'" in printed
