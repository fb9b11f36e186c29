//! [`ReactionWheels`]: momentum wheels fixed in the bus, their exact dynamics in closed form, the
//! torque and speed limits, and the equivalent URDF.
//!
//! # The model (docs/model.md, "Reaction wheels")
//! Wheel `w` spins about a unit axis `a` fixed in the bus (base frame) with its centre at `p`,
//! mass `m`, spin inertia `J_s` about `a` and transverse inertia `J_t` about any axis through the
//! centre normal to `a`. Its speed `Ω` (rad/s) is relative to the bus, positive about `a`. The
//! motor applies `u` (N·m) to the wheel about `a` (the bus feels `−u a`); viscous friction
//! `c Ω` opposes the relative spin (the bus feels `+c Ω a`).
//!
//! The rotor is axisymmetric, so its inertia in bus axes, `J_t (𝟙 − a aᵀ) + J_s a aᵀ`, does not
//! depend on the wheel angle, which therefore never enters the dynamics: the state holds `Ω`
//! only. With `ω` the bus rate, the wheel's angular momentum about its centre splits exactly into
//! a part locked to the bus and a free axial part:
//!
//! ```text
//! L_w = J_t (𝟙 − a aᵀ) ω + h a,        h = J_s (a·ω + Ω)
//! ```
//! The axial component of Euler's equation (bearing torques are normal to `a`, and
//! `L_w · (ω × a) = 0`) gives
//!
//! ```text
//! J_s (a·ω̇ + Ω̇) = u − c Ω                                                        (W1)
//! ```
//! and the bus supplies the rest of `d L_w/dt`: beyond the locked part it feels the moment
//!
//! ```text
//! n_w = −a (u − c Ω) − ω × (h a)                                                (W2)
//! ```
//! (a pure moment, the same about every point). Hence the bus with wheels is exactly
//! 1. the user's base inertia plus, per wheel, the mass `m` at `p` and the rotational inertia
//!    `J_t (𝟙 − a aᵀ)` about `p` ([`ReactionWheels::locked_inertia`], built once);
//! 2. acted on by `Σ n_w` in addition to its base wrench ([`ReactionWheels::base_moment`]);
//! 3. with `Ω̇ = (u − c Ω)/J_s − a·ω̇` once the arm's dynamics give `ω̇`
//!    ([`ReactionWheels::speed_rates`]).
//!
//! This is the articulated-body algorithm for a symmetric rotor on the base, in closed form (the
//! rotor's articulated inertia seen from the bus lacks exactly `J_s a aᵀ`): the dynamics equal
//! those of the robot with each wheel a link on a continuous joint of the root
//! ([`ReactionWheels::to_urdf`]), joint velocity `Ω`, joint torque `u − c Ω`.
//!
//! # Conserved quantities
//! Without external wrench the total momentum of bus, arm and wheels is constant for any `u` and
//! `c`: the locked parts are in the augmented base, and the spin part adds `R_B Σ h a` (a free
//! vector) to the angular momentum. The energy gains `Σ ½ J_s (a·ω + Ω)²` and changes at the
//! rate `Σ (u − c Ω) Ω`.
//!
//! # Limits (in the manner of Basilisk's `reactionWheelStateEffector`)
//! Once per step, the commanded torque is clipped to `±max_torque`; a wheel at or beyond
//! `max_speed` gets no torque that would speed it up further ([`saturated_torque`]).

use crate::args::check_vector;
use crate::error::{Error, Result};
use crate::model::{check_inertia, Robot};
use crate::spatial::{Inertia, Mat3, Transform, Vec3};

/// How far from 1 the norm of a given axis may be (relative) and still be taken as a unit vector
/// (and normalised): digits typed from a table, `0.57735` for `1/√3`, pass; a vector that is
/// not meant to be unit is refused, not silently rescaled.
pub const AXIS_TOLERANCE: f64 = 1e-5;

/// One reaction wheel, in base-frame components: the values a data sheet gives. (Serialised by
/// an FMU's `fmu.toml`, with these field names.)
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Wheel {
    /// Unit spin axis `a`, fixed in the bus (base frame).
    pub axis: [f64; 3],
    /// Centre `p` of the wheel, base frame (m).
    pub position: [f64; 3],
    /// Mass `m` (kg), > 0.
    pub mass: f64,
    /// `J_s` (kg·m²), > 0: inertia about the spin axis.
    pub spin_inertia: f64,
    /// `J_t` (kg·m²): inertia about any axis through the centre normal to the spin axis;
    /// `J_t ≥ J_s / 2` (a thin disc has `J_t = J_s / 2`).
    pub transverse_inertia: f64,
    /// Motor torque limit (N·m), > 0 (`f64::INFINITY`: none).
    pub max_torque: f64,
    /// Speed limit relative to the bus (rad/s), > 0 (`f64::INFINITY`: none).
    pub max_speed: f64,
    /// Viscous friction `c` (N·m·s/rad), ≥ 0, on the relative speed.
    pub friction: f64,
}

