//! Facts about the state layout, the quaternion helpers, the joint parameters, the controllers and
//! `simulate`, each pinned to a value derived independently of the code under test (closed forms,
//! exact binary arithmetic, a dense reference). Written to kill mutants `cargo mutants` found
//! surviving in `src/flex/` and `src/integrate/`.

use orbitflex::flex::{normalise_quaternion, quaternion_log, reflected_inertia, StateLayout};
use orbitflex::integrate::simulate::record_bytes;
use orbitflex::integrate::{
    simulate, stability_warning, Drive, Observer, Run, StateRows, Unobserved,
};
use orbitflex::testing::random_chain;
use orbitflex::{
    Controller, Error, FlexibleArm, FlexibleJoints, Inputs, Method, MotorPD, Robot, Schedule,
    Wrenches,
};

/// A two-joint arm with round spring parameters: `k = [100, 200]`, `j = [1, 1]`,
/// `d = [0.5, 0.25]`, `β = 0`.
fn two_joint_arm() -> FlexibleArm {
    let joints = FlexibleJoints::new(
        vec![100.0, 200.0],
        vec![1.0, 1.0],
        vec![0.5, 0.25],
        vec![0.0, 0.0],
    )
    .unwrap();
    FlexibleArm::new(random_chain(2, 11), joints).unwrap()
}

fn assert_close(actual: f64, expected: f64, relative: f64) {
    assert!(
        (actual - expected).abs() <= relative * expected.abs(),
        "{actual:e} vs {expected:e}"
    );
}

// ---------------------------------------------------------------------------------------------
// flex/state.rs

#[test]
fn state_layout_is_never_empty() {
    // the base alone has 13 states
    assert!(!StateLayout::new(0).is_empty());
    assert!(!StateLayout::new(3).is_empty());
}

#[test]
fn element_names_follow_the_layout() {
    let names = StateLayout::new(2).element_names(&["a", "b"]);
    let expected = [
        "r_x",
        "r_y",
        "r_z",
        "quat_x",
        "quat_y",
        "quat_z",
        "quat_w",
        "q[a]",
        "q[b]",
        "theta[a]",
        "theta[b]",
        "omega_x",
        "omega_y",
        "omega_z",
        "v_x",
        "v_y",
        "v_z",
        "qd[a]",
        "qd[b]",
        "theta_dot[a]",
        "theta_dot[b]",
    ];
    assert_eq!(names, expected);
    assert_eq!(names.len(), StateLayout::new(2).len());
}

#[test]
fn normalise_quaternion_divides_by_the_norm() {
    // |(1, 2, 2, 4)| = 5; the quotients are correctly rounded, so equal to the literals
    let mut q = [1.0, 2.0, 2.0, 4.0];
    normalise_quaternion(&mut q);
    assert_eq!(q, [0.2, 0.4, 0.4, 0.8]);
}

#[test]
fn normalise_quaternion_survives_overflowing_and_underflowing_squares() {
    // (3, 0, 0, 4) · 1e300: the squares overflow; the unit quaternion is (0.6, 0, 0, 0.8)
    let mut huge = [3e300, 0.0, 0.0, 4e300];
    normalise_quaternion(&mut huge);
    assert_close(huge[0], 0.6, 1e-15);
    assert_close(huge[3], 0.8, 1e-15);
    assert_eq!((huge[1], huge[2]), (0.0, 0.0));
    // (3, 0, 0, 4) · 1e-170: the squares underflow to zero
    let mut tiny = [3e-170, 0.0, 0.0, 4e-170];
    normalise_quaternion(&mut tiny);
    assert_close(tiny[0], 0.6, 1e-15);
    assert_close(tiny[3], 0.8, 1e-15);
    assert_eq!((tiny[1], tiny[2]), (0.0, 0.0));
}

#[test]
fn normalise_quaternion_leaves_zero_and_infinite_quaternions_alone() {
    let mut zero = [0.0; 4];
    normalise_quaternion(&mut zero);
    assert_eq!(zero, [0.0; 4]);
    let mut infinite = [f64::INFINITY, 0.0, 0.0, 1.0];
    normalise_quaternion(&mut infinite);
    assert_eq!(infinite, [f64::INFINITY, 0.0, 0.0, 1.0]);
}

#[test]
fn quaternion_log_of_a_tiny_rotation_is_scale_free() {
    // Log sees only the direction of the quaternion: (1e-9, 0, 0, 1e-3) is the rotation by
    // 2 atan(1e-6) about x, as is its normalised form. The vector part is below the series
    // threshold (1e-8), where the second term of θ/sin(θ/2) is 1e-12/3 relative, far above
    // rounding.
    let angle = 2.0 * (1e-6f64).atan();
    let log = quaternion_log(&[1e-9, 0.0, 0.0, 1e-3]);
    assert_close(log.x, angle, 1e-15);
    assert_eq!((log.y, log.z), (0.0, 0.0));
    let norm = (1e-18f64 + 1e-6).sqrt();
    let unit = quaternion_log(&[1e-9 / norm, 0.0, 0.0, 1e-3 / norm]);
    assert_close(unit.x, angle, 1e-15);
    // the same rotation with w < 0
    let negated = quaternion_log(&[-1e-9, 0.0, 0.0, -1e-3]);
    assert_close(negated.x, angle, 1e-15);
}

