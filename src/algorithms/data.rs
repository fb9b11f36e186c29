//! [`Data`]: the workspace of the recursive algorithms, one buffer per quantity.

use super::derivatives::Derivatives;
use crate::model::Robot;
use crate::spatial::{ArticulatedInertia, Force, Inertia, Mat3, Mat6, Motion, Transform, Vec3};
use nalgebra::{DMatrix, DVector};

/// Per-body scratch buffers for one [`Robot`], allocated by [`Data::new`].
///
/// Index 0 is the base and `i` is link `i`. Each buffer has one meaning. Per-body quantities are
/// in each body's **joint frame**: the link frame turned by the constant
/// [`Robot::joint_frame_rotation`] so that the joint axis is `e_z` (the base frame is unchanged);
/// `Q_iᵀ` takes their 3-vectors back to link-frame components. Results in joint space, the base
/// frame or the EE frame (`tau`, `ddq`, `mass_matrix`, `jacobian`, `ee_base`) do not depend on
/// this. Reuse one `Data` for many
/// calls: after the first call of each algorithm nothing is allocated. The memory is O(n); the
/// one dense buffer, the (6+n)² mass matrix, is allocated by the first [`crate::algorithms::crba`]
/// call, not by `Data::new`.
#[derive(Debug, Clone)]
pub struct Data {
    /// `Φ'_{i,λ(i)}(q)` (A.5) between joint frames, from the parent `λ(i)` to body `i`; entry 0 is
    /// unused.
    pub x: Vec<Transform>,
    /// Body velocities `V_i` (A.4), joint frames. [`crate::algorithms::velocities`] (and
    /// `momentum`, `kinetic_energy`) fill them whole. The classical-acceleration recursions
    /// ([`crate::algorithms::aba`], [`crate::algorithms::rnea`], `bias_forces`) need only the
    /// angular parts (the Coriolis terms `a_i` and the bias forces `b_i` depend on `ω` alone) and
    /// leave NaN in the linear parts of the links (entry 0 holds the base twist whole).
    pub v: Vec<Motion>,
    /// Coriolis terms `a_i` (A.7); entry 0 is zero (`a_B = 0`).
    pub c: Vec<Motion>,
    /// Classical body accelerations `α_i` (A.6), joint frames.
    pub acc: Vec<Motion>,
    /// Body forces `f_i` (A.8), joint frames: the force body `i` receives through joint `i` from
    /// its parent.
    pub f: Vec<Force>,
    /// Spatial momenta: `M_i V_i` summed over the subtree of body `i`, about origin `i`.
    pub h: Vec<Force>,
    /// Articulated-body inertias `I^A_i` (ABA), in 3×3 blocks.
    pub ia: Vec<ArticulatedInertia>,
    /// Articulated bias forces `p^A_i` (ABA).
    pub pa: Vec<Force>,
    /// Composite-rigid-body inertias `I^c_i` (CRBA).
    pub ic: Vec<Inertia>,
    /// ABA `U_i = I^A_i H_i`.
    pub u_col: Vec<Force>,
    /// ABA `D_i = H_iᵀ U_i`.
    pub d: Vec<f64>,
    /// ABA `u_i = τ_i − H_iᵀ p^A_i`.
    pub u: Vec<f64>,
    /// Generalized forces `[f_B; τ]` (RNEA), length 6+n.
    pub tau: DVector<f64>,
    /// Generalized accelerations `[α_B; q̈]` (ABA), length 6+n.
    pub ddq: DVector<f64>,
    /// The (6+n)×(6+n) mass matrix (CRBA); 0×0 until the first `crba` call.
    pub mass_matrix: DMatrix<f64>,
    /// `J` (6×n).
    pub jacobian: DMatrix<f64>,
    /// `Φ_{n+1,B}` (6×6).
    pub ee_base: Mat6,
    /// Inertial placements of the bodies from the last [`crate::algorithms::frame_poses`]: the
    /// axes (joint-frame components to inertial components) and the origin (m, inertial).
    pub placements: Vec<(Mat3, Vec3)>,
    /// The derivatives of the dynamics ([`crate::algorithms::aba_derivatives`],
    /// [`crate::algorithms::rnea_derivatives`]); empty until the first of them runs.
    pub derivatives: Derivatives,
}

impl Data {
    /// Allocates every per-body buffer for `robot` (O(n) memory).
    pub fn new(robot: &Robot) -> Self {
        // Choose between the AVX2 and portable copies here, where allocating is fine: reading
        // ORBITFLEX_PORTABLE allocates when it is set, and the hot paths must not.
        crate::simd::avx2();
        let bodies = robot.dof() + 1;
        Self {
            x: vec![Transform::identity(); bodies],
            v: vec![Motion::zero(); bodies],
            c: vec![Motion::zero(); bodies],
            acc: vec![Motion::zero(); bodies],
            f: vec![Force::zero(); bodies],
            h: vec![Force::zero(); bodies],
            ia: vec![ArticulatedInertia::zero(); bodies],
            pa: vec![Force::zero(); bodies],
            ic: vec![Inertia::zero(); bodies],
            u_col: vec![Force::zero(); bodies],
            d: vec![0.0; bodies],
            u: vec![0.0; bodies],
            tau: DVector::zeros(5 + bodies),
            ddq: DVector::zeros(5 + bodies),
            mass_matrix: DMatrix::zeros(0, 0),
            jacobian: DMatrix::zeros(6, bodies - 1),
            ee_base: Mat6::identity(),
            placements: vec![(Mat3::identity(), Vec3::zeros()); bodies],
            derivatives: Derivatives::default(),
        }
    }

    /// Number of joints this workspace was made for.
    pub fn dof(&self) -> usize {
        self.x.len() - 1
    }

    /// The mass-matrix buffer, allocated (zeroed) on first use, or an error if it would exceed
    /// [`crate::args::MAX_DENSE_BYTES`]. (On a tree, [`crate::algorithms::crba`] clears the
    /// entries of joints on different branches itself: a workspace may have served another
    /// model of the same size.)
    pub(crate) fn mass_matrix_buffer(&mut self) -> crate::Result<&mut DMatrix<f64>> {
        let size = 6 + self.dof();
        if self.mass_matrix.nrows() != size {
            crate::args::check_dense(
                "mass matrix",
                size,
                size,
                1,
                "the recursive algorithms (forward and inverse dynamics) need no dense matrix",
            )?;
            self.mass_matrix = DMatrix::zeros(size, size);
        }
        Ok(&mut self.mass_matrix)
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
