//! Instructions per RK4 step with and without reaction wheels, for callgrind's differencing
//! method (BENCHMARKS.md, "Reaction wheels"):
//!
//! ```text
//! valgrind --tool=callgrind target/release/examples/wheel_step_cost BLOCKS [WHEELS [RUN]]
//! ```
//! runs `BLOCKS × 1000` steps of the built-in space arm from a moving state, with `WHEELS` (0 or
//! 4, default 0) wheels in a pyramid driven by constant commands. The difference of the totals at
//! two block counts over the extra steps is the cost of one step; loading and set-up cancel.
//! With `RUN` = 1 the steps are those of a run (`Stepper::step` with a `Drive`: constant motor
//! torques, and with wheels an `AttitudePD` holding the bus), which is what `simulate` does.

use orbitflex::control::{AttitudePD, AttitudeTarget, Schedule};
use orbitflex::flex::{ReactionWheels, Wheel};
use orbitflex::integrate::{Drive, Stepper};
use orbitflex::{FlexibleArm, FlexibleJoints, Inputs, Robot, StateSpec};
use std::hint::black_box;

fn main() {
    let args: Vec<usize> = std::env::args()
        .skip(1)
        .map(|a| a.parse().unwrap())
        .collect();
    let (blocks, wheels, run) = (
        args.first().copied().unwrap_or(1),
        args.get(1).copied().unwrap_or(0),
        args.get(2).copied().unwrap_or(0) == 1,
    );
    let mut arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    if wheels > 0 {
        let tilt = (1.0f64 / 3.0).sqrt();
        let side = (2.0f64 / 3.0).sqrt();
        let pyramid = (0..wheels)
            .map(|w| {
                let phi = std::f64::consts::TAU * w as f64 / wheels as f64;
                Wheel {
                    axis: [side * phi.cos(), side * phi.sin(), tilt],
                    position: [0.3 * phi.cos(), 0.3 * phi.sin(), -0.4],
                    mass: 4.0,
                    spin_inertia: 0.04,
                    transverse_inertia: 0.025,
                    max_torque: 0.2,
                    max_speed: 600.0,
                    friction: 1e-4,
                }
            })
            .collect();
        arm = arm
            .with_wheels(ReactionWheels::new(pyramid).unwrap())
            .unwrap();
    }
    let q = [0.1, -0.2, 0.3, 0.4, -0.5, 0.6, 0.1];
    let mut x = arm
        .state(&StateSpec {
            q: Some(&q),
            qd: Some(&[0.05; 7]),
            base_twist: Some(&[0.01, 0.02, -0.01, 0.0, 0.0, 0.0]),
            ..StateSpec::default()
        })
        .unwrap();
    let layout = arm.layout();
    x[layout.wheel_speed()].iter_mut().for_each(|s| *s = 100.0);
    let u = [1.0; 7];
    let commands = vec![0.1; wheels];
    let inputs = Inputs {
        wheel_torque: &commands,
        ..Inputs::torques(&u)
    };
    if run {
        let mut stepper = Stepper::new(&arm);
        let (mut motor, mut zero6, mut zero_ee) = (
            Schedule::Constant(u.to_vec()),
            Schedule::Zero,
            Schedule::Zero,
        );
        let mut hold: Box<dyn orbitflex::control::Controller> = match arm.wheels() {
            Some(w) => Box::new(
                AttitudePD::new(
                    [2e5; 3],
                    [2e4; 3],
                    AttitudeTarget::Initial,
                    w.allocation().unwrap(),
                )
                .unwrap(),
            ),
            None => Box::new(Schedule::Zero),
        };
        let mut drive = Drive {
            u: &mut motor,
            base_wrench: &mut zero6,
            ee_wrench: &mut zero_ee,
            wheel_torque: hold.as_mut(),
        };
        for k in 0..blocks * 1000 {
            stepper
                .step(&arm, &mut drive, black_box(&mut x), k, 1e-3)
                .unwrap();
        }
    } else {
        let mut ws = arm.workspace();
        for _ in 0..blocks * 1000 {
            arm.step(&mut ws, black_box(&mut x), 1e-3, &inputs).unwrap();
        }
    }
    println!("{}", x[layout.q().start]);
}
