"""The 3-D view: frame poses along runs, shapes and meshes from URDF, the self-contained HTML
animation rendered in headless Chromium, and the live viewer on loopback."""

from __future__ import annotations

import base64
import os
import pickle
import re
import shutil
import subprocess
import warnings
from pathlib import Path

import json

import numpy as np
import pytest

import orbitflex
from orbitflex import viz
from pin_helpers import robots_dir

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None,
    reason="headless Chromium not found (Debian's 'chromium' package; .ci/run installs it)",
)


def ur5():
    return orbitflex.Robot.from_urdf(
        os.path.join(robots_dir(), "ur_description/urdf/ur5_robot.urdf"), ee_link="tool0"
    )


def panda():
    return orbitflex.Robot.from_urdf(
        os.path.join(robots_dir(), "panda_description/urdf/panda.urdf"),
        ee_link="panda_hand_tcp",
        locked_joints=["panda_finger_joint1", "panda_finger_joint2"],
    )


def short_run(robot=None, steps=400, dt=0.005):
    """A free-floating run with the springs loaded at the start, so the arm and bus move."""
    robot = robot or orbitflex.models.space_arm()
    joints = orbitflex.FlexibleJoints(2e3, 0.05, 5.0)
    arm = orbitflex.FlexibleArm(robot, joints)
    x0 = arm.state()
    n = robot.dof
    x0[7 + n : 7 + 2 * n] = 0.4  # θ ahead of q: the springs drive the links
    return arm.simulate(x0, dt, steps)


# ------------------------------------------------------------------------------- frames


def test_space_arm_frames_are_its_links():
    robot = orbitflex.models.space_arm()
    assert robot.frame_names == [
        "bus", "shoulder_roll_link", "shoulder_yaw_link", "upper_boom", "lower_boom",
        "wrist_pitch_link", "wrist_yaw_link", "wrist_roll_link", "ee",
    ]


def test_frame_poses_batch_equals_single_calls_and_out():
    robot = panda()
    rng = np.random.default_rng(7)
    base = np.concatenate([rng.normal(size=(5, 3)), rng.normal(size=(5, 4))], axis=1)
    q = rng.uniform(-2, 2, (5, robot.dof))
    batch = robot.frame_poses(base, q)
    assert batch.shape == (5, len(robot.frame_names), 7)
    for k in range(5):
        np.testing.assert_array_equal(batch[k], robot.frame_poses(base[k], q[k]))
    shared = robot.frame_poses(base[0], q)
    np.testing.assert_array_equal(shared[3], robot.frame_poses(base[0], q[3]))
    out = np.empty_like(batch)
    assert robot.frame_poses(base, q, out=out) is out
    np.testing.assert_array_equal(out, batch)
    single = np.empty((len(robot.frame_names), 7))
    assert robot.frame_poses(base[1], q[1], out=single) is single
    np.testing.assert_array_equal(single, batch[1])


def test_frame_poses_errors_name_the_argument():
    robot = orbitflex.models.space_arm()
    with pytest.raises(orbitflex.ModelError, match=r"q: expected length 7, given length 3"):
        robot.frame_poses([0, 0, 0, 0, 0, 0, 1], [0.0] * 3)
    with pytest.raises(orbitflex.ModelError, match="zero norm"):
        robot.frame_poses([0.0] * 7, [0.0] * 7)
    with pytest.raises(orbitflex.ModelError, match=r"base_pose \(row 1\): the quaternion .* has zero norm"):
        robot.frame_poses([[0, 0, 0, 0, 0, 0, 1], [0] * 7], [0.0] * 7)
    with pytest.raises(orbitflex.ModelError, match=r"out: expected shape \(9, 7\), given shape \(9, 6\)"):
        robot.frame_poses([0, 0, 0, 0, 0, 0, 1], [0.0] * 7, out=np.zeros((9, 6)))


def test_trajectory_frame_poses_at_chosen_rows():
    traj = short_run(steps=30)
    all_rows = traj.frame_poses(motor_side=2.0)
    np.testing.assert_array_equal(traj.frame_poses(motor_side=2.0, rows=[30, 0, 5]), all_rows[[30, 0, 5]])
    assert traj.frame_poses(rows=[]).shape == (0, 9, 7)
    with pytest.raises(orbitflex.ModelError, match=r"rows\[1\]: expected a row index in 0\.\.31, given 31"):
        traj.frame_poses(rows=[0, 31])
    with pytest.raises(orbitflex.ModelError, match=r"rows\[0\]: expected a row index in 0\.\.31, given -1"):
        traj.frame_poses(rows=[-1])


