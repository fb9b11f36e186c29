//! The stepping `Simulator`: bit for bit the states of `simulate` with the same inputs, held
//! inputs, outputs, save/restore, failures, and no allocation per step.

use orbitflex::integrate::{Observer, Outputs, STATE_FORMAT_VERSION};
use orbitflex::testing::{random_joints, random_tree_all_leaves, Rng};
use orbitflex::{
    Controller, Error, FlexibleArm, FlexibleJoints, MotorPD, Robot, Schedule, Simulator, StateSpec,
    Wrenches,
};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|c| c.set(c.get() + 1));
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations(f: impl FnOnce()) -> usize {
    let before = ALLOCATIONS.with(Cell::get);
    f();
    ALLOCATIONS.with(Cell::get) - before
}

fn space_arm() -> FlexibleArm {
    FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap()
}

/// A tree with two end-effectors, so that EE wrenches have two rows.
fn tree_arm(seed: u64) -> FlexibleArm {
    // body 1 carries two branches, 2-3 and 4-5: end-effectors on 3 and 5
    let robot = random_tree_all_leaves(&[0, 0, 1, 2, 1, 4], seed);
    let n = robot.dof();
    FlexibleArm::new(robot, random_joints(n, seed)).unwrap()
}

fn moving_state(arm: &FlexibleArm, seed: u64) -> Vec<f64> {
    let n = arm.dof();
    let mut rng = Rng::new(seed);
    let q = rng.vector(n, -1.0, 1.0);
    let theta: Vec<f64> = q.iter().map(|v| v + rng.range(-0.01, 0.01)).collect();
    arm.state(&StateSpec {
        q: Some(&q),
        theta: Some(&theta),
        qd: Some(&rng.vector(n, -0.3, 0.3)),
        theta_dot: Some(&rng.vector(n, -0.3, 0.3)),
        // not unit: both normalise it first
        base_pose: Some(&[0.3, -0.2, 0.1, 0.2, 0.4, -0.6, 1.8]),
        base_twist: Some(&rng.vector(6, -0.2, 0.2)),
    })
    .unwrap()
}

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|v| v.to_bits()).collect()
}

fn table(rng: &mut Rng, steps: usize, width: usize, scale: f64) -> Schedule {
    Schedule::Table {
        values: rng.vector(steps * width, -scale, scale),
        width,
    }
}

fn row(s: &Schedule, k: usize, width: usize) -> Vec<f64> {
    let mut out = vec![0.0; width];
    s.write(k, &mut out);
    out
}

/// Per-step tables of torques, base and EE wrenches: setting each row and stepping once gives
/// every state of `simulate`, bit for bit.
#[test]
fn steps_equal_simulate_with_tables() {
    for (arm, seed) in [(space_arm(), 1), (tree_arm(5), 5)] {
        let (n, k) = (arm.dof(), arm.robot().end_effectors().len());
        let steps = 60;
        let mut rng = Rng::new(seed);
        let u = table(&mut rng, steps, n, 5.0);
        let wrenches = Wrenches {
            base: table(&mut rng, steps, 6, 2.0),
            ee: table(&mut rng, steps, 6 * k, 1.0),
            wheel_torque: Schedule::Zero,
        };
        let x0 = moving_state(&arm, seed);
        let dt = 2e-3;
        let traj = arm
            .simulate(&x0, dt, steps, &mut u.clone(), &wrenches)
            .unwrap();
        let mut sim = Simulator::new(arm.clone(), &x0, dt).unwrap();
        assert_eq!(bits(sim.state()), bits(traj.state(0)));
        for step in 0..steps {
            sim.set_motor_torque(&row(&u, step, n)).unwrap();
            sim.set_base_wrench(&row(&wrenches.base, step, 6)).unwrap();
            sim.set_ee_wrench(Some(&row(&wrenches.ee, step, 6 * k)))
                .unwrap();
            sim.step(1).unwrap();
            assert_eq!(bits(sim.state()), bits(traj.state(step + 1)), "step {step}");
            assert_eq!(sim.t().to_bits(), traj.t[step + 1].to_bits());
        }
    }
}

