//! Motor PD gains chosen from the physics of each joint: a closed-loop bandwidth and a damping
//! ratio, placed exactly on the joint's two-mass model (docs/model.md §5.3). No step size enters:
//! the controller is a property of the arm, and the integrator's step must then be chosen within
//! the closed loop's stability limit ([`FlexibleArm::rk4_stability_limit`]), never the other way
//! round.
//!
//! Joint `i` is a motor `j` coupled by the spring `k` and damper `d` to a link of inertia `m`,
//! the link-side inertia the joint sees at the configuration `q`: the diagonal of the
//! free-floating joint-space inertia `H = M_r − M_br M_b⁻¹ M_rb` (base free, the other joints
//! held by their own servos). The motor PD `u = k_p (θ_ref − θ) + k_d (θ̇_ref − θ̇)`, with motor
//! friction `β`, closes the loop
//!
//! ```text
//! P(s) = A(s) + (k_p + k_d s) B(s),   B(s) = m s² + d s + k,
//! A(s) = (m s² + d s + k)(j s² + β s) + m s² (d s + k)
//! ```
//! (the characteristic polynomial of link and motor). The gains put two of its four roots at the
//! roots of `s² + 2ζω s + ω²`, `ω = 2π f`: `k_p + k_d s` must equal `R(s) = −A(s)/B(s)` there,
//! i.e. it is `R` reduced modulo that quadratic. Reducing with `s² ≡ −2ζω s − ω²`,
//! `−(j s² + β s) ≡ j ω² + (2ζω j − β) s`, and the link's part `−m s² (d s + k)/B(s) ≡ a + b s`
//! where, with `B ≡ D₁ s + D₀` and `−m s² (d s + k) ≡ P₁ s + P₀`,
//!
//! ```text
//! D₀ = k − m ω²,          D₁ = d − 2 m ζ ω,
//! P₀ = m (k ω² − 2 d ζ ω³), P₁ = m (2 k ζ ω − d (4ζ² − 1) ω²),
//! D₀ a − ω² D₁ b = P₀,    D₁ a + (D₀ − 2ζω D₁) b = P₁.
//! ```
//! So `k_p = j ω² + a`, `k_d = 2ζω j − β + b`. The system's determinant is `B(s₁) B(s₂)`: zero
//! exactly when a requested pole is the link's own resonance with the motor held, which no motor
//! gain can move. For a stiff joint (`k ≫ m ω²`) `a → m ω²`, `b → 2 m ζ ω`, and the gains become
//! the rigid rule `k_p = (j + m) ω²`, `k_d = 2ζω (j + m) − β`; the spring raises the apparent
//! link inertia `m (d s + k)/B(s)` as `ω` nears the resonance, and the exact form accounts for it.
//!
//! The other two roots (the joint's vibration mode) are left where the loop puts them; a
//! collocated PD with `k_p, k_d ≥ 0` keeps them stable. Where the motor friction alone already
//! damps the placed pair more than `ζ` asks (`k_d < 0` above), `k_d = 0`.

use super::arm::FlexibleArm;
use crate::algorithms::{self, Data};
use crate::args::check_vector;
use crate::error::{Error, Result};

/// Motor PD gains per joint ([`FlexibleArm::motor_pd_gains`]).
#[derive(Debug, Clone, PartialEq)]
pub struct MotorGains {
    /// `k_p` (N·m/rad), one per joint.
    pub kp: Vec<f64>,
    /// `k_d` (N·m·s/rad), one per joint.
    pub kd: Vec<f64>,
    /// The link-side inertia `m_i` each joint drives (kg·m²): the diagonal of the free-floating
    /// joint-space inertia at the configuration the gains were chosen at.
    pub link_inertia: Vec<f64>,
}

/// `value` is a finite number > 0, or an error naming `what`.
fn check_positive(what: &str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        return Ok(());
    }
    Err(Error::InvalidArgument {
        what: what.into(),
        message: format!(
            "expected a finite number > 0, given {}",
            crate::args::number(value)
        ),
    })
}

/// The diagonal of the free-floating joint-space inertia `H = M_r − M_br M_b⁻¹ M_rb` at `q`
/// (kg·m²): the inertia joint `i` drives with the base free and the other joints held.
pub fn free_floating_inertia(arm: &FlexibleArm, q: &[f64]) -> Result<Vec<f64>> {
    let robot = arm.robot();
    let n = robot.dof();
    let mut data = Data::new(robot);
    let mass = algorithms::crba(robot, &mut data, q)?;
    let base = mass.view((0, 0), (6, 6)).into_owned();
    let cholesky = base.cholesky().ok_or_else(|| Error::InvalidModel {
        source_name: robot.source().to_string(),
        message: "the composite inertia about the base is not positive definite".into(),
    })?;
    Ok((0..n)
        .map(|i| {
            let column = mass.view((0, 6 + i), (6, 1)).into_owned();
            mass[(6 + i, 6 + i)] - column.dot(&cholesky.solve(&column))
        })
        .collect())
}

impl FlexibleArm {
    /// The motor servo of a tracking loop: `k_p = j ω²`, `k_d = 2 j ω` per joint (N·m/rad,
    /// N·m·s/rad), `ω = 2π bandwidth_hz`, `j` the motor inertia: each motor a critically damped
    /// servo on its own inertia, whatever drives the link (the rule of `orbitflex plan`'s tracking
    /// PD, which [`motor_pd_gains`](Self::motor_pd_gains) refines with the link and the spring).
    /// An error when `bandwidth_hz` is not a finite number > 0.
    ///
    /// ```
    /// use orbitflex::{FlexibleArm, FlexibleJoints, Robot};
    /// let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
    /// let (kp, kd) = arm.motor_servo_gains(5.0)?;
    /// let (j, w) = (arm.joints().motor_inertia[0], 2.0 * std::f64::consts::PI * 5.0);
    /// assert_eq!((kp[0], kd[0]), (j * (w * w), 2.0 * j * w));
    /// # Ok::<(), orbitflex::Error>(())
    /// ```
    pub fn motor_servo_gains(&self, bandwidth_hz: f64) -> Result<(Vec<f64>, Vec<f64>)> {
        check_positive("bandwidth", bandwidth_hz)?;
        let w = 2.0 * std::f64::consts::PI * bandwidth_hz;
        let j = &self.joints().motor_inertia;
        Ok((
            j.iter().map(|j| j * (w * w)).collect(),
            j.iter().map(|j| 2.0 * j * w).collect(),
        ))
    }

