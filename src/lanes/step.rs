//! One flexible RK4 step of `W` runs at once ([`LaneGroup`]), lane for lane the bits of
//! [`crate::integrate::step`].

use super::lane::L;
use super::spatial::{bias_force, Art, In, Sv, Xf, M3, V3};
use crate::flex::{normalise_quaternion, FlexibleArm, FlexibleJoints, StateLayout, Wheel};

/// The inputs of one step in lanes, held over the step: motor torques `u` (n), `f_B`, the
/// end-effector wrenches (one per end-effector, or none) and the reaction-wheel torques
/// applied (k, already saturated), each lane its run's.
#[derive(Debug, Clone, Copy)]
pub struct LaneInputs<'a, const W: usize> {
    /// `u` (n), N·m.
    pub u: &'a [L<W>],
    /// `f_B` (base frame).
    pub base_wrench: &'a Sv<W>,
    /// `[f_1; …; f_k]` (each in its EE frame), or empty for no wrench.
    pub ee_wrench: &'a [Sv<W>],
    /// The torques the wheel motors apply over the step (k, N·m, after
    /// [`crate::flex::ReactionWheels::saturate`], as the scalar `Stepper` holds them); empty
    /// for an arm without wheels.
    pub wheel_torque: &'a [L<W>],
}

/// What the dynamics read of one reaction wheel ([`crate::flex::wheels`]), each lane its run's:
/// the unit axis `a` (base frame), the spin inertia `J_s` and the viscous friction `c`. (Its mass,
/// position and transverse inertia are in the lanes' base inertia, the locked part; its limits
/// are applied per lane by the scalar `Stepper` before the step.)
#[derive(Debug, Clone, Copy, Default)]
struct WheelLanes<const W: usize> {
    axis: V3<W>,
    spin_inertia: L<W>,
    friction: L<W>,
}

impl<const W: usize> WheelLanes<W> {
    fn set_lane(&mut self, k: usize, wheel: &Wheel) {
        let [x, y, z] = wheel.axis;
        (self.axis.x.0[k], self.axis.y.0[k], self.axis.z.0[k]) = (x, y, z);
        self.spin_inertia.0[k] = wheel.spin_inertia;
        self.friction.0[k] = wheel.friction;
    }

    /// (W2) `n_w = −a (u − c Ω) − ω × (h a)`, `h = J_s (a·ω + Ω)`, grouped as
    /// [`crate::flex::wheels::wheel_moment_on_bus`] groups it.
    #[inline(always)]
    fn moment_on_bus(&self, omega: &V3<W>, speed: L<W>, torque: L<W>) -> V3<W> {
        let a = &self.axis;
        let drive = torque - self.friction * speed;
        let h = self.spin_inertia * (a.dot(omega) + speed);
        let pushed = a.scale(drive);
        V3::new(-pushed.x, -pushed.y, -pushed.z).sub(&omega.cross(&a.scale(h)))
    }

    /// (W1) `Ω̇ = (u − c Ω)/J_s − a·ω̇`, as [`crate::flex::wheels::wheel_acceleration`].
    #[inline(always)]
    fn acceleration(&self, omega_dot: &V3<W>, speed: L<W>, torque: L<W>) -> L<W> {
        (torque - self.friction * speed) / self.spin_inertia - self.axis.dot(omega_dot)
    }
}

/// The ABA's per-body buffers in lanes (the lane form of [`crate::algorithms::Data`]).
#[derive(Debug, Clone)]
struct AbaLanes<const W: usize> {
    x: Vec<Xf<W>>,
    omega: Vec<V3<W>>,
    c: Vec<Sv<W>>,
    ia: Vec<Art<W>>,
    pa: Vec<Sv<W>>,
    u_col: Vec<Sv<W>>,
    d: Vec<L<W>>,
    u: Vec<L<W>>,
    acc: Vec<Sv<W>>,
}

