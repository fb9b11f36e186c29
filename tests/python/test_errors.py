"""Every error orbitflex must report (SPEC.md §3, §4, §5, §7, §8), with a clear message.

Each test builds the smallest input that triggers one error and checks the exception type and
that the message names what is wrong: the file (a path, or ``<urdf string>``), the element
(joint, link, argument) and, for sizes, the expected and the given length. Nothing here may
crash the interpreter; the cases that could abort the process run in a subprocess.
"""

from __future__ import annotations

import re
import os
import subprocess
import sys
import textwrap
import warnings

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, FlexibleJoints, ModelError, MotorPD, Robot, SimulationError

# ---------------------------------------------------------------------------------------------
# Small URDFs written inline
# ---------------------------------------------------------------------------------------------


def link(name, mass=1.0, ixx=0.1, iyy=0.1, izz=0.1, com="0.25 0 0"):
    return (
        f'<link name="{name}"><inertial><origin xyz="{com}" rpy="0 0 0"/>'
        f'<mass value="{mass}"/><inertia ixx="{ixx}" ixy="0" ixz="0" iyy="{iyy}" iyz="0" '
        f'izz="{izz}"/></inertial></link>'
    )


def joint(name, parent, child, kind="revolute", axis="0 0 1", xyz="0.5 0 0"):
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}" rpy="0 0 0"/><axis xyz="{axis}"/>'
        f'<limit lower="-3" upper="3" effort="10" velocity="1"/></joint>'
    )


def urdf(*parts, name="tiny"):
    return f'<?xml version="1.0"?><robot name="{name}">' + "".join(parts) + "</robot>"


BASE = link("base", mass=50.0, ixx=5.0, iyy=5.0, izz=5.0, com="0 0 0")


def chain3():
    """base -> j1 (z) -> l1 -> j2 (y) -> l2 -> j3 (z) -> l3: a healthy 3-joint chain."""
    return urdf(
        BASE, link("l1"), link("l2"), link("l3"),
        joint("j1", "base", "l1"), joint("j2", "l1", "l2", axis="0 1 0"), joint("j3", "l2", "l3"),
    )


def one_joint(kind="revolute", **link_kw):
    return urdf(BASE, link("l1", **link_kw), joint("j1", "base", "l1", kind=kind))


@pytest.fixture(params=["file", "string"])
def loader(request, tmp_path):
    """Loads URDF text either from a file or from the string; returns (load, source name)."""
    if request.param == "file":
        path = tmp_path / "model.urdf"

        def load(xml, **kw):
            path.write_text(xml)
            return Robot.from_urdf(str(path), **kw)

        return load, str(path)

    def load(xml, **kw):
        return Robot.from_urdf_string(xml, **kw)

    return load, "<urdf string>"


def message_of(excinfo) -> str:
    return str(excinfo.value)


@pytest.fixture(scope="module")
def robot():
    return Robot.from_urdf_string(chain3())


@pytest.fixture(scope="module")
def arm(robot):
    return FlexibleArm(robot, FlexibleJoints(100.0, 0.05, damping=0.1, motor_damping=0.1))


# ---------------------------------------------------------------------------------------------
# URDF loading (SPEC §7)
# ---------------------------------------------------------------------------------------------


def test_model_error_is_a_value_error():
    assert issubclass(ModelError, ValueError)
    assert issubclass(SimulationError, Exception)


def test_missing_file_is_file_not_found_naming_the_path(tmp_path):
    path = tmp_path / "does_not_exist" / "arm.urdf"
    with pytest.raises(FileNotFoundError) as e:
        Robot.from_urdf(str(path))
    assert str(path) in message_of(e)


def test_missing_file_accepts_pathlike(tmp_path):
    path = tmp_path / "nope.urdf"
    with pytest.raises(FileNotFoundError) as e:
        Robot.from_urdf(path)
    assert str(path) in message_of(e)


@pytest.mark.parametrize(
    "xml",
    [
        '<robot name="x"><link name="a"></robot>',  # badly nested
        "<robot name='x'><link name='a'>",  # truncated
        "this is not xml",
        "",
    ],
    ids=["nesting", "truncated", "text", "empty"],
)
def test_malformed_xml(loader, xml):
    load, source = loader
    with pytest.raises(ModelError) as e:
        load(xml)
    msg = message_of(e)
    assert source in msg
    assert "malformed" in msg.lower()


def test_malformed_number_in_urdf(loader):
    load, source = loader
    xml = one_joint().replace('<mass value="1.0"/>', '<mass value="heavy"/>')
    with pytest.raises(ModelError) as e:
        load(xml)
    assert source in message_of(e)


@pytest.mark.parametrize("kind", ["prismatic", "planar", "floating"])
def test_unsupported_joint_type_names_joint_type_and_hint(loader, kind):
    load, source = loader
    xml = urdf(BASE, link("l1"), link("l2"), joint("j1", "base", "l1"),
               joint("slider", "l1", "l2", kind=kind))
    with pytest.raises(ModelError) as e:
        load(xml)
    msg = message_of(e)
    assert source in msg
    assert "'slider'" in msg
    assert kind in msg
    assert "locked_joints" in msg  # the hint says how to keep the model


def test_locked_prismatic_joint_loads(loader):
    load, _ = loader
    xml = urdf(BASE, link("l1"), link("l2"), joint("j1", "base", "l1"),
               joint("slider", "l1", "l2", kind="prismatic"))
    robot = load(xml, locked_joints=["slider"])
    assert robot.dof == 1
    assert robot.joint_names == ["j1"]
    # The locked link's mass stays in the model.
    assert robot.total_mass == pytest.approx(52.0)