/// Held inputs: `step(n)` with constant inputs is `simulate` with the same constants, and
/// `step(a)` then `step(b)` is `step(a + b)`.
#[test]
fn held_inputs_equal_constant_schedules() {
    let arm = space_arm();
    let n = arm.dof();
    let x0 = moving_state(&arm, 3);
    let u: Vec<f64> = (0..n).map(|i| 0.5 - 0.2 * i as f64).collect();
    let base = [0.1, -0.2, 0.3, 1.0, -2.0, 0.5];
    let traj = arm
        .simulate(
            &x0,
            1e-3,
            250,
            &mut Schedule::Constant(u.clone()),
            &Wrenches {
                base: Schedule::Constant(base.to_vec()),
                ee: Schedule::Zero,
                wheel_torque: Schedule::Zero,
            },
        )
        .unwrap();
    let mut sim = Simulator::new(arm.clone(), &x0, 1e-3).unwrap();
    sim.set_motor_torque(&u).unwrap();
    sim.set_base_wrench(&base).unwrap();
    sim.step(250).unwrap();
    assert_eq!(bits(sim.state()), bits(traj.state(250)));
    let mut split = Simulator::new(arm, &x0, 1e-3).unwrap();
    split.set_motor_torque(&u).unwrap();
    split.set_base_wrench(&base).unwrap();
    for chunk in [1, 0, 99, 150] {
        split.step(chunk).unwrap();
    }
    assert_eq!(bits(split.state()), bits(traj.state(250)));
    assert_eq!(split.steps(), 250);
}

/// A MotorPD run computed the same way: ask the controller at each step's start state, hold its
/// torque, step once.
#[test]
fn steps_equal_a_motor_pd_run() {
    let arm = space_arm();
    let n = arm.dof();
    let steps = 400;
    let mut rng = Rng::new(9);
    let reference = table(&mut rng, steps, n, 0.3);
    let pd = MotorPD::new(
        vec![800.0; n],
        vec![120.0; n],
        reference,
        Schedule::Zero,
        Schedule::Constant(vec![0.1; n]),
    )
    .unwrap();
    let x0 = moving_state(&arm, 9);
    let dt = 1e-3;
    let traj = arm
        .simulate(&x0, dt, steps, &mut pd.clone(), &Wrenches::ZERO)
        .unwrap();
    let mut sim = Simulator::new(arm, &x0, dt).unwrap();
    let mut master = pd;
    let mut u = vec![0.0; n];
    for k in 0..steps {
        master.output(k, sim.t(), sim.state(), &mut u).unwrap();
        sim.set_motor_torque(&u).unwrap();
        sim.step(1).unwrap();
        assert_eq!(bits(sim.state()), bits(traj.state(k + 1)), "step {k}");
    }
    assert_eq!(bits(&u), bits(&traj.u[(steps - 1) * n..]));
}

#[test]
fn outputs_are_the_arms_quantities() {
    let arm = tree_arm(7);
    let n = arm.dof();
    let x0 = moving_state(&arm, 7);
    let mut sim = Simulator::new(arm.clone(), &x0, 1e-3).unwrap();
    sim.set_motor_torque(&vec![0.3; n]).unwrap();
    sim.step(20).unwrap();
    let x = sim.state().to_vec();
    let out = sim.outputs();
    let layout = arm.layout();
    assert_eq!(out.q, x[layout.q()]);
    assert_eq!(out.qd, x[layout.qd()]);
    assert_eq!(out.theta, x[layout.theta()]);
    assert_eq!(out.theta_dot, x[layout.theta_dot()]);
    let (theta, q) = (&x[layout.theta()], &x[layout.q()]);
    let deflection: Vec<f64> = theta.iter().zip(q).map(|(t, q)| t - q).collect();
    assert_eq!(out.deflection, deflection);
    let mut tau = vec![0.0; n];
    arm.spring_torque(&x, &mut tau);
    assert_eq!(out.spring_torque, tau);
    assert_eq!(out.base_pose.as_slice(), &x[layout.base_pose()]);
    assert_eq!(out.base_twist.as_slice(), &x[layout.base_twist()]);
    let k = arm.robot().end_effectors().len();
    assert_eq!(k, 2);
    for e in 0..k {
        assert_eq!(
            &out.ee_poses[7 * e..7 * e + 7],
            arm.ee_pose(&x, e).as_slice()
        );
    }
    let mut ws = arm.workspace();
    assert_eq!(out.momentum, arm.momentum(&mut ws, &x));
    assert_eq!(out.energy, arm.energy(&mut ws, &x));
    let mut into = Outputs::for_arm(&arm);
    sim.outputs_into(&mut into);
    assert_eq!(into, out);
}

