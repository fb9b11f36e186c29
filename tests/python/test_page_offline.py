"""The 3-D page loads nothing from anywhere (issue 24): every external reference a mesh
carries is embedded or dropped with a warning, and a Content-Security-Policy forbids network
loads. Rendered in headless Chromium while a local HTTP server on 127.0.0.1 counts the
requests it receives; also the page's mesh budget and package:// paths that leave their
package."""

from __future__ import annotations

import http.server
import os
import shutil
import subprocess
import threading
import warnings
from pathlib import Path

import numpy as np
import pytest

import orbitflex
from orbitflex import viz

CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
needs_chromium = pytest.mark.skipif(
    CHROMIUM is None,
    reason="headless Chromium not found (Debian's 'chromium' package; .ci/run installs it)",
)


class CountingServer:
    """An HTTP server on 127.0.0.1 that answers every GET with a PNG and records its path."""

    def __init__(self) -> None:
        requests = self.requests = []

        class Handler(http.server.BaseHTTPRequestHandler):
            def do_GET(self) -> None:  # noqa: N802
                requests.append(self.path)
                body = bytes.fromhex("89504e470d0a1a0a")
                self.send_response(200)
                self.send_header("Content-Type", "image/png")
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)

            def log_message(self, *args: object) -> None:
                pass

        self.server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.port = self.server.server_address[1]
        self.thread = threading.Thread(target=self.server.serve_forever, daemon=True)

    def __enter__(self) -> "CountingServer":
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.shutdown()
        self.server.server_close()

    def url(self, name: str) -> str:
        return f"http://127.0.0.1:{self.port}/{name}"


def textured_dae(texture: str) -> str:
    """A COLLADA triangle whose material's diffuse colour is the image ``texture`` names, so that
    three.js loads it."""
    return f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset><up_axis>Z_UP</up_axis></asset>
  <library_images><image id="beacon"><init_from>
      {texture}
  </init_from></image></library_images>
  <library_effects><effect id="fx"><profile_COMMON>
    <newparam sid="surf"><surface type="2D"><init_from>beacon</init_from></surface></newparam>
    <newparam sid="samp"><sampler2D><source>surf</source></sampler2D></newparam>
    <technique sid="common"><lambert><diffuse><texture texture="samp" texcoord="UV"/></diffuse></lambert></technique>
  </profile_COMMON></effect></library_effects>
  <library_materials><material id="mat"><instance_effect url="#fx"/></material></library_materials>
  <library_geometries><geometry id="tri"><mesh>
    <source id="pos"><float_array id="pos-a" count="9">0 0 0 0.3 0 0 0 0.3 0</float_array>
      <technique_common><accessor source="#pos-a" count="3" stride="3"><param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
    <source id="uv"><float_array id="uv-a" count="6">0 0 1 0 0 1</float_array>
      <technique_common><accessor source="#uv-a" count="3" stride="2"><param name="S" type="float"/><param name="T" type="float"/></accessor></technique_common></source>
    <vertices id="vtx"><input semantic="POSITION" source="#pos"/></vertices>
    <triangles count="1" material="m"><input semantic="VERTEX" source="#vtx" offset="0"/><input semantic="TEXCOORD" source="#uv" offset="0" set="0"/><p>0 1 2</p></triangles>
  </mesh></geometry></library_geometries>
  <library_visual_scenes><visual_scene id="scene"><node id="n">
    <instance_geometry url="#tri"><bind_material><technique_common><instance_material symbol="m" target="#mat"/></technique_common></bind_material></instance_geometry>
  </node></visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#scene"/></scene>