/// `k ≥ 1` reaction wheels fixed in the bus, validated (see the module docs for the model).
///
/// ```
/// use orbitflex::flex::{ReactionWheels, Wheel};
/// let wheel = |axis| Wheel { axis, position: [0.0, 0.0, 0.5], mass: 5.0, spin_inertia: 0.05,
///     transverse_inertia: 0.03, max_torque: 0.2, max_speed: 600.0, friction: 0.0 };
/// let wheels = ReactionWheels::new(vec![wheel([1.0, 0.0, 0.0]), wheel([0.0, 1.0, 0.0])])?;
/// assert_eq!(wheels.len(), 2);
/// let err = ReactionWheels::new(vec![wheel([1.0, 1.0, 0.0])]).unwrap_err();
/// assert!(err.to_string().starts_with("axes[0]: expected a unit vector"));
/// # Ok::<(), orbitflex::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct ReactionWheels {
    wheels: Vec<Wheel>,
}

impl ReactionWheels {
    /// Checks every wheel and normalises the axes. Errors name the parameter and the wheel
    /// (`spin_inertia[2]`), with what was expected and what was given:
    /// - no wheel;
    /// - a value that is not finite (the limits may be `+∞`);
    /// - an axis whose norm is not 1 within [`AXIS_TOLERANCE`];
    /// - `mass`, `spin_inertia`, `max_torque`, `max_speed` not > 0; `friction` not ≥ 0;
    /// - an inertia that no rigid rotor has (`J_t < J_s / 2`, the triangle inequality), or
    ///   beyond the supported range ([`check_inertia`]).
    pub fn new(mut wheels: Vec<Wheel>) -> Result<Self> {
        if wheels.is_empty() {
            return Err(Error::InvalidArgument {
                what: "ReactionWheels".into(),
                message: "expected at least one wheel, given none (an arm without wheels takes \
                          no ReactionWheels)"
                    .into(),
            });
        }
        for (w, wheel) in wheels.iter_mut().enumerate() {
            check_wheel(w, wheel)?;
            let norm = Vec3::from(wheel.axis).norm();
            wheel.axis = wheel.axis.map(|v| v / norm);
        }
        Ok(Self { wheels })
    }

    /// Wheels read back from a file written from [`wheels`](Self::wheels) (an FMU's
    /// resources): checked as [`new`](Self::new) checks them, but the axes, already normalised
    /// once, are kept bit for bit (normalising again could move them by a rounding, and the
    /// dynamics with them).
    pub(crate) fn normalised(wheels: Vec<Wheel>) -> Result<Self> {
        if wheels.is_empty() {
            return Self::new(wheels);
        }
        for (w, wheel) in wheels.iter().enumerate() {
            check_wheel(w, wheel)?;
        }
        Ok(Self { wheels })
    }

    /// Number of wheels `k`.
    pub fn len(&self) -> usize {
        self.wheels.len()
    }

    /// Never true: there is at least one wheel.
    pub fn is_empty(&self) -> bool {
        self.wheels.is_empty()
    }

    /// The wheels, axes normalised.
    pub fn wheels(&self) -> &[Wheel] {
        &self.wheels
    }

    /// The minimum-norm torque allocation of these wheels (k×3, row-major,
    /// [`crate::control::min_norm_allocation`] of their axes): what
    /// [`AttitudePD`](crate::control::AttitudePD) uses by default. An error naming the axes if
    /// they do not span three dimensions.
    pub fn allocation(&self) -> Result<Vec<f64>> {
        let axes: Vec<[f64; 3]> = self.wheels.iter().map(|w| w.axis).collect();
        crate::control::min_norm_allocation(&axes)
    }