def test_branching_moving_joint_off_the_chain(loader):
    load, source = loader
    xml = urdf(BASE, link("l1"), link("l2"), link("side_link"),
               joint("j1", "base", "l1"), joint("j2", "l1", "l2"),
               joint("side", "l1", "side_link"))
    with pytest.raises(ModelError) as e:
        load(xml, ee_link="l2")
    msg = message_of(e)
    assert source in msg
    assert "'side'" in msg
    assert "'j1'" not in msg and "'j2'" not in msg  # it blames the branch, not the chain
    # locking the branch (as the message suggests) makes a valid serial chain
    robot = load(xml, ee_link="l2", locked_joints=["side"])
    assert robot.joint_names == ["j1", "j2"]


def test_multiple_leaves_without_ee_link_lists_the_leaves(loader):
    load, source = loader
    xml = urdf(BASE, link("l1"), link("tip_a"), link("tip_b"),
               joint("j1", "base", "l1"), joint("ja", "l1", "tip_a"), joint("jb", "l1", "tip_b"))
    with pytest.raises(ModelError) as e:
        load(xml)
    msg = message_of(e)
    assert source in msg
    assert "tip_a" in msg and "tip_b" in msg
    assert "ee_link" in msg


def test_unknown_ee_link_names_it_and_lists_links(loader):
    load, source = loader
    with pytest.raises(ModelError) as e:
        load(chain3(), ee_link="gripper")
    msg = message_of(e)
    assert source in msg
    assert "gripper" in msg
    for name in ["base", "l1", "l2", "l3"]:
        assert name in msg


def test_unknown_locked_joint_names_it_and_lists_joints(loader):
    load, source = loader
    with pytest.raises(ModelError) as e:
        load(chain3(), locked_joints=["finger"])
    msg = message_of(e)
    assert source in msg
    assert "finger" in msg
    for name in ["j1", "j2", "j3"]:
        assert name in msg


def test_negative_mass_names_link(loader):
    load, source = loader
    with pytest.raises(ModelError) as e:
        load(one_joint(mass=-2.0))
    msg = message_of(e)
    assert source in msg
    assert "'l1'" in msg
    assert "mass" in msg


def test_non_positive_definite_inertia_names_link(loader):
    load, source = loader
    with pytest.raises(ModelError) as e:
        load(one_joint(ixx=-0.1))
    msg = message_of(e)
    assert source in msg
    assert "'l1'" in msg
    assert "positive definite" in msg


def test_triangle_violating_inertia_names_link(loader):
    load, source = loader
    with pytest.raises(ModelError) as e:
        load(one_joint(ixx=1.0, iyy=1.0, izz=3.0))
    msg = message_of(e)
    assert source in msg
    assert "'l1'" in msg
    assert "triangle" in msg


def test_non_finite_inertial_data_names_link(loader):
    load, source = loader
    with pytest.raises(ModelError) as e:
        load(one_joint(mass=float("nan")))
    msg = message_of(e)
    assert source in msg and "'l1'" in msg


def test_massless_last_link_makes_mass_matrix_singular(loader):
    load, source = loader
    xml = urdf(BASE, link("l1"), link("l2", mass=0.0, ixx=0.0, iyy=0.0, izz=0.0),
               joint("j1", "base", "l1"), joint("j2", "l1", "l2"))
    with pytest.raises(ModelError) as e:
        load(xml)
    msg = message_of(e)
    assert source in msg
    assert "'j2'" in msg
    assert "singular" in msg


def test_point_mass_on_the_axis_makes_mass_matrix_singular(loader):
    # Mass but no inertia about the joint axis: the last joint moves nothing.
    load, source = loader
    xml = urdf(BASE, link("l1"), link("l2", mass=1.0, ixx=0.0, iyy=0.0, izz=0.0, com="0 0 0"),
               joint("j1", "base", "l1"), joint("j2", "l1", "l2"))
    with pytest.raises(ModelError) as e:
        load(xml)
    assert source in message_of(e) and "'j2'" in message_of(e)


def test_massless_middle_link_is_fine(loader):
    load, _ = loader
    xml = urdf(BASE, link("l1"), link("l2", mass=0.0, ixx=0.0, iyy=0.0, izz=0.0), link("l3"),
               joint("j1", "base", "l1"), joint("j2", "l1", "l2"), joint("j3", "l2", "l3"))
    assert load(xml).dof == 3


def test_massless_base_tree_is_singular(loader):
    load, source = loader
    xml = urdf(link("base", mass=0.0, ixx=0.0, iyy=0.0, izz=0.0))
    with pytest.raises(ModelError) as e:
        load(xml)
    assert source in message_of(e) and "base" in message_of(e)


@pytest.mark.parametrize("axis", ["0 0 0", "nan 0 1"])
def test_zero_or_non_finite_axis_names_joint(loader, axis):
    load, source = loader
    xml = urdf(BASE, link("l1"), joint("j1", "base", "l1", axis=axis))
    with pytest.raises(ModelError) as e:
        load(xml)
    msg = message_of(e)
    assert source in msg
    assert "'j1'" in msg
    assert "axis" in msg


def test_non_finite_joint_origin_names_joint(loader):
    load, source = loader
    xml = urdf(BASE, link("l1"), joint("j1", "base", "l1", xyz="nan 0 0"))
    with pytest.raises(ModelError) as e:
        load(xml)
    assert source in message_of(e) and "'j1'" in message_of(e)


