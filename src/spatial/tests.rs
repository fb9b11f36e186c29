//! Each closed-form spatial operation against its dense 6×6 form.

use super::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

fn vec3(rng: &mut ChaCha8Rng) -> Vec3 {
    Vec3::new(
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
        rng.gen_range(-1.0..1.0),
    )
}

fn transform(rng: &mut ChaCha8Rng) -> Transform {
    let axis = vec3(rng).normalize();
    Transform::new(
        rotation_about_axis(&axis, rng.gen_range(-3.0..3.0)),
        vec3(rng),
    )
}

fn inertia(rng: &mut ChaCha8Rng) -> Inertia {
    let a = nalgebra::Matrix3::from_fn(|_, _| rng.gen_range(-1.0..1.0));
    Inertia::from_com(
        rng.gen_range(0.1..5.0),
        vec3(rng),
        a * a.transpose() + Mat3::identity() * 0.1,
    )
}

fn close6(a: &Vec6, b: &Vec6) {
    assert!((a - b).norm() <= 1e-12 * (1.0 + b.norm()), "{a} vs {b}");
}

fn close66(a: &Mat6, b: &Mat6) {
    assert!((a - b).norm() <= 1e-12 * (1.0 + b.norm()), "{a} vs {b}");
}

#[test]
fn compact_operations_equal_their_matrices() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for _ in 0..50 {
        let phi = transform(&mut rng);
        let psi = transform(&mut rng);
        let m = Motion::new(vec3(&mut rng), vec3(&mut rng));
        let f = Force::new(vec3(&mut rng), vec3(&mut rng));
        let inertia = inertia(&mut rng);
        let x = phi.matrix();

        close6(&phi.apply_motion(&m).to_vector(), &(x * m.to_vector()));
        close6(
            &phi.apply_force_transpose(&f).to_vector(),
            &(x.transpose() * f.to_vector()),
        );
        let xi = x.try_inverse().unwrap();
        close6(
            &phi.apply_motion_inverse(&m).to_vector(),
            &(xi * m.to_vector()),
        );
        close6(
            &phi.apply_force(&f).to_vector(),
            &(xi.transpose() * f.to_vector()),
        );
        close66(&phi.compose(&psi).matrix(), &(x * psi.matrix()));
        close66(&phi.inverse().matrix(), &xi);

        close6(
            &m.cross_motion(&Motion::from_vector(&f.to_vector()))
                .to_vector(),
            &(m.cross_motion_matrix() * f.to_vector()),
        );
        close6(
            &m.cross_force(&f).to_vector(),
            &(m.cross_force_matrix() * f.to_vector()),
        );

        close6(
            &inertia.apply(&m).to_vector(),
            &(inertia.matrix() * m.to_vector()),
        );
        let sym = inertia.matrix();
        close66(&congruence(&phi, &sym), &(x.transpose() * sym * x));
        close66(
            &inertia.transformed_to_parent(&phi).matrix(),
            &(x.transpose() * sym * x),
        );
        let other = self::inertia(&mut rng);
        close66(&inertia.add(&other).matrix(), &(sym + other.matrix()));
    }
}

#[test]
fn bias_force_is_velocity_cross_momentum_for_pure_rotation() {
    // (A.10) with v = 0 equals V ×* (M V), the Featherstone bias, since then ω × v terms vanish.
    let mut rng = ChaCha8Rng::seed_from_u64(8);
    for _ in 0..20 {
        let inertia = inertia(&mut rng);
        let w = vec3(&mut rng);
        let v = Motion::new(w, Vec3::zeros());
        close6(
            &bias_force(&inertia, &w).to_vector(),
            &v.cross_force(&inertia.apply(&v)).to_vector(),
        );
    }
}

