//! Time integration of the flexible arm (model §5): the RK4 integrator, what drives a run, and
//! the run itself.
//!
//! - [`rk4`]: classic RK4, generic over an [`OdeSystem`], owning its stage buffers;
//! - [`simulate`](mod@simulate): one [`step`], a whole run ([`simulate()`]) with its checks,
//!   stability warning and [`Observer`] hook;
//! - [`batch`]: many runs at once over a pool of threads ([`simulate_batch`]), inputs broadcast
//!   over a leading run axis, one record with a status per run;
//! - [`footprint`]: the bytes a run allocates, by part, and the check against the memory
//!   available, before anything is allocated;
//! - [`record`]: which rows a run keeps (`record_every`) and where they go: the [`Recorder`]
//!   trait, the in-memory [`Trajectory`], the streaming [`Chunks`];
//! - [`simulator`]: a [`Simulator`] stepped by its caller with held inputs (co-simulation);
//! - [`trajectory`]: the [`Trajectory`] a run returns and the diagnostics along it.
//!
//! ```
//! use orbitflex::integrate::{MotorPD, Schedule, Wrenches};
//! use orbitflex::{FlexibleArm, FlexibleJoints, Robot};
//!
//! let robot = Robot::space_arm();
//! let n = robot.dof();
//! let arm = FlexibleArm::new(robot, FlexibleJoints::uniform(n, 2e4, 1.0, 2.0, 1.0)?)?;
//! let mut pd = MotorPD::new(vec![2000.0; n], vec![800.0; n], Schedule::Constant(vec![0.2; n]),
//!                           Schedule::Zero, Schedule::Zero)?;
//! let traj = arm.simulate(&arm.rest_state(), 1e-3, 100, &mut pd, &Wrenches::ZERO)?;
//! assert_eq!(traj.len(), 101);
//! // free floating from rest: the momentum stays zero up to RK4's truncation error
//! let h = traj.rows().momentum(&arm);
//! assert!(h.iter().all(|v| v.abs() < 1e-6));
//! # Ok::<(), orbitflex::Error>(())
//! ```

pub mod arm;
pub mod batch;
pub mod energy_balance;
pub mod footprint;
pub mod record;
pub mod rk4;
pub mod run;
pub mod simulate;
pub mod simulator;
pub mod stepper;
pub mod trajectory;

pub use batch::{simulate_batch, Batch, BatchRecord, BatchSettings, RunRecord, RunStatus};
// the controllers live below the model (`crate::control`); re-exported where runs are made
pub use crate::control::{Controller, Feedback, MotorPD, Schedule, Wrenches};
pub use arm::ArmWorkspace;
pub use energy_balance::EnergyBalance;
pub use record::{is_recorded, recorded_rows, Chunk, Chunks, Recorder};
pub use rk4::{OdeSystem, Rk4};
pub use run::{Drive, Run};
pub use simulate::{
    run_steps, simulate, simulate_into, stability_warning, step, Observer, SimulationFailure,
    Unobserved,
};
pub use simulator::{arm_fingerprint, Outputs, Simulator, STATE_FORMAT_VERSION};
pub use stepper::{ArmSteps, StepBody, Stepper};
pub use trajectory::{StateRows, Trajectory};