def test_cycle_and_duplicate_names(loader):
    load, source = loader
    cycle = urdf(BASE, link("l1"), joint("j1", "base", "l1"), joint("back", "l1", "base"))
    with pytest.raises(ModelError) as e:
        load(cycle)
    assert source in message_of(e) and "cycle" in message_of(e)
    duplicate = urdf(BASE, link("l1"), joint("j1", "base", "l1"), joint("j1", "base", "l1"))
    with pytest.raises(ModelError) as e:
        load(duplicate)
    assert source in message_of(e) and "'j1'" in message_of(e)
    dangling = urdf(BASE, link("l1"), joint("j1", "base", "ghost"))
    with pytest.raises(ModelError) as e:
        load(dangling)
    assert "'ghost'" in message_of(e)


def test_wrong_argument_types_to_loaders_are_type_errors():
    with pytest.raises(TypeError):
        Robot.from_urdf_string(chain3(), ee_link=5)
    with pytest.raises(TypeError):
        Robot.from_urdf(None)


# ---------------------------------------------------------------------------------------------
# Robot method arguments (SPEC §8)
# ---------------------------------------------------------------------------------------------

N = 3
GOOD = {
    "q": np.array([0.1, -0.2, 0.3]),
    "base_twist": np.array([0.01, 0.02, -0.03, 0.1, 0.0, -0.1]),
    "qd": np.array([0.2, 0.1, -0.1]),
    "tau": np.array([1.0, -1.0, 0.5]),
    "base_wrench": np.array([0.1, 0.0, 0.0, 1.0, 0.0, 0.0]),
    "ee_wrench": np.array([0.0, 0.1, 0.0, 0.0, 1.0, 0.0]),
    "base_acc": np.array([0.0, 0.1, 0.0, 0.2, 0.0, 0.0]),
    "qdd": np.array([0.3, 0.2, 0.1]),
    "base_pose": np.array([1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0]),
}
SIGNATURES = {
    "mass_matrix": ["q"],
    "ee_jacobian": ["q"],
    "ee_base_operator": ["q"],
    "bias_forces": ["q", "base_twist", "qd"],
    "forward_dynamics": ["q", "base_twist", "qd", "tau", "base_wrench", "ee_wrench"],
    "inverse_dynamics": ["q", "base_twist", "qd", "base_acc", "qdd", "ee_wrench"],
    "operators": ["q", "base_twist", "qd"],
    "momentum": ["base_pose", "q", "base_twist", "qd"],
    "kinetic_energy": ["q", "base_twist", "qd"],
}
CASES = [(method, arg) for method, args in SIGNATURES.items() for arg in args]
IDS = [f"{m}-{a}" for m, a in CASES]


def call(robot, fn, **override):
    kwargs = {name: GOOD[name] for name in SIGNATURES[fn]}
    kwargs.update(override)
    return getattr(robot, fn)(**kwargs)


@pytest.mark.parametrize("method", list(SIGNATURES))
def test_good_arguments_work(robot, method):
    call(robot, method)


@pytest.mark.parametrize("method,arg", CASES, ids=IDS)
@pytest.mark.parametrize("delta", [-1, +2])
def test_wrong_length_says_expected_and_given(robot, method, arg, delta):
    good = GOOD[arg]
    bad = np.zeros(len(good) + delta)
    with pytest.raises(ModelError) as e:
        call(robot, method, **{arg: bad})
    msg = message_of(e)
    assert msg.startswith(arg + ":") or f"{arg}:" in msg
    assert f"expected length {len(good)}, given length {len(bad)}" in msg


@pytest.mark.parametrize("method,arg", CASES, ids=IDS)
@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf], ids=["nan", "inf", "-inf"])
def test_non_finite_element_is_named(robot, method, arg, value):
    bad = GOOD[arg].copy()
    bad[1] = value
    with pytest.raises(ModelError) as e:
        call(robot, method, **{arg: bad})
    msg = message_of(e)
    assert f"{arg}:" in msg
    assert "element 1" in msg
    assert "not finite" in msg


@pytest.mark.parametrize("method,arg", CASES, ids=IDS)
def test_two_dimensional_array_rejected(robot, method, arg):
    bad = GOOD[arg][None, :]
    with pytest.raises(ModelError) as e:
        call(robot, method, **{arg: bad})
    msg = message_of(e)
    assert f"{arg}:" in msg
    assert "1-D" in msg
    assert str(len(GOOD[arg])) in msg


@pytest.mark.parametrize("method,arg", CASES, ids=IDS)
def test_string_where_numbers_expected(robot, method, arg):
    with pytest.raises(ModelError) as e:
        call(robot, method, **{arg: "not numbers"})
    msg = message_of(e)
    assert f"{arg}:" in msg
    assert "numbers" in msg


def test_lists_and_integer_arrays_are_accepted(robot):
    a = robot.mass_matrix([0, 0, 0])
    b = robot.mass_matrix(np.zeros(3, dtype=np.int64))
    c = robot.mass_matrix(np.zeros(6)[::2])  # non-contiguous
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, c)


def test_zero_quaternion_in_base_pose(robot):
    pose = GOOD["base_pose"].copy()
    pose[3:] = 0.0
    with pytest.raises(ModelError) as e:
        robot.momentum(pose, GOOD["q"], GOOD["base_twist"], GOOD["qd"])
    assert "base_pose" in message_of(e) and "quaternion" in message_of(e)


@pytest.mark.parametrize(
    "method", ["mass_matrix", "bias_forces", "forward_dynamics", "inverse_dynamics"]
)
@pytest.mark.parametrize("name", ["bogus", "Operator", "aba", ""])
def test_invalid_method_name(robot, method, name):
    with pytest.raises(ModelError) as e:
        call(robot, method, method=name)
    msg = message_of(e)
    assert "method" in msg
    assert "recursive" in msg and "operator" in msg
    assert repr(name).strip("'") in msg