</COLLADA>"""


def mesh_robot(folder: Path, meshes: dict, visuals: list) -> orbitflex.Robot:
    """A two-link robot whose base draws ``visuals`` (URDF <visual> text), with the files of
    ``meshes`` (name → text) beside the URDF."""
    for name, text in meshes.items():
        (folder / name).write_text(text)
    xml = f"""<robot name="meshes"><link name="a"><inertial><mass value="10"/><inertia ixx="1" ixy="0" ixz="0" iyy="1" iyz="0" izz="1"/></inertial>{"".join(visuals)}</link>
      <joint name="j" type="revolute"><parent link="a"/><child link="b"/><origin xyz="0.5 0 0"/><axis xyz="0 0 1"/></joint>
      <link name="b"><inertial><origin xyz="0.5 0 0"/><mass value="2"/><inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link></robot>"""
    (folder / "robot.urdf").write_text(xml)
    return orbitflex.Robot.from_urdf(folder / "robot.urdf")


def page_of(robot: orbitflex.Robot, path: Path) -> Path:
    arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints(100.0, 0.01, 0.1))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", viz.VisualWarning)
        return arm.simulate(arm.state(theta=np.full(robot.dof, 0.3)), 0.01, 20).animate(path)


def browse(page: Path) -> tuple:
    """The page rendered in headless Chromium (no proxy: loopback is reachable): its DOM and
    Chromium's log, which reports every load the Content-Security-Policy refused."""
    result = subprocess.run(
        [CHROMIUM, "--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
         "--disable-background-networking", "--enable-logging=stderr", "--v=0",
         "--virtual-time-budget=6000", "--dump-dom", page.resolve().as_uri()],
        capture_output=True, text=True, timeout=120,
    )
    return result.stdout, result.stderr


def visual(filename: str, x: float = 0.0) -> str:
    return f'<visual><origin xyz="{x} 0 0"/><geometry><mesh filename="{filename}"/></geometry></visual>'


@needs_chromium
def test_hostile_mesh_references_load_nothing(tmp_path):
    # Issue 24: a DAE naming an http:// texture made the browser request /beacon.png from a
    # 127.0.0.1 server, while the warning said the mesh was "drawn without it".
    with CountingServer() as server:
        meshes = {
            "http.dae": textured_dae(server.url("beacon.png")),
            "https.dae": textured_dae(server.url("beacon.png").replace("http:", "https:")),
            "network_path.dae": textured_dae(f"//127.0.0.1:{server.port}/network_path.png"),
            # found trying: a name in CDATA, or broken by a comment, is the same text to three.js
            "cdata.dae": textured_dae(f"<![CDATA[{server.url('cdata.png')}]]>"),
            "comment.dae": textured_dae(f"http://127.0.0.1:{server.port}/comm<!-- x -->ent.png"),
            "hostile.obj": f"mtllib {server.url('m.mtl')}\nusemtl skin\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n",
        }
        robot = mesh_robot(tmp_path, meshes, [visual(name, k) for k, name in enumerate(meshes)])
        page = page_of(robot, tmp_path / "hostile.html")
        dom, log = browse(page)
        assert "ready" in dom.split("</title>")[0], dom[:2000]
        assert server.requests == []
        # the viewer itself runs within the policy: nothing was refused
        assert "Content Security Policy" not in log, log[-3000:]
        with pytest.warns(viz.VisualWarning) as record:
            viz._scene(robot, None, ghost=False, share=True)
        notes = [str(w.message) for w in record]
        assert sum("a network address; the page loads nothing" in n for n in notes) == 5, notes


@needs_chromium
def test_the_content_security_policy_blocks_what_would_slip_through(tmp_path):
    # The policy is the second wall: markup and a script that a page should never hold, put
    # into a copy of a real page, load nothing either. Without the policy each would reach the
    # server (checked: the same markup in a page without it does).
    robot = orbitflex.models.space_arm()
    page = page_of(robot, tmp_path / "clean.html").read_text()
    with CountingServer() as server:
        hostile = (f'<img src="{server.url("img.png")}"><link rel="stylesheet" href="{server.url("style.css")}">'
                   f'<iframe src="{server.url("frame.html")}"></iframe>'
                   f'<script>fetch("{server.url("fetch")}"); new Image().src = "{server.url("js.png")}";</script>')
        injected = tmp_path / "injected.html"
        injected.write_text(page.replace("<body>", "<body>" + hostile, 1))
        dom, log = browse(injected)
        assert "ready" in dom.split("</title>")[0]
        assert server.requests == []
        assert "Content Security Policy" in log
        # the same markup without the policy reaches the server
        open_page = tmp_path / "open.html"
        open_page.write_text(page.replace("<body>", "<body>" + hostile, 1).replace(
            '<meta http-equiv="Content-Security-Policy"', '<meta name="no-policy"', 1))
        browse(open_page)
        assert {"/img.png", "/style.css", "/frame.html", "/fetch", "/js.png"} <= set(server.requests), \
            server.requests


