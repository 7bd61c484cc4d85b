"""The browser replay: one self-contained HTML page per trajectory (contactdiff.replay)."""

from __future__ import annotations

import base64
import json
import re
import sys

import numpy as np
import pytest
from helpers import load_script

from contactdiff.cli import main
from contactdiff.integration.hybrid import simulate
from contactdiff.replay import MissingExtraError
from contactdiff.replay_frames import frame_times, sample_frames
from contactdiff.scenes.scene_file import load_source

FPS = 20.0


@pytest.fixture(scope="module")
def run():
    """planar_trot_soft for 2 s: both feet land at t = 1 (one touchdown), then lift off."""
    scene = load_source("planar_trot_soft")
    return scene, simulate(scene, 2.0, dense=True)


@pytest.fixture(scope="module")
def page(run, tmp_path_factory):
    pytest.importorskip("meshcat")
    scene, traj = run
    path = tmp_path_factory.mktemp("replay") / "trot.html"
    traj.to_html(path, scene, fps=FPS)
    return path, path.read_text()


def _commands(text: str) -> list[dict]:
    """The meshcat commands embedded in the page as data URIs, unpacked."""
    import umsgpack

    blobs = re.findall(r'fetch\("data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"\)', text)
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def _animation(text: str) -> list[dict]:
    (command,) = [c for c in _commands(text) if c["type"] == "set_animation"]
    return command["animations"]


def test_the_run_has_the_events_the_tests_rely_on(run):
    _, traj = run
    assert [e.kind for e in traj.events][:1] == ["touchdown"]
    assert any(e.kind == "lift-off" for e in traj.events)


def test_the_page_needs_no_network(page):
    _, text = page
    # every script is inline and every asset a data: URI
    assert not re.search(r"<script[^>]*\bsrc\s*=", text, re.I)
    assert not re.search(r"<link[^>]*\bhref\s*=", text, re.I)
    assert not re.search(r"""\b(?:src|href)\s*=\s*["']?\s*(?:https?:)?//""", text, re.I)
    assert not re.search(r"""\bimport\s*(?:\(\s*)?["'](?:https?:)?//""", text, re.I)
    assert not re.search(r"""url\(\s*["']?\s*(?:https?:)?//""", text, re.I)
    assert not re.search(r"""fetch\(\s*["'`](?!data:)""", text, re.I)
    fetched = re.findall(r"""fetch\(\s*["'`]([a-z]+):""", text, re.I)
    assert fetched and set(fetched) == {"data"}
    # the embedded commands point nowhere either
    for command in _commands(text):
        assert not re.search(rb"https?://", json.dumps(command, default=repr).encode())


def test_the_page_holds_every_frame(run, page):
    _, traj = run
    _, text = page
    times, is_event = frame_times(traj, FPS)
    assert len(times) == 41 + sum(1 for t in {e.t for e in traj.events} if abs(t * FPS - round(t * FPS)) > 1e-6)
    assert times[0] == traj.t0 and times[-1] == pytest.approx(traj.t)
    assert set(np.round(times[is_event], 12)) == set(np.round([e.t for e in traj.events], 12))
    info = json.loads(re.search(r'id="contactdiff-replay">(.*?)</script>', text, re.S).group(1))
    assert info["frames"] == len(times) and info["fps"] == FPS
    animations = _animation(text)
    assert len(animations) >= 3  # body spheres and two contact markers
    for animation in animations:
        assert animation["clip"]["fps"] == FPS
        for track in animation["clip"]["tracks"]:
            if track["name"] in (".position", ".quaternion", ".visible"):
                keys = [k["time"] for k in track["keys"]]
                assert keys == pytest.approx(list((times - traj.t0) * FPS))


def test_contact_markers_show_only_while_closed(run, page):
    scene, traj = run
    _, text = page
    times, _ = frame_times(traj, FPS)
    tracks = {a["path"].rsplit("/", 1)[-1]: a["clip"]["tracks"] for a in _animation(text) if "/contacts/" in a["path"]}
    assert set(tracks) == {"rear_foot", "front_foot"}
    touchdown = next(e for e in traj.events if e.kind == "touchdown")
    for name, clip in tracks.items():
        (visible,) = [t for t in clip if t["name"] == ".visible"]
        assert visible["type"] == "boolean"
        shown = [k["value"] for k in visible["keys"]]
        for t, value in zip(times, shown):
            mode = next(s.mode for s in reversed(traj.segments) if s.t0 <= t)
            assert value == (name in mode), (name, t)
        # off before the touchdown, on from its exact time on
        assert not any(v for t, v in zip(times, shown) if t < touchdown.t)
        assert shown[list(times).index(touchdown.t)] is True
        # the marker sits at the foot: on the ground (z = 0) while closed
        (position,) = [t for t in clip if t["name"] == ".position"]
        z = np.array([k["value"][2] for k in position["keys"]])
        assert np.all(np.abs(z[np.array(shown)]) < 1e-6)
        assert np.max(z) > 0.1