#[test]
fn save_and_restore_are_bit_exact() {
    let arm = tree_arm(11);
    let (n, k) = (arm.dof(), arm.robot().end_effectors().len());
    let x0 = moving_state(&arm, 11);
    let mut sim = Simulator::new(arm, &x0, 5e-4).unwrap();
    sim.set_motor_torque(&vec![0.2; n]).unwrap();
    sim.set_ee_wrench(Some(&vec![0.1; 6 * k])).unwrap();
    sim.step(37).unwrap();
    let blob = sim.save();
    assert_eq!(blob.len(), sim.saved_len());
    assert_eq!(&blob[8..12], STATE_FORMAT_VERSION.to_le_bytes().as_slice());
    let (x_saved, t_saved) = (sim.state().to_vec(), sim.t());
    sim.step(50).unwrap();
    let x_ahead = sim.state().to_vec();
    // change every held input, then restore: all of them come back
    sim.set_motor_torque(&vec![-3.0; n]).unwrap();
    sim.set_base_wrench(&[1.0; 6]).unwrap();
    sim.set_ee_wrench(None).unwrap();
    sim.restore(&blob).unwrap();
    assert_eq!(bits(sim.state()), bits(&x_saved));
    assert_eq!(sim.t().to_bits(), t_saved.to_bits());
    assert_eq!(sim.motor_torque(), vec![0.2; n].as_slice());
    assert_eq!(sim.base_wrench(), &[0.0; 6]);
    assert_eq!(sim.ee_wrench(), vec![0.1; 6 * k].as_slice());
    sim.step(50).unwrap();
    assert_eq!(bits(sim.state()), bits(&x_ahead), "the replay differs");
    assert_eq!(sim.save().len(), blob.len());
}

fn refusal(sim: &mut Simulator, blob: &[u8]) -> String {
    let before = sim.save();
    let message = match sim.restore(blob) {
        Err(Error::InvalidArgument { what, message }) => {
            assert_eq!(what, "simulator state");
            message
        }
        other => panic!("expected a refusal, got {other:?}"),
    };
    assert_eq!(sim.save(), before, "a refused blob changed the simulator");
    message
}

