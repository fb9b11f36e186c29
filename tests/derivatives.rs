//! The analytical derivatives of the dynamics against central finite differences, on random
//! chains with awkward features and on the built-in arm, at random states with every input
//! non-zero.

use nalgebra::DMatrix;
use orbitflex::algorithms::{self, Data};
use orbitflex::testing::{
    random_chain, random_state, random_tree, Rng, TREE_ONE_TRUNK, TREE_THREE_ARMS,
};
use orbitflex::{Loads, RigidState, Robot};

/// Largest entrywise difference relative to the largest entry of `want` (at least 1).
fn rel(got: &DMatrix<f64>, want: &DMatrix<f64>) -> f64 {
    (got - want).amax() / want.amax().max(1.0)
}

struct Case {
    robot: Robot,
    q: Vec<f64>,
    v: Vec<f64>,
    qd: Vec<f64>,
    tau: Vec<f64>,
    fb: Vec<f64>,
    f: Vec<f64>,
    acc: Vec<f64>,
}

fn case(robot: Robot, seed: u64) -> Case {
    let (q, v, qd) = random_state(&robot, seed);
    let (n, k) = (robot.dof(), robot.end_effectors().len());
    let mut rng = Rng::new(seed + 17);
    Case {
        robot,
        q,
        v,
        qd,
        tau: rng.vector(n, -5.0, 5.0),
        fb: rng.vector(6, -5.0, 5.0),
        f: rng.vector(6 * k, -5.0, 5.0),
        acc: rng.vector(6 + n, -2.0, 2.0),
    }
}

/// Central differences of `eval` (a function of the perturbed input vector) along each
/// coordinate of `x`, step `h` scaled by the coordinate.
fn central(x: &[f64], h: f64, mut eval: impl FnMut(&[f64]) -> Vec<f64>) -> DMatrix<f64> {
    let rows = eval(x).len();
    let mut out = DMatrix::zeros(rows, x.len());
    let mut xp = x.to_vec();
    for k in 0..x.len() {
        let step = h * x[k].abs().max(1.0);
        xp[k] = x[k] + step;
        let plus = eval(&xp);
        xp[k] = x[k] - step;
        let minus = eval(&xp);
        xp[k] = x[k];
        for r in 0..rows {
            out[(r, k)] = (plus[r] - minus[r]) / (2.0 * step);
        }
    }
    out
}

fn id(c: &Case, q: &[f64], nu: &[f64], acc: &[f64], f: &[f64]) -> Vec<f64> {
    let mut data = Data::new(&c.robot);
    let state = RigidState::new(q, &nu[..6], &nu[6..]);
    algorithms::rnea(&c.robot, &mut data, &state, &acc[..6], &acc[6..], f)
        .unwrap()
        .as_slice()
        .to_vec()
}

fn fd(c: &Case, q: &[f64], nu: &[f64], tau: &[f64], fb: &[f64], f: &[f64]) -> Vec<f64> {
    let mut data = Data::new(&c.robot);
    let state = RigidState::new(q, &nu[..6], &nu[6..]);
    let loads = Loads::from_slices(Some(fb), Some(f)).unwrap();
    algorithms::aba(&c.robot, &mut data, &state, tau, &loads)
        .unwrap()
        .as_slice()
        .to_vec()
}

fn check(c: &Case, label: &str) {
    let nu: Vec<f64> = c.v.iter().chain(&c.qd).copied().collect();
    let h = 1e-6;
    let mut data = Data::new(&c.robot);
    let state = RigidState::new(&c.q, &c.v, &c.qd);

    let d =
        algorithms::rnea_derivatives(&c.robot, &mut data, &state, &c.acc[..6], &c.acc[6..], &c.f)
            .unwrap()
            .clone();
    let tol = 1e-6;
    let dq = central(&c.q, h, |q| id(c, q, &nu, &c.acc, &c.f));
    assert!(
        rel(&d.id_q, &dq) < tol,
        "{label}: ∂ID/∂q {}",
        rel(&d.id_q, &dq)
    );
    let dv = central(&nu, h, |nu| id(c, &c.q, nu, &c.acc, &c.f));
    assert!(
        rel(&d.id_v, &dv) < tol,
        "{label}: ∂ID/∂ν {}",
        rel(&d.id_v, &dv)
    );
    let df = central(&c.f, h, |f| id(c, &c.q, &nu, &c.acc, f));
    assert!(rel(&d.id_ee_wrench, &df) < tol, "{label}: ∂ID/∂f");

    let loads = Loads::from_slices(Some(&c.fb), Some(&c.f)).unwrap();
    let d = algorithms::aba_derivatives(&c.robot, &mut data, &state, &c.tau, &loads)
        .unwrap()
        .clone();
    let dq = central(&c.q, h, |q| fd(c, q, &nu, &c.tau, &c.fb, &c.f));
    assert!(
        rel(&d.fd_q, &dq) < tol,
        "{label}: ∂FD/∂q {}",
        rel(&d.fd_q, &dq)
    );
    let dv = central(&nu, h, |nu| fd(c, &c.q, nu, &c.tau, &c.fb, &c.f));
    assert!(
        rel(&d.fd_v, &dv) < tol,
        "{label}: ∂FD/∂ν {}",
        rel(&d.fd_v, &dv)
    );
    let dt = central(&c.tau, h, |tau| fd(c, &c.q, &nu, tau, &c.fb, &c.f));
    assert!(rel(&d.fd_tau, &dt) < tol, "{label}: ∂FD/∂τ");
    let db = central(&c.fb, h, |fb| fd(c, &c.q, &nu, &c.tau, fb, &c.f));
    assert!(rel(&d.fd_base_wrench, &db) < tol, "{label}: ∂FD/∂f_B");
    let de = central(&c.f, h, |f| fd(c, &c.q, &nu, &c.tau, &c.fb, f));
    assert!(rel(&d.fd_ee_wrench, &de) < tol, "{label}: ∂FD/∂f");
}