    /// What the wheels add to the bus as rigid bodies locked to it: per wheel the mass `m` at
    /// `p` and the rotational inertia `J_t (𝟙 − a aᵀ)` about `p` (no spin inertia: that is
    /// the free axial part), summed about the base origin in base axes.
    pub fn locked_inertia(&self) -> Inertia {
        self.wheels.iter().fold(Inertia::zero(), |sum, wheel| {
            let a = Vec3::from(wheel.axis);
            let transverse = (Mat3::identity() - a * a.transpose()) * wheel.transverse_inertia;
            sum.add(&Inertia::from_com(
                wheel.mass,
                Vec3::from(wheel.position),
                transverse,
            ))
        })
    }

    /// `Σ n_w` (W2): the moment (N·m, base frame) the wheels exert on the bus beyond their locked
    /// parts, at bus rate `omega`, speeds `speed` (k) and applied torques `torque` (k, or empty
    /// for none).
    #[inline]
    pub fn base_moment(&self, omega: &Vec3, speed: &[f64], torque: &[f64]) -> Vec3 {
        let mut sum = Vec3::zeros();
        for (w, wheel) in self.wheels.iter().enumerate() {
            sum += wheel_moment_on_bus(
                wheel,
                omega,
                speed[w],
                torque.get(w).copied().unwrap_or(0.0),
            );
        }
        sum
    }

    /// `Ω̇` (W1) into `out` (k) from the bus's angular acceleration `omega_dot` (base frame).
    #[inline]
    pub fn speed_rates(&self, omega_dot: &Vec3, speed: &[f64], torque: &[f64], out: &mut [f64]) {
        for (w, (wheel, rate)) in self.wheels.iter().zip(out).enumerate() {
            let u = torque.get(w).copied().unwrap_or(0.0);
            *rate = wheel_acceleration(wheel, omega_dot, speed[w], u);
        }
    }

    /// `Σ h a`: the wheels' axial (spin) angular momentum, base frame (N·m·s). A free vector:
    /// the total angular momentum adds it rotated to inertial axes, about any point.
    pub fn spin_momentum(&self, omega: &Vec3, speed: &[f64]) -> Vec3 {
        self.wheels
            .iter()
            .zip(speed)
            .map(|(wheel, &s)| Vec3::from(wheel.axis) * axial_momentum(wheel, omega, s))
            .sum()
    }

    /// `Σ ½ J_s (a·ω + Ω)²`: the kinetic energy of the spin beyond the locked parts (J).
    pub fn spin_energy(&self, omega: &Vec3, speed: &[f64]) -> f64 {
        self.wheels
            .iter()
            .zip(speed)
            .map(|(wheel, &s)| {
                let spin = Vec3::from(wheel.axis).dot(omega) + s;
                0.5 * wheel.spin_inertia * spin * spin
            })
            .sum()
    }

    /// The torques the motors apply ([`saturated_torque`] per wheel) for the commands `command`
    /// (k, or empty for none) at speeds `speed` (k), into `applied` (k).
    #[inline]
    pub fn saturate(&self, command: &[f64], speed: &[f64], applied: &mut [f64]) {
        for (w, (wheel, out)) in self.wheels.iter().zip(applied).enumerate() {
            *out = saturated_torque(wheel, command.get(w).copied().unwrap_or(0.0), speed[w]);
        }
    }

    /// Checks commanded torques: `k` finite numbers, or none (empty: zero torque).
    pub fn check_torque(&self, torque: &[f64]) -> Result<()> {
        if torque.is_empty() {
            return Ok(());
        }
        check_vector("wheel_torque", torque, self.len())
    }

    /// The names of wheel `w`'s link and joint in [`to_urdf`](Self::to_urdf):
    /// `reaction_wheel_{w}` and `reaction_wheel_{w}_spin`.
    pub fn urdf_names(w: usize) -> (String, String) {
        (
            format!("reaction_wheel_{w}"),
            format!("reaction_wheel_{w}_spin"),
        )
    }