#[test]
fn foreign_or_damaged_blobs_are_refused() {
    let arm = space_arm();
    let x0 = arm.rest_state();
    let mut sim = Simulator::new(arm.clone(), &x0, 1e-3).unwrap();
    sim.step(3).unwrap();
    let blob = sim.save();
    sim.step(2).unwrap();

    // another arm: other joint parameters of the same robot
    let mut joints = FlexibleJoints::space_arm();
    joints.stiffness[3] *= 1.0 + 1e-12;
    let other = FlexibleArm::new(Robot::space_arm(), joints).unwrap();
    let mut foreign = Simulator::new(other, &x0, 1e-3).unwrap();
    let message = refusal(&mut foreign, &blob);
    assert!(message.contains("saved from another arm"), "{message}");
    // another dynamics method is another arm too
    let operator = arm.clone().with_method(orbitflex::Method::Operator);
    let message = refusal(&mut Simulator::new(operator, &x0, 1e-3).unwrap(), &blob);
    assert!(message.contains("another arm"), "{message}");
    // another dt
    let message = refusal(&mut Simulator::new(arm.clone(), &x0, 2e-3).unwrap(), &blob);
    assert!(message.contains("dt = 1e-3"), "{message}");

    let message = refusal(&mut sim, b"not a state");
    assert!(
        message.contains("not a saved orbitflex simulator state"),
        "{message}"
    );
    let mut version = blob.clone();
    version[8..12].copy_from_slice(&(STATE_FORMAT_VERSION + 1).to_le_bytes());
    let message = refusal(&mut sim, &version);
    let expected = format!(
        "format version {}; this orbitflex reads version {STATE_FORMAT_VERSION}",
        STATE_FORMAT_VERSION + 1
    );
    assert!(message.contains(&expected), "{message}");
    for cut in [10, 20, 40, blob.len() - 1] {
        let message = refusal(&mut sim, &blob[..cut]);
        assert!(
            message.contains("truncated") || message.contains("bytes"),
            "{message}"
        );
    }
    let mut longer = blob.clone();
    longer.push(0);
    refusal(&mut sim, &longer);
    let mut nan = blob.clone();
    let at = nan.len() - 8;
    nan[at..].copy_from_slice(&f64::NAN.to_bits().to_le_bytes());
    let message = refusal(&mut sim, &nan);
    assert!(message.contains("not finite"), "{message}");
    // a zero quaternion is no state
    let mut zero_quaternion = blob.clone();
    for i in 3..7 {
        let at = 48 + 8 * i; // the header is 48 bytes
        zero_quaternion[at..at + 8].copy_from_slice(&0f64.to_bits().to_le_bytes());
    }
    refusal(&mut sim, &zero_quaternion);
}

#[test]
fn bad_inputs_are_refused_and_leave_the_held_ones() {
    let arm = tree_arm(2);
    let n = arm.dof();
    let mut sim = Simulator::new(arm.clone(), &arm.rest_state(), 1e-3).unwrap();
    sim.set_motor_torque(&vec![1.0; n]).unwrap();
    assert!(matches!(
        sim.set_motor_torque(&vec![1.0; n + 1]),
        Err(Error::Dimension { .. })
    ));
    let mut bad = vec![1.0; n];
    bad[1] = f64::NAN;
    assert!(matches!(
        sim.set_motor_torque(&bad),
        Err(Error::NonFinite { index: 1, .. })
    ));
    assert_eq!(sim.motor_torque(), vec![1.0; n].as_slice());
    assert!(sim.set_base_wrench(&[0.0; 5]).is_err());
    assert!(sim
        .set_base_wrench(&[0.0, f64::INFINITY, 0.0, 0.0, 0.0, 0.0])
        .is_err());
    assert!(
        sim.set_ee_wrench(Some(&[0.0; 6])).is_err(),
        "two EEs take 12"
    );
    assert!(Simulator::new(arm.clone(), &arm.rest_state(), 0.0).is_err());
    assert!(Simulator::new(arm.clone(), &arm.rest_state(), f64::NAN).is_err());
    match Simulator::new(arm.clone(), &[0.0; 3], 1e-3) {
        Err(Error::Dimension { what, .. }) => assert_eq!(what, "x0"),
        other => panic!("{other:?}"),
    }
}