def test_trajectory_frame_poses_along_the_rows():
    traj = short_run(steps=60)
    robot = traj.arm.robot
    poses = traj.frame_poses()
    assert poses.shape == (61, len(robot.frame_names), 7)
    np.testing.assert_array_equal(poses, robot.frame_poses(traj.base_pose, traj.q))
    # the EE frame is the EE pose, the bus frame the base pose. Two paths through the same
    # transforms (frames in joint frames, §2.6, against the EE recursion): each of the n + 2
    # compositions rounds its 3-term products at the scale of the arm's reach, so the positions
    # agree to 3 (n + 2) ε reach and the unit quaternions to 3 (n + 2) ε (measured: a quarter of it)
    k = robot.frame_names.index(robot.ee_link)
    eps, depth = np.finfo(float).eps, 3 * (robot.dof + 2)
    reach = max(1.0, float(np.abs(poses[..., :3]).max()))
    np.testing.assert_allclose(poses[:, k, :3], traj.ee_pose[:, :3], atol=depth * eps * reach, rtol=0)
    np.testing.assert_allclose(poses[:, k, 3:], traj.ee_pose[:, 3:], atol=depth * eps, rtol=0)
    np.testing.assert_allclose(poses[:, 0, :3], traj.base_pose[:, :3], atol=1e-15, rtol=0)
    # the motor side at s: q + s (θ − q)
    s = 7.0
    ghost = traj.frame_poses(motor_side=s)
    np.testing.assert_array_equal(ghost, robot.frame_poses(traj.base_pose, traj.q + s * (traj.theta - traj.q)))
    assert not np.array_equal(ghost, poses)
    np.testing.assert_array_equal(traj.frame_poses(motor_side=0.0), poses)
    with pytest.raises(orbitflex.ModelError, match="motor_side"):
        traj.frame_poses(motor_side=float("nan"))


def test_pickled_robots_keep_their_frames_and_visuals():
    for robot in (orbitflex.models.space_arm(), ur5()):
        again = pickle.loads(pickle.dumps(robot))
        assert again.frame_names == robot.frame_names
        assert again.scene() == robot.scene()
        base, q = [0.1, 0.2, 0.3, 0, 0, 0.6, 0.8], np.linspace(-1, 1, robot.dof)
        np.testing.assert_array_equal(again.frame_poses(base, q), robot.frame_poses(base, q))


# ------------------------------------------------------------------------------- shapes


def test_space_arm_has_a_bus_with_solar_panels_and_cylinder_links():
    robot = orbitflex.models.space_arm()
    shapes, problems = robot.scene()
    assert problems == []
    bus = [s for s in shapes if s["frame"] == 0]
    kinds = sorted(s["kind"] for s in bus)
    assert kinds == ["box", "box", "box", "cylinder", "cylinder"]  # body, 2 panels, 2 yokes
    panels = [s for s in bus if s["kind"] == "box" and s["size"][1] == 3.0]
    assert sorted(p["origin"][1] for p in panels) == [-2.75, 2.75]
    assert all(s["kind"] == "cylinder" for s in shapes if s["frame"] > 0)
    assert all(s["color"] is not None and not s["stand_in"] for s in shapes)


@pytest.mark.parametrize("load", [ur5, panda], ids=["ur5", "panda"])
def test_example_robot_data_meshes_load(load):
    robot = load()
    shapes, problems = robot.scene()
    assert problems == []
    meshes = [s for s in shapes if s["kind"] == "mesh"]
    assert len(meshes) >= 7
    for mesh in meshes:
        assert os.path.isfile(mesh["path"]) and mesh["format"] in ("dae", "stl")
    # the meshcat objects are built from the files without error
    with warnings.catch_warnings():
        warnings.simplefilter("error", viz.VisualWarning)
        scene = viz._scene(robot, None, ghost=True)
    assert len(scene.commands) > len(meshes)