    /// `robot` as URDF ([`Robot::to_urdf`]) with each wheel a link on a continuous joint of the
    /// root: link [`urdf_names`](Self::urdf_names) with its mass at the joint origin `p` and
    /// inertia `diag(J_t, J_t, J_s)` in a frame whose `z` is the spin axis `a`, joint axis
    /// `0 0 1`. Its rigid dynamics (joint velocity `Ω`, joint torque `u − c Ω`) are those of an
    /// arm with these wheels. An error if a wheel's name is taken by one of the robot's links or
    /// joints.
    pub fn to_urdf(&self, robot: &Robot) -> Result<String> {
        let taken: Vec<&str> = robot
            .body_names()
            .iter()
            .map(String::as_str)
            .chain(robot.joint_names())
            .chain(robot.ee_links())
            .collect();
        let mut extra = String::new();
        for (w, wheel) in self.wheels.iter().enumerate() {
            let (link, joint) = Self::urdf_names(w);
            if let Some(name) = [&link, &joint]
                .into_iter()
                .find(|n| taken.contains(&n.as_str()))
            {
                return Err(Error::InvalidArgument {
                    what: "ReactionWheels.to_urdf".into(),
                    message: format!(
                        "the robot already has a link or joint named '{name}', the name of wheel \
                         {w}; rename it in the robot"
                    ),
                });
            }
            let spin_frame = Transform::new(
                crate::model::to_z(&Vec3::from(wheel.axis)),
                Vec3::from(wheel.position),
            );
            let inertia = Inertia::from_com(
                wheel.mass,
                Vec3::zeros(),
                Mat3::from_diagonal(&Vec3::new(
                    wheel.transverse_inertia,
                    wheel.transverse_inertia,
                    wheel.spin_inertia,
                )),
            );
            let root = robot.body_names()[0].as_str();
            extra.push_str(&crate::model::urdf_write::link(&link, &inertia));
            extra.push_str(&format!(
                "  <joint name=\"{joint}\" type=\"continuous\">\n    <parent link=\"{}\"/>\n    <child link=\"{link}\"/>\n{}    <axis xyz=\"0 0 1\"/>\n  </joint>\n",
                crate::model::urdf_write::escape(root),
                crate::model::urdf_write::origin(&spin_frame),
            ));
        }
        Ok(crate::model::urdf_write::write_urdf(robot, &extra))
    }
}

/// Checks one wheel (see [`ReactionWheels::new`]).
fn check_wheel(w: usize, wheel: &Wheel) -> Result<()> {
    let bad = |what: &str, message: String| Error::InvalidArgument {
        what: format!("{what}[{w}]"),
        message,
    };
    for (what, v) in [("axes", &wheel.axis), ("positions", &wheel.position)] {
        if let Some(i) = v.iter().position(|x| !x.is_finite()) {
            return Err(bad(what, format!("element {i} is not finite ({})", v[i])));
        }
    }
    let norm = Vec3::from(wheel.axis).norm();
    // finite components: the norm is finite or +inf (refused), never NaN
    if (norm - 1.0).abs() > AXIS_TOLERANCE {
        return Err(bad(
            "axes",
            format!(
                "expected a unit vector (norm 1 within {AXIS_TOLERANCE:e}), given {:?} of norm \
                 {norm}",
                wheel.axis
            ),
        ));
    }
    for (what, v, zero_ok, infinite_ok) in [
        ("mass", wheel.mass, false, false),
        ("spin_inertia", wheel.spin_inertia, false, false),
        ("transverse_inertia", wheel.transverse_inertia, false, false),
        ("max_torque", wheel.max_torque, false, true),
        ("max_speed", wheel.max_speed, false, true),
        ("friction", wheel.friction, true, false),
    ] {
        let finite = v.is_finite() || (infinite_ok && v == f64::INFINITY);
        let in_domain = if zero_ok { v >= 0.0 } else { v > 0.0 };
        if !(finite && in_domain) {
            let domain = if zero_ok { ">= 0" } else { "> 0" };
            let inf = if infinite_ok { " (inf: no limit)" } else { "" };
            return Err(bad(
                what,
                format!("expected a finite number {domain}{inf}, given {v}"),
            ));
        }
    }
    let about_centre = Mat3::from_diagonal(&Vec3::new(
        wheel.transverse_inertia,
        wheel.transverse_inertia,
        wheel.spin_inertia,
    ));
    check_inertia(wheel.mass, &Vec3::zeros(), &about_centre).map_err(|message| {
        let hint = if wheel.spin_inertia > 2.0 * wheel.transverse_inertia {
            format!(
                "; a rigid rotor has transverse_inertia >= spin_inertia / 2 ({} kg·m² here)",
                wheel.spin_inertia / 2.0
            )
        } else {
            String::new()
        };
        bad(
            "transverse_inertia",
            format!(
                "the wheel's inertia diag(J_t, J_t, J_s) = diag({0}, {0}, {1}) kg·m² with mass {2} \
                 kg is not physical: {message}{hint}",
                wheel.transverse_inertia, wheel.spin_inertia, wheel.mass
            ),
        )
    })
}