/// A step past the RK4 stability limit diverges: the simulator keeps the last good state and
/// time, names the step, and equals what `simulate` kept.
#[test]
fn a_diverging_step_keeps_the_last_good_state() {
    let arm = space_arm();
    let x0 = moving_state(&arm, 4);
    let dt = 0.2; // far past the limit (about 1e-2 s)
    let failure = arm
        .simulate(&x0, dt, 10_000, &mut Schedule::Zero, &Wrenches::ZERO)
        .unwrap_err();
    let Error::Simulation { step, .. } = failure.error else {
        panic!("{:?}", failure.error)
    };
    let mut sim = Simulator::new(arm, &x0, dt).unwrap();
    match sim.step(10_000) {
        Err(Error::Simulation {
            step: s, message, ..
        }) => {
            assert_eq!(s, step);
            assert!(message.contains("diverged"), "{message}");
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(sim.steps(), step as u64);
    let last = failure.trajectory.state(failure.trajectory.len() - 1);
    assert_eq!(bits(sim.state()), bits(last));
}

struct StopAt(usize, usize);

impl Observer for StopAt {
    fn every(&self) -> usize {
        4
    }
    fn observe(&mut self, step: usize, _: usize) -> bool {
        self.1 += 1;
        step < self.0
    }
}

#[test]
fn an_observer_stops_between_steps() {
    let arm = space_arm();
    let mut sim = Simulator::new(arm.clone(), &arm.rest_state(), 1e-3).unwrap();
    let mut observer = StopAt(10, 0);
    let e = sim.step_observed(100, &mut observer).unwrap_err();
    assert!(e.to_string().contains("interrupted"), "{e}");
    assert_eq!(sim.steps(), 12, "asked before steps 4, 8 and 12");
    assert_eq!(observer.1, 3);
}

#[test]
fn reset_starts_over() {
    let arm = space_arm();
    let x0 = moving_state(&arm, 8);
    let mut sim = Simulator::new(arm.clone(), &x0, 1e-3).unwrap();
    sim.set_motor_torque(&[1.0; 7]).unwrap();
    sim.step(5).unwrap();
    let first = sim.state().to_vec();
    sim.reset(&x0).unwrap();
    assert_eq!(sim.steps(), 0);
    assert_eq!(sim.motor_torque(), &[0.0; 7]);
    sim.set_motor_torque(&[1.0; 7]).unwrap();
    sim.step(5).unwrap();
    assert_eq!(bits(sim.state()), bits(&first));
    assert!(sim.reset(&[1.0; 4]).is_err());
}

#[test]
fn a_step_allocates_nothing() {
    let arm = tree_arm(3);
    let (n, k) = (arm.dof(), arm.robot().end_effectors().len());
    let mut sim = Simulator::new(arm.clone(), &moving_state(&arm, 3), 1e-3).unwrap();
    sim.set_ee_wrench(Some(&vec![0.1; 6 * k])).unwrap();
    sim.step(1).unwrap();
    let mut out = Outputs::for_arm(&arm);
    let mut blob = Vec::with_capacity(sim.saved_len());
    let u = vec![0.4; n];
    let count = allocations(|| {
        sim.set_motor_torque(&u).unwrap();
        sim.set_base_wrench(&[0.1; 6]).unwrap();
        sim.set_ee_wrench(Some(&vec![0.2; 6 * k][..])).unwrap();
        sim.step(25).unwrap();
        sim.outputs_into(&mut out);
        sim.save_into(&mut blob);
    });
    // the one allocation is the test's own `vec![0.2; 6 * k]`
    assert_eq!(count, 1);
}

/// With reaction wheels: held wheel-torque commands, saturated at the start of each step as a
/// run saturates them, give bit for bit the run of `simulate` with the same constant commands
/// (one command past the torque limit, so that saturation is exercised); the commands survive
/// save and restore, and an arm without wheels refuses them.
#[test]
fn wheel_torques_are_held_and_saturated_as_in_a_run() {
    use orbitflex::flex::{ReactionWheels, Wheel};
    let wheels: Vec<Wheel> = (0..4)
        .map(|w| {
            let phi = std::f64::consts::FRAC_PI_2 * w as f64;
            let (side, tilt) = ((2.0f64 / 3.0).sqrt(), (1.0f64 / 3.0).sqrt());
            Wheel {
                axis: [side * phi.cos(), side * phi.sin(), tilt],
                position: [0.3 * phi.cos(), 0.3 * phi.sin(), -0.4],
                mass: 4.0,
                spin_inertia: 0.04,
                transverse_inertia: 0.025,
                max_torque: 0.2,
                max_speed: 600.0,
                friction: 1e-3,
            }
        })
        .collect();
    let plain = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    let arm = plain
        .clone()
        .with_wheels(ReactionWheels::new(wheels).unwrap())
        .unwrap();
    let x0 = arm.rest_state();
    let (u, commands) = ([2.0; 7], [0.1, -0.3, 0.05, 0.2]);
    let run = arm
        .simulate(
            &x0,
            1e-3,
            200,
            &mut Schedule::Constant(u.to_vec()),
            &Wrenches {
                wheel_torque: Schedule::Constant(commands.to_vec()),
                ..Wrenches::ZERO
            },
        )
        .unwrap();
    let mut sim = Simulator::new(arm.clone(), &x0, 1e-3).unwrap();
    sim.set_motor_torque(&u).unwrap();
    sim.set_wheel_torque(&commands).unwrap();
    sim.step(120).unwrap();
    let blob = sim.save();
    sim.set_wheel_torque(&[0.0; 4]).unwrap();
    sim.restore(&blob).unwrap();
    assert_eq!(sim.wheel_torque(), &commands);
    sim.step(80).unwrap();
    assert_eq!(sim.state(), &run.x[run.x.len() - x0.len()..]);
    // the applied torques of the run: the −0.3 command clipped to −0.2; the simulator reports
    // those of its last step, as the run's last row of applied torques
    assert_eq!(&run.u[7..11], &[0.1, -0.2, 0.05, 0.2]);
    let last = &run.u[run.u.len() - 11..];
    assert_eq!(sim.applied_wheel_torque(), &last[7..]);
    let out = sim.outputs();
    assert_eq!(out.applied_wheel_torque, &last[7..]);
    assert_eq!(out.wheel_speed, &sim.state()[41..45]);
    // a saved state of the arm without wheels, or of three wheels, is refused, saying so
    let mut bare = Simulator::new(plain.clone(), &plain.rest_state(), 1e-3).unwrap();
    let message = refusal(&mut sim, &bare.save());
    assert!(
        message.contains(
            "saved from an arm with no reaction wheels; this simulator's arm has 4 reaction \
             wheels"
        ),
        "{message}"
    );
    let message = refusal(&mut bare, &blob);
    assert!(
        message.contains("saved from an arm with 4 reaction wheels; this simulator's arm has no"),
        "{message}"
    );
    let three = plain
        .clone()
        .with_wheels(ReactionWheels::new(arm.wheels().unwrap().wheels()[..3].to_vec()).unwrap())
        .unwrap();
    let mut other = Simulator::new(three.clone(), &three.rest_state(), 1e-3).unwrap();
    let message = refusal(&mut other, &blob);
    assert!(message.contains("has 3 reaction wheels"), "{message}");
    // other wheels of the same count make another arm
    let mut heavier = arm.wheels().unwrap().wheels().to_vec();
    heavier[1].mass *= 2.0;
    let heavier = plain
        .clone()
        .with_wheels(ReactionWheels::new(heavier).unwrap())
        .unwrap();
    let mut other = Simulator::new(heavier.clone(), &heavier.rest_state(), 1e-3).unwrap();
    let message = refusal(&mut other, &blob);
    assert!(message.contains("saved from another arm"), "{message}");
    // a failed step puts the applied torques back with the state
    let before = sim.applied_wheel_torque().to_vec();
    sim.set_motor_torque(&[1e300; 7]).unwrap();
    sim.set_wheel_torque(&[-0.1, 0.1, -0.1, 0.1]).unwrap();
    assert!(sim.step(3).is_err());
    assert_eq!(sim.applied_wheel_torque(), before.as_slice());
    sim.reset(&x0).unwrap();
    assert_eq!(sim.applied_wheel_torque(), &[0.0; 4]);
    let e = bare.set_wheel_torque(&[0.0; 4]).unwrap_err().to_string();
    assert!(e.contains("no reaction wheels"), "{e}");
}