def _bad_robot(tmp_path: Path) -> Path:
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "bad.stl").write_bytes(b"not an stl at all")
    xml = """<robot name="bad">
  <link name="base"><inertial><mass value="10"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
    <visual><geometry><mesh filename="meshes/missing.stl"/></geometry></visual></link>
  <joint name="j" type="revolute"><parent link="base"/><child link="arm"/><origin xyz="0.5 0 0"/><axis xyz="0 0 1"/></joint>
  <link name="arm"><inertial><origin xyz="0.5 0 0"/><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
    <visual><geometry><cylinder radius="0.1"/></geometry></visual>
    <visual><geometry><mesh filename="meshes/bad.stl"/></geometry></visual></link>
  <joint name="t" type="fixed"><parent link="arm"/><child link="tip"/><origin xyz="1 0 0"/></joint>
  <link name="tip"/>
</robot>"""
    path = tmp_path / "bad.urdf"
    path.write_text(xml)
    return path


def test_missing_meshes_and_malformed_visuals_warn_and_get_stand_ins(tmp_path):
    path = _bad_robot(tmp_path)
    robot = orbitflex.Robot.from_urdf(path)
    joints = orbitflex.FlexibleJoints(100.0, 0.01, 0.1)
    traj = orbitflex.FlexibleArm(robot, joints).simulate(orbitflex.FlexibleArm(robot, joints).state(), 0.01, 20)
    with pytest.warns(viz.VisualWarning) as record:
        page = traj.animate(tmp_path / "bad.html")
    messages = [str(w.message) for w in record if issubclass(w.category, viz.VisualWarning)]
    assert messages == [
        f"link 'base', mesh 'meshes/missing.stl': no file at {tmp_path / 'meshes' / 'missing.stl'}; drawn as a stand-in",
        "link 'arm', visual 1: line 6: <cylinder> has no length=\"…\" attribute; drawn as a stand-in",
        "link 'arm', mesh 'meshes/bad.stl': not an STL file: 17 bytes, neither ASCII ('solid … facet') nor "
        "binary (84 + 50 bytes per triangle); drawn as a stand-in",
    ]
    assert page.is_file() and page.stat().st_size > 100_000
    shapes, _ = robot.scene()
    stand_ins = [s for s in shapes if s["stand_in"]]
    assert {s["frame"] for s in stand_ins} == {0, 1}
    # the arm's stand-in is its capsule to the tip; the tip, without visuals, a grey sphere
    arm = [s for s in stand_ins if s["frame"] == 1]
    assert [(s["kind"], s["length"]) for s in arm] == [("capsule", 1.0)]
    tip = [s for s in shapes if s["frame"] == 2]
    assert [(s["kind"], s["stand_in"]) for s in tip] == [("sphere", False)]


def test_package_map_finds_meshes(tmp_path):
    """A package:// mesh found only through the explicit map."""
    pkg = tmp_path / "elsewhere" / "my_pkg"
    (pkg / "meshes").mkdir(parents=True)
    stl = b"\0" * 80 + (1).to_bytes(4, "little") + b"\0" * 50
    (pkg / "meshes" / "m.stl").write_bytes(stl)
    xml = """<robot name="p"><link name="a"><inertial><mass value="1"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
      <visual><geometry><mesh filename="package://my_pkg/meshes/m.stl"/></geometry></visual></link></robot>"""
    robot = orbitflex.Robot.from_urdf_string(xml)
    old = os.environ.pop("ROS_PACKAGE_PATH", None)
    try:
        _, problems = robot.scene()
        assert problems and "package 'my_pkg' not found" in problems[0]
        shapes, problems = robot.scene({"my_pkg": pkg})
        assert problems == []
        assert shapes[0]["path"] == pkg / "meshes" / "m.stl"
        os.environ["ROS_PACKAGE_PATH"] = str(tmp_path / "elsewhere")
        shapes, problems = robot.scene()
        assert problems == [] and shapes[0]["path"] == pkg / "meshes" / "m.stl"
    finally:
        os.environ.pop("ROS_PACKAGE_PATH", None)
        if old is not None:
            os.environ["ROS_PACKAGE_PATH"] = old


# ------------------------------------------------------------------------------- the page


def test_ghost_scale_and_frame_rows():
    traj = short_run(steps=100)
    peak = float(np.max(np.abs(traj.deflection)))
    s = viz.ghost_scale(traj)
    assert 0.15 / 2.5 < s * peak <= 0.15 or s == 1.0
    assert re.fullmatch(r"[125]0*(\.0)?", f"{s:g}") or s < 1
    t = np.arange(0, 1.0001, 0.001)
    rows = viz.frame_rows(t, 30)
    assert rows[0] == 0 and rows[-1] == t.size - 1
    assert np.all(np.diff(t[rows][:-1]) > 1 / 30 - 1.5e-3)
    assert len(rows) == 31
    with pytest.raises(ValueError, match="fps"):
        viz.frame_rows(t, 0)
    # more frames than rows: every row, without building the frame times
    np.testing.assert_array_equal(viz.frame_rows(t, 1e12), np.arange(t.size))
    np.testing.assert_array_equal(viz.frame_rows(np.arange(0, 1e6), 1e7), np.arange(10**6))