def test_invalid_method_name_for_flexible_arm(robot):
    with pytest.raises(ModelError) as e:
        FlexibleArm(robot, FlexibleJoints(1.0, 1.0), method="fast")
    assert "method" in message_of(e) and "fast" in message_of(e)


# ---------------------------------------------------------------------------------------------
# FlexibleJoints (SPEC §3)
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs,name,index",
    [
        (dict(stiffness=0.0, motor_inertia=1.0), "stiffness", 0),
        (dict(stiffness=-5.0, motor_inertia=1.0), "stiffness", 0),
        (dict(stiffness=[1.0, 2.0, 0.0], motor_inertia=1.0), "stiffness", 2),
        (dict(stiffness=1.0, motor_inertia=0.0), "motor_inertia", 0),
        (dict(stiffness=1.0, motor_inertia=[1.0, -1.0, 1.0]), "motor_inertia", 1),
        (dict(stiffness=1.0, motor_inertia=1.0, damping=-0.1), "damping", 0),
        (dict(stiffness=1.0, motor_inertia=1.0, damping=[0.0, 0.0, -1.0]), "damping", 2),
        (dict(stiffness=1.0, motor_inertia=1.0, motor_damping=-1e-3), "motor_damping", 0),
    ],
)
def test_flexible_joints_domain(kwargs, name, index):
    with pytest.raises(ModelError) as e:
        FlexibleJoints(**kwargs)
    msg = message_of(e)
    assert f"{name}[{index}]" in msg
    assert ">" in msg  # says what is expected (> 0 or >= 0)


def test_flexible_joints_zero_damping_is_fine():
    FlexibleJoints(1.0, 1.0, damping=0.0, motor_damping=0.0)


@pytest.mark.parametrize("name", ["stiffness", "motor_inertia", "damping", "motor_damping"])
@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_flexible_joints_non_finite(name, value):
    kwargs = dict(stiffness=[1.0, 1.0], motor_inertia=[1.0, 1.0], damping=0.0, motor_damping=0.0)
    kwargs[name] = [1.0, value]
    with pytest.raises(ModelError) as e:
        FlexibleJoints(**kwargs)
    assert name in message_of(e) and "element 1" in message_of(e)
    kwargs[name] = value
    with pytest.raises(ModelError) as e:
        FlexibleJoints(**kwargs)
    assert name in message_of(e) and "not finite" in message_of(e)


@pytest.mark.parametrize("name", ["motor_inertia", "damping", "motor_damping"])
def test_flexible_joints_mismatched_lengths(name):
    kwargs = dict(stiffness=[1.0, 2.0, 3.0], motor_inertia=1.0)
    kwargs[name] = [1.0, 1.0]
    with pytest.raises(ModelError) as e:
        FlexibleJoints(**kwargs)
    msg = message_of(e)
    assert name in msg and "expected length 3" in msg and "given length 2" in msg


def test_flexible_joints_bad_types():
    with pytest.raises(ModelError) as e:
        FlexibleJoints("stiff", 1.0)
    assert "stiffness" in message_of(e)
    with pytest.raises(ModelError) as e:
        FlexibleJoints(np.ones((2, 3)), 1.0)
    assert "stiffness" in message_of(e) and "1-D" in message_of(e)


def test_flexible_arm_joint_count_must_match_robot(robot):
    joints = FlexibleJoints([100.0, 100.0], 0.05)
    with pytest.raises(ModelError) as e:
        FlexibleArm(robot, joints)
    msg = message_of(e)
    assert "stiffness" in msg
    assert "3" in msg and "2" in msg
    with pytest.raises(TypeError):
        FlexibleArm(robot, "joints")


@pytest.mark.parametrize(
    "args,name",
    [
        ((100.0, 0.0, 1e-5), "gear_ratio"),
        ((100.0, -160.0, 1e-5), "gear_ratio"),
        ((100.0, 160.0, 0.0), "rotor_inertia"),
        ((100.0, 160.0, [1e-5, -1e-5]), "rotor_inertia"),
        ((100.0, np.nan, 1e-5), "gear_ratio"),
        ((100.0, [160.0, 160.0], [1e-5] * 3), "rotor_inertia"),
    ],
)
def test_from_gear_errors(args, name):
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_gear(*args)
    assert name in message_of(e)


# ---- from_toml -------------------------------------------------------------------------------


