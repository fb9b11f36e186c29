//! [`AttitudePD`]: the bus's attitude held by its reaction wheels, quaternion-error PD with the
//! torque allocated to the wheels.
//!
//! The bus attitude `q_B` (unit quaternion `(x, y, z, w)`, base to inertial) and rate `ω_B`
//! (base frame, rad/s) are read from the state; the target `q_ref` (and its rate `ω_ref`, in the
//! target frame, if given) from an [`AttitudeTarget`]. Then
//!
//! ```text
//! q_e = q_ref* ⊗ q_B            (sign chosen so that w ≥ 0: the shorter way round)
//! e   = 2 vec(q_e)              (rad for small errors; the base-frame rotation vector taking
//!                                the target to the bus, R_B = R_ref Exp(e))
//! T   = −kp ∘ e − kd ∘ (ω_B − R(q_e)ᵀ ω_ref)      (N·m, base frame: what the bus must feel)
//! u   = −M T                    (N·m, one torque per wheel)
//! ```
//!
//! A wheel driven with `u_w` about its axis `a_w` pushes the bus with `−u_w a_w`, so the wheels
//! deliver `T` when `A (−u) = T`, `A = [a_1 … a_k]` (3×k): any allocation `M` (k×3) with
//! `A M = 1` does. The default is the minimum-norm one, the pseudo-inverse `A⁺ = Aᵀ (A Aᵀ)⁻¹`
//! ([`min_norm_allocation`]), which needs the axes to span three dimensions. The run saturates
//! the commands once per step (torque, then speed limits), after this controller.

use super::controller::{Controller, Feedback};
use crate::args::check_length;
use crate::error::{Error, Result};
use crate::spatial::{quaternion_product, Mat3, Vec3};
use crate::state::StateLayout;

/// The attitude an [`AttitudePD`] holds.
#[derive(Debug, Clone, PartialEq)]
pub enum AttitudeTarget {
    /// The bus attitude at step 0 of the run (latched there), at rest.
    Initial,
    /// A fixed attitude `(x, y, z, w)` (normalised when the controller is made), at rest.
    Constant([f64; 4]),
    /// One attitude per step (row `k` held during step `k`), `rows × 4`, and optionally the
    /// target's angular velocity per step (`rows × 3`, rad/s, in the target's own frame;
    /// zero if absent).
    Table {
        /// The attitudes, row-major.
        attitude: Vec<f64>,
        /// The target rates, row-major, or empty for zero.
        rate: Vec<f64>,
    },
}

/// Quaternion-error PD on the bus attitude, allocated to the reaction wheels: a [`Controller`]
/// of the wheel-torque channel (width `k`). With `q_e = q_ref* ⊗ q_B` (the shorter way round)
/// and `e = 2 vec(q_e)`, the bus must feel `T = −kp ∘ e − kd ∘ (ω_B − R(q_e)ᵀ ω_ref)` (N·m, base
/// frame), and the wheels get `u = −M T` (a wheel driven with `u_w` pushes the bus with
/// `−u_w a_w`; any `M` with `A M = 1` delivers `T`; [`min_norm_allocation`] by default).
///
/// ```
/// use orbitflex::control::{min_norm_allocation, AttitudePD, AttitudeTarget, Controller};
/// // three wheels along the base axes: the allocation is the identity
/// let m = min_norm_allocation(&[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])?;
/// let mut pd = AttitudePD::new([2.0; 3], [5.0; 3], AttitudeTarget::Initial, m)?;
/// // no joints: x = [r | quat | ω, v | Ω (3)], the bus turning at 0.1 rad/s about z
/// let mut x = [0.0; 16];
/// x[6] = 1.0;
/// x[9] = 0.1;
/// let mut u = [0.0; 3];
/// pd.output(0, 0.0, &x, &mut u)?;
/// // T_z = −kd ω_z = −0.5 N·m on the bus, so the z wheel is driven with +0.5 N·m
/// assert!((u[2] - 0.5).abs() < 1e-15 && u[0] == 0.0);
/// # Ok::<(), orbitflex::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct AttitudePD {
    /// Proportional gains per base axis (N·m/rad), ≥ 0.
    pub kp: [f64; 3],
    /// Derivative gains per base axis (N·m·s/rad), ≥ 0.
    pub kd: [f64; 3],
    target: AttitudeTarget,
    /// `M`, k×3 row-major.
    allocation: Vec<f64>,
    /// The attitude latched at step 0 for [`AttitudeTarget::Initial`].
    latched: Option<[f64; 4]>,
}