/// `W` runs of one [`FlexibleArm`] side by side, structure of arrays: element `j` of the
/// state of every run is one [`L`]. [`LaneGroup::step`] advances all of them by one RK4 step,
/// each lane with the bits the scalar [`crate::integrate::step`] gives for that run.
///
/// A lane whose step fails (a singular articulated pivot or base inertia, a state that turns
/// non-finite, a collapsed quaternion) is reported by `step` and keeps the state it had before
/// that step ([`LaneGroup::state`]); the caller masks it (for example, hands it back to the
/// scalar path, which reproduces the failure with its message). Masked lanes keep computing: so
/// that they compute on ordinary numbers, [`LaneGroup::park`] copies a live lane into them.
#[derive(Debug, Clone)]
pub struct LaneGroup<const W: usize> {
    layout: StateLayout,
    x: Vec<L<W>>,
    start: Vec<L<W>>,
    stages: [Vec<L<W>>; 4],
    trial: Vec<L<W>>,
    tau: Vec<L<W>>,
    ddq: Vec<L<W>>,
    aba: AbaLanes<W>,
    joints: [Vec<L<W>>; 4],
    /// Each body's inertia and articulated inertia (joint frames) of the rigid model (the base's
    /// augmented by the wheels' locked parts), each lane its run's.
    inertias: Vec<In<W>>,
    articulated: Vec<Art<W>>,
    /// The reaction wheels (k; none without).
    wheels: Vec<WheelLanes<W>>,
}

impl<const W: usize> LaneGroup<W> {
    /// Buffers for `arm`, every lane at rest.
    pub fn new(arm: &FlexibleArm) -> Self {
        let layout = arm.layout();
        let (n, len) = (layout.n, layout.len());
        let bodies = n + 1;
        let p = arm.joints();
        let lanes = |v: &[f64]| v.iter().map(|&a| L::splat(a)).collect::<Vec<_>>();
        let mut group = Self {
            layout,
            x: vec![L::zero(); len],
            start: vec![L::zero(); len],
            stages: std::array::from_fn(|_| vec![L::zero(); len]),
            trial: vec![L::zero(); len],
            tau: vec![L::zero(); n],
            ddq: vec![L::zero(); 6 + n],
            aba: AbaLanes {
                x: vec![Xf::default(); bodies],
                omega: vec![V3::default(); bodies],
                c: vec![Sv::default(); bodies],
                ia: vec![Art::default(); bodies],
                pa: vec![Sv::default(); bodies],
                u_col: vec![Sv::default(); bodies],
                d: vec![L::zero(); bodies],
                u: vec![L::zero(); bodies],
                acc: vec![Sv::default(); bodies],
            },
            joints: [
                lanes(&p.stiffness),
                lanes(&p.damping),
                lanes(&p.motor_inertia),
                lanes(&p.motor_damping),
            ],
            inertias: arm
                .rigid_model()
                .frame_inertias()
                .iter()
                .map(In::splat)
                .collect(),
            articulated: arm
                .rigid_model()
                .frame_articulated()
                .iter()
                .map(Art::splat)
                .collect(),
            wheels: vec![WheelLanes::default(); layout.wheels],
        };
        let rest = arm.rest_state();
        for k in 0..W {
            group.set_state(k, &rest);
            group.set_wheels(k, arm);
        }
        group
    }

    /// The state layout of each lane.
    pub fn layout(&self) -> StateLayout {
        self.layout
    }

    /// Puts state `x` (of the arm's layout, checked by the caller) in lane `k`, its quaternion
    /// normalised as [`crate::integrate::simulate()`] does with `x0`.
    pub fn set_state(&mut self, k: usize, x: &[f64]) {
        for (lane, v) in self.x.iter_mut().zip(x) {
            lane.0[k] = *v;
        }
        let mut quat = [0.0; 4];
        let q = self.layout.quaternion();
        quat.copy_from_slice(&x[q.clone()]);
        normalise_quaternion(&mut quat);
        for (j, v) in q.zip(quat) {
            self.x[j].0[k] = v;
        }
    }