def test_page_is_self_contained(tmp_path):
    traj = short_run(steps=100)
    path = traj.animate(tmp_path / "a.html", ghost=True)
    text = path.read_text()
    # nothing loaded from elsewhere: no src/href attributes, no fetches of our own
    assert not re.search(r"<(script|link|img|iframe)[^>]*(src|href)=", text)
    ours = text[text.rindex("<script>"):]
    assert "fetch(" not in ours and "XMLHttpRequest" not in ours
    assert "deflection &times; \" + DATA.ghost_scale" in ours
    assert f"{traj.arm.robot.name}: 7 joints, dt = 0.005 s, 101 rows" in text


def _render(page: str, tmp_path: Path, name: str, size=(900, 600)) -> Path:
    """A screenshot of ``page`` (a file URL with its hash) in headless Chromium, with every
    network request sent to a dead proxy, so anything fetched from outside would be missing."""
    shot = tmp_path / f"{name}.png"
    subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--proxy-server=127.0.0.1:9", "--disable-background-networking", f"--window-size={size[0]},{size[1]}",
         "--virtual-time-budget=6000", f"--screenshot={shot}", page],
        check=True, capture_output=True, timeout=120,
    )
    return shot


def _dom(page: str) -> str:
    result = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--proxy-server=127.0.0.1:9", "--virtual-time-budget=6000", "--dump-dom", page],
        check=True, capture_output=True, timeout=120, text=True,
    )
    return result.stdout


def _pixels(path: Path) -> np.ndarray:
    from PIL import Image

    return np.asarray(Image.open(path).convert("RGB")).astype(float)


@needs_chromium
def test_page_renders_in_headless_chromium(tmp_path):
    traj = short_run(steps=400)
    page = traj.animate(tmp_path / "slew.html", ghost=True)
    end = float(traj.t[-1])
    url = page.resolve().as_uri()
    dom = _dom(url)
    assert "ready" in dom.split("</title>")[0], dom[:2000]
    assert "t = 0.00 s / 2.00 s" in dom  # opens paused at t = 0
    dom_end = _dom(f"{url}#t={end}")
    assert "t = 2.00 s / 2.00 s" in dom_end
    first = _pixels(_render(url, tmp_path, "t0"))
    last = _pixels(_render(f"{url}#t={end}", tmp_path, "tT"))
    scene = (slice(60, 520), slice(0, 900))  # above the controls, below the title
    for image in (first, last):
        assert image[scene].std() > 10, "blank render"
    # the arm moved: the two frames differ in a region, and not everywhere
    changed = np.abs(first[scene] - last[scene]).max(axis=2) > 30
    assert 300 < changed.sum() < 0.5 * changed.size, changed.sum()


