//! [`Plan::wheel_demand`]: what holding the bus through a held-base plan asks of reaction wheels.
//!
//! A held bus does not turn (`ω_B = 0`), so each wheel's moment on it is `−a (u_w − c Ω)` (the
//! gyroscopic `ω × h` vanishes). The wheels deliver the moment part `M` of the plan's holding
//! wrench (base frame; a couple, so the point does not matter) when `−Σ a_w τ_w = M` with
//! `τ_w = u_w − c_w Ω_w`; the minimum-norm choice is `τ = −A⁺ M` (`A = [a_1 … a_k]`). Then
//! `J_s Ω̇_w = τ_w`: the speeds are the integrals `Ω_w = ∫ τ_w / J_s` from rest, taken by the
//! trapezoid rule over the plan's samples (dense where the plan peaks), the motor torques
//! `u_w = τ_w + c_w Ω_w`, and the stored spin momentum `h = Σ J_s Ω_w a_w = −∫ M`. The force
//! part of the wrench is not the wheels' to give (thrusters, or a drifting bus).

use super::slew::Plan;
use crate::error::{Error, Result};
use crate::flex::{BaseMode, ReactionWheels};

/// The limit that binds the wheels, as a fraction of it.
#[derive(Debug, Clone, PartialEq)]
pub struct WheelBinding {
    /// `"max_torque"` or `"max_speed"`.
    pub limit: &'static str,
    /// The wheel (0-based).
    pub wheel: usize,
    /// When it peaks (s from the start of the plan).
    pub time: f64,
    /// The peak magnitude (N·m or rad/s).
    pub value: f64,
    /// The bound.
    pub bound: f64,
}

impl WheelBinding {
    /// `value / bound`: above 1, the wheels cannot hold the bus through the plan.
    pub fn ratio(&self) -> f64 {
        self.value / self.bound
    }
}

/// What holding the bus through a held-base plan asks of reaction wheels (minimum-norm
/// allocation), at the plan's samples.
#[derive(Debug, Clone, PartialEq)]
pub struct WheelDemand {
    /// The sample times (s).
    pub t: Vec<f64>,
    /// The motor torques `u_w` (N·m), `samples × k`.
    pub torque: Vec<f64>,
    /// The wheel speeds `Ω_w` (rad/s, relative to the bus), `samples × k`.
    pub speed: Vec<f64>,
    /// The stored spin momentum `h` (N·m·s, base frame), `samples × 3`.
    pub momentum: Vec<f64>,
    /// `max |u_w|` per wheel (N·m).
    pub peak_torque: Vec<f64>,
    /// `max |Ω_w|` per wheel (rad/s).
    pub peak_speed: Vec<f64>,
    /// `max |h|` (N·m·s).
    pub peak_momentum: f64,
    /// The limit closest to (or past) its bound.
    pub binding: WheelBinding,
}

impl Plan {
    /// The reaction-wheel torques and speeds that hold the bus through this held-base plan
    /// (see the [module](self)); an error for a free-floating plan, which asks nothing of them,
    /// or wheels whose axes do not span three dimensions.
    pub fn wheel_demand(&self, wheels: &ReactionWheels) -> Result<WheelDemand> {
        if self.base() != BaseMode::Held {
            return Err(Error::InvalidArgument {
                what: "wheel_demand".into(),
                message: "a free-floating plan asks nothing of the wheels (its bus turns); plan \
                          with base = \"held\" to see what holding the bus takes"
                    .into(),
            });
        }
        let allocation = wheels.allocation()?;
        let k = wheels.len();
        let samples = self.samples();
        let rows = samples.t.len();
        let mut demand = WheelDemand::zeros(samples.t.clone(), k, wheels.wheels()[0].max_torque);
        let net = allocated_torques(&samples.base_wrench, rows, &allocation, k);
        let mut best = -1.0;
        for r in 0..rows {
            for (w, wheel) in wheels.wheels().iter().enumerate() {
                let speed = if r == 0 {
                    0.0
                } else {
                    let h = samples.t[r] - samples.t[r - 1];
                    demand.speed[(r - 1) * k + w]
                        + 0.5 * h * (net[(r - 1) * k + w] + net[r * k + w]) / wheel.spin_inertia
                };
                let torque = net[r * k + w] + wheel.friction * speed;
                demand.speed[r * k + w] = speed;
                demand.torque[r * k + w] = torque;
                for v in 0..3 {
                    demand.momentum[3 * r + v] += wheel.spin_inertia * speed * wheel.axis[v];
                }
                demand.peak_torque[w] = demand.peak_torque[w].max(torque.abs());
                demand.peak_speed[w] = demand.peak_speed[w].max(speed.abs());
                for (limit, value, bound) in [
                    ("max_torque", torque.abs(), wheel.max_torque),
                    ("max_speed", speed.abs(), wheel.max_speed),
                ] {
                    if value / bound > best {
                        best = value / bound;
                        demand.binding = WheelBinding {
                            limit,
                            wheel: w,
                            time: samples.t[r],
                            value,
                            bound,
                        };
                    }
                }
            }
            let h = &demand.momentum[3 * r..3 * r + 3];
            demand.peak_momentum = demand
                .peak_momentum
                .max((h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt());
        }
        Ok(demand)
    }
}

impl WheelDemand {
    /// A demand of zeros at the sample times `t` for `k` wheels, bound by wheel 0's torque
    /// limit `max_torque` until a sample says otherwise.
    fn zeros(t: Vec<f64>, k: usize, max_torque: f64) -> Self {
        let rows = t.len();
        WheelDemand {
            t,
            torque: vec![0.0; rows * k],
            speed: vec![0.0; rows * k],
            momentum: vec![0.0; rows * 3],
            peak_torque: vec![0.0; k],
            peak_speed: vec![0.0; k],
            peak_momentum: 0.0,
            binding: WheelBinding {
                limit: "max_torque",
                wheel: 0,
                time: 0.0,
                value: 0.0,
                bound: max_torque,
            },
        }
    }
}

/// `τ = −A⁺ M` at each sample: the net wheel torques (`rows × k`) that deliver the moment
/// part `M` of each of the `rows` rows of `base_wrench` (6 wide), with `allocation` the rows of
/// `A⁺` (3 per wheel).
fn allocated_torques(base_wrench: &[f64], rows: usize, allocation: &[f64], k: usize) -> Vec<f64> {
    (0..rows)
        .flat_map(|r| {
            let m = &base_wrench[6 * r..6 * r + 3];
            (0..k).map(move |w| {
                let a = &allocation[3 * w..3 * w + 3];
                -(a[0] * m[0] + a[1] * m[1] + a[2] * m[2])
            })
        })
        .collect()
}