def write(tmp_path, text, name="joints.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def test_from_toml_missing_file(tmp_path, robot):
    path = tmp_path / "absent.toml"
    with pytest.raises(FileNotFoundError) as e:
        FlexibleJoints.from_toml(str(path), robot)
    assert str(path) in message_of(e)


def test_from_toml_malformed(tmp_path, robot):
    path = write(tmp_path, "[defaults\nstiffness = 1\n")
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_toml(str(path), robot)
    msg = message_of(e)
    assert str(path) in msg
    assert "line 1" in msg


def test_from_toml_wrong_value_type(tmp_path, robot):
    path = write(tmp_path, '[defaults]\nstiffness = "stiff"\nmotor_inertia = 1.0\n')
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_toml(str(path), robot)
    assert str(path) in message_of(e) and "line 2" in message_of(e)


def test_from_toml_unknown_joint(tmp_path, robot):
    path = write(tmp_path, """
        [defaults]
        stiffness = 100.0
        motor_inertia = 0.05
        [joints.elbow]
        stiffness = 200.0
        """)
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_toml(str(path), robot)
    msg = message_of(e)
    assert str(path) in msg and "elbow" in msg
    for name in ["j1", "j2", "j3"]:
        assert name in msg


@pytest.mark.parametrize("missing", ["stiffness", "motor_inertia"])
def test_from_toml_missing_parameter_names_joint(tmp_path, robot, missing):
    values = {"stiffness": 100.0, "motor_inertia": 0.05}
    del values[missing]
    body = "\n".join(f"{k} = {v}" for k, v in values.items())
    path = write(tmp_path, f"[defaults]\n{body}\n[joints.j2]\n{missing} = 1.0\n")
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_toml(str(path), robot)
    msg = message_of(e)
    assert str(path) in msg and missing in msg
    assert "'j1'" in msg  # j1 has neither its own value nor a default


@pytest.mark.parametrize(
    "text,key",
    [
        ("[defaults]\nstiffness = 1.0\nmotor_inertia = 1.0\nstifness = 3.0\n", "stifness"),
        ("[defaults]\nstiffness = 1.0\nmotor_inertia = 1.0\n[joints.j2]\nmass = 3.0\n", "mass"),
        ("stiffness = 1.0\nmotor_inertia = 1.0\n", "stiffness"),
        ("[defaults]\nstiffness = 1.0\nmotor_inertia = 1.0\n[extra]\nx = 1\n", "extra"),
    ],
    ids=["typo-in-defaults", "typo-in-joint", "top-level-key", "unknown-table"],
)
def test_from_toml_unknown_key(tmp_path, robot, text, key):
    path = write(tmp_path, text)
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_toml(str(path), robot)
    msg = message_of(e)
    assert str(path) in msg and key in msg


def test_from_toml_both_inertia_forms_in_joint_table(tmp_path, robot):
    path = write(tmp_path, """
        [defaults]
        stiffness = 100.0
        motor_inertia = 0.05
        [joints.j3]
        motor_inertia = 0.1
        gear_ratio = 100.0
        rotor_inertia = 1e-5
        """)
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_toml(str(path), robot)
    msg = message_of(e)
    assert "'j3'" in msg and "either" in msg


def test_from_toml_both_inertia_forms_in_defaults(tmp_path, robot):
    # Same conflict as above, in [defaults]: the message must explain the conflict, as the
    # per-joint message does, not claim that motor_inertia is missing.
    path = write(tmp_path, """
        [defaults]
        stiffness = 100.0
        motor_inertia = 0.05
        gear_ratio = 100.0
        """)
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_toml(str(path), robot)
    msg = message_of(e)
    assert str(path) in msg
    assert "either" in msg, msg


def test_from_toml_out_of_domain_value_names_the_joint(tmp_path, robot):
    # The file is keyed by joint name, so the error must say which joint, not an index.
    path = write(tmp_path, """
        [defaults]
        stiffness = 100.0
        motor_inertia = 0.05
        [joints.j3]
        stiffness = -5.0
        """)
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_toml(str(path), robot)
    msg = message_of(e)
    assert str(path) in msg and "stiffness" in msg
    assert "j3" in msg, msg


@pytest.mark.parametrize("gear_ratio", [0.0, -160.0])
def test_from_toml_rejects_non_positive_gear_ratio_like_from_gear(tmp_path, robot, gear_ratio):
    with pytest.raises(ModelError):
        FlexibleJoints.from_gear(100.0, gear_ratio, 1e-5)
    path = write(tmp_path, f"""
        [defaults]
        stiffness = 100.0
        gear_ratio = {gear_ratio}
        rotor_inertia = 1e-5
        """)
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_toml(str(path), robot)
    assert "gear_ratio" in message_of(e)


def test_from_toml_string_names_its_source(robot):
    with pytest.raises(ModelError) as e:
        FlexibleJoints.from_toml_string("[defaults]\nstiffness = 1.0\n", robot)
    assert "<toml string>" in message_of(e)


# ---------------------------------------------------------------------------------------------
# MotorPD
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "args,kwargs,words",
    [
        (([1.0, 2.0], 1.0, np.zeros(3)), {}, ["kp", "expected length 3", "given length 2"]),
        ((1.0, [1.0] * 4, np.zeros(3)), {}, ["kd", "expected length 3", "given length 4"]),
        ((-1.0, 1.0, np.zeros(3)), {}, ["kp[0]", ">= 0"]),
        ((1.0, [1.0, -1.0, 1.0], np.zeros(3)), {}, ["kd[1]", ">= 0"]),
        ((np.nan, 1.0, np.zeros(3)), {}, ["kp", "not finite"]),
        ((1.0, 1.0, np.zeros((2, 2, 3))), {}, ["theta_ref", "[2, 2, 3]"]),
        ((1.0, 1.0, 0.0), {}, ["theta_ref"]),
        ((1.0, 1.0, [0.0, np.nan, 0.0]), {}, ["theta_ref", "element 1"]),
        ((1.0, 1.0, "zero"), {}, ["theta_ref", "numbers"]),
        ((1.0, 1.0, np.zeros(3)), {"theta_dot_ref": np.zeros(2)}, ["theta_dot_ref", "length 3"]),
        ((1.0, 1.0, np.zeros(3)), {"theta_dot_ref": np.zeros((5, 2))}, ["theta_dot_ref", "(5, 2)"]),
        ((1.0, 1.0, np.zeros(3)), {"feedforward": np.zeros((5, 4))}, ["feedforward", "(5, 4)"]),
    ],
)
def test_motor_pd_errors(args, kwargs, words):
    with pytest.raises(ModelError) as e:
        MotorPD(*args, **kwargs)
    msg = message_of(e)
    for word in words:
        assert word in msg, msg