    /// Puts state `x` in lane `k` as it is (a state the scalar step computed).
    pub fn put_state(&mut self, k: usize, x: &[f64]) {
        for (lane, v) in self.x.iter_mut().zip(x) {
            lane.0[k] = *v;
        }
    }

    /// Gives lane `k` the joint parameters, the body inertias and the reaction wheels of `arm`,
    /// an arm of this group's structure ([`super::shares_kernel`]: the same joints and frames,
    /// as many wheels; masses, inertias, stiffness, damping, motor parameters and the wheels'
    /// axes, inertias, masses, positions and friction may differ).
    pub fn set_arm(&mut self, k: usize, arm: &FlexibleArm) {
        self.set_joints(k, arm.joints());
        self.set_wheels(k, arm);
        let robot = arm.rigid_model();
        for (lanes, one) in self.inertias.iter_mut().zip(robot.frame_inertias()) {
            lanes.set_lane(k, one);
        }
        for (lanes, one) in self.articulated.iter_mut().zip(robot.frame_articulated()) {
            lanes.set_lane(k, one);
        }
    }

    /// Gives lane `k` the joint parameters `joints` (of an arm with this group's robot): runs
    /// of one robot with dispersed stiffness, damping, motor inertia or friction share a group.
    pub fn set_joints(&mut self, k: usize, joints: &FlexibleJoints) {
        let [stiffness, damping, motor_inertia, motor_damping] = &mut self.joints;
        for (lanes, values) in [
            (stiffness, &joints.stiffness),
            (damping, &joints.damping),
            (motor_inertia, &joints.motor_inertia),
            (motor_damping, &joints.motor_damping),
        ] {
            for (lane, v) in lanes.iter_mut().zip(values) {
                lane.0[k] = *v;
            }
        }
    }

    /// Lane `k`'s wheels from `arm`'s (as many as this group's; none without).
    fn set_wheels(&mut self, k: usize, arm: &FlexibleArm) {
        let given = arm.wheels().map_or(&[][..], |w| w.wheels());
        for (lanes, wheel) in self.wheels.iter_mut().zip(given) {
            lanes.set_lane(k, wheel);
        }
    }

    /// Lane `k`'s state into `out`: after a step that failed in this lane, the state before it.
    pub fn state(&self, k: usize, out: &mut [f64]) {
        for (o, lane) in out.iter_mut().zip(&self.x) {
            *o = lane.0[k];
        }
    }

    /// The whole state in lanes (element `j` of every run).
    pub fn states(&self) -> &[L<W>] {
        &self.x
    }

    /// Copies lane `from` into lane `k` (a masked lane), so that it computes on ordinary numbers.
    pub fn park(&mut self, k: usize, from: usize) {
        for lane in &mut self.x {
            lane.0[k] = lane.0[from];
        }
    }

    /// Motor-side PD in lanes ([`crate::MotorPD`]'s law, the same grouping):
    /// `u = K_p (θ_ref − θ) + K_d (θ̇_ref − θ̇) + u_ff`, every argument of length n.
    pub fn motor_pd(
        &self,
        gains: [&[L<W>]; 2],
        theta_ref: &[L<W>],
        theta_dot_ref: &[L<W>],
        feedforward: &[L<W>],
        u: &mut [L<W>],
    ) {
        let (theta, theta_dot) = (
            &self.x[self.layout.theta()],
            &self.x[self.layout.theta_dot()],
        );
        for i in 0..u.len() {
            u[i] = gains[0][i] * (theta_ref[i] - theta[i])
                + gains[1][i] * (theta_dot_ref[i] - theta_dot[i])
                + feedforward[i];
        }
    }