    /// Motor PD gains that give each joint a closed loop of `bandwidth_hz` (Hz) and
    /// `damping_ratio` (ζ > 0), from its motor inertia, its link-side inertia at `q` (n, rad)
    /// and its spring (module [`crate::flex::gains`] derives them). Errors name the joint whose
    /// spring cannot carry the bandwidth (its link resonates at or below it).
    ///
    /// ```
    /// use orbitflex::{FlexibleArm, FlexibleJoints, Robot};
    /// let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
    /// let gains = arm.motor_pd_gains(&[0.0; 7], 0.25, 1.0)?;
    /// // the rigid rule kp = (j + m) ω², kd = 2ζω (j + m) − β, corrected for the spring
    /// let (j, m, w) = (arm.joints().motor_inertia[1], gains.link_inertia[1], 2.0 * std::f64::consts::PI * 0.25);
    /// assert!((gains.kp[1] / ((j + m) * w * w) - 1.0).abs() < 0.1);
    /// # Ok::<(), orbitflex::Error>(())
    /// ```
    pub fn motor_pd_gains(
        &self,
        q: &[f64],
        bandwidth_hz: f64,
        damping_ratio: f64,
    ) -> Result<MotorGains> {
        check_vector("q", q, self.dof())?;
        check_positive("bandwidth", bandwidth_hz)?;
        check_positive("damping_ratio", damping_ratio)?;
        let link_inertia = free_floating_inertia(self, q)?;
        let p = self.joints();
        let (w, zeta) = (2.0 * std::f64::consts::PI * bandwidth_hz, damping_ratio);
        let (mut kp, mut kd) = (
            Vec::with_capacity(self.dof()),
            Vec::with_capacity(self.dof()),
        );
        let mut too_soft = Vec::new();
        for (i, &m) in link_inertia.iter().enumerate() {
            let (k, d, j, beta) = (
                p.stiffness[i],
                p.damping[i],
                p.motor_inertia[i],
                p.motor_damping[i],
            );
            let (d0, d1) = (k - m * w * w, d - 2.0 * m * zeta * w);
            let p0 = m * (k * w * w - 2.0 * d * zeta * w * w * w);
            let p1 = m * (2.0 * k * zeta * w - d * (4.0 * zeta * zeta - 1.0) * w * w);
            let det = d0 * (d0 - 2.0 * zeta * w * d1) + w * w * d1 * d1;
            let a = (p0 * (d0 - 2.0 * zeta * w * d1) + w * w * d1 * p1) / det;
            let b = (d0 * p1 - d1 * p0) / det;
            let (gain_p, gain_d) = (j * w * w + a, 2.0 * zeta * w * j - beta + b);
            if !(gain_p.is_finite() && gain_p > 0.0 && gain_d.is_finite()) {
                too_soft.push(format!(
                    "{} Hz for joint {i} ('{}', {} kg·m² on {} N·m/rad)",
                    crate::args::short((k / m).sqrt() / (2.0 * std::f64::consts::PI)),
                    self.robot().joint_names()[i],
                    crate::args::short(m),
                    crate::args::number(k),
                ));
            }
            kp.push(gain_p);
            kd.push(gain_d.max(0.0));
        }
        if !too_soft.is_empty() {
            return Err(Error::InvalidArgument {
                what: "bandwidth".into(),
                message: format!(
                    "{} Hz is more than the joints' springs can carry: a motor PD cannot place the \
                     closed loop at or above the resonance of a link on its spring with the motor \
                     held, which is {}; ask for well below it",
                    crate::args::number(bandwidth_hz),
                    too_soft.join(", "),
                ),
            });
        }
        Ok(MotorGains {
            kp,
            kd,
            link_inertia,
        })
    }
}

#[cfg(test)]
mod tests {
    use crate::{FlexibleArm, FlexibleJoints, Robot};

    #[test]
    fn the_servo_is_critically_damped_on_each_motors_inertia() {
        let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
        let (kp, kd) = arm.motor_servo_gains(5.0).unwrap();
        let w = 2.0 * std::f64::consts::PI * 5.0;
        assert_eq!(kp.len(), arm.dof());
        for (i, &j) in arm.joints().motor_inertia.iter().enumerate() {
            // j s² + kd s + kp = j (s + ω)²
            assert_eq!(kp[i], j * (w * w), "joint {i}");
            assert_eq!(kd[i], 2.0 * j * w, "joint {i}");
        }
        for bad in [0.0, -5.0, f64::NAN, f64::INFINITY] {
            let message = arm.motor_servo_gains(bad).unwrap_err().to_string();
            assert!(
                message.starts_with("bandwidth: expected a finite number > 0, given"),
                "{message}"
            );
        }
        assert!(arm.motor_pd_gains(&[0.0; 7], 0.25, 1.0).is_ok());
        let message = arm.motor_pd_gains(&[0.0; 7], 0.25, 0.0).unwrap_err();
        assert!(
            message.to_string().starts_with("damping_ratio: "),
            "{message}"
        );
    }
}