# ---------------------------------------------------------------------------------------------
# FlexibleArm.state / derivative / step
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "name,length", [("q", 3), ("theta", 3), ("qd", 3), ("theta_dot", 3),
                    ("base_pose", 7), ("base_twist", 6)]
)
def test_state_argument_errors(arm, name, length):
    with pytest.raises(ModelError) as e:
        arm.state(**{name: np.zeros(length + 1)})
    assert f"{name}:" in message_of(e)
    assert f"expected length {length}, given length {length + 1}" in message_of(e)
    bad = np.ones(length)
    bad[-1] = np.nan
    with pytest.raises(ModelError) as e:
        arm.state(**{name: bad})
    assert f"{name}:" in message_of(e) and f"element {length - 1}" in message_of(e)
    with pytest.raises(ModelError) as e:
        arm.state(**{name: np.ones((1, length))})
    assert f"{name}:" in message_of(e) and "1-D" in message_of(e)


def test_state_zero_quaternion(arm):
    with pytest.raises(ModelError) as e:
        arm.state(base_pose=np.zeros(7))
    assert "base_pose" in message_of(e) and "quaternion" in message_of(e)


@pytest.mark.parametrize("fn", ["derivative", "step"])
def test_derivative_and_step_argument_errors(arm, fn):
    x = arm.state(q=[0.1, 0.2, 0.3])
    extra = (1e-3,) if fn == "step" else ()
    f = getattr(arm, fn)
    with pytest.raises(ModelError) as e:
        f(x[:-1], *extra)
    assert "x" in message_of(e) and "expected length 25, given length 24" in message_of(e)
    bad = x.copy()
    bad[20] = np.nan
    with pytest.raises(ModelError) as e:
        f(bad, *extra)
    assert "element 20" in message_of(e)
    for kw, length in [("u", 3), ("base_wrench", 6), ("ee_wrench", 6)]:
        with pytest.raises(ModelError) as e:
            f(x, *extra, **{kw: np.zeros(length + 2)})
        assert f"{kw}:" in message_of(e)
        assert f"expected length {length}, given length {length + 2}" in message_of(e)
        bad = np.zeros(length)
        bad[0] = np.inf
        with pytest.raises(ModelError) as e:
            f(x, *extra, **{kw: bad})
        assert f"{kw}:" in message_of(e) and "element 0" in message_of(e)
    with pytest.raises(ModelError):
        f(np.tile(x, (2, 1)), *extra)


@pytest.mark.parametrize("fn", ["derivative", "step", "energy", "momentum", "ee_pose"])
def test_zero_quaternion_in_state_is_an_error(arm, fn):
    # A state whose quaternion is zero has no attitude: every function taking x must refuse it
    # rather than return NaN.
    x = arm.state(q=[0.1, 0.2, 0.3], base_twist=[0, 0, 0, 1.0, 0, 0])
    x[3:7] = 0.0
    extra = (1e-3,) if fn == "step" else ()
    with pytest.raises(ModelError) as e:
        getattr(arm, fn)(x, *extra)
    assert "quaternion" in message_of(e)


@pytest.mark.parametrize("dt", [0.0, -1e-3, np.nan, np.inf])
def test_step_bad_dt(arm, dt):
    with pytest.raises(ModelError) as e:
        arm.step(arm.state(), dt)
    assert "dt" in message_of(e)


# ---------------------------------------------------------------------------------------------
# simulate (SPEC §5)
# ---------------------------------------------------------------------------------------------


@pytest.mark.parametrize("dt", [0.0, -1e-3, np.nan, np.inf])
def test_simulate_bad_dt(arm, dt):
    with pytest.raises(ModelError) as e:
        arm.simulate(arm.state(), dt, 10)
    assert "dt" in message_of(e)


@pytest.mark.parametrize("steps", [-1, 2.5, True, "10", None])
def test_simulate_bad_steps(arm, steps):
    with pytest.raises(ModelError) as e:
        arm.simulate(arm.state(), 1e-3, steps)
    assert "steps" in message_of(e)


def test_simulate_wrong_x0(arm):
    x0 = arm.state()
    with pytest.raises(ModelError) as e:
        arm.simulate(x0[:-1], 1e-3, 5)
    assert "x0" in message_of(e) and "25" in message_of(e) and "24" in message_of(e)
    bad = x0.copy()
    bad[20] = np.nan
    with pytest.raises(ModelError) as e:
        arm.simulate(bad, 1e-3, 5)
    assert "x0" in message_of(e) and "element 20" in message_of(e)


def test_simulate_non_finite_angle_in_x0_names_x0(arm):
    # The user passed x0, not q: the message should say which element of x0 is bad.
    bad = arm.state()
    bad[8] = np.nan  # q[1]
    with pytest.raises(ModelError) as e:
        arm.simulate(bad, 1e-3, 5)
    assert "x0" in message_of(e), message_of(e)


@pytest.mark.parametrize(
    "kw,value,words",
    [
        ("u", np.zeros((9, 3)), ["u", "(10, 3)", "(9, 3)"]),
        ("u", np.zeros((10, 2)), ["u", "(10, 2)"]),
        ("u", np.zeros(2), ["u", "expected length 3", "given length 2"]),
        ("u", np.zeros((10, 3, 1)), ["u", "3-D"]),
        ("u", "torque", ["u", "numbers"]),
        ("u", np.full(3, np.nan), ["u", "not finite"]),
        ("base_wrench", np.zeros((9, 6)), ["base_wrench", "(10, 6)", "(9, 6)"]),
        ("base_wrench", np.zeros((11, 6)), ["base_wrench", "(10, 6)", "(11, 6)"]),
        ("base_wrench", np.zeros((10, 5)), ["base_wrench", "(10, 5)"]),
        ("base_wrench", np.zeros(5), ["base_wrench", "expected length 6"]),
        ("ee_wrench", np.zeros((11, 6)), ["ee_wrench", "(10, 6)", "(11, 6)"]),
        ("ee_wrench", np.zeros(7), ["ee_wrench", "expected length 6"]),
    ],
)
def test_simulate_input_shapes(arm, kw, value, words):
    with pytest.raises(ModelError) as e:
        arm.simulate(arm.state(), 1e-3, 10, **{kw: value})
    msg = message_of(e)
    for word in words:
        assert word in msg, msg