#[test]
fn coriolis_term_is_derivative_of_propagated_velocity() {
    // a_{i+1} (A.7) is the part of d/dt V_{i+1} not explained by Φ α_i + H q̈: check by finite
    // differences of a two-body chain turning about a fixed axis at constant rates.
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let h = vec3(&mut rng).normalize();
    let p = vec3(&mut rng);
    let w0 = vec3(&mut rng);
    let qd = 0.7;
    // body i turns at constant ω_i (inertial derivative of ω_i and of its origin velocity are 0
    // when the origin is fixed); child velocity in the inertial frame, differentiated numerically.
    let child_inertial = |t: f64| {
        let ri = rotation_about_axis(&w0.normalize(), w0.norm() * t); // frame i -> inertial
        let rj = rotation_about_axis(&h, qd * t); // joint rotation, child -> parent components
        let r_child = ri * rj; // child -> inertial
        let w = ri * w0 + r_child * h * qd;
        let v = (ri * w0).cross(&(ri * p));
        (r_child, w, v)
    };
    let dt = 1e-6;
    let (r, _, _) = child_inertial(0.0);
    let (_, wp, vp) = child_inertial(dt);
    let (_, wm, vm) = child_inertial(-dt);
    let numeric = Motion::new(
        r.transpose() * (wp - wm) / (2.0 * dt),
        r.transpose() * (vp - vm) / (2.0 * dt),
    );
    let phi = Transform::new(Mat3::identity(), p);
    let child =
        phi.apply_motion(&Motion::new(w0, Vec3::zeros())) + Motion::new(h * qd, Vec3::zeros());
    let a = coriolis_acceleration(&phi, &w0, &child.angular);
    // tolerance of the central difference
    assert!((numeric.to_vector() - a.to_vector()).norm() < 1e-8);
}

/// A random symmetric positive-definite 6×6 in block form (a general articulated inertia).
fn articulated(rng: &mut ChaCha8Rng) -> ArticulatedInertia {
    let a = Mat6::from_fn(|_, _| rng.gen_range(-1.0..1.0));
    ArticulatedInertia::from_matrix(&(a * a.transpose() + Mat6::identity() * 0.1))
}

#[test]
fn articulated_inertia_operations_equal_their_matrices() {
    let mut rng = ChaCha8Rng::seed_from_u64(10);
    for _ in 0..50 {
        let phi = transform(&mut rng);
        let x = phi.matrix();
        let ia = articulated(&mut rng);
        let dense = ia.matrix();
        assert_eq!(dense, dense.transpose());
        let m = Motion::new(vec3(&mut rng), vec3(&mut rng));
        let f = Force::new(vec3(&mut rng), vec3(&mut rng));
        let h = vec3(&mut rng).normalize();

        close6(&ia.apply(&m).to_vector(), &(dense * m.to_vector()));
        close6(
            &ia.apply_angular(&h).to_vector(),
            &(dense * Motion::new(h, Vec3::zeros()).to_vector()),
        );
        close66(
            &ia.minus_outer(&f, 0.7).matrix(),
            &(dense - f.to_vector() * f.to_vector().transpose() * 0.7),
        );
        close66(
            &ia.transformed_to_parent(&phi).matrix(),
            &(x.transpose() * dense * x),
        );
        close66(
            &ia.transformed_to_parent(&phi).matrix(),
            &congruence(&phi, &dense),
        );
        let other = articulated(&mut rng);
        close66(&(ia + other).matrix(), &(dense + other.matrix()));

        let solved = ia.solve(&f).expect("positive definite");
        close6(&(dense * solved.to_vector()), &f.to_vector());
        let inverse = ia.inverse().expect("positive definite");
        close66(&(dense * inverse), &Mat6::identity());

        let rigid = inertia(&mut rng);
        close66(&ArticulatedInertia::from(&rigid).matrix(), &rigid.matrix());

        let r = phi.rotation;
        let s = ia.angular;
        let rotated = s.rotated_by_transpose(&r).matrix();
        assert!(
            (rotated - r.transpose() * s.matrix() * r).norm() <= 1e-12 * (1.0 + rotated.norm())
        );
        assert!((s.mul_vec(&h) - s.matrix() * h).norm() <= 1e-12);
    }
}

#[test]
fn articulated_solve_rejects_what_is_not_positive_definite() {
    let mut rng = ChaCha8Rng::seed_from_u64(12);
    let f = Force::new(vec3(&mut rng), vec3(&mut rng));
    // indefinite linear block, indefinite Schur complement, and NaN
    let mut linear_bad = articulated(&mut rng);
    linear_bad.linear.yy = -1.0;
    let mut angular_bad = articulated(&mut rng);
    angular_bad.angular.zz = -100.0;
    let mut nan = articulated(&mut rng);
    nan.coupling[(1, 2)] = f64::NAN;
    for ia in [linear_bad, angular_bad, nan, ArticulatedInertia::zero()] {
        assert!(ia.solve(&f).is_none(), "{ia:?}");
        assert!(ia.inverse().is_none(), "{ia:?}");
    }
}

#[test]
fn rotation_about_axis_is_rodrigues() {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    for _ in 0..50 {
        let h = vec3(&mut rng).normalize();
        let angle: f64 = rng.gen_range(-4.0..4.0);
        let k = skew(&h);
        let expected = Mat3::identity() + k * angle.sin() + k * k * (1.0 - angle.cos());
        let r = rotation_about_axis(&h, angle);
        assert!((r - expected).norm() < 1e-14);
        assert!((r * r.transpose() - Mat3::identity()).norm() < 1e-14);
        assert!((r * h - h).norm() < 1e-14);
    }
}

