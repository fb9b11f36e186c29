"""FMI co-simulation FMUs of a flexible arm (FMI 3.0 or 2.0), for FMPy, Simulink and any FMI
master: :func:`write_fmu` (``orbitflex fmu`` on the command line).

An FMU holds ``modelDescription.xml``, the x86-64 Linux binary (orbitflex's C runtime,
``liborbitflex_c``, the same for every model) and the model as resources (the URDF, the joint
parameters and ``fmu.toml``), which the binary reads when the master instantiates it. Its
variables, units and behaviour are described in docs/cosimulation.md.
"""

from __future__ import annotations

import os
import re
import zipfile
from pathlib import Path
from typing import Optional, Sequence, Union

from ._core import FlexibleArm, _fmu_files

__all__ = ["write_fmu", "runtime_library"]

_RUNTIME_NAMES = ("liborbitflex_c.so",)


def runtime_library() -> Path:
    """The FMU runtime (``liborbitflex_c.so``): the file named by ``$ORBITFLEX_RUNTIME`` when it is
    set (an explicit choice wins, e.g. a freshly built ``target/release/liborbitflex_c.so``), else
    the one in the installed package. Raises ``FileNotFoundError`` saying how to build it."""
    env = os.environ.get("ORBITFLEX_RUNTIME")
    if env:
        if Path(env).is_file():
            return Path(env)
        raise FileNotFoundError(f"$ORBITFLEX_RUNTIME names {env}, which is not a file")
    here = Path(__file__).resolve().parent / "_runtime"
    for name in _RUNTIME_NAMES:
        if (here / name).is_file():
            return here / name
    raise FileNotFoundError(
        f"the FMU runtime liborbitflex_c.so is not in {here}: install orbitflex with `pip install .` "
        "(its build backend builds the runtime), or build it with `cargo build --release -p "
        "orbitflex-capi` and set ORBITFLEX_RUNTIME=target/release/liborbitflex_c.so")


def _identifier(name: str) -> str:
    ident = re.sub(r"[^A-Za-z0-9_]", "_", name)[:64] or "arm"
    return ident if not ident[0].isdigit() else f"_{ident[:63]}"


def write_fmu(out: Union[str, "os.PathLike[str]"], urdf: str, arm: FlexibleArm, dt: float, *, fmi: int = 3,
              ee_links: Sequence[str] = (), locked_joints: Sequence[str] = (),
              model_identifier: Optional[str] = None, runtime: Optional[Union[str, "os.PathLike[str]"]] = None) -> Path:
    """Writes the co-simulation FMU of ``arm`` to ``out`` and returns its path.

    ``urdf``: the robot's URDF *text* (``orbitflex.SPACE_ARM_URDF`` for the built-in arm), loaded
    in the FMU with ``ee_links`` and ``locked_joints`` as ``Robot.from_urdf_string`` does; it must
    make ``arm.robot``. ``arm``'s joint parameters are the FMU's (its ``stiffness.<joint>`` …
    parameters start at them). ``dt``: the internal RK4 step (s); every communication step must
    be a whole multiple of it. ``fmi``: 3 (FMI 3.0) or 2 (FMI 2.0). ``model_identifier``: the
    binary's name, a C identifier (default: the robot's name made one). ``runtime``: the
    runtime library (default :func:`runtime_library`).
    """
    if fmi not in (2, 3):
        raise ValueError(f"fmi: expected 2 or 3, given {fmi!r}")
    ident = model_identifier if model_identifier is not None else _identifier(arm.robot.name)
    files = _fmu_files(urdf, arm, list(ee_links), list(locked_joints), float(dt), ident, fmi)
    library = Path(runtime) if runtime is not None else runtime_library()
    platform = "x86_64-linux" if fmi == 3 else "linux64"
    out = Path(out)
    tmp = out.with_name(out.name + ".part")
    with zipfile.ZipFile(tmp, "w", compression=zipfile.ZIP_DEFLATED) as z:
        for name, data in files:
            z.writestr(name, data)
        z.write(library, f"binaries/{platform}/{ident}.so")
    os.replace(tmp, out)
    return out
