//! Recursive O(n) algorithms in the seed's conventions (`[ω; v]`, classical acceleration),
//! over an immutable [`Robot`] and a preallocated [`Data`] workspace.
//!
//! Each function checks its argument sizes first, then runs without allocating. Results are left
//! in `Data` and returned by reference. Each is tested against [`crate::operators::Operators`].

pub(crate) mod aba;
mod crba;
pub(crate) mod kinematics;
mod rnea;

pub use aba::aba;
pub use crba::crba;
pub use kinematics::{ee_jacobian, kinetic_energy, momentum, velocities};
pub use rnea::{bias_forces, rnea};

use crate::model::Robot;
use crate::spatial::{ArticulatedInertia, Force, Inertia, Mat6, Motion, Transform, Vec6};
use nalgebra::{DMatrix, DVector};

/// Which implementation of the dynamics to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// The recursive algorithms of this module (O(n), allocation-free). The default.
    #[default]
    Recursive,
    /// The seed's dense operator form (A.13)–(A.19): O(n³), the reference for validation.
    Operator,
}

/// Per-body scratch buffers for one [`Robot`], allocated once by [`Data::new`].
///
/// Index 0 is the base, `i` is link `i`. Reuse one `Data` for many calls: nothing is allocated
/// after construction.
#[derive(Debug, Clone)]
pub struct Data {
    /// `Φ_{i,i-1}(q)` (A.5); entry 0 is unused.
    pub x: Vec<Transform>,
    /// Body velocities `V_i` (A.4), body frames.
    pub v: Vec<Motion>,
    /// Coriolis terms `a_i` (A.7); entry 0 is zero (`a_B = 0`).
    pub c: Vec<Motion>,
    /// Classical body accelerations `α_i` (A.6).
    pub acc: Vec<Motion>,
    /// Body forces `f_i` (A.8/A.12) or articulated bias forces (ABA).
    pub f: Vec<Force>,
    /// Articulated-body inertias `I^A_i` (ABA), in 3×3 blocks.
    pub ia: Vec<ArticulatedInertia>,
    /// Composite-rigid-body inertias (CRBA).
    pub ic: Vec<Inertia>,
    /// ABA `U_i = I^A_i H_i`.
    pub u_col: Vec<Vec6>,
    /// ABA `D_i = H_iᵀ U_i`.
    pub d: Vec<f64>,
    /// ABA `u_i = τ_i − H_iᵀ p^A_i`.
    pub u: Vec<f64>,
    /// The (6+n)×(6+n) mass matrix (CRBA).
    pub mass_matrix: DMatrix<f64>,
    /// Generalized forces `[f_B; τ]` (RNEA) or accelerations `[α_B; q̈]` (ABA), length 6+n.
    pub out: DVector<f64>,
    /// `J` (6×n).
    pub jacobian: DMatrix<f64>,
    /// `Φ_{n+1,B}` (6×6).
    pub ee_base: Mat6,
}

impl Data {
    /// Allocates every buffer for `robot`.
    pub fn new(robot: &Robot) -> Self {
        let n = robot.dof();
        Self {
            x: vec![Transform::identity(); n + 1],
            v: vec![Motion::zero(); n + 1],
            c: vec![Motion::zero(); n + 1],
            acc: vec![Motion::zero(); n + 1],
            f: vec![Force::zero(); n + 1],
            ia: vec![ArticulatedInertia::zero(); n + 1],
            ic: vec![Inertia::zero(); n + 1],
            u_col: vec![Vec6::zeros(); n + 1],
            d: vec![0.0; n + 1],
            u: vec![0.0; n + 1],
            mass_matrix: DMatrix::zeros(6 + n, 6 + n),
            out: DVector::zeros(6 + n),
            jacobian: DMatrix::zeros(6, n),
            ee_base: Mat6::identity(),
        }
    }

    /// Number of joints this workspace was made for.
    pub fn dof(&self) -> usize {
        self.x.len() - 1
    }
}

/// Checks that `data` was made for `robot`.
pub(crate) fn check_data(robot: &Robot, data: &Data) -> crate::Result<()> {
    if data.dof() != robot.dof() {
        return Err(crate::Error::Dimension {
            what: "Data workspace".into(),
            expected: format!("one made for {} joints", robot.dof()),
            given: format!("one made for {} joints", data.dof()),
        });
    }
    Ok(())
}
