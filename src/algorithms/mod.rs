//! Recursive O(n) algorithms in the paper's conventions (`[ω; v]`, classical acceleration), over an
//! immutable [`Robot`](crate::Robot) and a preallocated [`Data`] workspace.
//!
//! Each public function checks its arguments first, then runs without allocating. Results are left
//! in `Data` and returned by reference. Every recursion reads each body's parent from
//! [`Robot::parents`](crate::Robot::parents) and accumulates into the parent's entry, so the loops
//! hold for trees as well as chains. Each algorithm is tested against
//! [`Operators`](crate::Operators), the paper's dense operator form.
//!
//! ```
//! use orbitflex::algorithms::{self, Data};
//! use orbitflex::{Loads, RigidState, Robot};
//!
//! let robot = Robot::space_arm();
//! let n = robot.dof();
//! let mut data = Data::new(&robot);
//! let (q, qd) = (vec![0.2; n], vec![0.1; n]);
//! let state = RigidState::new(&q, &[0.0; 6], &qd);
//! let acc = algorithms::aba(&robot, &mut data, &state, &vec![1.0; n], &Loads::ZERO)?.clone();
//! // inverse dynamics after forward dynamics gives back f_B = 0 and τ = 1
//! let gen = algorithms::rnea(&robot, &mut data, &state, &acc.as_slice()[..6], &acc.as_slice()[6..], &[0.0; 6])?;
//! assert!(gen.iter().take(6).all(|f| f.abs() < 1e-9));
//! assert!(gen.iter().skip(6).all(|t| (t - 1.0).abs() < 1e-9));
//! # Ok::<(), orbitflex::Error>(())
//! ```

pub(crate) mod aba;
pub(crate) mod crba;
mod data;
mod derivatives;
mod kinematics;
pub(crate) mod rnea;

pub use aba::aba;
pub use crba::crba;
pub use data::Data;
pub use derivatives::{aba_derivatives, rnea_derivatives, Derivatives};
pub use kinematics::{
    body_poses, ee_jacobian, frame_poses, kinetic_energy, momentum, pose, velocities,
};
pub use rnea::{bias_forces, rnea};

pub(crate) use aba::aba_unchecked;
pub(crate) use data::check_data;
pub(crate) use derivatives::{aba_derivatives_into, fd_directional};
pub(crate) use kinematics::{
    ee_from_base, frame_poses_unchecked, kinetic_energy_from_velocities, momentum_from_velocities,
    velocities_unchecked,
};
