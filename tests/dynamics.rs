//! Recursive algorithms against the operator form (model §6.5) and the structural identities of
//! model §6.4, on random chains with awkward features.

use nalgebra::{DMatrix, DVector};
use orbitflex::algorithms::{self, Data};
use orbitflex::spatial::Motion;
use orbitflex::testing::{random_chain, random_state, Rng};
use orbitflex::{Loads, Method, Operators, RigidState, Robot};
use proptest::prelude::*;

fn rel_err_m(a: &DMatrix<f64>, b: &DMatrix<f64>) -> f64 {
    (a - b).norm() / b.norm().max(1.0)
}
fn rel_err_v(a: &DVector<f64>, b: &DVector<f64>) -> f64 {
    (a - b).norm() / b.norm().max(1.0)
}

/// `(q, V_B, q̇, τ, f_B, f)`.
type Inputs = (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

fn inputs(robot: &Robot, seed: u64) -> Inputs {
    let (q, v, qd) = random_state(robot, seed);
    let mut rng = Rng::new(seed + 99);
    let n = robot.dof();
    (
        q,
        v,
        qd,
        rng.vector(n, -5.0, 5.0),
        rng.vector(6, -5.0, 5.0),
        rng.vector(6, -5.0, 5.0),
    )
}

fn check_agreement(n: usize, seed: u64) {
    let robot = random_chain(n, seed);
    let (q, v, qd, tau, fb, f) = inputs(&robot, seed);
    let state = RigidState::new(&q, &v, &qd);
    let loads = Loads::from_slices(Some(&fb), Some(&f)).unwrap();
    let ops = Operators::new(&robot, &state).unwrap();
    let mut data = Data::new(&robot);

    let m = algorithms::crba(&robot, &mut data, &q).unwrap().clone();
    assert!(
        rel_err_m(&m, &ops.mass_matrix()) < 1e-10,
        "mass matrix n={n} seed={seed}"
    );

    let c = algorithms::bias_forces(&robot, &mut data, &state)
        .unwrap()
        .clone();
    assert!(rel_err_v(&c, &ops.bias_forces()) < 1e-10, "bias n={n}");

    let acc = algorithms::aba(&robot, &mut data, &state, &tau, &loads)
        .unwrap()
        .clone();
    let acc_op = ops.forward_dynamics(&tau, &loads).unwrap();
    assert!(
        rel_err_v(&acc, &acc_op) < 1e-10,
        "forward dynamics n={n}: {}",
        rel_err_v(&acc, &acc_op)
    );

    let gen = algorithms::rnea(
        &robot,
        &mut data,
        &state,
        &acc.as_slice()[..6],
        &acc.as_slice()[6..],
        &f,
    )
    .unwrap()
    .clone();
    let gen_op = ops
        .inverse_dynamics(&acc.as_slice()[..6], &acc.as_slice()[6..], &f)
        .unwrap();
    assert!(rel_err_v(&gen, &gen_op) < 1e-10, "inverse dynamics n={n}");
    // inverse ∘ forward = identity (model §6.4)
    let mut given = DVector::zeros(6 + n);
    given.rows_mut(0, 6).copy_from_slice(&fb);
    given.rows_mut(6, n).copy_from_slice(&tau);
    assert!(rel_err_v(&gen, &given) < 1e-10, "ID(FD) n={n}");

    algorithms::ee_jacobian(&robot, &mut data, &q, 0).unwrap();
    assert!(rel_err_m(&data.jacobian, &ops.j) < 1e-10, "J n={n}");
    let ee_base = DMatrix::from_column_slice(6, 6, data.ee_base.as_slice());
    let ee_base_op = DMatrix::from_column_slice(6, 6, ops.phi_ee_base.as_slice());
    assert!(rel_err_m(&ee_base, &ee_base_op) < 1e-10, "Φ_(n+1,B) n={n}");

    let h = algorithms::momentum(&robot, &mut data, &state).unwrap();
    let h_op = ops.base_momentum(&v, &qd);
    assert!(
        rel_err_v(
            &DVector::from_column_slice(h.to_vector().as_slice()),
            &DVector::from_column_slice(h_op.to_vector().as_slice())
        ) < 1e-10
    );

    let mut nu = DVector::zeros(6 + n);
    nu.rows_mut(0, 6).copy_from_slice(&v);
    nu.rows_mut(6, n).copy_from_slice(&qd);
    let ke = algorithms::kinetic_energy(&robot, &mut data, &state).unwrap();
    let ke_op = 0.5 * nu.dot(&(ops.mass_matrix() * &nu));
    assert!((ke - ke_op).abs() < 1e-10 * ke_op.abs().max(1.0));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn recursive_algorithms_equal_operator_form(n in 1usize..=60, seed in 0u64..10_000) {
        check_agreement(n, seed);
    }
}

#[test]
fn agreement_on_short_chains_and_the_space_arm() {
    for n in 0..=4 {
        for seed in 0..5 {
            check_agreement(n, seed);
        }
    }
    let robot = Robot::space_arm();
    let (q, v, qd) = random_state(&robot, 3);
    let state = RigidState::new(&q, &v, &qd);
    let loads = Loads::from_slices(Some(&[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]), Some(&[0.5; 6])).unwrap();
    let a = robot
        .forward_dynamics(&state, &[1.0; 7], &loads, Method::Recursive)
        .unwrap();
    let b = robot
        .forward_dynamics(&state, &[1.0; 7], &loads, Method::Operator)
        .unwrap();
    assert!(rel_err_v(&a, &b) < 1e-10);
}

#[test]
fn mass_matrix_is_symmetric_positive_definite() {
    for seed in 0..20 {
        let robot = random_chain(1 + (seed as usize % 12), seed);
        let (q, _, _) = random_state(&robot, seed);
        let m = Operators::new(&robot, &RigidState::at_rest(&q, &vec![0.0; robot.dof()]))
            .unwrap()
            .mass_matrix();
        assert!((&m - m.transpose()).norm() <= 1e-12 * m.norm());
        assert!(m.clone().cholesky().is_some());
        // the operator form's M_br really is M_rbᵀ (A.19)
        let ops =
            Operators::new(&robot, &RigidState::at_rest(&q, &vec![0.0; robot.dof()])).unwrap();
        assert!((&ops.m_br - ops.m_rb.transpose()).norm() <= 1e-12 * ops.m_rb.norm().max(1.0));
    }
}

/// With `V_B = 0` and `α_B = 0`, the joint rows of (A.19) are the fixed-base equations: compare
/// `M_r q̈ + C_r` with a fixed-base Newton–Euler written independently here, in inertial-frame
/// vectors (no spatial algebra).
#[test]
fn fixed_base_reduction_matches_newton_euler() {
    use nalgebra::{Matrix3, Vector3};
    for seed in 0..10 {
        let n = 1 + seed as usize % 8;
        let robot = random_chain(n, 100 + seed);
        let (q, _, qd) = random_state(&robot, seed);
        let qdd = Rng::new(seed).vector(n, -2.0, 2.0);
        let ops = Operators::new(&robot, &RigidState::new(&q, &[0.0; 6], &qd)).unwrap();
        let tau_op = &ops.m_r * DVector::from_column_slice(&qdd) + &ops.c_r;

        // Inertial-frame kinematics: rotation E_i (body -> world), origin o_i, ω_i, ω̇_i, ö_i.
        let mut e = vec![Matrix3::identity()];
        let mut o = vec![Vector3::zeros()];
        let mut w = vec![Vector3::zeros()];
        let mut wd = vec![Vector3::zeros()];
        let mut od = vec![Vector3::zeros()];
        let mut odd = vec![Vector3::zeros()];
        let mut axis = vec![Vector3::zeros()];
        for (i, joint) in robot.joints().iter().enumerate() {
            let x = joint.transform(q[i]);
            let ei = e[i] * x.rotation.transpose();
            let r = e[i] * x.translation; // origin offset in world
            let z = ei * joint.axis;
            let wi = w[i] + z * qd[i];
            let wdi = wd[i] + z * qdd[i] + w[i].cross(&(z * qd[i]));
            let odi = od[i] + w[i].cross(&r);
            let oddi = odd[i] + wd[i].cross(&r) + w[i].cross(&w[i].cross(&r));
            e.push(ei);
            o.push(o[i] + r);
            w.push(wi);
            wd.push(wdi);
            od.push(odi);
            odd.push(oddi);
            axis.push(z);
        }
        // Backward: net force/moment about each joint origin.
        let mut tau = vec![0.0; n];
        let mut force = Vector3::zeros();
        let mut moment = Vector3::zeros(); // about o_{i}
        for i in (1..=n).rev() {
            let inertia = &robot.inertias()[i];
            let c = e[i] * inertia.com; // COM offset, world
            let ic = e[i] * inertia.inertia_about_com() * e[i].transpose();
            let acc_c = odd[i] + wd[i].cross(&c) + w[i].cross(&w[i].cross(&c));
            let f_i = inertia.mass * acc_c + force;
            // moment about o_i: child's moment moved from o_{i+1}, plus this body's
            let child_offset = if i < n {
                o[i + 1] - o[i]
            } else {
                Vector3::zeros()
            };
            moment = ic * wd[i]
                + w[i].cross(&(ic * w[i]))
                + c.cross(&(inertia.mass * acc_c))
                + moment
                + child_offset.cross(&force);
            force = f_i;
            tau[i - 1] = axis[i].dot(&moment);
        }
        let tau = DVector::from_column_slice(&tau);
        assert!(
            rel_err_v(&tau_op, &tau) < 1e-10,
            "seed {seed}: {tau_op} vs {tau}"
        );
    }
}

/// `V_{n+1} = Φ_{n+1,B} V_B + J q̇` (model §2) against the velocity recursion (A.4).
#[test]
fn ee_twist_from_jacobian_matches_velocity_recursion() {
    for seed in 0..10 {
        let robot = random_chain(1 + seed as usize % 9, seed);
        let (q, v, qd) = random_state(&robot, seed);
        let mut data = Data::new(&robot);
        algorithms::ee_jacobian(&robot, &mut data, &q, 0).unwrap();
        let twist = data.ee_base * nalgebra::Vector6::from_column_slice(&v)
            + nalgebra::Vector6::from_column_slice(
                (&data.jacobian * DVector::from_column_slice(&qd)).as_slice(),
            );
        algorithms::velocities(&robot, &mut data, &RigidState::new(&q, &v, &qd)).unwrap();
        // data.v is in joint frames: Q_nᵀ takes it back to the link frame of the public model
        let (body, turn) = (data.v[robot.dof()], robot.joint_frame_rotation(robot.dof()));
        let link = Motion::new(turn.tr_mul(&body.angular), turn.tr_mul(&body.linear));
        let ee = robot.ee_transform().apply_motion(&link);
        assert!((twist - ee.to_vector()).norm() < 1e-12 * (1.0 + twist.norm()));
    }
}

#[test]
fn workspace_for_another_robot_is_rejected() {
    let robot = random_chain(3, 1);
    let mut data = Data::new(&random_chain(4, 1));
    let err = algorithms::crba(&robot, &mut data, &[0.0; 3]).unwrap_err();
    assert!(err.to_string().contains("3 joints"), "{err}");
}

/// Regression (review): a model whose mass matrix is regular at q = 0 but singular elsewhere gave
/// q̈ ~ 1e31 without an error. Link 1 is massless about z; link 2 is a point mass at (0, 1, 0)
/// turning about x, so at q₂ = π/2 it sits on the z axis and joint 1 moves no inertia.
#[test]
fn configuration_dependent_singularity_is_an_error() {
    use orbitflex::spatial::{Inertia, Mat3, Transform, Vec3};
    let base = Inertia::from_com(50.0, Vec3::zeros(), Mat3::identity() * 5.0);
    let point = Inertia::from_com(1.0, Vec3::new(0.0, 1.0, 0.0), Mat3::zeros());
    let robot = orbitflex::RobotBuilder::new("singular", "base", base)
        .joint(
            "j1",
            Transform::identity(),
            Vec3::z(),
            "l1",
            Inertia::zero(),
        )
        .joint("j2", Transform::identity(), Vec3::x(), "l2", point)
        .build()
        .unwrap();
    let ok = robot.forward_dynamics(
        &RigidState::new(&[0.0, 0.0], &[0.0; 6], &[0.0; 2]),
        &[1.0, 1.0],
        &Loads::ZERO,
        Method::Recursive,
    );
    assert!(ok.is_ok());
    let q = [0.0, std::f64::consts::FRAC_PI_2];
    let err = robot
        .forward_dynamics(
            &RigidState::new(&q, &[0.0; 6], &[0.0; 2]),
            &[1.0, 1.0],
            &Loads::ZERO,
            Method::Recursive,
        )
        .unwrap_err()
        .to_string();
    assert!(err.contains("singular") && err.contains("'j1'"), "{err}");
}

#[test]
fn a_solid_cube_bus_has_m_s2_over_6_about_every_axis_through_its_centre() {
    use orbitflex::spatial::{Inertia, Mat3, Vec3};
    let com = Vec3::new(0.1, -0.2, 0.3);
    let cube = Inertia::solid_cube(500.0, orbitflex::model::DEFAULT_BUS_SIDE, com);
    assert_eq!(cube.mass, 500.0);
    assert_eq!(cube.com, com);
    let about = cube.inertia_about_com();
    assert!(
        (about - Mat3::identity() * 187.5).abs().max() < 1e-12,
        "{about}"
    );
}