#[test]
fn quaternion_log_of_the_identity_and_of_a_negated_quaternion() {
    assert_eq!(quaternion_log(&[0.0, 0.0, 0.0, 1.0]).as_slice(), [0.0; 3]);
    // 1 rad about y is (0, sin ½, 0, cos ½), and its negation is the same rotation
    let (s, c) = (0.5f64.sin(), 0.5f64.cos());
    for quat in [[0.0, s, 0.0, c], [0.0, -s, 0.0, -c]] {
        let log = quaternion_log(&quat);
        assert_close(log.y, 1.0, 1e-15);
        assert_eq!((log.x, log.z), (0.0, 0.0));
    }
}

// ---------------------------------------------------------------------------------------------
// flex/joints.rs

#[test]
fn reflected_inertia_names_the_non_positive_parameter() {
    match reflected_inertia("joint 3: ", 160.0, 0.0) {
        Err(Error::InvalidArgument { what, message }) => {
            assert_eq!(what, "joint 3: rotor_inertia");
            assert_eq!(message, "expected a finite number > 0, given 0");
        }
        other => panic!("{other:?}"),
    }
    match reflected_inertia("joint 3: ", 0.0, 1e-5) {
        Err(Error::InvalidArgument { what, .. }) => assert_eq!(what, "joint 3: gear_ratio"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn reflected_inertia_refuses_a_product_that_underflows_to_zero() {
    // (1e-200)² · 1e-200 = 1e-600 rounds to 0: not a positive inertia
    match reflected_inertia("", 1e-200, 1e-200) {
        Err(Error::InvalidArgument { what, message }) => {
            assert_eq!(what, "gear_ratio");
            assert!(
                message.contains("is not a finite positive number"),
                "{message}"
            );
        }
        other => panic!("{other:?}"),
    }
    // and the exact product otherwise: 160² · 4e-5 = 1.024
    assert_close(reflected_inertia("", 160.0, 4e-5).unwrap(), 1.024, 1e-15);
}

#[test]
fn defaults_for_scales_to_the_inverse_mass_matrix_diagonal() {
    // m_i = 1/(𝓜⁻¹)_ii at q = 0 from the dense CRBA matrix inverted by LU (the code uses one ABA
    // solve per joint); then k = (2π·5)² m, j = m, d = 2·0.05·√(k m) = π m, β = 0.
    let robot = Robot::space_arm();
    let n = robot.dof();
    let joints = FlexibleJoints::defaults_for(&robot).unwrap();
    let mut data = orbitflex::Data::new(&robot);
    let mass = orbitflex::algorithms::crba(&robot, &mut data, &vec![0.0; n])
        .unwrap()
        .clone();
    let inverse = mass.try_inverse().unwrap();
    let omega = 10.0 * std::f64::consts::PI;
    for i in 0..n {
        let m = 1.0 / inverse[(6 + i, 6 + i)];
        assert_close(joints.motor_inertia[i], m, 1e-9);
        assert_close(joints.stiffness[i], omega * omega * m, 1e-9);
        assert_close(joints.damping[i], std::f64::consts::PI * m, 1e-9);
        assert_eq!(joints.motor_damping[i], 0.0);
    }
}

#[test]
fn flexible_joints_is_empty_only_without_joints() {
    assert!(FlexibleJoints::new(vec![], vec![], vec![], vec![])
        .unwrap()
        .is_empty());
    assert!(!FlexibleJoints::uniform(2, 1.0, 1.0, 0.0, 0.0)
        .unwrap()
        .is_empty());
}

// ---------------------------------------------------------------------------------------------
// flex/arm.rs

#[test]
fn inputs_check_refuses_wrong_length_and_non_finite_torques() {
    let robot = random_chain(2, 1);
    assert!(matches!(
        Inputs::torques(&[1.0]).check(&robot),
        Err(Error::Dimension { .. })
    ));
    assert!(Inputs::torques(&[1.0, f64::NAN]).check(&robot).is_err());
    assert!(Inputs::torques(&[1.0, 2.0]).check(&robot).is_ok());
    // one EE wrench per end-effector, or none
    let mut inputs = Inputs::torques(&[1.0, 2.0]);
    inputs.loads.ee_wrench = &[0.0; 6];
    assert!(inputs.check(&robot).is_ok());
    inputs.loads.ee_wrench = &[0.0; 12];
    let err = inputs.check(&robot).unwrap_err().to_string();
    assert!(
        err.contains("expected 6 numbers") && err.contains("given 12"),
        "{err}"
    );
    inputs.loads.ee_wrench = &[0.0, 0.0, f64::INFINITY, 0.0, 0.0, 0.0];
    assert!(inputs.check(&robot).is_err());
}

#[test]
fn derivative_refuses_another_arms_workspace() {
    let arm = two_joint_arm();
    let other = FlexibleArm::new(
        random_chain(3, 5),
        FlexibleJoints::uniform(3, 100.0, 1.0, 0.0, 0.0).unwrap(),
    )
    .unwrap();
    let mut ws = other.workspace();
    let x = arm.rest_state();
    let mut xdot = vec![0.0; x.len()];
    match arm.derivative(&mut ws, &x, &Inputs::torques(&[0.0, 0.0]), &mut xdot) {
        Err(Error::Dimension { what, .. }) => assert_eq!(what, "Data workspace"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn method_reports_the_selected_dynamics() {
    let arm = two_joint_arm();
    assert_eq!(arm.method(), Method::Recursive);
    assert_eq!(arm.with_method(Method::Operator).method(), Method::Operator);
}

// ---------------------------------------------------------------------------------------------
// integrate/control.rs

#[test]
fn schedule_torque_refuses_a_step_past_its_table() {
    let mut table = Schedule::Table {
        values: vec![1.0, 2.0],
        width: 1,
    };
    let mut u = [0.0];
    table.output(1, 0.0, &[], &mut u).unwrap();
    assert_eq!(u, [2.0]);
    match table.output(2, 0.0, &[], &mut u) {
        Err(Error::Dimension { what, given, .. }) => {
            assert_eq!(what, "u");
            assert_eq!(given, "2 rows");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn schedule_check_run_checks_width_rows_and_values() {
    assert!(Schedule::Constant(vec![1.0; 3])
        .check_run("u", 2, 5)
        .is_err());
    assert!(Schedule::Constant(vec![1.0; 2])
        .check_run("u", 2, 5)
        .is_ok());
    let table = |rows: usize, value: f64| Schedule::Table {
        values: vec![value; 2 * rows],
        width: 2,
    };
    assert!(table(4, 1.0).check_run("u", 2, 5).is_err());
    assert!(table(6, 1.0).check_run("u", 2, 5).is_err());
    assert!(table(5, f64::NAN).check_run("u", 2, 5).is_err());
    assert!(table(5, 1.0).check_run("u", 2, 5).is_ok());
}

#[test]
fn motor_pd_reports_its_joints_and_refuses_a_step_past_its_table() {
    let reference = Schedule::Table {
        values: vec![0.5, 0.25, 0.75, 0.5, 0.5, 0.5],
        width: 3,
    };
    let mut pd = MotorPD::new(
        vec![2.0; 3],
        vec![0.0; 3],
        reference,
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    assert_eq!(pd.dof(), 3);
    let x = vec![0.0; StateLayout::new(3).len()];
    let mut u = [0.0; 3];
    // θ = 0: u = 2 θ_ref of row 1
    pd.output(1, 0.0, &x, &mut u).unwrap();
    assert_eq!(u, [1.0, 1.0, 1.0]);
    assert!(matches!(
        pd.output(2, 0.0, &x, &mut u),
        Err(Error::Dimension { .. })
    ));
}

// ---------------------------------------------------------------------------------------------
// integrate/trajectory.rs

/// Two rows of the two-joint layout: q, θ, q̇, θ̇ chosen so that every result is exact.
fn two_rows() -> Vec<f64> {
    let layout = StateLayout::new(2);
    let mut x = vec![0.0; 2 * layout.len()];
    for (row, (q, theta, qd, theta_dot)) in [
        ([0.5, -0.25], [0.75, 0.25], [1.0, 2.0], [1.5, 1.0]),
        ([-1.0, 2.0], [-1.5, 2.0], [0.0, 0.0], [0.0, 4.0]),
    ]
    .into_iter()
    .enumerate()
    {
        let x = &mut x[row * layout.len()..(row + 1) * layout.len()];
        x[6] = 1.0; // identity quaternion
        x[layout.q()].copy_from_slice(&q);
        x[layout.theta()].copy_from_slice(&theta);
        x[layout.qd()].copy_from_slice(&qd);
        x[layout.theta_dot()].copy_from_slice(&theta_dot);
    }
    x
}

#[test]
fn state_rows_count_and_deflection() {
    let x = two_rows();
    let rows = StateRows {
        layout: StateLayout::new(2),
        x: &x,
    };
    assert_eq!(rows.len(), 2);
    assert!(!rows.is_empty());
    // θ − q
    assert_eq!(rows.deflection(), [0.25, 0.5, -0.5, 0.0]);
    let none = StateRows {
        layout: StateLayout::new(2),
        x: &[],
    };
    assert_eq!(none.len(), 0);
    assert!(none.is_empty());
    assert!(none.deflection().is_empty());
}

#[test]
fn state_rows_spring_torque() {
    let arm = two_joint_arm();
    let x = two_rows();
    let rows = StateRows {
        layout: arm.layout(),
        x: &x,
    };
    // k (θ − q) + d (θ̇ − q̇) with k = [100, 200], d = [0.5, 0.25]
    assert_eq!(
        rows.spring_torque(&arm),
        [
            100.0 * (0.75 - 0.5) + 0.5 * (1.5 - 1.0),
            200.0 * (0.25 + 0.25) + 0.25 * (1.0 - 2.0),
            100.0 * (-1.5 + 1.0) + 0.5 * (0.0 - 0.0),
            200.0 * (2.0 - 2.0) + 0.25 * (4.0 - 0.0),
        ]
    );
}

#[test]
fn state_rows_spring_torque_without_joints() {
    let arm = FlexibleArm::new(
        random_chain(0, 3),
        FlexibleJoints::new(vec![], vec![], vec![], vec![]).unwrap(),
    )
    .unwrap();
    let x = [arm.rest_state(), arm.rest_state()].concat();
    let rows = StateRows {
        layout: arm.layout(),
        x: &x,
    };
    assert_eq!(rows.len(), 2);
    assert!(rows.spring_torque(&arm).is_empty());
}

#[test]
#[should_panic(expected = "spring_torque: out holds 3 torques, the arm has n = 2")]
fn spring_torque_refuses_a_buffer_of_another_size() {
    let arm = two_joint_arm();
    let x = arm.rest_state();
    let mut out = [7.0; 3];
    arm.spring_torque(&x, &mut out);
}

// ---------------------------------------------------------------------------------------------
// integrate/simulate.rs

#[test]
fn unobserved_never_interrupts() {
    let mut none = Unobserved;
    assert_eq!(none.every(), 0);
    assert!(none.observe(1, 2));
}

/// Records when it is asked; stops the run when asked at `stop_at`.
struct Recorder {
    every: usize,
    stop_at: Option<usize>,
    calls: Vec<(usize, usize)>,
}

impl Observer for Recorder {
    fn every(&self) -> usize {
        self.every
    }
    fn observe(&mut self, step: usize, steps: usize) -> bool {
        self.calls.push((step, steps));
        Some(step) != self.stop_at
    }
}

#[test]
fn simulate_asks_the_observer_before_every_nth_step_but_the_first() {
    let arm = two_joint_arm();
    let x0 = arm.rest_state();
    let mut observer = Recorder {
        every: 3,
        stop_at: None,
        calls: vec![],
    };
    let traj = simulate(
        &arm,
        &Run::new(&x0, 1e-3, 10),
        &mut Drive::new(&mut Schedule::Zero, &mut Wrenches::default()),
        &mut observer,
    )
    .unwrap();
    assert_eq!(traj.len(), 11);
    assert_eq!(observer.calls, [(3, 10), (6, 10), (9, 10)]);

    let mut never = Recorder {
        every: 0,
        stop_at: Some(1),
        calls: vec![],
    };
    let traj = simulate(
        &arm,
        &Run::new(&x0, 1e-3, 4),
        &mut Drive::new(&mut Schedule::Zero, &mut Wrenches::default()),
        &mut never,
    )
    .unwrap();
    assert_eq!(traj.len(), 5);
    assert!(never.calls.is_empty());
}

#[test]
fn simulate_stops_when_the_observer_says_so() {
    let arm = two_joint_arm();
    let mut observer = Recorder {
        every: 2,
        stop_at: Some(4),
        calls: vec![],
    };
    let failure = simulate(
        &arm,
        &Run::new(&arm.rest_state(), 1e-3, 10),
        &mut Drive::new(&mut Schedule::Zero, &mut Wrenches::default()),
        &mut observer,
    )
    .unwrap_err();
    assert_eq!(observer.calls, [(2, 10), (4, 10)]);
    match failure.error {
        Error::Simulation { step, message, .. } => {
            assert_eq!(step, 4);
            assert_eq!(message, "interrupted by the caller");
        }
        other => panic!("{other:?}"),
    }
    // the states before step 4: t = 0 … 4 dt
    assert_eq!(failure.trajectory.len(), 5);
    assert_eq!(failure.trajectory.u.len(), 4 * 2);
}

#[test]
fn record_bytes_counts_times_states_and_inputs() {
    let layout = StateLayout::new(2);
    // 10 steps: 11 times, 11 states of 21 numbers, 10 inputs of 2, 8 bytes each
    assert_eq!(record_bytes(layout, 10), Some(8 * (11 + 11 * 21 + 10 * 2)));
    assert_eq!(record_bytes(layout, 0), Some(8 * 22));
    assert_eq!(record_bytes(layout, usize::MAX), None);
    assert_eq!(record_bytes(layout, usize::MAX / 8), None);
}

#[test]
fn simulate_allocates_the_record_once_and_exactly() {
    let arm = two_joint_arm();
    // 9 steps (with 10, a too-small reservation of the inputs can regrow to exactly 20 by
    // doubling and go unnoticed)
    let traj = simulate(
        &arm,
        &Run::new(&arm.rest_state(), 1e-3, 9),
        &mut Drive::new(&mut Schedule::Zero, &mut Wrenches::default()),
        &mut Unobserved,
    )
    .unwrap();
    // reserved once for 10 times, 10 × 21 states and 9 × 2 inputs; a push past that would
    // have reallocated to a larger capacity
    assert_eq!((traj.t.len(), traj.t.capacity()), (10, 10));
    assert_eq!((traj.x.len(), traj.x.capacity()), (210, 210));
    assert_eq!((traj.u.len(), traj.u.capacity()), (18, 18));
}

#[test]
fn simulate_refuses_a_record_that_overflows() {
    let arm = two_joint_arm();
    let failure = simulate(
        &arm,
        &Run::new(&arm.rest_state(), 1e-3, usize::MAX),
        &mut Drive::new(&mut Schedule::Zero, &mut Wrenches::default()),
        &mut Unobserved,
    )
    .unwrap_err();
    match failure.error {
        Error::InvalidArgument { what, .. } => assert_eq!(what, "steps"),
        other => panic!("{other:?}"),
    }
    assert!(failure.trajectory.is_empty());
}

/// Fails at once: shows whether a run got as far as its first step.
struct Failing;

impl Controller for Failing {
    fn output(&mut self, _: usize, _: f64, _: &[f64], _: &mut [f64]) -> orbitflex::Result<()> {
        Err(Error::InvalidArgument {
            what: "u".into(),
            message: "failing on purpose".into(),
        })
    }
}

#[test]
fn simulate_refuses_a_record_larger_than_the_available_memory() {
    let Some(available) = orbitflex::io::available_memory() else {
        return;
    };
    let arm = two_joint_arm();
    // just over the available memory: refused before the first step, whether or not the
    // system would have handed out the (overcommitted) allocation
    let per_step = record_bytes(arm.layout(), 1).unwrap() - record_bytes(arm.layout(), 0).unwrap();
    let steps = (available as usize / per_step) * 51 / 50;
    assert!(record_bytes(arm.layout(), steps).unwrap() as u64 > available);
    let failure = simulate(
        &arm,
        &Run::new(&arm.rest_state(), 1e-3, steps),
        &mut Drive::new(&mut Failing, &mut Wrenches::default()),
        &mut Unobserved,
    )
    .unwrap_err();
    match failure.error {
        Error::InvalidArgument { what, message } => {
            assert_eq!(what, "steps");
            assert!(message.contains("more than the"), "{message}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn stability_warning_starts_past_the_limit_not_at_it() {
    let arm = two_joint_arm();
    let x0 = arm.rest_state();
    let pd = MotorPD::new(
        vec![50.0; 2],
        vec![5.0; 2],
        Schedule::Zero,
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    let limit = arm.rk4_stability_limit(&x0, &pd).unwrap();
    assert!(limit.dt.is_finite());
    // the limit is the largest stable step: no warning at it, one just past it
    assert_eq!(stability_warning(&arm, &x0, limit.dt, &pd).unwrap(), None);
    let past = limit.dt * (1.0 + 1e-12);
    let warning = stability_warning(&arm, &x0, past, &pd).unwrap().unwrap();
    assert!(
        warning.contains("exceeds the RK4 stability limit"),
        "{warning}"
    );
}

// ---------------------------------------------------------------------------------------------
// flex/stability.rs

/// `m = 1/(𝓜⁻¹)_qq` of a one-joint robot at `q = 0`, from the dense CRBA matrix.
fn effective_inertia(robot: &Robot) -> f64 {
    let mut data = orbitflex::Data::new(robot);
    let mass = orbitflex::algorithms::crba(robot, &mut data, &[0.0])
        .unwrap()
        .clone();
    1.0 / mass.try_inverse().unwrap()[(6, 6)]
}

/// `dt` is a bisection's lower end for the boundary `exact`: within 1e-4 below it.
fn assert_bisected(dt: f64, exact: f64) {
    assert!(
        dt <= exact * (1.0 + 1e-12) && dt >= exact * (1.0 - 1e-4),
        "{dt:e} vs {exact:e}"
    );
}

#[test]
fn stability_limit_of_an_undamped_joint_is_on_rk4s_imaginary_axis() {
    // One joint at rest, relaxed, no damping, open loop: the base and the rigid rotation give
    // zero eigenvalues and the spring couples the link (effective inertia m with the base free)
    // to the motor j at Ω² = k (1/m + 1/j). RK4 is stable on the imaginary axis up to
    // |λ h| = 2√2 (|R(iy)|² = 1 − y⁶/72 + y⁸/576), so the limit is 2√2/Ω; both the dense
    // analysis and the joint-by-joint estimate (exact here) find it.
    use orbitflex::flex::stability::joint_by_joint_limit;
    let robot = random_chain(1, 4);
    let m = effective_inertia(&robot);
    let (k, j) = (400.0, 0.3);
    let joints = FlexibleJoints::new(vec![k], vec![j], vec![0.0], vec![0.0]).unwrap();
    let arm = FlexibleArm::new(robot, joints).unwrap();
    let x0 = arm.rest_state();
    let omega = (k * (1.0 / m + 1.0 / j)).sqrt();
    let exact = 2.0 * std::f64::consts::SQRT_2 / omega;
    let dense = arm.rk4_stability_limit(&x0, &Schedule::Zero).unwrap();
    assert_bisected(dense.dt, exact);
    assert_close(dense.fastest_mode.norm(), omega, 1e-9);
    let (estimate, fastest) = joint_by_joint_limit(&arm, &x0, &Schedule::Zero.feedback()).unwrap();
    assert_bisected(estimate, exact);
    assert_close(fastest.norm(), omega, 1e-9);
    assert_close(fastest.im.abs(), omega, 1e-9);
}

#[test]
fn joint_by_joint_estimate_is_exact_for_one_joint_at_rest() {
    // At rest with relaxed springs nothing depends on the base twist (the bias forces are
    // quadratic in the velocities), so the dense linearisation is block triangular: zeros for
    // the base, and the 4×4 link/motor block the estimate builds, with a = (𝓜⁻¹)_qq exactly.
    // The two analyses then bisect the same boundary (each to 1e-4 from below), and find the
    // same fastest mode. Damping, friction and both PD gains all enter.
    use orbitflex::flex::stability::joint_by_joint_limit;
    for (k, j, d, beta, kp, kd) in [
        (400.0, 0.3, 1.5, 0.7, 0.0, 0.0),
        (400.0, 0.3, 1.5, 0.7, 300.0, 2.0),
        (50.0, 2.0, 0.2, 3.0, 900.0, 0.5),
        (900.0, 0.5, 8.0, 0.0, 20.0, 40.0),
    ] {
        let robot = random_chain(1, 4);
        let joints = FlexibleJoints::new(vec![k], vec![j], vec![d], vec![beta]).unwrap();
        let arm = FlexibleArm::new(robot, joints).unwrap();
        let x0 = arm.rest_state();
        let pd = MotorPD::new(
            vec![kp],
            vec![kd],
            Schedule::Zero,
            Schedule::Zero,
            Schedule::Zero,
        )
        .unwrap();
        let dense = arm.rk4_stability_limit(&x0, &pd).unwrap();
        let (estimate, fastest) = joint_by_joint_limit(&arm, &x0, &pd.feedback()).unwrap();
        assert!(
            (estimate - dense.dt).abs() <= 1e-4 * dense.dt,
            "{k} {j} {d} {beta} {kp} {kd}: {estimate:e} vs {:e}",
            dense.dt
        );
        assert_close(fastest.norm(), dense.fastest_mode.norm(), 1e-9);
        assert_close(fastest.re, dense.fastest_mode.re, 1e-9);
    }
}

/// Spectral radius of the RK4 step matrix `M(h) = R(hF) + h S(hF) G K` (a reference written
/// out term by term: `R(z) = I + z + z²/2 + z³/6 + z⁴/24`, `S(z) = I + z/2 + z²/6 + z³/24`).
fn step_radius(f: &nalgebra::DMatrix<f64>, gk: &nalgebra::DMatrix<f64>, h: f64) -> f64 {
    let z = f * h;
    let identity = nalgebra::DMatrix::<f64>::identity(f.nrows(), f.nrows());
    let z2 = &z * &z;
    let z3 = &z2 * &z;
    let z4 = &z3 * &z;
    let r = &identity + &z + &z2 / 2.0 + &z3 / 6.0 + &z4 / 24.0;
    let s = &identity + &z / 2.0 + &z2 / 6.0 + &z3 / 24.0;
    let m = r + s * gk * h;
    // the crate's Hessenberg–QR (nalgebra's Schur iteration can cycle on the free base's exact
    // zero eigenvalues)
    orbitflex::linalg::eigenvalues(&m)
        .unwrap()
        .iter()
        .map(|l| l.norm())
        .fold(0.0, f64::max)
}

#[test]
fn dense_stability_limit_is_the_boundary_of_a_finite_difference_reference() {
    // Two joints at rest (no mode grows: the criterion is a spectral radius of at most 1, to
    // the code's 1e-6), a PD on both with gains that matter. F by central differences of the
    // derivative on [q | θ | V_B | q̇ | θ̇] (the plain coordinates there are the tangent's), G K
    // placed by hand on the θ̈ rows: the step matrix is stable just inside the limit and
    // unstable just outside it.
    let robot = random_chain(2, 9);
    let joints = FlexibleJoints::new(
        vec![300.0, 150.0],
        vec![0.4, 0.25],
        vec![1.0, 0.5],
        vec![0.3, 0.6],
    )
    .unwrap();
    let arm = FlexibleArm::new(robot, joints.clone()).unwrap();
    let (kp, kd) = (vec![200.0, 500.0], vec![3.0, 6.0]);
    let pd = MotorPD::new(
        kp.clone(),
        kd.clone(),
        Schedule::Zero,
        Schedule::Zero,
        Schedule::Zero,
    )
    .unwrap();
    let x0 = arm.rest_state();
    let layout = arm.layout();
    let start = layout.dynamic().start;
    let size = layout.dynamic().len();
    let mut ws = arm.workspace();
    let zero = [0.0, 0.0];
    let derivative = |ws: &mut orbitflex::ArmWorkspace, x: &[f64]| {
        let mut xdot = vec![0.0; x.len()];
        arm.derivative(ws, x, &Inputs::torques(&zero), &mut xdot)
            .unwrap();
        xdot
    };
    let eps = 1e-6;
    let mut f = nalgebra::DMatrix::<f64>::zeros(size, size);
    for c in 0..size {
        let (mut plus, mut minus) = (x0.clone(), x0.clone());
        plus[start + c] += eps;
        minus[start + c] -= eps;
        let (a, b) = (derivative(&mut ws, &plus), derivative(&mut ws, &minus));
        for r in 0..size {
            f[(r, c)] = (a[start + r] - b[start + r]) / (2.0 * eps);
        }
    }
    let mut gk = nalgebra::DMatrix::<f64>::zeros(size, size);
    for i in 0..2 {
        let row = layout.theta_dot().start + i - start;
        gk[(row, layout.theta().start + i - start)] = -kp[i] / joints.motor_inertia[i];
        gk[(row, row)] = -kd[i] / joints.motor_inertia[i];
    }
    let limit = arm.rk4_stability_limit(&x0, &pd).unwrap();
    let inside = step_radius(&f, &gk, 0.999 * limit.dt);
    let outside = step_radius(&f, &gk, 1.001 * limit.dt);
    assert!(inside <= 1.0 + 1e-6, "{inside} at {:e}", limit.dt);
    assert!(outside > 1.0 + 1e-6, "{outside} at {:e}", limit.dt);
}

#[test]
fn stability_limit_of_a_spinning_base_is_set_by_its_momentum_rotating_in_the_base_frame() {
    // A bare base (no joints), its centre of mass at its origin, inertia diag(2, 3, 4), spinning
    // at 0.3 rad/s about its major axis z (a stable spin). In base-frame components the
    // momentum turns at −ω: v̇ = −ω × v gives ±0.3i, Euler's equations ±i·0.3·√((4−2)(4−3)/(2·3))
    // (slower), the quaternion kinematics ±0.15i (slower still). RK4 on the imaginary axis is
    // stable up to |λ h| = 2√2, so the limit is 2√2/0.3.
    use orbitflex::spatial::{Inertia, Mat3, Transform, Vec3};
    let base = Inertia::from_com(
        10.0,
        Vec3::zeros(),
        Mat3::from_diagonal(&Vec3::new(2.0, 3.0, 4.0)),
    );
    let robot = orbitflex::RobotBuilder::new("spinning_base", "base", base)
        .ee("ee", Transform::identity())
        .build()
        .unwrap();
    let arm = FlexibleArm::new(
        robot,
        FlexibleJoints::new(vec![], vec![], vec![], vec![]).unwrap(),
    )
    .unwrap();
    let twist = [0.0, 0.0, 0.3, 0.0, 0.0, 0.0];
    let x0 = arm
        .state(&orbitflex::StateSpec {
            base_twist: Some(&twist),
            ..Default::default()
        })
        .unwrap();
    let limit = arm.rk4_stability_limit(&x0, &Schedule::Zero).unwrap();
    assert_bisected(limit.dt, 2.0 * std::f64::consts::SQRT_2 / 0.3);
    assert_close(limit.fastest_mode.norm(), 0.3, 1e-12);
}

#[test]
fn stability_limit_of_a_drifting_base_is_infinite() {
    // The same bare base translating without rotation: the only coupling is v̇ = −ω × v, linear
    // in δω (F = [[0, 0], [[v]×, 0]], F² = 0), so every eigenvalue is zero and RK4 is exact
    // for any step: nothing limits it. (The scan must stop at its cap and say so.)
    use orbitflex::spatial::{Inertia, Mat3, Transform, Vec3};
    let base = Inertia::from_com(
        10.0,
        Vec3::zeros(),
        Mat3::from_diagonal(&Vec3::new(2.0, 3.0, 4.0)),
    );
    let robot = orbitflex::RobotBuilder::new("drifting_base", "base", base)
        .ee("ee", Transform::identity())
        .build()
        .unwrap();
    let arm = FlexibleArm::new(
        robot,
        FlexibleJoints::new(vec![], vec![], vec![], vec![]).unwrap(),
    )
    .unwrap();
    let twist = [0.0, 0.0, 0.0, 0.5, 0.2, 0.0];
    let x0 = arm
        .state(&orbitflex::StateSpec {
            base_twist: Some(&twist),
            ..Default::default()
        })
        .unwrap();
    let limit = arm.rk4_stability_limit(&x0, &Schedule::Zero).unwrap();
    assert_eq!(limit.dt, f64::INFINITY);
    // zero, to the rounding of the eigenvalue solver on entries of size |v| = 0.54
    assert!(limit.fastest_mode.norm() < 1e-12, "{limit:?}");
}

#[test]
fn joint_by_joint_estimate_takes_each_joints_own_effective_inertia() {
    // Two joints, undamped, open loop: joint i alone is the two-mass oscillator
    // Ω_i² = k_i (a_i + 1/j_i) with a_i = (𝓜⁻¹)_{6+i,6+i} at the state's q (here 0, from the
    // dense CRBA inverse); the estimate is the smallest 2√2/Ω_i, and its fastest mode the largest
    // Ω_i. Joint 2 (index 1) is made the fastest so that its own inertia is the one that counts.
    use orbitflex::flex::stability::joint_by_joint_limit;
    let robot = random_chain(2, 6);
    let mut data = orbitflex::Data::new(&robot);
    let inverse = orbitflex::algorithms::crba(&robot, &mut data, &[0.0, 0.0])
        .unwrap()
        .clone()
        .try_inverse()
        .unwrap();
    let (k, j) = ([100.0, 5000.0], [0.5, 0.2]);
    let joints = FlexibleJoints::new(k.to_vec(), j.to_vec(), vec![0.0; 2], vec![0.0; 2]).unwrap();
    let arm = FlexibleArm::new(robot, joints).unwrap();
    let omega: Vec<f64> = (0..2)
        .map(|i| (k[i] * (inverse[(6 + i, 6 + i)] + 1.0 / j[i])).sqrt())
        .collect();
    assert!(omega[1] > omega[0]);
    let (estimate, fastest) =
        joint_by_joint_limit(&arm, &arm.rest_state(), &Schedule::Zero.feedback()).unwrap();
    assert_bisected(estimate, 2.0 * std::f64::consts::SQRT_2 / omega[1]);
    assert_close(fastest.norm(), omega[1], 1e-9);
}

#[test]
fn a_spinning_base_sets_the_estimated_limit_by_its_quaternion_kinematics() {
    // Past DENSE_LIMIT joints the limit is the joint-by-joint estimate, which leaves the base's
    // rotation out, and the minimum with the quaternion kinematics' term: q̇ = ½ q ⊗ ω_B
    // oscillates at ±i|ω_B|/2, on RK4's imaginary axis, stable up to |λ h| = 2√2. With soft
    // joints (modes near 0.22 rad/s) that term sets the limit: 2√2 / (|ω_B|/2), exactly as
    // computed (|ω_B| = w exactly for a spin about z). At rest the term is absent.
    use orbitflex::flex::stability::DENSE_LIMIT;
    let n = DENSE_LIMIT + 4;
    let joints = FlexibleJoints::new(vec![1e-2; n], vec![1.0; n], vec![0.0; n], vec![0.0; n]);
    let arm = FlexibleArm::new(random_chain(n, 7), joints.unwrap()).unwrap();
    let at_rest = arm
        .rk4_stability_limit(&arm.rest_state(), &Schedule::Zero)
        .unwrap();
    assert!(at_rest.estimated);
    for w in [0.5, 2.0, 10.0] {
        let mut x = arm.rest_state();
        x[arm.layout().base_twist()][..3].copy_from_slice(&[0.0, 0.0, w]);
        let limit = arm.rk4_stability_limit(&x, &Schedule::Zero).unwrap();
        let pose = 2.0 * std::f64::consts::SQRT_2 / (0.5 * w);
        assert!(
            pose < at_rest.dt,
            "w = {w}: the joints' limit {:e}",
            at_rest.dt
        );
        assert_eq!(limit.dt, pose, "w = {w}");
        assert!(limit.estimated);
    }
}