def test_sampled_states_come_from_the_dense_output(run):
    _, traj = run
    frames = sample_frames(traj, FPS)
    k = len(frames.times) // 3
    assert np.allclose(frames.q[k], traj.at(float(frames.times[k]))[0])


def test_the_events_are_listed_in_the_page(run, page):
    _, traj = run
    _, text = page
    for e in traj.events:
        assert f"{e.t:.6f} s: {e.kind}" in text


def test_a_run_without_dense_output_is_refused(run, tmp_path):
    pytest.importorskip("meshcat")
    from contactdiff.errors import InvalidInputError

    scene, _ = run
    sparse = simulate(scene, 0.5)
    with pytest.raises(InvalidInputError, match=r"dense=True"):
        sparse.to_html(tmp_path / "x.html", scene)
    with pytest.raises(InvalidInputError, match=r"fps must be finite and > 0 \(frames per second\), got -1"):
        frame_times(sparse, -1)


def test_missing_meshcat_gives_the_named_error(run, tmp_path, monkeypatch):
    scene, traj = run
    monkeypatch.setitem(sys.modules, "meshcat", None)  # import meshcat raises ImportError
    with pytest.raises(MissingExtraError, match=r"pip install 'contactdiff\[viz\]'"):
        traj.to_html(tmp_path / "x.html", scene)
    assert not (tmp_path / "x.html").exists()
    status = main(["simulate", "ball", "--t-final", "0.1", "--html", str(tmp_path / "y.html")])
    assert status == 2 and not (tmp_path / "y.html").exists()


def test_cli_html_writes_the_page(tmp_path, capsys):
    pytest.importorskip("meshcat")
    out = tmp_path / "ball.html"
    assert main(["simulate", "ball", "--t-final", "1.6", "--html", str(out), "--fps", "10"]) == 0
    assert f"replay written to {out}" in capsys.readouterr().out
    text = out.read_text()
    assert text.startswith("<!DOCTYPE html>")
    info = json.loads(re.search(r'id="contactdiff-replay">(.*?)</script>', text, re.S).group(1))
    # the ball (g = 1, from z = 1) bounces at t = sqrt(2): 17 grid frames at 10 fps, plus that one
    assert info["scene"] == "ball" and [e["kind"] for e in info["events"]] == ["bounce"]
    assert info["events"][0]["t"] == pytest.approx(2**0.5) and info["frames"] == 18


def test_cli_html_refuses_a_missing_folder(tmp_path, capsys):
    pytest.importorskip("meshcat")
    assert main(["simulate", "ball", "--t-final", "0.1", "--html", str(tmp_path / "no" / "x.html")]) == 2
    assert "does not exist" in capsys.readouterr().err


def _screenshot_script():
    return load_script("replay_screenshot")


@pytest.mark.browser
def test_the_page_loads_in_headless_chromium(run, page):
    sync_api = pytest.importorskip("playwright.sync_api")
    script = _screenshot_script()
    path, _ = page
    _, traj = run
    with sync_api.sync_playwright() as p:
        try:
            browser, tab, blocked = script.open_page(p, 800, 500)
        except script.NoBrowserError as exc:
            pytest.skip(str(exc))
        try:
            facts = script.load_replay(tab, path)
            script.seek(tab, 1.5)
            shown = tab.evaluate("""['rear_foot', 'front_foot'].map(
                n => viewer.scene_tree.find(['meshcat', 'contactdiff', 'contacts', n]).object.visible)""")
        finally:
            browser.close()
    assert facts["errors"] == [] and blocked == []
    assert facts["duration"] == pytest.approx(traj.t - traj.t0)
    mode = next(s.mode for s in reversed(traj.segments) if s.t0 <= 1.5)
    assert shown == [n in mode for n in ("rear_foot", "front_foot")]