    /// One RK4 step of `dt` for every lane (inputs held), the quaternions renormalised. Returns,
    /// per lane, whether the step succeeded; a lane that failed keeps its state from before the
    /// step. Runs the AVX-512 or AVX2 copy where the processor has it ([`super::level`]).
    pub fn step(&mut self, arm: &FlexibleArm, dt: f64, inputs: &LaneInputs<W>) -> [bool; W] {
        #[cfg(target_arch = "x86_64")]
        {
            #[cfg(orbitflex_avx512)]
            #[target_feature(enable = "avx512f")]
            unsafe fn avx512<const W: usize>(
                g: &mut LaneGroup<W>,
                arm: &FlexibleArm,
                dt: f64,
                inputs: &LaneInputs<W>,
            ) -> [bool; W] {
                g.step_kernel(arm, dt, inputs)
            }
            #[target_feature(enable = "avx2")]
            unsafe fn avx2<const W: usize>(
                g: &mut LaneGroup<W>,
                arm: &FlexibleArm,
                dt: f64,
                inputs: &LaneInputs<W>,
            ) -> [bool; W] {
                g.step_kernel(arm, dt, inputs)
            }
            // 8 lanes take the AVX-512 copy where there is one, 4 lanes (or 8 without it) AVX2
            match super::level() {
                // SAFETY: `level` reports AVX-512F only where the processor has it.
                #[cfg(orbitflex_avx512)]
                super::Level::Avx512 if W >= 8 => return unsafe { avx512(self, arm, dt, inputs) },
                // SAFETY: `level` reports AVX2 (or more) only where the processor has it.
                super::Level::Avx512 | super::Level::Avx2 => {
                    return unsafe { avx2(self, arm, dt, inputs) }
                }
                super::Level::Portable => {}
            }
        }
        self.step_kernel(arm, dt, inputs)
    }