#[test]
fn derivatives_equal_central_differences_on_random_chains() {
    for n in 1..=9 {
        for seed in 0..3 {
            check(
                &case(random_chain(n, seed), seed),
                &format!("n={n} seed={seed}"),
            );
        }
    }
}

/// On a branched tree the subtree and ancestor bookkeeping matters: joints on other branches
/// leave each other's torques unchanged (zeros in `∂ID/∂q`, `∂ID/∂q̇`), and the EE wrench
/// reaches only the joints on its path.
#[test]
fn derivatives_equal_central_differences_on_branched_trees() {
    for seed in 0..3 {
        let c = case(random_tree(TREE_ONE_TRUNK, seed), seed);
        check(&c, &format!("one trunk, seed={seed}"));
        let mut data = Data::new(&c.robot);
        let state = RigidState::new(&c.q, &c.v, &c.qd);
        let d = algorithms::rnea_derivatives(
            &c.robot,
            &mut data,
            &state,
            &c.acc[..6],
            &c.acc[6..],
            &c.f,
        )
        .unwrap();
        // body 5 (under 4, under 2) and body 3 (under 2) are on different branches
        assert_eq!(d.id_q[(6 + 4, 2)], 0.0);
        assert_eq!(d.id_q[(6 + 2, 4)], 0.0);
        assert!(d.id_q[(6 + 1, 4)] != 0.0, "joint 2 carries joint 5");
        // the EE (on body 5) reaches joints 5, 4, 2, 1 only
        for off_path in [2, 5, 6] {
            assert!(d.id_ee_wrench.row(6 + off_path).iter().all(|&x| x == 0.0));
        }
        let c = case(random_tree(TREE_THREE_ARMS, seed), seed);
        check(&c, &format!("three arms, seed={seed}"));
    }
}

/// With an end-effector on every leaf (five on the three-armed tree, three on the trunk), every
/// wrench at once: `∂/∂f` has one 6-column block per end-effector, and each block reaches only the
/// joints on its end-effector's path.
#[test]
fn derivatives_with_several_end_effectors_equal_central_differences() {
    for seed in 0..3 {
        for (shape, label) in [
            (TREE_ONE_TRUNK.0, "one trunk"),
            (TREE_THREE_ARMS.0, "three arms"),
        ] {
            let robot = orbitflex::testing::random_tree_all_leaves(shape, seed);
            let c = case(robot, seed);
            assert_eq!(c.f.len(), 6 * c.robot.end_effectors().len());
            check(&c, &format!("{label}, every leaf, seed={seed}"));
            let mut data = Data::new(&c.robot);
            let state = RigidState::new(&c.q, &c.v, &c.qd);
            let d = algorithms::rnea_derivatives(
                &c.robot,
                &mut data,
                &state,
                &c.acc[..6],
                &c.acc[6..],
                &c.f,
            )
            .unwrap();
            for (e, ee) in c.robot.end_effectors().iter().enumerate() {
                let path: Vec<usize> = c.robot.path_to_base(ee.body).collect();
                for body in 1..=c.robot.dof() {
                    let row = d.id_ee_wrench.view((5 + body, 6 * e), (1, 6));
                    assert_eq!(
                        row.iter().any(|&x| x != 0.0),
                        path.contains(&body),
                        "{label}: EE {e} and joint {body}"
                    );
                }
            }
        }
    }
}

/// Above 28 joints `∂FD/∂x = −𝓜⁻¹ ∂ID/∂x` runs the factorisation on the columns instead of the
/// dense product.
#[test]
fn derivatives_equal_central_differences_on_long_chains() {
    for (n, seed) in [(25, 1), (40, 2)] {
        check(&case(random_chain(n, seed), seed), &format!("n={n}"));
    }
}

#[test]
fn derivatives_equal_central_differences_on_the_space_arm() {
    check(&case(Robot::space_arm(), 5), "space arm");
}

/// `∂FD/∂τ` is the joint block of `𝓜⁻¹` and `∂FD/∂f_B` its base block: together `𝓜⁻¹`.
#[test]
fn forward_derivatives_in_the_inputs_are_the_inverse_mass_matrix() {
    let c = case(random_chain(6, 9), 9);
    let mut data = Data::new(&c.robot);
    let m = algorithms::crba(&c.robot, &mut data, &c.q).unwrap().clone();
    let state = RigidState::new(&c.q, &c.v, &c.qd);
    let d = algorithms::aba_derivatives(&c.robot, &mut data, &state, &c.tau, &Loads::ZERO).unwrap();
    let mut inverse = DMatrix::zeros(12, 12);
    inverse.columns_mut(0, 6).copy_from(&d.fd_base_wrench);
    inverse.columns_mut(6, 6).copy_from(&d.fd_tau);
    let identity = &m * inverse;
    assert!((identity - DMatrix::identity(12, 12)).amax() < 1e-10);
}