def test_objects_are_drawn_as_their_shapes_where_the_run_puts_them(tmp_path):
    """Newton's cradle: three spheres of radius 0.02 m, the last frame at the run's end
    (ball 1 back at -0.04 - u/3 (0.3 - 0.1) = -0.1067 m, module doc of its test)."""
    pytest.importorskip("meshcat")
    scene = load_source("newtons_cradle")
    traj = simulate(scene, 0.3, dense=True)
    path = traj.to_html(tmp_path / "cradle.html", scene, fps=FPS)
    commands = _commands(path.read_text())
    shapes = {
        c["path"].rsplit("/", 1)[-1]: c["object"]["geometries"][0]
        for c in commands
        if c["type"] == "set_object" and "/visuals/" in c["path"]
    }
    assert set(shapes) == {"ball1_sphere", "ball2_sphere", "ball3_sphere"}
    assert all(g["type"] == "SphereGeometry" and g["radius"] == 0.02 for g in shapes.values())
    last = {
        a["path"].rsplit("/", 1)[-1]: a["clip"]["tracks"][0]["keys"][-1]["value"] for a in _animation(path.read_text())
    }
    for k, name in enumerate(("ball1", "ball2", "ball3")):
        start = scene.robot.model.joints[scene.robot.joint_id(name)].idx_q
        assert last[f"{name}_sphere"] == pytest.approx(traj.q[start : start + 3].tolist(), abs=1e-12)
    assert last["ball1_sphere"][0] == pytest.approx(-0.04 - 0.2 / 3, abs=1e-9)


def _surfaces(commands: list[dict]) -> dict[str, tuple[dict, np.ndarray]]:
    """The drawn contact planes: name -> (geometry, 4 x 4 pose)."""
    objects = {
        c["path"].rsplit("/", 1)[-1]: c["object"]["geometries"][0]
        for c in commands
        if c["type"] == "set_object" and "/surfaces/" in c["path"]
    }
    poses = {
        c["path"].rsplit("/", 1)[-1]: np.array(c["matrix"], dtype=float).reshape(4, 4).T
        for c in commands
        if c["type"] == "set_transform" and "/surfaces/" in c["path"]
    }
    return {name: (objects[name], poses[name]) for name in objects}


def _slab_covers(geometry: dict, pose: np.ndarray, points: np.ndarray, top: float) -> None:
    """A box geometry posed by ``pose`` whose top face is the plane z = ``top`` and whose
    footprint holds every point's (x, y); the box is axis-aligned here (upward normal)."""
    width, depth, thickness = geometry["width"], geometry["height"], geometry["depth"]
    assert np.allclose(pose[:3, :3], np.eye(3), atol=1e-12)
    assert pose[2, 3] + thickness / 2 == pytest.approx(top, abs=1e-12)
    centre = pose[:2, 3]
    assert np.all(np.abs(points[:, 0] - centre[0]) <= width / 2)
    assert np.all(np.abs(points[:, 1] - centre[1]) <= depth / 2)


def test_the_floor_is_drawn_under_the_feet(run, page):
    """planar_trot_soft's feet close on the plane z = 0 (offset 0): a slab whose top face is
    z = 0 lies under every place the feet go; meshcat's grid is hidden."""
    scene, traj = run
    _, text = page
    commands = _commands(text)
    surfaces = _surfaces(commands)
    assert set(surfaces) == {"ground"}
    frames = sample_frames(traj, FPS)
    data = scene.robot.model.createData()
    import pinocchio as pin

    feet = []
    for q in frames.q:
        pin.framesForwardKinematics(scene.robot.model, data, q)
        feet += [data.oMf[c.fid].translation.copy() for c in scene.contacts]
    _slab_covers(*surfaces["ground"], np.array(feet), 0.0)
    assert any(
        c["type"] == "set_property" and c["path"] == "/Grid" and c["property"] == "visible" and c["value"] is False
        for c in commands
    )


def test_the_panda_table_is_drawn_under_the_box(tmp_path):
    """panda_lift's table: the plane z = offset (0.4616... m, robots/panda_lift.toml) under the
    box's three supports, and no floor (no contact of the robot's own presses on one)."""
    pytest.importorskip("meshcat")
    scene = load_source("panda_lift")
    traj = simulate(scene, 0.05, dense=True)
    path = traj.to_html(tmp_path / "panda.html", scene, fps=FPS)
    surfaces = _surfaces(_commands(path.read_text()))
    assert set(surfaces) == {"plane1"}
    offset = next(c.offset for c in scene.contacts if c.name == "table1")
    data = scene.robot.model.createData()
    import pinocchio as pin

    pin.framesForwardKinematics(scene.robot.model, data, traj.q0)
    supports = np.array([data.oMf[c.fid].translation for c in scene.contacts if c.name.startswith("table")])
    assert supports[:, 2] == pytest.approx(offset, abs=1e-9)  # the box rests on the table at the start
    _slab_covers(*surfaces["plane1"], supports, offset)


