//! The integrator's side of [`FlexibleArm`]: its workspace ([`ArmWorkspace`]: the model's scratch
//! and the RK4 stages) and the methods that step and run the arm, which call this module's
//! free functions ([`step`](super::step()), [`simulate`](super::simulate())).

use super::rk4::Rk4;
use super::run::{Drive, Run};
use super::simulate::{self, Unobserved};
use super::trajectory::Trajectory;
use super::SimulationFailure;
use crate::control::{Controller, Wrenches};
use crate::error::Result;
use crate::flex::{FlexibleArm, Inputs, ModelWorkspace};
use std::ops::{Deref, DerefMut};

/// Scratch memory for one [`FlexibleArm`]: the model's [`ModelWorkspace`] (rigid-body data,
/// spring torques, the step Jacobians' buffers) and the RK4 stages of [`FlexibleArm::step`].
/// Made by [`FlexibleArm::workspace`]; one per thread. It stands in for a `&mut ModelWorkspace`
/// (it dereferences to one), so the same workspace serves every call on the arm.
#[derive(Debug, Clone)]
pub struct ArmWorkspace {
    model: ModelWorkspace,
    pub(crate) rk4: Rk4,
}

impl ArmWorkspace {
    /// Buffers for `arm`.
    pub fn new(arm: &FlexibleArm) -> Self {
        Self {
            model: ModelWorkspace::new(arm),
            rk4: Rk4::new(arm.layout().len()),
        }
    }

    /// The model's scratch and the RK4 stages, apart.
    pub(crate) fn parts(&mut self) -> (&mut ModelWorkspace, &mut Rk4) {
        (&mut self.model, &mut self.rk4)
    }
}

impl Deref for ArmWorkspace {
    type Target = ModelWorkspace;
    fn deref(&self) -> &ModelWorkspace {
        &self.model
    }
}

impl DerefMut for ArmWorkspace {
    fn deref_mut(&mut self) -> &mut ModelWorkspace {
        &mut self.model
    }
}

impl FlexibleArm {
    /// A workspace for this arm ([`ArmWorkspace::new`]).
    pub fn workspace(&self) -> ArmWorkspace {
        ArmWorkspace::new(self)
    }

    /// One classic RK4 step of length `dt` in place, inputs held over the step; the quaternion is
    /// renormalised afterwards (model §5). Allocation-free. See [`super::step()`].
    pub fn step(
        &self,
        ws: &mut ArmWorkspace,
        x: &mut [f64],
        dt: f64,
        inputs: &Inputs,
    ) -> Result<()> {
        simulate::step(self, ws, x, dt, inputs)
    }

    /// Integrates `steps` RK4 steps of `dt` from `x0` under the controller `u` and the
    /// `wrenches`: a [`Run`] driven by a [`Drive`] of these three channels
    /// ([`super::simulate()`]).
    pub fn simulate(
        &self,
        x0: &[f64],
        dt: f64,
        steps: usize,
        u: &mut dyn Controller,
        wrenches: &Wrenches,
    ) -> std::result::Result<Trajectory, Box<SimulationFailure>> {
        let (mut base, mut ee, mut wheel) = (&wrenches.base, &wrenches.ee, &wrenches.wheel_torque);
        let mut drive = Drive {
            u,
            base_wrench: &mut base,
            ee_wrench: &mut ee,
            wheel_torque: &mut wheel,
        };
        simulate::simulate(self, &Run::new(x0, dt, steps), &mut drive, &mut Unobserved)
    }
}