/// The tilted congruence (two plane turns and a shift) equals the general one on a tilted
/// transform, and each plane turn equals its dense `R X Rᵀ`.
#[test]
fn tilted_congruence_equals_the_general_one() {
    let mut rng = crate::testing::Rng::new(17);
    for _ in 0..20 {
        let m = rng.inertia().matrix();
        let u = Force::from_slice(&[0.3, -0.2, 0.5, 0.1, 0.4, -0.6]);
        let ia = ArticulatedInertia::from_matrix(&m).minus_outer(&u, 0.7);
        let (theta, alpha) = (rng.range(-3.0, 3.0), rng.range(-3.0, 3.0));
        let r = rotation_about_axis(&Vec3::z(), -theta) * rotation_about_axis(&Vec3::x(), -alpha);
        let phi = Transform::new(
            r,
            Vec3::new(
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
                rng.range(-1.0, 1.0),
            ),
        );
        let fast = ia.tilted_to_parent(&phi).matrix();
        let dense = congruence(&phi, &ia.matrix());
        assert!(
            (fast - dense).amax() < 1e-13 * (1.0 + dense.amax()),
            "{fast} vs {dense}"
        );
        let (c, s) = (theta.cos(), theta.sin());
        let rz = rotation_about_axis(&Vec3::z(), theta);
        let rx = rotation_about_axis(&Vec3::x(), theta);
        let sym = ia.angular;
        assert!(
            (sym.turned_about_z(c, s).matrix() - rz * sym.matrix() * rz.transpose()).amax() < 1e-14
        );
        assert!(
            (sym.turned_about_x(c, s).matrix() - rx * sym.matrix() * rx.transpose()).amax() < 1e-14
        );
    }
}

/// `euler_zyx` inverts `R = R_z(yaw) R_y(pitch) R_x(roll)`: the quaternion of that product (built
/// from three axis rotations, not from the formula under test) gives the angles back.
#[test]
fn euler_zyx_inverts_the_z_y_x_product() {
    let axis = |k: usize, angle: f64| {
        let mut q = [0.0, 0.0, 0.0, (0.5 * angle).cos()];
        q[k] = (0.5 * angle).sin();
        q
    };
    for &(yaw, pitch, roll) in &[
        (0.3, -0.2, 1.1),
        (-2.9, 1.2, -3.0),
        (1.0, 0.0, 0.0),
        (0.0, 0.0, -0.5),
    ] {
        let q = quaternion_product(
            &quaternion_product(&axis(2, yaw), &axis(1, pitch)),
            &axis(0, roll),
        );
        let [y, p, r] = euler_zyx(&q);
        for (got, want) in [(y, yaw), (p, pitch), (r, roll)] {
            assert!((got - want).abs() < 1e-14, "{got} vs {want}");
        }
        // and the matrix agrees with the product of the three
        let expected = rotation_about_axis(&Vec3::z(), yaw)
            * rotation_about_axis(&Vec3::y(), pitch)
            * rotation_about_axis(&Vec3::x(), roll);
        assert!((quaternion_to_rotation(&q) - expected).abs().max() < 1e-14);
    }
}

/// `rotation_angle` is the angle of the relative rotation, symmetric, the short way round, and
/// keeps its digits at tiny angles (where `2 acos(a · b)` returns 0 below about 1e-8 rad).
#[test]
fn rotation_angle_is_the_relative_angle_even_when_tiny() {
    let about = |axis: Vec3, angle: f64| {
        let s = (0.5 * angle).sin();
        let a = axis.normalize();
        [a.x * s, a.y * s, a.z * s, (0.5 * angle).cos()]
    };
    let a = about(Vec3::new(1.0, 2.0, -0.5), 0.7);
    for &angle in &[1e-12, 1e-9, 1e-4, 0.5, 3.0] {
        let turn = about(Vec3::new(-0.3, 0.1, 0.9), angle);
        let b = quaternion_product(&a, &turn);
        for got in [rotation_angle(&a, &b), rotation_angle(&b, &a)] {
            assert!(
                (got - angle).abs() <= 1e-15 + 4.0 * f64::EPSILON * angle,
                "{got} vs {angle}"
            );
        }
        // −b is the same attitude
        let minus_b = [-b[0], -b[1], -b[2], -b[3]];
        assert!((rotation_angle(&a, &minus_b) - angle).abs() <= 1e-15 + 4.0 * f64::EPSILON * angle);
    }
}