def test_the_timeline_has_a_legend_of_its_colours(run, page):
    from contactdiff.replay import EVENT_COLOURS

    _, traj = run
    _, text = page
    keys = dict(re.findall(r'<span class="key" data-kind="([^"]+)"><i style="background:(#[0-9a-f]{6})"></i>', text))
    kinds = {e.kind for e in traj.events}
    assert kinds <= set(keys)
    assert all(keys[k] == EVENT_COLOURS[k] for k in kinds)


def test_contact_markers_show_from_the_default_distance(run, page):
    """Each marker is drawn over everything (no depth test) and its radius is at least
    MARKER_MIN_SCREEN times the camera's distance from the origin it looks at."""
    from contactdiff.replay_geometry import MARKER_MIN_SCREEN

    _, text = page
    commands = _commands(text)
    (camera,) = [
        c
        for c in commands
        if c["type"] == "set_property" and c["path"].startswith("/Cameras") and c["property"] == "position"
    ]
    distance = float(np.linalg.norm(camera["value"]))
    markers = [c["object"] for c in commands if c["type"] == "set_object" and "/contacts/" in c["path"]]
    assert len(markers) == 2
    for m in markers:
        assert m["geometries"][0]["radius"] >= MARKER_MIN_SCREEN * distance * (1 - 1e-12)
        assert m["materials"][0]["depthTest"] is False and m["materials"][0]["transparent"] is True


_MESH = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 0 0.1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"  # a tetrahedron
_URDF = """<?xml version="1.0"?>
<robot name="arm">
  <link name="base"/>
  <joint name="hinge" type="revolute">
    <parent link="base"/><child link="bar"/><origin xyz="0 0 1"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="10"/>
  </joint>
  <link name="bar">
    <inertial><origin xyz="0 0 -0.5"/><mass value="1"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
    <visual><geometry><mesh filename="package://mypkg/meshes/tetra.obj"/></geometry></visual>
  </link>
</robot>
"""


@pytest.fixture
def package_robot(tmp_path):
    """A one-link URDF whose mesh is ``package://mypkg/...``, with the package in a folder
    (``pkgs/mypkg``) that is not above the URDF (``robot/arm.urdf``)."""
    (tmp_path / "pkgs" / "mypkg" / "meshes").mkdir(parents=True)
    (tmp_path / "pkgs" / "mypkg" / "meshes" / "tetra.obj").write_text(_MESH)
    (tmp_path / "robot").mkdir()
    (tmp_path / "robot" / "arm.urdf").write_text(_URDF)
    return tmp_path / "robot" / "arm.urdf", tmp_path / "pkgs"


def test_package_meshes_are_found_in_the_given_package_folders(package_robot, tmp_path):
    pytest.importorskip("meshcat")
    from contactdiff.errors import InvalidInputError

    urdf, pkgs = package_robot
    scene = load_source(str(urdf))
    traj = simulate(scene, 0.1, dense=True)
    with pytest.raises(InvalidInputError, match="package://mypkg/meshes/tetra.obj.*--package-dir"):
        traj.to_html(tmp_path / "no.html", scene)
    path = traj.to_html(tmp_path / "arm.html", scene, package_dirs=[pkgs])
    meshes = [
        c["object"]["geometries"][0]
        for c in _commands(path.read_text())
        if c["type"] == "set_object" and "/visuals/" in c["path"]
    ]
    assert len(meshes) == 1 and meshes[0]["format"] == "obj"
    data = meshes[0]["data"]
    assert "f 2 3 4" in (data.decode() if isinstance(data, bytes) else data)  # the package's file, inlined
    with pytest.raises(InvalidInputError, match="not a folder"):
        traj.to_html(tmp_path / "no.html", scene, package_dirs=[pkgs / "missing"])
    assert not (tmp_path / "no.html").exists()


def test_cli_package_dir(package_robot, tmp_path, capsys):
    """--package-dir points the replay at the package; without it, or with a folder that is
    not one, the command refuses in one line before the run (no page, no run output)."""
    pytest.importorskip("meshcat")
    urdf, pkgs = package_robot
    page = tmp_path / "arm.html"
    base = ["simulate", str(urdf), "--t-final", "0.1", "--html", str(page)]
    assert main(base) == 2
    out, err = capsys.readouterr()
    assert "could not be found" in err and "--package-dir" in err and len(err.strip().splitlines()) == 1
    assert "simulation of" not in out and not page.exists()
    assert main(base + ["--package-dir", str(tmp_path / "missing")]) == 2
    assert "not a folder" in capsys.readouterr().err and not page.exists()
    assert main(base + ["--package-dir", str(tmp_path), "--package-dir", str(pkgs)]) == 0
    assert page.exists() and "replay written to" in capsys.readouterr().out