def test_simulate_motor_pd_with_wrong_dof(arm):
    pd = MotorPD(1.0, 1.0, np.zeros(2))
    with pytest.raises(ModelError) as e:
        arm.simulate(arm.state(), 1e-3, 10, u=pd)
    msg = message_of(e)
    assert "MotorPD" in msg and "2" in msg and "3" in msg


def test_simulate_motor_pd_table_too_short(arm):
    pd = MotorPD(1.0, 1.0, np.zeros((5, 3)))
    with pytest.raises(ModelError) as e:
        arm.simulate(arm.state(), 1e-3, 10, u=pd)
    assert "theta_ref" in message_of(e) and "10" in message_of(e) and "5" in message_of(e)


# ---- the controller fails ---------------------------------------------------------------------


def test_controller_exception_becomes_simulation_error_with_cause(arm):
    dt = 1e-3
    x0 = arm.state(q=[0.1, 0.2, 0.3], theta=[0.15, 0.2, 0.3])
    original = KeyError("lost the reference")
    calls = []

    def controller(t, x):
        calls.append(t)
        if len(calls) == 5:
            raise original
        return np.array([0.1, -0.1, 0.2])

    with pytest.raises(SimulationError) as e:
        arm.simulate(x0, dt, 20, u=controller)
    err = e.value
    assert err.__cause__ is original
    assert "lost the reference" in str(err)
    assert err.step == 4
    assert err.time == pytest.approx(4 * dt)
    assert "step 4" in str(err)
    traj = err.trajectory
    assert isinstance(traj, orbitflex.Trajectory)
    assert traj.x.shape == (5, arm.state_size)
    np.testing.assert_allclose(traj.t, np.arange(5) * dt)
    assert np.isfinite(traj.x).all()
    # The kept states are the ones a clean run of 4 steps computes.
    clean = arm.simulate(x0, dt, 4, u=np.array([0.1, -0.1, 0.2]))
    np.testing.assert_array_equal(traj.x, clean.x)


@pytest.mark.parametrize(
    "returned,words",
    [
        (np.full(3, np.nan), ["not finite"]),
        (np.array([0.0, np.inf, 0.0]), ["element 1", "not finite"]),
        (np.zeros(2), ["expected length 3", "given length 2"]),
        (np.zeros(4), ["expected length 3", "given length 4"]),
        (np.zeros((1, 3)), ["1-D"]),
        (None, []),
        ("torque", ["numbers"]),
    ],
    ids=["nan", "inf", "short", "long", "2d", "none", "str"],
)
def test_controller_bad_output_is_simulation_error(arm, returned, words):
    with pytest.raises(SimulationError) as e:
        arm.simulate(arm.state(), 1e-3, 10, u=lambda t, x: returned)
    msg = str(e.value)
    assert "step 0" in msg and "controller" in msg
    for word in words:
        assert word in msg, msg
    assert e.value.step == 0
    assert e.value.trajectory.x.shape == (1, arm.state_size)


def test_controller_with_wrong_signature(arm):
    with pytest.raises(SimulationError) as e:
        arm.simulate(arm.state(), 1e-3, 10, u=lambda: np.zeros(3))
    assert isinstance(e.value.__cause__, TypeError)


def test_keyboard_interrupt_in_controller_is_not_swallowed(arm):
    # Ctrl-C during a run with a Python controller must stop the program, not turn into a
    # SimulationError (a RuntimeError that ``except SimulationError`` would catch and carry on).
    def controller(t, x):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        arm.simulate(arm.state(), 1e-3, 10, u=controller)


# ---- divergence ---------------------------------------------------------------------------------


def diverging_arm():
    robot = Robot.from_urdf_string(chain3())
    arm = FlexibleArm(robot, FlexibleJoints(100.0, 0.05))
    x0 = arm.state(q=[0.1, 0.2, 0.3], theta=[0.2, 0.3, 0.4])
    return arm, x0


@pytest.mark.parametrize("dt", [0.2, 1.0])
def test_huge_dt_warns_then_fails_keeping_finite_steps(dt):
    arm, x0 = diverging_arm()
    limit = arm.rk4_stability_limit(x0)
    assert dt > limit
    with pytest.warns(RuntimeWarning, match="stability limit") as record:
        with pytest.raises(SimulationError) as e:
            arm.simulate(x0, dt, 10_000)
    stated = re.search(r"stability limit ([0-9.e+-]+) s", str(record[0].message))
    assert stated and float(stated.group(1)) == pytest.approx(limit, rel=1e-4), record[0].message
    assert record[0].filename == __file__  # points at the caller
    err = e.value
    assert f"step {err.step}" in str(err)
    assert f"t = {err.time}" in str(err) or f"t = {err.time:g}" in str(err)
    assert err.time == pytest.approx(err.step * dt)
    traj = err.trajectory
    assert 1 <= len(traj.t) <= err.step + 1
    assert traj.x.shape == (len(traj.t), arm.state_size)
    assert np.isfinite(traj.x).all()
    np.testing.assert_allclose(traj.t, np.arange(len(traj.t)) * dt)
    # The kept states are exactly those of a run that stops before the failure.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        clean = arm.simulate(x0, dt, len(traj.t) - 1)
    np.testing.assert_array_equal(traj.x, clean.x)