@needs_chromium
def test_demo_animation_is_small_and_renders(tmp_path):
    result = subprocess.run(
        ["orbitflex", "demo", "--out", str(tmp_path / "out"), "--quiet", "--no-plots"],
        capture_output=True, text=True, timeout=600,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    page = tmp_path / "out" / "animation.html"
    assert page.stat().st_size <= 5_000_000
    url = page.resolve().as_uri()
    assert "t = 20.00 s / 20.00 s" in _dom(f"{url}#t=20")
    start = _pixels(_render(url, tmp_path, "demo0"))
    end = _pixels(_render(f"{url}#t=20", tmp_path, "demo20"))
    changed = np.abs(start[60:520] - end[60:520]).max(axis=2) > 30
    assert changed.sum() > 300


@needs_chromium
@pytest.mark.parametrize("load", [ur5, panda], ids=["ur5", "panda"])
def test_mesh_robots_render(load, tmp_path):
    traj = short_run(load(), steps=500, dt=0.002)
    page = traj.animate(tmp_path / "m.html")
    url = page.resolve().as_uri()
    assert "ready" in _dom(url).split("</title>")[0]
    first = _pixels(_render(url, tmp_path, "m0"))
    last = _pixels(_render(f"{url}#t={float(traj.t[-1])}", tmp_path, "mT"))
    assert first[60:520].std() > 5
    assert (np.abs(first[60:520] - last[60:520]).max(axis=2) > 30).sum() > 100


# ------------------------------------------------------------------------------- live viewer


@needs_chromium
def test_live_viewer_serves_on_loopback_and_updates(tmp_path):
    robot = orbitflex.models.space_arm()
    viewer = viz.Viewer(robot, ghost=True, ghost_scale=10.0)
    try:
        assert viewer.url.startswith("http://127.0.0.1:")
        traj = short_run(steps=40)
        viewer.display(traj.x[-1])
        viewer.display(traj.base_pose[0], traj.q[0])
        viewer.play(traj, speed=100.0)
        rows = []
        traj.arm.simulate(traj.x[0], 0.005, 30, on_rows=lambda t, x, u: (rows.append(len(t)), viewer.on_rows(t, x, u)))
        assert sum(rows) == 31
        shot = _pixels(_render(viewer.url, tmp_path, "live"))
        assert shot[60:520].std() > 10
        # the server holds the scene: every shape of the robot and the ghost, and the axes
        scene = viewer._vis.static_html()
        drawn = len(viz._scene(robot, None, ghost=True).commands)
        assert scene.count("handle_command") >= drawn + 1
        with pytest.raises(ValueError, match=r"x: expected a state of length 41"):
            viewer.display(np.zeros(5))
    finally:
        viewer.close()


# ------------------------------------------------------------------------------- hostile models


HOSTILE = """<robot name="__DATA__ &lt;/title&gt;&lt;script&gt;document.title=1337&lt;/script&gt;">
  <link name="&lt;img src=x onerror=document.title=1337&gt;"><inertial><mass value="10"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>
    <visual><geometry><box size="1 1 1"/></geometry></visual></link>
  <joint name="j" type="revolute"><parent link="&lt;img src=x onerror=document.title=1337&gt;"/><child link="&lt;!--&lt;script&gt;"/><origin xyz="0.5 0 0"/><axis xyz="0 0 1"/></joint>
  <link name="&lt;!--&lt;script&gt;"><inertial><origin xyz="0.5 0 0"/><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="k" type="fixed"><parent link="&lt;!--&lt;script&gt;"/><child link="&lt;/script&gt;__TITLE__"/><origin xyz="1 0 0"/></joint>
  <link name="&lt;/script&gt;__TITLE__"/>
</robot>"""


def _hostile_run():
    robot = orbitflex.Robot.from_urdf_string(HOSTILE)
    assert robot.frame_names == ["<img src=x onerror=document.title=1337>", "<!--<script>", "</script>__TITLE__"]
    arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints(100.0, 0.01, 0.1))
    return arm.simulate(arm.state(theta=[0.3]), 0.01, 50)


def test_names_cannot_inject_into_the_page(tmp_path):
    page = _hostile_run().animate(tmp_path / "h.html")
    text = page.read_text()
    script = text[text.rindex("<script>"):]
    assert "<img" not in script and "<!--" not in script and script.count("</script>") == 1
    title = text[text.index("<title>") + 7 : text.index("</title>")]
    assert title == "__DATA__ &lt;/title&gt;&lt;script&gt;document.title=1337&lt;/script&gt;: 1 joints, dt = 0.01 s, 51 rows"


@needs_chromium
def test_hostile_names_render_as_text(tmp_path):
    page = _hostile_run().animate(tmp_path / "h.html")
    dom = _dom(page.resolve().as_uri())
    head = dom.split("</title>")[0]
    assert "1337" not in head.split("<title>")[1].split("document.title=1337")[0]
    assert head.endswith("\u2014 ready") or head.endswith("— ready"), head[-200:]
    assert "t = 0.00 s / 0.50 s" in dom


def _collada_robot(tmp_path: Path, dae: str, texture: bool = False) -> "orbitflex.Robot":
    (tmp_path / "m.dae").write_text(dae)
    visuals = "".join(f'<visual><origin xyz="{k} 0 0"/><geometry><mesh filename="m.dae"/></geometry></visual>' for k in range(3))
    xml = f"""<robot name="dae"><link name="a"><inertial><mass value="10"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>{visuals}</link>
      <joint name="j" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.5 0 0"/><axis xyz="0 0 1"/></joint>
      <link name="b"><inertial><origin xyz="0.5 0 0"/><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link></robot>"""
    (tmp_path / "dae.urdf").write_text(xml)
    return orbitflex.Robot.from_urdf(tmp_path / "dae.urdf")