/// `h = J_s (a·ω + Ω)`: the wheel's axial angular momentum (N·m·s).
#[inline]
pub fn axial_momentum(wheel: &Wheel, omega: &Vec3, speed: f64) -> f64 {
    wheel.spin_inertia * (Vec3::from(wheel.axis).dot(omega) + speed)
}

/// (W2) `n_w = −a (u − c Ω) − ω × (h a)`: the moment (N·m, base frame) one wheel exerts on the
/// bus beyond its locked part, at bus rate `omega`, speed `speed` and applied torque `torque`.
#[inline]
pub fn wheel_moment_on_bus(wheel: &Wheel, omega: &Vec3, speed: f64, torque: f64) -> Vec3 {
    let a = Vec3::from(wheel.axis);
    let drive = torque - wheel.friction * speed;
    -(a * drive) - omega.cross(&(a * axial_momentum(wheel, omega, speed)))
}

/// (W1) `Ω̇ = (u − c Ω)/J_s − a·ω̇`: one wheel's acceleration relative to the bus (rad/s²).
#[inline]
pub fn wheel_acceleration(wheel: &Wheel, omega_dot: &Vec3, speed: f64, torque: f64) -> f64 {
    (torque - wheel.friction * speed) / wheel.spin_inertia - Vec3::from(wheel.axis).dot(omega_dot)
}

/// The torque the motor applies for `command` at speed `speed`, in the manner of Basilisk's
/// `reactionWheelStateEffector`: clipped to `±max_torque`, then cut to zero when the wheel is
/// at or beyond `max_speed` and the torque has the sign of `Ω` (it would speed the wheel up
/// further). A torque that slows the wheel down always passes.
///
/// ```
/// use orbitflex::flex::{saturated_torque, Wheel};
/// let wheel = Wheel { axis: [0.0, 0.0, 1.0], position: [0.0; 3], mass: 5.0, spin_inertia: 0.05,
///     transverse_inertia: 0.03, max_torque: 0.2, max_speed: 600.0, friction: 0.0 };
/// assert_eq!(saturated_torque(&wheel, 0.5, 0.0), 0.2);
/// assert_eq!(saturated_torque(&wheel, 0.1, 600.0), 0.0);
/// assert_eq!(saturated_torque(&wheel, -0.1, 600.0), -0.1);
/// ```
#[inline]
pub fn saturated_torque(wheel: &Wheel, command: f64, speed: f64) -> f64 {
    let u = command.clamp(-wheel.max_torque, wheel.max_torque);
    if speed.abs() >= wheel.max_speed && u * speed > 0.0 {
        0.0
    } else {
        u
    }
}

/// [`FlexibleArm::derivative`](super::FlexibleArm::derivative) of an arm with wheels, `tau`
/// holding the spring torques: the arm's forward dynamics on the augmented `robot` with the
/// wheels' moment `Σ n_w` (W2) added to `f_B`, then `Ω̇` (W1) from the bus's `ω̇`. The wheel
/// torques in `inputs` are applied as given (already saturated); `mounted` holds the wheels and
/// the augmented robot.
#[inline]
pub(super) fn derivative_with_wheels(
    arm: &super::FlexibleArm,
    mounted: &super::arm::Mounted,
    data: &mut crate::algorithms::Data,
    tau: &[f64],
    x: &[f64],
    inputs: &super::Inputs,
    xdot: &mut [f64],
) -> Result<()> {
    let (wheels, robot) = (&mounted.wheels, &mounted.robot);
    let layout = arm.layout();
    let s = layout.split(x);
    let mut loads = inputs.loads;
    loads.base_wrench.angular += wheels.base_moment(&s.omega(), s.wheel_speed, inputs.wheel_torque);
    let rigid = crate::args::RigidState::new(s.q, s.base_twist, s.qd);
    arm.method()
        .forward_dynamics_unchecked(robot, data, &rigid, tau, &loads)?;
    let acc = data.ddq.as_slice();
    arm.assemble_derivative(x, inputs, tau, acc, xdot);
    let omega_dot = Vec3::new(acc[0], acc[1], acc[2]);
    wheels.speed_rates(
        &omega_dot,
        s.wheel_speed,
        inputs.wheel_torque,
        &mut xdot[layout.wheel_speed()],
    );
    Ok(())
}