def test_the_policy_lists_the_pages_own_scripts_by_hash(tmp_path):
    text = page_of(orbitflex.models.space_arm(), tmp_path / "p.html").read_text()
    head = text[: text.index("<title>")]
    assert '<meta http-equiv="Content-Security-Policy" content="default-src \'none\'; script-src \'sha256-' in head
    policy = head.split('content="')[1].split('"')[0]
    assert policy.count("'sha256-") == text.count("<script>") == 2
    for directive in ("img-src data: blob:", "connect-src data: blob:", "base-uri 'none'", "form-action 'none'"):
        assert directive in policy
    assert "unsafe-inline'" not in policy.split("style-src")[0]  # no inline scripts but these two


# ------------------------------------------------------------------------ the mesh budget


TRIANGLE_STL = "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n"


def scaled(filename: str, s: float, rgba: str = "") -> str:
    material = f'<material name="c{rgba}"><color rgba="{rgba}"/></material>' if rgba else ""
    return f'<visual><geometry><mesh filename="{filename}" scale="{s} {s} {s}"/></geometry>{material}</visual>'


def test_a_mesh_at_many_scales_is_embedded_once(tmp_path):
    # Issue 24: one 8 MB mesh at 36 scales embedded 288 MB (a 265 MB page) without a warning.
    robot = mesh_robot(tmp_path, {"m.stl": TRIANGLE_STL}, [scaled("m.stl", 1 + k) for k in range(36)])
    scene = viz._scene(robot, None, ghost=False, share=True)
    drawn = [c for c in scene.commands if "clone" not in c and c["path"].startswith("/robot/a/")]
    clones = [c for c in scene.commands if "clone" in c]
    assert len(clones) == 35 and len(drawn) == 1
    # each copy keeps its own scale in its matrix (column-major: the diagonal)
    assert sorted(c["matrix"][0] for c in clones) == [float(2 + k) for k in range(35)]


def test_the_budget_counts_every_copy_embedded(tmp_path, monkeypatch):
    # a copy that cannot be shared (another colour; every copy in the live viewer) is embedded
    # again and counted; past the budget a mesh is not drawn and says so
    size = len(TRIANGLE_STL)
    monkeypatch.setattr(viz, "MAX_PAGE_MESH_BYTES", 3 * size)
    colours = ["1 0 0 1", "0 1 0 1", "0 0 1 1", "1 1 0 1", "0 1 1 1"]
    robot = mesh_robot(tmp_path, {"m.stl": TRIANGLE_STL}, [scaled("m.stl", 1, c) for c in colours])
    with pytest.warns(viz.VisualWarning) as record:
        scene = viz._scene(robot, None, ghost=False, share=True)
    notes = [str(w.message) for w in record]
    assert len(notes) == 2, notes
    assert all(n.startswith("link 'a', mesh '") and "not drawn: with it the meshes embedded would pass" in n
               for n in notes)
    assert len([c for c in scene.commands if "clone" not in c and c["path"].startswith("/robot/a/")]) == 3
    # the same five in one colour: one copy, no warning
    same = mesh_robot(tmp_path, {"m.stl": TRIANGLE_STL}, [scaled("m.stl", 1 + k) for k in range(5)])
    with warnings.catch_warnings():
        warnings.simplefilter("error", viz.VisualWarning)
        viz._scene(same, None, ghost=False, share=True)


# ------------------------------------------------------------------------ package:// escapes


def test_package_paths_cannot_leave_their_package(tmp_path):
    # Issue 24: package://../outside/secret.obj resolved outside the package folder.
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "secret.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    package = tmp_path / "pkg"
    (package / "meshes").mkdir(parents=True)
    (package / "urdf").mkdir()
    os.symlink(outside / "secret.obj", package / "meshes" / "link.obj")
    robot = mesh_robot(package / "urdf", {}, [visual("package://../outside/secret.obj"),
                                              visual("package://pkg/meshes/link.obj")])
    shapes, problems = robot.scene()
    assert not any(s["kind"] == "mesh" for s in shapes)
    assert "package://../outside/secret.obj': '..' is not a package name" in problems[0], problems
    assert "package://pkg/meshes/link.obj': the path 'meshes/link.obj' leaves the package 'pkg'" in problems[1], \
        problems
    assert np.all([s["stand_in"] for s in shapes if s["frame"] == 0])