impl AttitudePD {
    /// A validated controller: gains finite and ≥ 0, a unit-normable target, an allocation of
    /// `k × 3` finite numbers (`k ≥ 1`).
    pub fn new(
        kp: [f64; 3],
        kd: [f64; 3],
        target: AttitudeTarget,
        allocation: Vec<f64>,
    ) -> Result<Self> {
        for (what, gains) in [("kp", &kp), ("kd", &kd)] {
            crate::args::check_parameter(what, gains, 3, crate::args::Domain::NonNegative)?;
        }
        if allocation.is_empty() || allocation.len() % 3 != 0 {
            return Err(Error::Dimension {
                what: "allocation".into(),
                expected: "a (k, 3) matrix, k ≥ 1 (one row per wheel)".into(),
                given: format!("{} numbers", allocation.len()),
            });
        }
        crate::args::check_finite("allocation", &allocation)?;
        let target = match target {
            AttitudeTarget::Constant(q) => AttitudeTarget::Constant(unit("attitude", &q)?),
            AttitudeTarget::Table { attitude, rate } => {
                let rows = attitude.len() / 4;
                if attitude.is_empty() || attitude.len() % 4 != 0 {
                    return Err(Error::Dimension {
                        what: "attitude".into(),
                        expected: "a (steps, 4) table of quaternions (x, y, z, w)".into(),
                        given: format!("{} numbers", attitude.len()),
                    });
                }
                if !rate.is_empty() && rate.len() != 3 * rows {
                    return Err(Error::Dimension {
                        what: "rate".into(),
                        expected: format!("a ({rows}, 3) table (one row per attitude)"),
                        given: format!("{} numbers", rate.len()),
                    });
                }
                crate::args::check_finite("rate", &rate)?;
                let mut unit_rows = Vec::with_capacity(attitude.len());
                for (row, q) in attitude.chunks_exact(4).enumerate() {
                    unit_rows.extend(unit(&format!("attitude[{row}]"), q)?);
                }
                AttitudeTarget::Table {
                    attitude: unit_rows,
                    rate,
                }
            }
            AttitudeTarget::Initial => AttitudeTarget::Initial,
        };
        Ok(Self {
            kp,
            kd,
            target,
            allocation,
            latched: None,
        })
    }

    /// The number of wheels it drives (`k`).
    pub fn wheels(&self) -> usize {
        self.allocation.len() / 3
    }

    /// The allocation `M` (k×3, row-major).
    pub fn allocation(&self) -> &[f64] {
        &self.allocation
    }

    /// The target.
    pub fn target(&self) -> &AttitudeTarget {
        &self.target
    }

    /// The commanded bus torque `T` (N·m, base frame) at step `step` from the bus attitude
    /// `quat` and rate `omega` (base frame). Latches the initial attitude at step 0.
    pub fn bus_torque(&mut self, step: usize, quat: &[f64], omega: &Vec3) -> Vec3 {
        let (reference, rate) = match &self.target {
            AttitudeTarget::Initial => {
                if step == 0 || self.latched.is_none() {
                    let norm = quat.iter().map(|v| v * v).sum::<f64>().sqrt();
                    self.latched = Some([
                        quat[0] / norm,
                        quat[1] / norm,
                        quat[2] / norm,
                        quat[3] / norm,
                    ]);
                }
                (self.latched.unwrap_or([0.0, 0.0, 0.0, 1.0]), Vec3::zeros())
            }
            AttitudeTarget::Constant(q) => (*q, Vec3::zeros()),
            AttitudeTarget::Table { attitude, rate } => {
                let row = step.min(attitude.len() / 4 - 1);
                let q = [
                    attitude[4 * row],
                    attitude[4 * row + 1],
                    attitude[4 * row + 2],
                    attitude[4 * row + 3],
                ];
                let w = if rate.is_empty() {
                    Vec3::zeros()
                } else {
                    Vec3::new(rate[3 * row], rate[3 * row + 1], rate[3 * row + 2])
                };
                (q, w)
            }
        };
        let conj = [-reference[0], -reference[1], -reference[2], reference[3]];
        let mut q_e = quaternion_product(&conj, quat);
        if q_e[3] < 0.0 {
            q_e.iter_mut().for_each(|v| *v = -*v);
        }
        let e = Vec3::new(2.0 * q_e[0], 2.0 * q_e[1], 2.0 * q_e[2]);
        // the target's rate in base components: R(q_e)ᵀ ω_ref
        let rate_in_base = if rate == Vec3::zeros() {
            rate
        } else {
            crate::spatial::quaternion_to_rotation(&q_e).transpose() * rate
        };
        let de = omega - rate_in_base;
        Vec3::new(
            -self.kp[0] * e.x - self.kd[0] * de.x,
            -self.kp[1] * e.y - self.kd[1] * de.y,
            -self.kp[2] * e.z - self.kd[2] * de.z,
        )
    }
}

/// The quaternion `q` normalised, or an error naming `what` if it is not finite or zero.
fn unit(what: &str, q: &[f64]) -> Result<[f64; 4]> {
    crate::args::check_finite(what, q)?;
    let norm = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    // a norm that is NaN was refused above (finite values)
    if norm <= 1e-12 {
        return Err(Error::InvalidArgument {
            what: what.into(),
            message: format!(
                "a quaternion (x, y, z, w) of norm 1 is expected, given norm {norm:e}"
            ),
        });
    }
    Ok([q[0] / norm, q[1] / norm, q[2] / norm, q[3] / norm])
}

