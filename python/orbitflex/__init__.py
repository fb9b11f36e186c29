"""orbitflex: flexible-joint robot arms on a floating base (spacecraft manipulators).

Rigid floating-base dynamics in the operator form of the source derivation (Appendix A, eqs.
A.1-A.19, of "Trajectory Generation for Flexible-Joint Space Manipulators", Frontiers in Robotics
and AI, 2022) and in O(n) recursive form, Spong flexible joints, a fixed-step RK4 simulator, and
minimum-time slews planned with the flexible-joint inverse dynamics (``plan_slew``, ``Limits``,
``Plan``).
The model, its conventions and equations are documented in docs/model.md.

Conventions: spatial vectors are ``[angular; linear]`` in the body's own frame; the base twist is
``[omega_B; v_B]`` in base-frame components; quaternions are ``(x, y, z, w)``, scalar last,
mapping base-frame to inertial-frame components; the base acceleration ``alpha_B`` is
"classical"; SI units; no gravity.

Everything here is implemented in the compiled module ``orbitflex._core``; this package
re-exports it.

Threads and Ctrl-C: every object may be called from several threads at once (each call takes a
workspace of its own; no lock is held while it computes or builds numpy arrays), with the same
results as from one thread. Long calls (batched per-call functions, ``simulate`` with a Rust
controller, ``simulate_batch``, ``plan_slew``, the ``Trajectory`` diagnostics) release the GIL
and stop within a fraction of a second of Ctrl-C with ``KeyboardInterrupt``. See
docs/threads_and_interrupts.md.

>>> import orbitflex
>>> robot = orbitflex.models.space_arm()
>>> robot.dof
7
"""

from ._core import (
    DUAL_ARM_URDF,
    SPACE_ARM_URDF,
    BatchTrajectory,
    Capture,
    CaptureEvent,
    CaptureWhen,
    FlexibleArm,
    FlexibleJoints,
    LimitWarning,
    Limits,
    ModelError,
    AttitudePD,
    MotorPD,
    Sampled,
    Plan,
    ReactionWheels,
    Robot,
    SimulationError,
    Simulator,
    StabilityLimit,
    Target,
    Trajectory,
    __version__,
    available_memory,
    capture,
    check_run_memory,
    euler_zyx,
    plan_slew,
    quintic_reference,
    recorded_rows,
    rotation_angle,
    rotation_matrix,
    run_bytes,
    simulate_batch,
    simulate_capture_batch,
)
from . import analysis, models
from .detumble import detumble_metrics

__all__ = [
    "rotation_matrix",
    "euler_zyx",
    "rotation_angle",
    "Robot",
    "FlexibleJoints",
    "FlexibleArm",
    "ReactionWheels",
    "AttitudePD",
    "MotorPD",
    "Sampled",
    "Trajectory",
    "Simulator",
    "StabilityLimit",
    "simulate_batch",
    "simulate_capture_batch",
    "detumble_metrics",
    "BatchTrajectory",
    "recorded_rows",
    "run_bytes",
    "check_run_memory",
    "available_memory",
    "Limits",
    "LimitWarning",
    "Plan",
    "plan_slew",
    "quintic_reference",
    "Target",
    "capture",
    "Capture",
    "CaptureWhen",
    "CaptureEvent",
    "ModelError",
    "SimulationError",
    "models",
    "analysis",
    "SPACE_ARM_URDF",
    "DUAL_ARM_URDF",
    "__version__",
]