    #[inline(always)]
    pub(super) fn step_kernel(
        &mut self,
        arm: &FlexibleArm,
        dt: f64,
        inputs: &LaneInputs<W>,
    ) -> [bool; W] {
        self.start.copy_from_slice(&self.x);
        let mut ok = [true; W];
        let mut stages = std::mem::take(&mut self.stages);
        let mut trial = std::mem::take(&mut self.trial);
        let mut x = std::mem::take(&mut self.x);
        // k₁ = f(x), k₂ = f(x + dt/2 k₁), k₃ = f(x + dt/2 k₂), k₄ = f(x + dt k₃) (`Rk4::step`);
        // one loop so that the derivative is compiled once
        let steps = [0.5 * dt, 0.5 * dt, dt];
        for s in 0..4 {
            let at = if s == 0 { &x } else { &trial };
            self.derivative(arm, at, inputs, &mut stages[s], &mut ok);
            if s < 3 {
                advance(&mut trial, &x, steps[s], &stages[s]);
            }
        }
        let [k1, k2, k3, k4] = &stages;
        let h = dt / 6.0;
        for i in 0..x.len() {
            x[i] += h * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
        self.x = x;
        self.stages = stages;
        self.trial = trial;
        // per lane: renormalise the quaternion, then the scalar path's state checks
        let quat = self.layout.quaternion();
        for (k, good) in ok.iter_mut().enumerate() {
            let mut q = [0.0; 4];
            for (v, lane) in q.iter_mut().zip(&self.x[quat.clone()]) {
                *v = lane.0[k];
            }
            normalise_quaternion(&mut q);
            for (lane, v) in self.x[quat.clone()].iter_mut().zip(q) {
                lane.0[k] = v;
            }
            let finite = self.x.iter().all(|lane| lane.0[k].is_finite());
            let scale = q.iter().fold(0.0f64, |m, v| m.max(v.abs()));
            *good = *good && finite && scale != 0.0;
            if !*good {
                for (lane, before) in self.x.iter_mut().zip(&self.start) {
                    lane.0[k] = before.0[k];
                }
            }
        }
        ok
    }

    /// `ẋ` ([`FlexibleArm::derivative`]) of every lane at `x`; a lane whose articulated pivot or
    /// base inertia is singular is cleared in `ok`. With reaction wheels, as
    /// `flex::wheels::derivative_with_wheels`: `f_B` gains `Σ n_w` (W2) before the ABA (on the
    /// augmented base), and `Ω̇` (W1) follows from `ω̇_B`.
    #[inline(always)]
    fn derivative(
        &mut self,
        arm: &FlexibleArm,
        x: &[L<W>],
        inputs: &LaneInputs<W>,
        xdot: &mut [L<W>],
        ok: &mut [bool; W],
    ) {
        let layout = self.layout;
        let n = layout.n;
        let (q, theta) = (&x[layout.q()], &x[layout.theta()]);
        let (qd, theta_dot) = (&x[layout.qd()], &x[layout.theta_dot()]);
        {
            let [stiffness, damping, ..] = &self.joints;
            // τ = k (θ − q) + d (θ̇ − q̇)
            for i in 0..n {
                self.tau[i] =
                    stiffness[i] * (theta[i] - q[i]) + damping[i] * (theta_dot[i] - qd[i]);
            }
        }
        let twist = layout.base_twist().start;
        let omega_b = V3::new(x[twist], x[twist + 1], x[twist + 2]);
        let v_b = V3::new(x[twist + 3], x[twist + 4], x[twist + 5]);
        let speed = &x[layout.wheel_speed()];
        let (loaded_wrench, loaded_inputs);
        let inputs = if self.wheels.is_empty() {
            inputs
        } else {
            loaded_wrench = self.wheel_loads(&omega_b, speed, inputs);
            loaded_inputs = LaneInputs {
                base_wrench: &loaded_wrench,
                ..*inputs
            };
            &loaded_inputs
        };
        self.aba(arm, omega_b, q, qd, inputs, ok);

        let quat = layout.quaternion().start;
        let rotation = attitude(&x[quat..quat + 4]);
        let r_dot = rotation.mul_vec(&v_b);
        let p = layout.position().start;
        (xdot[p], xdot[p + 1], xdot[p + 2]) = (r_dot.x, r_dot.y, r_dot.z);
        // quat' = ½ quat ⊗ (ω, 0) (`quaternion_rate`)
        let vq = V3::new(x[quat], x[quat + 1], x[quat + 2]);
        let d = omega_b
            .scale(x[quat + 3])
            .add(&vq.cross(&omega_b))
            .scale(L::splat(0.5));
        (xdot[quat], xdot[quat + 1], xdot[quat + 2]) = (d.x, d.y, d.z);
        xdot[quat + 3] = -0.5 * vq.dot(&omega_b);
        xdot[layout.q()].copy_from_slice(qd);
        xdot[layout.theta()].copy_from_slice(theta_dot);
        let acc = &self.ddq;
        let v_dot = V3::new(acc[3], acc[4], acc[5]).sub(&omega_b.cross(&v_b));
        xdot[twist..twist + 3].copy_from_slice(&acc[..3]);
        (xdot[twist + 3], xdot[twist + 4], xdot[twist + 5]) = (v_dot.x, v_dot.y, v_dot.z);
        xdot[layout.qd()].copy_from_slice(&acc[6..]);
        let [_, _, motor_inertia, motor_damping] = &self.joints;
        let motor = &mut xdot[layout.theta_dot()];
        for i in 0..n {
            motor[i] =
                (inputs.u[i] - self.tau[i] - motor_damping[i] * theta_dot[i]) / motor_inertia[i];
        }
        let omega_dot = V3::new(acc[0], acc[1], acc[2]);
        let rates = &mut xdot[layout.wheel_speed()];
        for (w, wheel) in self.wheels.iter().enumerate() {
            rates[w] = wheel.acceleration(&omega_dot, speed[w], inputs.wheel_torque[w]);
        }
    }

    /// `f_B` of `inputs` with the wheels' `Σ n_w` (W2) added to its moment, at bus rate `omega`
    /// and wheel speeds `speed`: summed from zero, then added, as
    /// [`crate::flex::ReactionWheels::base_moment`] and `derivative_with_wheels` do.
    #[inline(always)]
    fn wheel_loads(&self, omega: &V3<W>, speed: &[L<W>], inputs: &LaneInputs<W>) -> Sv<W> {
        let mut sum = V3::<W>::default();
        for (w, wheel) in self.wheels.iter().enumerate() {
            sum = sum.add(&wheel.moment_on_bus(omega, speed[w], inputs.wheel_torque[w]));
        }
        let f = inputs.base_wrench;
        Sv::new(f.angular.add(&sum), f.linear)
    }

    /// The three ABA passes ([`crate::algorithms::aba`]'s kernel) in lanes, into `self.ddq`:
    /// velocities (A.4), Coriolis terms (A.7), `I^A = M_i` (A.9) and `p^A = b_i` (A.10) forwards;
    /// the articulated inertias backwards; the base solve and `q̈`, `α_i` (A.6) forwards,
    /// operation for operation the scalar kernel's.
    #[inline(always)]
    fn aba(
        &mut self,
        arm: &FlexibleArm,
        omega_b: V3<W>,
        q: &[L<W>],
        qd: &[L<W>],
        inputs: &LaneInputs<W>,
        ok: &mut [bool; W],
    ) {
        let robot = arm.robot();
        let n = robot.dof();
        let (articulated, inertias) = (&self.articulated, &self.inertias);
        let parents = robot.parents();
        let s = &mut self.aba;
        s.omega[0] = omega_b;
        s.c[0] = Sv::default();
        s.ia[0] = articulated[0];
        s.pa[0] = bias_force(&inertias[0], &omega_b);
        for i in 1..=n {
            // (A.5) Φ_{i,λ}(q) as `joint_transform` builds it, one libm sin_cos per lane
            let (origin, tilt) = robot.joint_frame(i);
            let angle = match tilt {
                Some((gamma, _, _)) => q[i - 1] + gamma,
                None => q[i - 1],
            };
            let (mut s_q, mut c_q) = (L::<W>::zero(), L::<W>::zero());
            for k in 0..W {
                (s_q.0[k], c_q.0[k]) = angle.0[k].sin_cos();
            }
            let mut x = Xf::<W> {
                rotation: M3::splat(&origin.rotation),
                translation: V3::splat(&origin.translation),
            };
            let m = &mut x.rotation.m;
            match tilt {
                // R_z(−(q + γ)) R_x(−α) (`tilted_rotation`)
                Some((_, ca, sa)) => {
                    *m = [
                        [c_q, s_q * ca, s_q * sa],
                        [-s_q, c_q * ca, c_q * sa],
                        [L::zero(), L::splat(-sa), L::splat(ca)],
                    ];
                }
                // the first two rows of R'_0 turned by q
                None => {
                    for j in 0..3 {
                        let (a, b) = (m[0][j], m[1][j]);
                        m[0][j] = c_q * a + s_q * b;
                        m[1][j] = c_q * b - s_q * a;
                    }
                }
            }
            // (A.4), (A.7): ω_i = R ω_λ + e_z q̇_i, a_i = [q̇_i (R ω_λ) × e_z; R (ω_λ × (ω_λ × p))]
            let parent = s.omega[parents[i]];
            let w_rotated = x.rotation.mul_vec(&parent);
            let w_cross_p = parent.cross(&x.translation);
            let qdi = qd[i - 1];
            let mut omega = w_rotated;
            omega.z += qdi;
            s.omega[i] = omega;
            s.c[i] = Sv::new(
                V3::new(qdi * w_rotated.y, -qdi * w_rotated.x, L::zero()),
                x.rotation.mul_vec(&parent.cross(&w_cross_p)),
            );
            s.x[i] = x;
            s.ia[i] = articulated[i];
            s.pa[i] = bias_force(&inertias[i], &omega);
        }
        for (e, w) in inputs.ee_wrench.iter().enumerate() {
            let body = robot.end_effectors()[e].body;
            let moved = Xf::splat(robot.frame_ee_transform(e)).apply_force_transpose(w);
            s.pa[body] = s.pa[body].add(&moved);
        }

        for i in (1..=n).rev() {
            let (ia, pa, c) = (s.ia[i], s.pa[i], s.c[i]);
            let u_col = ia.column_z();
            let d = u_col.angular.z;
            let scale = ia.angular.xx + ia.angular.yy + ia.angular.zz;
            for k in 0..W {
                let dk = d.0[k];
                ok[k] &= dk > 1e-12 * scale.0[k] && dk.is_finite();
            }
            let u = self.tau[i - 1] - pa.angular.z;
            let reduced = ia.minus_outer(&u_col, 1.0 / d);
            let pa_child = pa
                .add(&ia.apply(&c))
                .add(&u_col.scale((u - c.dot(&u_col)) / d));
            let x = &s.x[i];
            let moved = if robot.is_tilted(i) {
                reduced.tilted_to_parent(x)
            } else {
                reduced.transformed_to_parent(x)
            };
            s.ia[parents[i]].add_assign(&moved);
            let force = x.apply_force_transpose(&pa_child);
            s.pa[parents[i]] = s.pa[parents[i]].add(&force);
            s.u_col[i] = u_col;
            s.d[i] = d;
            s.u[i] = u;
        }

        let (base_acc, base_ok) = s.ia[0].solve(&inputs.base_wrench.sub(&s.pa[0]));
        for (good, base) in ok.iter_mut().zip(base_ok) {
            *good &= base;
        }
        s.acc[0] = base_acc;
        let ddq = &mut self.ddq;
        let a = base_acc;
        ddq[..6].copy_from_slice(&[
            a.angular.x,
            a.angular.y,
            a.angular.z,
            a.linear.x,
            a.linear.y,
            a.linear.z,
        ]);
        for i in 1..=n {
            // (A.6) α_i = Φ α_λ + a_i + H q̈_i, q̈_i = (u − Uᵀ (Φ α_λ + a_i))/D
            let mut acc = s.x[i].apply_motion(&s.acc[parents[i]]).add(&s.c[i]);
            let qdd = (s.u[i] - acc.dot(&s.u_col[i])) / s.d[i];
            acc.angular.z += qdd;
            s.acc[i] = acc;
            ddq[5 + i] = qdd;
        }
    }
}

/// `R_B` from `quat_B = (x, y, z, w)`, as `crate::spatial::quaternion_to_rotation` computes it
/// through nalgebra: the quaternion divided by its norm `√((x² + z²) + (y² + w²))`, then
/// `UnitQuaternion::to_rotation_matrix`'s products and sums, in their order.
#[inline(always)]
fn attitude<const W: usize>(quat: &[L<W>]) -> M3<W> {
    // nalgebra's dot product of 4-vectors pairs the first and third, second and fourth terms
    let norm =
        ((quat[0] * quat[0] + quat[2] * quat[2]) + (quat[1] * quat[1] + quat[3] * quat[3])).sqrt();
    let (i, j, k, w) = (
        quat[0] / norm,
        quat[1] / norm,
        quat[2] / norm,
        quat[3] / norm,
    );
    let (ww, ii, jj, kk) = (w * w, i * i, j * j, k * k);
    let (ij, wk, wj) = (i * j * 2.0, w * k * 2.0, w * j * 2.0);
    let (ik, jk, wi) = (i * k * 2.0, j * k * 2.0, w * i * 2.0);
    M3 {
        m: [
            [ww + ii - jj - kk, ij - wk, wj + ik],
            [wk + ij, ww - ii + jj - kk, jk - wi],
            [ik - wj, wi + jk, ww - ii - jj + kk],
        ],
    }
}

/// `trial = x + h k` (`Rk4`'s `advance`).
#[inline(always)]
fn advance<const W: usize>(trial: &mut [L<W>], x: &[L<W>], h: f64, k: &[L<W>]) {
    for (t, (xi, ki)) in trial.iter_mut().zip(x.iter().zip(k)) {
        *t = *xi + h * *ki;
    }
}