impl Controller for AttitudePD {
    fn output(&mut self, step: usize, _t: f64, x: &[f64], out: &mut [f64]) -> Result<()> {
        let k = self.wheels();
        check_length("wheel_torque", out.len(), k)?;
        let layout = layout_of(x.len(), k)?;
        let omega = Vec3::from_column_slice(&x[layout.base_twist()][..3]);
        let torque = self.bus_torque(step, &x[layout.quaternion()], &omega);
        for (w, u) in out.iter_mut().enumerate() {
            let m = &self.allocation[3 * w..3 * w + 3];
            *u = -(m[0] * torque.x + m[1] * torque.y + m[2] * torque.z);
        }
        Ok(())
    }

    fn feedback(&self) -> Feedback<'_> {
        Feedback::Unknown
    }

    fn check_run(&self, what: &str, width: usize, steps: usize) -> Result<()> {
        if width != self.wheels() {
            return Err(Error::Dimension {
                what: what.into(),
                expected: format!("an AttitudePD for {width} wheels (the arm's)"),
                given: format!("an allocation for {} wheels", self.wheels()),
            });
        }
        if let AttitudeTarget::Table { attitude, .. } = &self.target {
            let rows = attitude.len() / 4;
            if rows < steps {
                return Err(Error::Dimension {
                    what: "attitude".into(),
                    expected: format!("at least {steps} rows (one per step)"),
                    given: format!("{rows} rows"),
                });
            }
        }
        Ok(())
    }
}

/// The state layout of a state of `len` numbers with `k` wheels, or an error.
fn layout_of(len: usize, k: usize) -> Result<StateLayout> {
    let arm = len.checked_sub(13 + k).filter(|rest| rest % 4 == 0);
    match arm {
        Some(rest) => Ok(StateLayout::with_wheels(rest / 4, k)),
        None => Err(Error::Dimension {
            what: "x (state)".into(),
            expected: format!("length 13 + 4n + {k} (an arm with {k} reaction wheels)"),
            given: format!("length {len}"),
        }),
    }
}

/// The minimum-norm allocation `A⁺ = Aᵀ (A Aᵀ)⁻¹` (k×3, row-major) of wheels with unit spin
/// axes `axes` (base frame): the smallest wheel torques (in the 2-norm) whose reaction on the
/// bus is a given torque. An error naming the axes if they do not span three dimensions
/// (`A Aᵀ` singular to 1e-10 of its largest eigenvalue: all parallel, or all in one plane).
pub fn min_norm_allocation(axes: &[[f64; 3]]) -> Result<Vec<f64>> {
    let mut gram = Mat3::zeros();
    for a in axes {
        let a = Vec3::from(*a);
        gram += a * a.transpose();
    }
    let eig = nalgebra::SymmetricEigen::new(gram).eigenvalues;
    let (low, high) = (eig.min(), eig.max());
    let inverse = (low > 1e-10 * high).then(|| gram.try_inverse()).flatten();
    let Some(inverse) = inverse else {
        let listed: Vec<String> = axes
            .iter()
            .map(|a| format!("({}, {}, {})", a[0], a[1], a[2]))
            .collect();
        let span = if eig.iter().filter(|&&l| l > 1e-10 * high).count() <= 1 {
            "all lie along one line"
        } else {
            "all lie in one plane"
        };
        return Err(Error::InvalidArgument {
            what: "allocation".into(),
            message: format!(
                "the wheel axes {} {span}: they cannot hold the bus about all three axes; give \
                 wheels whose axes span three dimensions, or an allocation matrix (k, 3)",
                listed.join(", ")
            ),
        });
    };
    let mut m = Vec::with_capacity(3 * axes.len());
    for a in axes {
        let row = inverse * Vec3::from(*a);
        m.extend_from_slice(row.as_slice());
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_allocation_inverts_the_axes() {
        let s = 1.0 / 3f64.sqrt();
        let axes = [[s, s, s], [-s, s, s], [-s, -s, s], [s, -s, s]];
        let m = min_norm_allocation(&axes).unwrap();
        // A M = 1
        for i in 0..3 {
            for j in 0..3 {
                let v: f64 = axes
                    .iter()
                    .enumerate()
                    .map(|(w, a)| a[i] * m[3 * w + j])
                    .sum();
                assert!(
                    (v - f64::from(u8::from(i == j))).abs() < 1e-14,
                    "{i} {j} {v}"
                );
            }
        }
    }

    #[test]
    fn coplanar_axes_are_named() {
        let e = min_norm_allocation(&[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("(1, 0, 0), (0, 1, 0), (1, 0, 0) all lie in one plane"),
            "{e}"
        );
        let e = min_norm_allocation(&[[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]])
            .unwrap_err()
            .to_string();
        assert!(e.contains("all lie along one line"), "{e}");
    }
}