/// The slope `∂u/∂command` of [`saturated_torque`] at `command` and `speed`: 1 where the command
/// passes unchanged (strictly inside `±max_torque`, and not cut by the speed limit), 0 where it
/// is clipped or cut. At the kinks (`|command| = max_torque`, or a wheel at `max_speed` with
/// `command = 0`) the side that limits is taken.
#[inline]
pub fn saturation_slope(wheel: &Wheel, command: f64, speed: f64) -> f64 {
    let clipped = command.abs() >= wheel.max_torque;
    let cut = speed.abs() >= wheel.max_speed && command * speed >= 0.0;
    if clipped || cut {
        0.0
    } else {
        1.0
    }
}

/// Adds the wheels' terms to the Jacobians `out` of the derivative at `x` (tangent coordinates),
/// whose rigid rows already hold the dynamics of the augmented bus loaded with `Σ n_w` (so that
/// `out.base_wrench` is `∂[α_B; q̈]/∂f_B` there). With `h = J_s (a·ω + Ω)` and `u` the applied
/// torque, (W2) varies as
///
/// ```text
/// δn_w = (h [a]× + J_s (a × ω) aᵀ) δω + (J_s (a × ω) + c a) δΩ − a δu
/// ```
///
/// which enters the rigid rows through `∂/∂f_B`'s moment columns, and (W1) gives the wheel rows
/// `δΩ̇ = −aᵀ δω̇ − (c/J_s) δΩ + δu/J_s`. `δu = s δu_cmd` with `s` the
/// [`saturation_slope`]; `command` holds the commanded torques (k, or empty for zero).
pub(super) fn add_wheel_jacobians(
    wheels: &ReactionWheels,
    layout: crate::state::StateLayout,
    x: &[f64],
    command: &[f64],
    out: &mut super::Jacobians,
) {
    let n = layout.n;
    let k = wheels.len();
    let rows = out.x.nrows();
    let (twist, wheel0) = (6 + 2 * n, 12 + 4 * n);
    let s = layout.split(x);
    let omega = s.omega();
    out.wheel_torque = nalgebra::DMatrix::zeros(rows, k);
    // ∂n/∂ω (3×3), ∂n/∂Ω (3×k), ∂n/∂u_cmd (3×k)
    let mut d_omega = Mat3::zeros();
    let mut d_speed = nalgebra::Matrix3xX::zeros(k);
    let mut d_command = nalgebra::Matrix3xX::zeros(k);
    for (w, wheel) in wheels.wheels().iter().enumerate() {
        let a = Vec3::from(wheel.axis);
        let h = axial_momentum(wheel, &omega, s.wheel_speed[w]);
        let gyro = a.cross(&omega) * wheel.spin_inertia;
        d_omega += crate::spatial::skew(&a) * h + gyro * a.transpose();
        d_speed.set_column(w, &(gyro + a * wheel.friction));
        let cmd = command.get(w).copied().unwrap_or(0.0);
        let slope = saturation_slope(wheel, cmd, s.wheel_speed[w]);
        d_command.set_column(w, &(-a * slope));
    }
    // the rigid rows (twist and q̈): through the moment columns of ∂/∂f_B
    for r in (twist..twist + 6).chain(12 + 2 * n..12 + 3 * n) {
        let g = nalgebra::RowVector3::new(
            out.base_wrench[(r, 0)],
            out.base_wrench[(r, 1)],
            out.base_wrench[(r, 2)],
        );
        let by_omega = g * d_omega;
        for j in 0..3 {
            out.x[(r, twist + j)] += by_omega[j];
        }
        let by_speed = g * &d_speed;
        let by_command = g * &d_command;
        for w in 0..k {
            out.x[(r, wheel0 + w)] += by_speed[w];
            out.wheel_torque[(r, w)] = by_command[w];
        }
    }
    // the wheel rows: δΩ̇ = −aᵀ δω̇ − (c/J_s) δΩ + s δu_cmd / J_s
    for (w, wheel) in wheels.wheels().iter().enumerate() {
        let row = wheel0 + w;
        let a = wheel.axis;
        for block in [
            &mut out.x,
            &mut out.u,
            &mut out.base_wrench,
            &mut out.ee_wrench,
            &mut out.wheel_torque,
        ] {
            for c in 0..block.ncols() {
                block[(row, c)] = -(0..3).map(|m| a[m] * block[(twist + m, c)]).sum::<f64>();
            }
        }
        out.x[(row, row)] -= wheel.friction / wheel.spin_inertia;
        let cmd = command.get(w).copied().unwrap_or(0.0);
        out.wheel_torque[(row, w)] +=
            saturation_slope(wheel, cmd, s.wheel_speed[w]) / wheel.spin_inertia;
    }
}