@pytest.mark.parametrize("dt", [0.2, 1.0])
def test_divergence_message_points_at_dt(dt):
    # However the blow-up surfaces (a non-finite state, or a non-finite intermediate RK4 stage
    # inside the dynamics), the message must say the run diverged and point at dt.
    arm, x0 = diverging_arm()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with pytest.raises(SimulationError) as e:
            arm.simulate(x0, dt, 10_000)
    msg = str(e.value)
    assert "diverged" in msg, msg
    assert f"dt = {dt:g} s" in msg or f"dt = {dt} s" in msg, msg


def test_simulation_error_step_convention_is_consistent():
    # e.step must relate to the kept trajectory the same way whatever stopped the run.
    arm, x0 = diverging_arm()
    offsets = {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        for dt in (0.2, 1.0):
            with pytest.raises(SimulationError) as e:
                arm.simulate(x0, dt, 10_000)
            offsets[f"diverged dt={dt}"] = e.value.step - (len(e.value.trajectory.t) - 1)

    def controller(t, x):
        if t > 0.0025:
            raise ValueError("stop")
        return np.zeros(3)

    with pytest.raises(SimulationError) as e:
        arm.simulate(x0, 1e-3, 10, u=controller)
    offsets["controller"] = e.value.step - (len(e.value.trajectory.t) - 1)
    assert len(set(offsets.values())) == 1, offsets


@pytest.mark.parametrize("dt,deflection", [(0.1, 1.0), (0.3, 0.01), (0.2, 0.1)])
def test_kept_states_of_a_diverged_run_are_valid_states(dt, deflection):
    # "Finite" is not enough: when the quaternion overflows, renormalising it by an infinite
    # norm gives a zero quaternion, a state every other function rejects (and on which
    # ee_pose never returns). The kept part must be usable: unit quaternions throughout.
    robot = Robot.from_urdf_string(chain3())
    arm = FlexibleArm(robot, FlexibleJoints(100.0, 0.05))
    x0 = arm.state(theta=np.full(3, deflection))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        with pytest.raises(SimulationError) as e:
            arm.simulate(x0, dt, 10_000)
    traj = e.value.trajectory
    assert np.isfinite(traj.x).all()
    norms = np.linalg.norm(traj.base_pose[:, 3:], axis=1)
    np.testing.assert_allclose(norms, 1.0, atol=1e-9, err_msg=f"quaternion norms {norms}")


def test_trajectory_from_user_rows_rejects_a_zero_quaternion(arm):
    # A Trajectory built from user data (e.g. a loaded file) with a zero quaternion is refused
    # when it is made, so that its diagnostics (momentum, energy, EE pose) never see NaN.
    x = np.tile(arm.state(q=[0.1, 0.2, 0.3]), (3, 1))
    x[1, 3:7] = 0.0
    with pytest.raises(ModelError) as e:
        orbitflex.Trajectory(arm, np.arange(3) * 1e-3, x, np.zeros((2, 3)))
    assert "quaternion" in message_of(e) and "x[1]" in message_of(e)


def test_trajectory_ee_pose_with_a_zero_quaternion_raises_instead_of_hanging():
    # ee_pose of such a state loops forever inside Rust with the GIL released, so not even
    # Ctrl-C stops it. Run it in a subprocess with a time limit.
    body = """
        x = np.tile(arm.state(q=[0.1, 0.2, 0.3]), (2, 1))
        x[1, 3:7] = 0.0
        try:
            traj = orbitflex.Trajectory(arm, np.arange(2) * 1e-3, x, np.zeros((1, 3)))
            traj.ee_pose
            print("returned")
        except ValueError as e:
            print("raised", e)
        """
    try:
        result = run_isolated(body, timeout=10.0)
    except subprocess.TimeoutExpired:
        pytest.fail("Trajectory.ee_pose did not return within 10 s (infinite loop)")
    assert result.returncode == 0, result.stderr[-500:]
    assert "raised" in result.stdout, result.stdout


def test_dt_within_limit_does_not_warn(arm):
    x0 = arm.state(q=[0.1, 0.2, 0.3])
    dt = 0.5 * arm.rk4_stability_limit(x0)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        arm.simulate(x0, dt, 3)


# ---- never crash the interpreter ----------------------------------------------------------------


def run_isolated(body: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    script = textwrap.dedent(
        """
        import numpy as np, orbitflex
        robot = orbitflex.Robot.from_urdf_string({xml!r})
        arm = orbitflex.FlexibleArm(robot, orbitflex.FlexibleJoints(100.0, 0.05))
        """
    ).format(xml=chain3()) + textwrap.dedent(body)
    env = dict(os.environ, RUST_BACKTRACE="0")
    return subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                          timeout=timeout, env=env)


@pytest.mark.parametrize("steps", ["10**12", "2**60"])
def test_absurd_step_count_raises_instead_of_aborting(steps):
    # The simulator must not pre-allocate (steps+1) states blindly: an impossible request is a
    # Python exception (MemoryError or ModelError), not an abort of the interpreter or a Rust
    # panic (pyo3 PanicException, a BaseException).
    result = run_isolated(f"""
        try:
            arm.simulate(arm.state(), 1e-3, {steps})
        except (MemoryError, ValueError) as e:
            print("raised", type(e).__name__)
        except BaseException as e:
            print("wrong exception", type(e).__module__, type(e).__name__)
        """)
    assert result.returncode == 0, f"exit code {result.returncode}: {result.stderr[-500:]}"
    assert "raised" in result.stdout, result.stdout + result.stderr[-500:]