# well-formed COLLADA that three.js cannot turn into a mesh (a triangle list indexing nothing)
BROKEN_DAE = """<?xml version="1.0"?><COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<library_geometries><geometry id="g"><mesh><triangles count="1"><input semantic="VERTEX" source="#nothing" offset="0"/><p>0 1 2</p></triangles></mesh></geometry></library_geometries>
<library_visual_scenes><visual_scene id="s"><node id="n"><instance_geometry url="#g"/></node></visual_scene></library_visual_scenes>
<scene><instance_visual_scene url="#s"/></scene></COLLADA>"""


@needs_chromium
def test_a_mesh_three_js_cannot_read_leaves_a_gap_not_a_blank_page(tmp_path):
    robot = _collada_robot(tmp_path, BROKEN_DAE)
    arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints(100.0, 0.01, 0.1))
    page = arm.simulate(arm.state(theta=[0.3]), 0.01, 50).animate(tmp_path / "d.html")
    dom = _dom(page.resolve().as_uri())
    assert "ready" in dom.split("</title>")[0]
    assert "t = 0.00 s / 0.50 s" in dom


def test_a_mesh_drawn_several_times_is_embedded_once(tmp_path):
    robot = _collada_robot(tmp_path, BROKEN_DAE)
    scene = viz._scene(robot, None, ghost=False, share=True)
    clones = [c for c in scene.commands if "clone" in c]
    assert [c["path"] for c in clones] == [["robot", "a", "shape1"], ["robot", "a", "shape2"]]
    assert all(c["clone"] == ["robot", "a", "shape0"] for c in clones)
    assert clones[1]["matrix"][12] == 2.0  # column-major: the translation x of the third visual
    # the live viewer (share=False) sends every copy
    assert not any("clone" in c for c in viz._scene(robot, None, ghost=False).commands)


def test_dae_textures_are_embedded_or_reported(tmp_path):
    textured = BROKEN_DAE.replace(
        "<library_geometries>",
        "<library_images><image id='i1'><init_from>skin.png</init_from></image>"
        "<image id='i2'><init_from>gone.jpg</init_from></image></library_images><library_geometries>",
    )
    png = base64.b64decode("iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAYAAAAfFcSJAAAADUlEQVR42mNk+M9QDwADhgGAWjR9awAAAABJRU5ErkJggg==")
    (tmp_path / "skin.png").write_bytes(png)
    robot = _collada_robot(tmp_path, textured)
    with pytest.warns(viz.VisualWarning) as record:
        scene = viz._scene(robot, None, ghost=False, share=True)
    notes = [str(w.message) for w in record if issubclass(w.category, viz.VisualWarning)]
    assert notes == [f"mesh '{tmp_path / 'm.dae'}': texture 'gone.jpg': not found, or not a PNG/JPEG/GIF/BMP/WebP/TGA image under 16 MB; drawn without it"]
    obj = scene.commands[0]["object"]["object"]
    # each reference is rewritten to a key of the resources: the texture, or a blank one
    assert "<init_from>orbitflex-texture-0</init_from>" in obj["data"] and "skin.png" not in obj["data"]
    assert obj["resources"] == {"orbitflex-texture-0": "data:image/png;base64," + base64.b64encode(png).decode(),
                                "orbitflex-texture-1": viz._BLANK_TEXTURE}


