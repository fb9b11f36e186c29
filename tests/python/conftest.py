"""Shared fixtures: robots loaded both in orbitflex and in Pinocchio from the same URDF."""

from __future__ import annotations

import os
import sys
import zlib
from dataclasses import dataclass, field
from typing import Optional, Sequence

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))

import orbitflex  # noqa: E402
from pin_helpers import PinRobot, robots_dir  # noqa: E402
from urdf_gen import random_chain  # noqa: E402

# Seeds of the random chains compared with Pinocchio in test_pinocchio.py. The simulation
# reference test uses different seeds (held out).
PIN_CHAIN_SEEDS = list(range(12))
SIM_CHAIN_SEED = 1000


@dataclass
class Case:
    """One robot: how to load it in orbitflex and in Pinocchio."""

    name: str
    path: Optional[str] = None  # a URDF file, or
    xml: Optional[str] = None  # URDF text (loaded with from_urdf_string / buildModelFromXML)
    ee_link: Optional[str] = None
    locked_joints: Sequence[str] = field(default_factory=list)
    builtin: bool = False  # orbitflex.models.space_arm() rather than the file

    def load(self):
        """``(robot, pin_robot)``."""
        kwargs = {}
        if self.ee_link is not None:
            kwargs["ee_link"] = self.ee_link
        if self.locked_joints:
            kwargs["locked_joints"] = list(self.locked_joints)
        if self.builtin:
            robot = orbitflex.models.space_arm()
        elif self.path is not None:
            robot = orbitflex.Robot.from_urdf(self.path, **kwargs)
        else:
            robot = orbitflex.Robot.from_urdf_string(self.xml, **kwargs)
        # Pinocchio's EE frame is looked up by the name orbitflex reports (checked separately).
        pin_robot = PinRobot(
            robot.joint_names,
            self.ee_link if self.ee_link is not None else robot.ee_link,
            path=self.path,
            xml=self.xml,
            locked_joints=self.locked_joints,
        )
        return robot, pin_robot

    def rng(self, salt: str = "") -> np.random.Generator:
        return np.random.default_rng(zlib.crc32((self.name + salt).encode()))


def _space_arm_case(tmpdir: str) -> Case:
    path = os.path.join(tmpdir, "space_arm.urdf")
    with open(path, "w") as fh:
        fh.write(orbitflex.models.space_arm_urdf())
    return Case("space_arm", path=path, ee_link="ee", builtin=True)


def erd_case(name: str) -> Case:
    root = robots_dir()
    if name == "ur5":
        return Case("ur5", path=os.path.join(root, "ur_description/urdf/ur5_robot.urdf"), ee_link="tool0")
    if name == "panda":
        return Case(
            "panda",
            path=os.path.join(root, "panda_description/urdf/panda.urdf"),
            ee_link="panda_hand_tcp",
            locked_joints=["panda_finger_joint1", "panda_finger_joint2"],
        )
    if name == "so101":
        # The jaw branches off the chain; locked, its leaf is no EE candidate, so the default EE
        # is the unique remaining leaf (gripper_frame_link).
        return Case(
            "so101",
            path=os.path.join(root, "so_arm_description/urdf/so101.urdf"),
            locked_joints=["gripper"],
        )
    if name == "xarm7":
        # No ee_link: the unique leaf (link_eef) is the default.
        return Case("xarm7", path=os.path.join(root, "xarm_description/urdf/xarm7.urdf"))
    raise KeyError(name)


def chain_case(seed: int, via_file_dir: Optional[str] = None) -> Case:
    chain = random_chain(seed)
    if via_file_dir is not None:
        path = os.path.join(via_file_dir, f"chain_{seed}.urdf")
        with open(path, "w") as fh:
            fh.write(chain.xml)
        return Case(f"chain{seed}", path=path, ee_link=chain.ee_link)
    return Case(f"chain{seed}", xml=chain.xml, ee_link=chain.ee_link)


# Locked revolute/continuous joints in the middle of a chain (held at zero on both sides).
LOCKED_CASES = {
    "ur5_locked_elbow": ("ur5", ["elbow_joint"]),
    "chain4_locked": (4, ["j2", "j3"]),
}

PIN_CASE_NAMES = (
    ["space_arm", "ur5", "panda", "xarm7", "so101"] + [f"chain{s}" for s in PIN_CHAIN_SEEDS] + list(LOCKED_CASES)
)


@pytest.fixture(scope="session")
def case_dir(tmp_path_factory):
    return str(tmp_path_factory.mktemp("urdf"))


_LOADED = {}


@pytest.fixture(scope="session", params=PIN_CASE_NAMES)
def loaded(request, case_dir):
    """``(case, robot, pin_robot)`` for every robot compared with Pinocchio."""
    name = request.param
    if name not in _LOADED:
        if name == "space_arm":
            case = _space_arm_case(case_dir)
        elif name in LOCKED_CASES:
            base, locked = LOCKED_CASES[name]
            case = erd_case(base) if isinstance(base, str) else chain_case(base)
            case.name, case.locked_joints = name, list(locked)
        elif name.startswith("chain"):
            seed = int(name[5:])
            # Even seeds go through a file, odd ones through the string loader.
            case = chain_case(seed, case_dir if seed % 2 == 0 else None)
        else:
            case = erd_case(name)
        _LOADED[name] = (case, *case.load())
    return _LOADED[name]
