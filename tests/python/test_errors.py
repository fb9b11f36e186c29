"""Every error orbitflex must report (docs/model.md §3–§5, §7), with a clear message.

Most cases are rows of a table: the smallest call that triggers one error, the exception it must
raise, and the words its message must contain: the file (a path, ``<urdf string>`` or
``<toml string>``), the element (joint, link, argument) and, for sizes, the expected and the
given length. A few parametrized tests run the tables. After them come the tests that check more
than one message (a model that loads once the error is fixed, the cause, step and trajectory of a
SimulationError, a warning) and the regressions, each under its own name. Nothing here may crash
the interpreter; the cases that could abort the process run in a subprocess.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
import warnings
from functools import partial
from operator import methodcaller

import numpy as np
import pytest

import orbitflex
from orbitflex import FlexibleArm, FlexibleJoints, ModelError, MotorPD, Robot, SimulationError

# =============================================================================================
# Helpers
# =============================================================================================

# ---- small URDFs written inline ---------------------------------------------------------------


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
MASSLESS = dict(mass=0.0, ixx=0.0, iyy=0.0, izz=0.0)


def chain3():
    """base -> j1 (z) -> l1 -> j2 (y) -> l2 -> j3 (z) -> l3: a healthy 3-joint chain."""
    return urdf(
        BASE, link("l1"), link("l2"), link("l3"),
        joint("j1", "base", "l1"), joint("j2", "l1", "l2", axis="0 1 0"), joint("j3", "l2", "l3"),
    )


def one_joint(kind="revolute", **link_kw):
    return urdf(BASE, link("l1", **link_kw), joint("j1", "base", "l1", kind=kind))


def write(tmp_path, text, name="joints.toml"):
    path = tmp_path / name
    path.write_text(textwrap.dedent(text))
    return path


def with_element(array, index, value):
    """A copy of ``array`` with ``array[index] = value``."""
    bad = array.copy()
    bad[index] = value
    return bad


# ---- fixtures --------------------------------------------------------------------------------


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


@pytest.fixture(scope="module")
def robot():
    return Robot.from_urdf_string(chain3())


@pytest.fixture(scope="module")
def arm(robot):
    return FlexibleArm(robot, FlexibleJoints(100.0, 0.05, damping=0.1, motor_damping=0.1))


def diverging_arm():
    robot = Robot.from_urdf_string(chain3())
    arm = FlexibleArm(robot, FlexibleJoints(100.0, 0.05))
    x0 = arm.state(q=[0.1, 0.2, 0.3], theta=[0.2, 0.3, 0.4])
    return arm, x0


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


# ---- the check every table row makes ------------------------------------------------------------


def raised(exc, call) -> str:
    """The message of the ``exc`` that ``call()`` must raise."""
    with pytest.raises(exc) as e:
        call()
    return str(e.value)


def assert_mentions(msg, words):
    """Every word (a substring, or a compiled regular expression) is in ``msg``."""
    for word in words:
        found = word.search(msg) if isinstance(word, re.Pattern) else word in msg
        assert found, f"{word!r} is not in the message {msg!r}"


def case(id, call, words=(), exc=ModelError):
    """A table row: ``call`` (given the test's fixture, if any) raises ``exc``, naming ``words``."""
    return pytest.param(call, exc, list(words), id=id)


# =============================================================================================
# Tables: what is called, the exception, the words of the message
# =============================================================================================

# ---- URDF loading (model §7) ------------------------------------------------------------------
# Each row is loaded from a file and from a string; the message must also name that source.


def urdf_case(id, xml, words=(), **load_kwargs):
    return pytest.param(xml, load_kwargs, list(words), id=id)


MALFORMED = re.compile("malformed", re.IGNORECASE)

URDF_ERRORS = [
    urdf_case("malformed-nesting", '<robot name="x"><link name="a"></robot>', [MALFORMED]),
    urdf_case("malformed-truncated", "<robot name='x'><link name='a'>", [MALFORMED]),
    urdf_case("malformed-text", "this is not xml", [MALFORMED]),
    urdf_case("malformed-empty", "", [MALFORMED]),
    urdf_case("malformed-number",
              one_joint().replace('<mass value="1.0"/>', '<mass value="heavy"/>')),
    # The hint (locked_joints) says how to keep the model.
    *[urdf_case(f"unsupported-{kind}-joint",
                urdf(BASE, link("l1"), link("l2"), joint("j1", "base", "l1"),
                     joint("slider", "l1", "l2", kind=kind)),
                ["'slider'", kind, "locked_joints"])
      for kind in ["prismatic", "planar", "floating"]],
    urdf_case("unknown-ee_links-entry-lists-links",
              urdf(BASE, link("l1"), link("tip_a"), link("tip_b"), joint("j1", "base", "l1"),
                   joint("ja", "l1", "tip_a"), joint("jb", "l1", "tip_b")),
              ["'tip_c'", "ee_links", "tip_a", "tip_b"], ee_links=["tip_a", "tip_c"]),
    urdf_case("unknown-ee_link-lists-links", chain3(), ["gripper", "base", "l1", "l2", "l3"],
              ee_link="gripper"),
    urdf_case("unknown-locked-joint-lists-joints", chain3(), ["finger", "j1", "j2", "j3"],
              locked_joints=["finger"]),
    urdf_case("negative-mass", one_joint(mass=-2.0), ["'l1'", "mass"]),
    urdf_case("inertia-not-positive-definite", one_joint(ixx=-0.1),
              ["'l1'", "positive definite"]),
    urdf_case("inertia-violates-triangle", one_joint(ixx=1.0, iyy=1.0, izz=3.0),
              ["'l1'", "triangle"]),
    urdf_case("non-finite-mass", one_joint(mass=float("nan")), ["'l1'"]),
    urdf_case("massless-last-link-singular",
              urdf(BASE, link("l1"), link("l2", **MASSLESS),
                   joint("j1", "base", "l1"), joint("j2", "l1", "l2")),
              ["'j2'", "singular"]),
    # Mass but no inertia about the joint axis: the last joint moves nothing.
    urdf_case("point-mass-on-the-axis-singular",
              urdf(BASE, link("l1"), link("l2", mass=1.0, ixx=0.0, iyy=0.0, izz=0.0, com="0 0 0"),
                   joint("j1", "base", "l1"), joint("j2", "l1", "l2")),
              ["'j2'"]),
    urdf_case("massless-base-tree-singular", urdf(link("base", **MASSLESS)), ["base"]),
    *[urdf_case(f"axis-{id}", urdf(BASE, link("l1"), joint("j1", "base", "l1", axis=axis)),
                ["'j1'", "axis"])
      for id, axis in [("zero", "0 0 0"), ("nan", "nan 0 1")]],
    urdf_case("non-finite-joint-origin",
              urdf(BASE, link("l1"), joint("j1", "base", "l1", xyz="nan 0 0")), ["'j1'"]),
    urdf_case("cycle",
              urdf(BASE, link("l1"), joint("j1", "base", "l1"), joint("back", "l1", "base")),
              ["cycle"]),
    urdf_case("duplicate-joint-name",
              urdf(BASE, link("l1"), joint("j1", "base", "l1"), joint("j1", "base", "l1")),
              ["'j1'"]),
    urdf_case("dangling-child-link", urdf(BASE, link("l1"), joint("j1", "base", "ghost")),
              ["'ghost'"]),
]

MISSING_FILES = [  # (file under tmp_path, how it is opened); FileNotFoundError naming the path
    pytest.param("does_not_exist/arm.urdf", lambda path, robot: Robot.from_urdf(str(path)),
                 id="urdf"),
    pytest.param("nope.urdf", lambda path, robot: Robot.from_urdf(path), id="urdf-pathlike"),
    pytest.param("absent.toml", lambda path, robot: FlexibleJoints.from_toml(str(path), robot),
                 id="toml"),
]

# ---- constructors that need no robot (model §3, §7) ---------------------------------------------

JOINTS_OF_2 = dict(stiffness=[1.0, 1.0], motor_inertia=[1.0, 1.0], damping=0.0, motor_damping=0.0)
MOTOR_PD_3 = (1.0, 1.0, np.zeros(3))  # kp, kd, theta_ref for 3 joints

ERRORS = [
    case("from_urdf_string-ee_link-int", partial(Robot.from_urdf_string, chain3(), ee_link=5),
         exc=TypeError),
    case("from_urdf-None", partial(Robot.from_urdf, None), exc=TypeError),
    # FlexibleJoints out of domain: the message names the element and says what is expected
    # (> 0 or >= 0).
    *[case(f"FlexibleJoints-{id}", partial(FlexibleJoints, **kwargs), [element, ">"])
      for id, kwargs, element in [
          ("stiffness-zero", dict(stiffness=0.0, motor_inertia=1.0), "stiffness[0]"),
          ("stiffness-negative", dict(stiffness=-5.0, motor_inertia=1.0), "stiffness[0]"),
          ("stiffness-2-zero", dict(stiffness=[1.0, 2.0, 0.0], motor_inertia=1.0), "stiffness[2]"),
          ("motor_inertia-zero", dict(stiffness=1.0, motor_inertia=0.0), "motor_inertia[0]"),
          ("motor_inertia-1-negative", dict(stiffness=1.0, motor_inertia=[1.0, -1.0, 1.0]),
           "motor_inertia[1]"),
          ("damping-negative", dict(stiffness=1.0, motor_inertia=1.0, damping=-0.1),
           "damping[0]"),
          ("damping-2-negative", dict(stiffness=1.0, motor_inertia=1.0, damping=[0.0, 0.0, -1.0]),
           "damping[2]"),
          ("motor_damping-negative", dict(stiffness=1.0, motor_inertia=1.0, motor_damping=-1e-3),
           "motor_damping[0]"),
      ]],
    *[case(f"FlexibleJoints-{name}-{form}-{value}",
           partial(FlexibleJoints, **{**JOINTS_OF_2, name: bad}), [name, word])
      for name in ["stiffness", "motor_inertia", "damping", "motor_damping"]
      for value in [np.nan, np.inf]
      for form, bad, word in [("list", [1.0, value], "element 1"),
                              ("scalar", value, "not finite")]],
    *[case(f"FlexibleJoints-{name}-length-2-of-3",
           partial(FlexibleJoints, **{"stiffness": [1.0, 2.0, 3.0], "motor_inertia": 1.0,
                                      name: [1.0, 1.0]}),
           [name, "expected length 3", "given length 2"])
      for name in ["motor_inertia", "damping", "motor_damping"]],
    case("FlexibleJoints-stiffness-str", partial(FlexibleJoints, "stiff", 1.0), ["stiffness"]),
    case("FlexibleJoints-stiffness-2d", partial(FlexibleJoints, np.ones((2, 3)), 1.0),
         ["stiffness", "1-D"]),
    # FlexibleJoints.from_gear
    *[case(f"from_gear-{id}", partial(FlexibleJoints.from_gear, *args), [name])
      for id, args, name in [
          ("gear_ratio-zero", (100.0, 0.0, 1e-5), "gear_ratio"),
          ("gear_ratio-negative", (100.0, -160.0, 1e-5), "gear_ratio"),
          ("rotor_inertia-zero", (100.0, 160.0, 0.0), "rotor_inertia"),
          ("rotor_inertia-negative", (100.0, 160.0, [1e-5, -1e-5]), "rotor_inertia"),
          ("gear_ratio-nan", (100.0, np.nan, 1e-5), "gear_ratio"),
          ("lengths-differ", (100.0, [160.0, 160.0], [1e-5] * 3), "rotor_inertia"),
      ]],
    # MotorPD
    *[case(f"MotorPD-{id}", partial(MotorPD, *args, **kwargs), words)
      for id, args, kwargs, words in [
          ("kp-short", ([1.0, 2.0], 1.0, np.zeros(3)), {},
           ["kp", "expected length 3", "given length 2"]),
          ("kd-long", (1.0, [1.0] * 4, np.zeros(3)), {},
           ["kd", "expected length 3", "given length 4"]),
          ("kp-negative", (-1.0, 1.0, np.zeros(3)), {}, ["kp[0]", ">= 0"]),
          ("kd-1-negative", (1.0, [1.0, -1.0, 1.0], np.zeros(3)), {}, ["kd[1]", ">= 0"]),
          ("kp-nan", (np.nan, 1.0, np.zeros(3)), {}, ["kp", "not finite"]),
          ("theta_ref-3d", (1.0, 1.0, np.zeros((2, 2, 3))), {}, ["theta_ref", "[2, 2, 3]"]),
          ("theta_ref-scalar", (1.0, 1.0, 0.0), {}, ["theta_ref"]),
          ("theta_ref-nan", (1.0, 1.0, [0.0, np.nan, 0.0]), {}, ["theta_ref", "element 1"]),
          ("theta_ref-str", (1.0, 1.0, "zero"), {}, ["theta_ref", "numbers"]),
          ("theta_dot_ref-short", MOTOR_PD_3, {"theta_dot_ref": np.zeros(2)},
           ["theta_dot_ref", "length 3"]),
          ("theta_dot_ref-5x2", MOTOR_PD_3, {"theta_dot_ref": np.zeros((5, 2))},
           ["theta_dot_ref", "(5, 2)"]),
          ("feedforward-5x4", MOTOR_PD_3, {"feedforward": np.zeros((5, 4))},
           ["feedforward", "(5, 4)"]),
      ]],
]

# ---- Robot method arguments (the public names) ----------------------------------------------------------

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


def robot_call(fn, **override):
    """``robot.<fn>(...)`` with the GOOD arguments of its signature but those in ``override``."""
    kwargs = {name: GOOD[name] for name in SIGNATURES[fn]}
    kwargs.update(override)
    return methodcaller(fn, **kwargs)


# Functions that take a leading batch axis: (1, n) is a batch of one row, (1, 1, n) is wrong.
BATCHED = {"mass_matrix", "bias_forces", "forward_dynamics", "inverse_dynamics"}


def bad_arrays(good, batched=False):
    """The ways to get an array argument wrong: (id, bad value, words besides its name)."""
    n = len(good)
    wrong_rank = (("3d", good[None, None, :], [f"expected shape ({n},) or (1, {n})", f"(1, 1, {n})"])
                  if batched else ("2d", good[None, :], ["1-D", str(n)]))
    return [
        ("short", np.zeros(n - 1), [f"expected length {n}, given length {n - 1}"]),
        ("long", np.zeros(n + 2), [f"expected length {n}, given length {n + 2}"]),
        ("nan", with_element(good, 1, np.nan), ["element 1", "not finite"]),
        ("inf", with_element(good, 1, np.inf), ["element 1", "not finite"]),
        ("-inf", with_element(good, 1, -np.inf), ["element 1", "not finite"]),
        wrong_rank,
        ("str", "not numbers", ["numbers"]),
    ]


ROBOT_ERRORS = [
    # Every array argument of every method, wrong in every way: the message starts "<arg>:".
    *[case(f"{fn}-{arg}-{id}", robot_call(fn, **{arg: bad}), [f"{arg}:", *words])
      for fn, args in SIGNATURES.items() for arg in args
      for id, bad, words in bad_arrays(GOOD[arg], fn in BATCHED)],
    case("momentum-zero-quaternion",
         lambda robot: robot.momentum(np.array([1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 0.0]), GOOD["q"],
                                      GOOD["base_twist"], GOOD["qd"]),
         ["base_pose", "quaternion"]),
    *[case(f"{fn}-method-{name or 'empty'}", robot_call(fn, method=name),
           ["method", "recursive", "operator", name])
      for fn in ["mass_matrix", "bias_forces", "forward_dynamics", "inverse_dynamics"]
      for name in ["bogus", "Operator", "aba", ""]],
    case("FlexibleArm-method-fast",
         lambda robot: FlexibleArm(robot, FlexibleJoints(1.0, 1.0), method="fast"),
         ["method", "fast"]),
    case("FlexibleArm-2-joints-for-3",
         lambda robot: FlexibleArm(robot, FlexibleJoints([100.0, 100.0], 0.05)),
         ["stiffness", "3", "2"]),
    case("FlexibleArm-joints-str", lambda robot: FlexibleArm(robot, "joints"), exc=TypeError),
    case("from_toml_string-names-its-source",
         lambda robot: FlexibleJoints.from_toml_string("[defaults]\nstiffness = 1.0\n", robot),
         ["<toml string>"]),
]

# ---- FlexibleJoints.from_toml ------------------------------------------------------------------
# Each text is written to a file; the message must also name that file.

TOML_ERRORS = [
    pytest.param("[defaults\nstiffness = 1\n", ["line 1"], id="malformed"),
    pytest.param('[defaults]\nstiffness = "stiff"\nmotor_inertia = 1.0\n', ["line 2"],
                 id="wrong-value-type"),
    pytest.param("""
        [defaults]
        stiffness = 100.0
        motor_inertia = 0.05
        [joints.elbow]
        stiffness = 200.0
        """, ["elbow", "j1", "j2", "j3"], id="unknown-joint-lists-joints"),
    # j1 has neither its own value nor a default.
    pytest.param("[defaults]\nmotor_inertia = 0.05\n[joints.j2]\nstiffness = 1.0\n",
                 ["stiffness", "'j1'"], id="missing-stiffness"),
    pytest.param("[defaults]\nstiffness = 100.0\n[joints.j2]\nmotor_inertia = 1.0\n",
                 ["motor_inertia", "'j1'"], id="missing-motor_inertia"),
    pytest.param("[defaults]\nstiffness = 1.0\nmotor_inertia = 1.0\nstifness = 3.0\n",
                 ["stifness"], id="unknown-key-typo-in-defaults"),
    pytest.param("[defaults]\nstiffness = 1.0\nmotor_inertia = 1.0\n[joints.j2]\nmass = 3.0\n",
                 ["mass"], id="unknown-key-typo-in-joint"),
    pytest.param("stiffness = 1.0\nmotor_inertia = 1.0\n", ["stiffness"],
                 id="unknown-key-top-level"),
    pytest.param("[defaults]\nstiffness = 1.0\nmotor_inertia = 1.0\n[extra]\nx = 1\n", ["extra"],
                 id="unknown-key-table"),
    pytest.param("""
        [defaults]
        stiffness = 100.0
        motor_inertia = 0.05
        [joints.j3]
        motor_inertia = 0.1
        gear_ratio = 100.0
        rotor_inertia = 1e-5
        """, ["'j3'", "either"], id="both-inertia-forms-in-joint-table"),
]

# ---- FlexibleArm: state, derivative, step, simulate (model §5) --------------------------------


def at_rest(fn, *args, **kwargs):
    """``arm.<fn>(arm.state(), *args, **kwargs)``."""
    return lambda arm: getattr(arm, fn)(arm.state(), *args, **kwargs)


def derivative_or_step(fn, change_x=lambda x: x, **kwargs):
    """``arm.<fn>(x, [dt = 1 ms,] **kwargs)`` with x = change_x(arm.state(q=[0.1, 0.2, 0.3]))."""

    def run(arm):
        x = change_x(arm.state(q=[0.1, 0.2, 0.3]))
        extra = (1e-3,) if fn == "step" else ()
        return getattr(arm, fn)(x, *extra, **kwargs)

    return run


def state_argument_cases():
    for name, n in [("q", 3), ("theta", 3), ("qd", 3), ("theta_dot", 3),
                    ("base_pose", 7), ("base_twist", 6)]:
        yield case(f"state-{name}-long", methodcaller("state", **{name: np.zeros(n + 1)}),
                   [f"{name}:", f"expected length {n}, given length {n + 1}"])
        yield case(f"state-{name}-last-nan",
                   methodcaller("state", **{name: with_element(np.ones(n), -1, np.nan)}),
                   [f"{name}:", f"element {n - 1}"])
        yield case(f"state-{name}-2d", methodcaller("state", **{name: np.ones((1, n))}),
                   [f"{name}:", "1-D"])


def derivative_and_step_cases():
    for fn in ["derivative", "step"]:
        yield case(f"{fn}-x-short", derivative_or_step(fn, lambda x: x[:-1]),
                   ["x", "expected length 25, given length 24"])
        yield case(f"{fn}-x-nan", derivative_or_step(fn, lambda x: with_element(x, 20, np.nan)),
                   ["element 20"])
        yield case(f"{fn}-x-2d", derivative_or_step(fn, lambda x: np.tile(x, (2, 1))))
        for kw, n in [("u", 3), ("base_wrench", 6), ("ee_wrench", 6)]:
            yield case(f"{fn}-{kw}-long", derivative_or_step(fn, **{kw: np.zeros(n + 2)}),
                       [f"{kw}:", f"expected length {n}, given length {n + 2}"])
            yield case(f"{fn}-{kw}-inf",
                       derivative_or_step(fn, **{kw: with_element(np.zeros(n), 0, np.inf)}),
                       [f"{kw}:", "element 0"])


BAD_DT = [0.0, -1e-3, np.nan, np.inf]

ARM_ERRORS = [
    *state_argument_cases(),
    case("state-zero-quaternion", methodcaller("state", base_pose=np.zeros(7)),
         ["base_pose", "quaternion"]),
    *derivative_and_step_cases(),
    *[case(f"step-dt-{dt}", at_rest("step", dt), ["dt"]) for dt in BAD_DT],
    *[case(f"simulate-dt-{dt}", at_rest("simulate", dt, 10), ["dt"]) for dt in BAD_DT],
    *[case(f"simulate-steps-{steps!r}", at_rest("simulate", 1e-3, steps), ["steps"])
      for steps in [-1, 2.5, True, "10", None]],
    case("simulate-x0-short", lambda arm: arm.simulate(arm.state()[:-1], 1e-3, 5),
         ["x0", "25", "24"]),
    case("simulate-x0-nan",
         lambda arm: arm.simulate(with_element(arm.state(), 20, np.nan), 1e-3, 5),
         ["x0", "element 20"]),
    # Inputs over a 10-step run: one row per step, or one row for all steps.
    *[case(f"simulate-{id}", at_rest("simulate", 1e-3, 10, **{kw: value}), words)
      for id, kw, value, words in [
          ("u-9-rows", "u", np.zeros((9, 3)), ["u", "(10, 3)", "(9, 3)"]),
          ("u-2-columns", "u", np.zeros((10, 2)), ["u", "(10, 2)"]),
          ("u-short", "u", np.zeros(2), ["u", "expected length 3", "given length 2"]),
          ("u-3d", "u", np.zeros((10, 3, 1)), ["u", "3-D"]),
          ("u-str", "u", "torque", ["u", "numbers"]),
          ("u-nan", "u", np.full(3, np.nan), ["u", "not finite"]),
          ("base_wrench-9-rows", "base_wrench", np.zeros((9, 6)),
           ["base_wrench", "(10, 6)", "(9, 6)"]),
          ("base_wrench-11-rows", "base_wrench", np.zeros((11, 6)),
           ["base_wrench", "(10, 6)", "(11, 6)"]),
          ("base_wrench-5-columns", "base_wrench", np.zeros((10, 5)),
           ["base_wrench", "(10, 5)"]),
          ("base_wrench-short", "base_wrench", np.zeros(5), ["base_wrench", "expected length 6"]),
          ("ee_wrench-11-rows", "ee_wrench", np.zeros((11, 6)),
           ["ee_wrench", "(10, 6)", "(11, 6)"]),
          ("ee_wrench-long", "ee_wrench", np.zeros(7), ["ee_wrench", "expected length 6"]),
      ]],
    case("simulate-MotorPD-2-joints-for-3",
         at_rest("simulate", 1e-3, 10, u=MotorPD(1.0, 1.0, np.zeros(2))), ["MotorPD", "2", "3"]),
    case("simulate-MotorPD-table-too-short",
         at_rest("simulate", 1e-3, 10, u=MotorPD(1.0, 1.0, np.zeros((5, 3)))),
         ["theta_ref", "10", "5"]),
]

# =============================================================================================
# The tests that run the tables
# =============================================================================================


@pytest.mark.parametrize("xml,kwargs,words", URDF_ERRORS)
def test_urdf_error_names_the_source(loader, xml, kwargs, words):
    load, source = loader
    msg = raised(ModelError, lambda: load(xml, **kwargs))
    assert source in msg
    # The words must be in the message itself, not in the path (which names the test).
    assert_mentions(msg.replace(source, "<source>"), words)


@pytest.mark.parametrize("name,load", MISSING_FILES)
def test_missing_file_is_file_not_found_naming_the_path(tmp_path, robot, name, load):
    path = tmp_path / name
    assert str(path) in raised(FileNotFoundError, lambda: load(path, robot))


@pytest.mark.parametrize("call,exc,words", ERRORS)
def test_error(call, exc, words):
    assert_mentions(raised(exc, call), words)


@pytest.mark.parametrize("call,exc,words", ROBOT_ERRORS)
def test_robot_error(robot, call, exc, words):
    assert_mentions(raised(exc, lambda: call(robot)), words)


@pytest.mark.parametrize("text,words", TOML_ERRORS)
def test_from_toml_error_names_the_file(tmp_path, robot, text, words):
    path = write(tmp_path, text)
    msg = raised(ModelError, lambda: FlexibleJoints.from_toml(str(path), robot))
    assert str(path) in msg
    assert_mentions(msg.replace(str(path), "<path>"), words)


@pytest.mark.parametrize("call,exc,words", ARM_ERRORS)
def test_arm_error(arm, call, exc, words):
    assert_mentions(raised(exc, lambda: call(arm)), words)


# =============================================================================================
# Inputs that must be accepted
# =============================================================================================


def test_model_error_is_a_value_error():
    assert issubclass(ModelError, ValueError)
    assert issubclass(SimulationError, Exception)


def test_locked_prismatic_joint_loads(loader):
    load, _ = loader
    xml = urdf(BASE, link("l1"), link("l2"), joint("j1", "base", "l1"),
               joint("slider", "l1", "l2", kind="prismatic"))
    robot = load(xml, locked_joints=["slider"])
    assert robot.dof == 1
    assert robot.joint_names == ["j1"]
    # The locked link's mass stays in the model.
    assert robot.total_mass == pytest.approx(52.0)


def test_a_branch_is_an_arm_of_a_tree(loader):
    load, source = loader
    xml = urdf(BASE, link("l1"), link("l2"), link("side_link"),
               joint("j1", "base", "l1"), joint("j2", "l1", "l2"),
               joint("side", "l1", "side_link"))
    # every leaf is an end-effector; joints depth-first, children in file order
    robot = load(xml)
    assert robot.joint_names == ["j1", "j2", "side"]
    assert robot.parents == [-1, 0, 0]
    assert robot.ee_links == ["l2", "side_link"]
    msg = raised(ModelError, lambda: robot.ee_link)
    assert "2 end-effectors ('l2', 'side_link')" in msg
    # ee_link keeps meaning one end-effector; the branch still moves
    robot = load(xml, ee_link="l2")
    assert robot.ee_links == ["l2"] and robot.ee_link == "l2" and robot.dof == 3
    # locking the branch gives the serial chain
    robot = load(xml, ee_link="l2", locked_joints=["side"])
    assert robot.joint_names == ["j1", "j2"] and robot.parents == [-1, 0]
    msg = raised(ModelError, lambda: load(xml, ee_link="l2", ee_links=["l2"]))
    assert source in msg or "not both" in msg


def test_massless_middle_link_is_fine(loader):
    load, _ = loader
    xml = urdf(BASE, link("l1"), link("l2", **MASSLESS), link("l3"),
               joint("j1", "base", "l1"), joint("j2", "l1", "l2"), joint("j3", "l2", "l3"))
    assert load(xml).dof == 3


@pytest.mark.parametrize("method", list(SIGNATURES))
def test_good_arguments_work(robot, method):
    robot_call(method)(robot)


def test_lists_and_integer_arrays_are_accepted(robot):
    a = robot.mass_matrix([0, 0, 0])
    b = robot.mass_matrix(np.zeros(3, dtype=np.int64))
    c = robot.mass_matrix(np.zeros(6)[::2])  # non-contiguous
    np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(a, c)


def test_flexible_joints_zero_damping_is_fine():
    FlexibleJoints(1.0, 1.0, damping=0.0, motor_damping=0.0)


def test_dt_within_limit_does_not_warn(arm):
    x0 = arm.state(q=[0.1, 0.2, 0.3])
    dt = 0.5 * arm.rk4_stability_limit(x0).dt
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        arm.simulate(x0, dt, 3)


# =============================================================================================
# Regressions: errors that were once wrong, each under its own name
# =============================================================================================


@pytest.mark.parametrize("xml", ["", "   \n\t  "], ids=["empty", "whitespace"])
def test_regression_empty_urdf_says_it_is_empty(loader, xml):
    # It used to say "No elements found", which does not tell a newcomer the file was empty.
    load, source = loader
    msg = raised(ModelError, lambda: load(xml))
    assert "empty" in msg and source in msg


def test_from_toml_both_inertia_forms_in_defaults(tmp_path, robot):
    # Same conflict as both-inertia-forms-in-joint-table, in [defaults]: the message must explain
    # the conflict, as the per-joint message does, not claim that motor_inertia is missing.
    path = write(tmp_path, """
        [defaults]
        stiffness = 100.0
        motor_inertia = 0.05
        gear_ratio = 100.0
        """)
    msg = raised(ModelError, lambda: FlexibleJoints.from_toml(str(path), robot))
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
    msg = raised(ModelError, lambda: FlexibleJoints.from_toml(str(path), robot))
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
    msg = raised(ModelError, lambda: FlexibleJoints.from_toml(str(path), robot))
    assert "gear_ratio" in msg


def test_simulate_non_finite_angle_in_x0_names_x0(arm):
    # The user passed x0, not q: the message should say which element of x0 is bad.
    bad = arm.state()
    bad[8] = np.nan  # q[1]
    msg = raised(ModelError, lambda: arm.simulate(bad, 1e-3, 5))
    assert "x0" in msg, msg


@pytest.mark.parametrize("fn", ["derivative", "step", "energy", "momentum", "ee_pose"])
def test_zero_quaternion_in_state_is_an_error(arm, fn):
    # A state whose quaternion is zero has no attitude: every function taking x must refuse it
    # rather than return NaN.
    x = arm.state(q=[0.1, 0.2, 0.3], base_twist=[0, 0, 0, 1.0, 0, 0])
    x[3:7] = 0.0
    extra = (1e-3,) if fn == "step" else ()
    assert "quaternion" in raised(ModelError, lambda: getattr(arm, fn)(x, *extra))


def test_trajectory_from_user_rows_rejects_a_zero_quaternion(arm):
    # A Trajectory built from user data (e.g. a loaded file) with a zero quaternion is refused
    # when it is made, so that its diagnostics (momentum, energy, EE pose) never see NaN.
    x = np.tile(arm.state(q=[0.1, 0.2, 0.3]), (3, 1))
    x[1, 3:7] = 0.0
    msg = raised(ModelError,
                 lambda: orbitflex.Trajectory(arm, np.arange(3) * 1e-3, x, np.zeros((2, 3))))
    assert "quaternion" in msg and "x[1]" in msg


# =============================================================================================
# The controller fails (model §5)
# =============================================================================================


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
    assert_mentions(str(e.value), ["step 0", "controller", *words])
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


# =============================================================================================
# Divergence (model §5)
# =============================================================================================


@pytest.mark.parametrize("dt", [0.2, 1.0])
def test_huge_dt_warns_then_fails_keeping_finite_steps(dt):
    arm, x0 = diverging_arm()
    limit = arm.rk4_stability_limit(x0).dt
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


# =============================================================================================
# Never crash the interpreter
# =============================================================================================


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