def test_extra_shapes_are_drawn_and_checked(tmp_path):
    robot = orbitflex.models.space_arm()
    bus = {"kind": "box", "size": [2.0, 2.0, 2.0], "origin": [0.1, 0, 0, 0, 0, 0, 1], "color": [1, 0, 0, 0.5]}
    plain = viz._scene(robot, None, ghost=False)
    scene = viz._scene(robot, None, ghost=False, extra=[viz._checked_shape(bus, 0, len(robot.frame_names))])
    assert len(scene.commands) == len(plain.commands) + 1
    added = scene.commands[-1]
    assert added["path"] == "/robot/bus/shape5"  # after the bus's five visuals
    assert added["object"]["geometries"][0]["width"] == 2.0
    assert added["object"]["object"]["matrix"][12] == 0.1
    bad = [
        ({"kind": "cone"}, r"shapes\[0\]: kind: expected one of box, sphere, cylinder, capsule, given 'cone'"),
        ({"kind": "box", "size": [1, 1]}, r"shapes\[0\]: size: expected three positive lengths \(m\), given \[1, 1\]"),
        ({"kind": "sphere", "radius": -1}, r"shapes\[0\]: radius: expected a positive length \(m\), given -1"),
        ({"kind": "sphere", "radius": 1, "frame": 9}, r"shapes\[0\]: frame: expected an index into robot.frame_names \(0..8\), given 9"),
        ({"kind": "sphere", "radius": 1, "origin": [0] * 7}, r"shapes\[0\]: origin: expected \[x, y, z, qx, qy, qz, qw\]"),
        ({"kind": "sphere", "radius": 1, "color": [2, 0, 0, 1]}, r"shapes\[0\]: color: expected RGBA"),
    ]
    traj = short_run(steps=10)
    for shape, message in bad:
        with pytest.raises(ValueError, match=message):
            traj.animate(tmp_path / "x.html", shapes=[shape])


@needs_chromium
def test_dual_arm_page_draws_a_trail_per_end_effector(tmp_path):
    traj = short_run(orbitflex.models.dual_arm(), steps=400)
    page = traj.animate(tmp_path / "dual.html", ghost=True)
    html = page.read_text("utf-8")
    assert '"trails": 2' in html
    end = float(traj.t[-1])
    url = page.resolve().as_uri()
    dom = _dom(f"{url}#t={end}")
    assert "ready" in dom.split("</title>")[0], dom[:2000]
    assert "t = 2.00 s / 2.00 s" in dom
    first = _pixels(_render(url, tmp_path, "d0"))
    last = _pixels(_render(f"{url}#t={end}", tmp_path, "dT"))
    scene = (slice(60, 520), slice(0, 900))
    for image in (first, last):
        assert image[scene].std() > 10, "blank render"
    changed = np.abs(first[scene] - last[scene]).max(axis=2) > 30
    assert 300 < changed.sum() < 0.5 * changed.size, changed.sum()
    # (the time label is written after both trails are extended: it reads t = 2.00 s only if
    # the second trail exists as a line, above)


def test_the_target_box_has_the_targets_mass_and_moments():
    # a uniform box of sides a, b, c: I_x = m/12 (b² + c²), ...; the view draws the box back
    m, sides = 200.0, np.array([1.0, 1.2, 1.4])
    a2, b2, c2 = sides**2
    inertia = np.diag([m / 12 * (b2 + c2), m / 12 * (a2 + c2), m / 12 * (a2 + b2)])
    from orbitflex.viz.animation import target_box

    np.testing.assert_allclose(target_box(m, inertia), sides, rtol=1e-14)


def _capture_page(tmp_path, duration):
    s = orbitflex.models.capture_scenario(meet=1.0)
    traj = s.run(duration, record_every=10)
    return traj, traj.animate(tmp_path / "capture.html")


def test_a_capture_run_draws_the_target_as_a_box(tmp_path):
    traj, page = _capture_page(tmp_path, 1.5)
    import re

    def names(html):
        return json.loads(re.search(r'"names": (\[[^\]]*\])', html).group(1))

    # the target is one more body of the scene, beside the robot's frames
    robot_frames = traj.arm.robot.frame_names
    assert names(page.read_text("utf-8")) == [*robot_frames, "target"]
    plain = short_run(steps=10).animate(tmp_path / "plain.html").read_text("utf-8")
    assert "target" not in names(plain)
    assert len(traj.events) == 1


@needs_chromium
def test_the_target_box_renders_before_and_after_the_capture(tmp_path):
    traj, page = _capture_page(tmp_path, 1.5)
    url = page.resolve().as_uri()
    assert "ready" in _dom(url).split("</title>")[0]
    event = traj.events[0].time
    before = _pixels(_render(f"{url}#t={event - 0.4:.2f}", tmp_path, "before"))
    after = _pixels(_render(f"{url}#t={traj.t[-1]:.2f}", tmp_path, "after"))
    scene = (slice(60, 520), slice(0, 900))
    # the target's orange box is on the screen both before and after the capture
    for image in (before, after):
        r, g, b = image[scene][..., 0], image[scene][..., 1], image[scene][..., 2]
        orange = (r > 150) & (g > 70) & (g < 170) & (b < 90)
        assert orange.sum() > 500, orange.sum()
