//! The quintic reference slew (`control::Quintic`): exact values on a dyadic grid against the
//! closed form in integer arithmetic, its end conditions and symmetry, its rate against the
//! exact derivative, the tables it gives a motor PD, and its errors.

use orbitflex::control::{quintic_profile, Quintic};
use orbitflex::{Error, Schedule};

/// On `s = k/16` every step of the factored evaluation is exact (all intermediates are dyadic
/// with at most 30 significant bits), so `p` and `dp/ds` equal the closed form computed in
/// integers: `p = k³(10·16² − 15·16k + 6k²)/16⁵`, `dp/ds = 30(k(16 − k))²/16⁴`.
#[test]
fn profile_is_exact_on_a_dyadic_grid() {
    for k in 0..=16i64 {
        let s = k as f64 / 16.0;
        let (p, dp) = quintic_profile(s);
        let p_exact = (k * k * k * (10 * 256 - 15 * 16 * k + 6 * k * k)) as f64 / 16f64.powi(5);
        let dp_exact = (30 * (k * (16 - k)) * (k * (16 - k))) as f64 / 16f64.powi(4);
        assert_eq!(p, p_exact, "p({s})");
        assert_eq!(dp, dp_exact, "dp/ds({s})");
    }
}

#[test]
fn profile_rests_at_both_ends_and_is_held_outside() {
    assert_eq!(quintic_profile(0.0), (0.0, 0.0));
    assert_eq!(quintic_profile(1.0), (1.0, 0.0));
    assert_eq!(quintic_profile(-3.0), (0.0, 0.0));
    assert_eq!(quintic_profile(7.5), (1.0, 0.0));
    assert!(quintic_profile(f64::NAN).0.is_nan());
}

/// `p(s) + p(1 − s) = 1` and `p'(s) = p'(1 − s)`. Each evaluation of `p` has an absolute error
/// of at most about 7 roundings of terms bounded by 10 + 15 + 6 = 31, i.e. 31·7·ε/2 < 128ε;
/// two evaluations and the sum: 256ε.
#[test]
fn profile_is_point_symmetric_about_the_midpoint() {
    for i in 0..=1000 {
        let s = i as f64 / 1000.0;
        let (p, dp) = quintic_profile(s);
        let (q, dq) = quintic_profile(1.0 - s);
        assert!((p + q - 1.0).abs() <= 256.0 * f64::EPSILON, "s = {s}");
        assert!((dp - dq).abs() <= 256.0 * f64::EPSILON * 30.0, "s = {s}");
        assert!(
            (0.0..=1.0).contains(&p) && dp >= 0.0,
            "monotone rise, s = {s}"
        );
    }
}

/// The rate is the derivative of the angle: central differences with h = 1e-4 have truncation
/// error h²/6·|p'''| ≤ h²/6·60 = 1e-7 and rounding error 2·ε/(2h) ≈ 1.1e-12.
#[test]
fn rate_is_the_derivative_of_the_profile() {
    let h = 1e-4;
    for i in 1..100 {
        let s = i as f64 / 100.0;
        let fd = (quintic_profile(s + h).0 - quintic_profile(s - h).0) / (2.0 * h);
        assert!((quintic_profile(s).1 - fd).abs() <= 1.1e-7, "s = {s}");
    }
}

#[test]
fn schedules_tabulate_the_slew_for_a_motor_pd() {
    let (start, goal, duration, dt) = ([0.5, -1.0], [1.5, 2.0], 2.0, 0.25);
    let quintic = Quintic::new(&start, &goal, duration).unwrap();
    let (theta, theta_dot) = quintic.schedules(dt, 12).unwrap();
    assert_eq!((theta.rows(), theta_dot.rows()), (Some(12), Some(12)));
    let mut row = [0.0; 2];
    let mut rate = [0.0; 2];
    for k in 0..12 {
        theta.write(k, &mut row);
        theta_dot.write(k, &mut rate);
        let t = k as f64 * dt;
        let (p, dp) = quintic_profile(t / duration);
        for i in 0..2 {
            let delta = goal[i] - start[i];
            assert_eq!(row[i], start[i] + p * delta);
            assert_eq!(rate[i], dp / duration * delta);
        }
    }
    // the midpoint (t = 1 s, s = 1/2): halfway, at the peak rate 15/8 · delta / T
    theta.write(4, &mut row);
    theta_dot.write(4, &mut rate);
    assert_eq!(row, [1.0, 0.5]);
    assert_eq!(rate, [15.0 / 16.0, 45.0 / 16.0]);
    // held at the goal after the slew
    theta.write(11, &mut row);
    theta_dot.write(11, &mut rate);
    assert_eq!((row, rate), (goal, [0.0; 2]));
    let (empty, _) = quintic.schedules(dt, 0).unwrap();
    assert_eq!(
        empty,
        Schedule::Table {
            values: vec![],
            width: 2
        }
    );
}

/// A slew of no joints (an arm whose joints are all fixed) tabulates rows of width 0: every
/// step is there, with nothing in it, and nothing panics.
#[test]
fn a_slew_of_no_joints_has_empty_rows() {
    let quintic = Quintic::new(&[], &[], 1.0).unwrap();
    assert_eq!(quintic.width(), 0);
    let (theta, theta_dot) = quintic.schedules(0.1, 5).unwrap();
    let empty = Schedule::Table {
        values: vec![],
        width: 0,
    };
    assert_eq!((&theta, &theta_dot), (&empty, &empty));
    let (mut row, mut rate) = ([0.0; 0], [0.0; 0]);
    quintic.write(0.5, &mut row, &mut rate);
}

#[test]
fn bad_slews_are_refused_with_what_and_why() {
    let message = |e: Error| e.to_string();
    let e = Quintic::new(&[0.0, 0.0], &[1.0], 1.0).unwrap_err();
    assert_eq!(message(e), "goal: expected length 2, given length 1");
    for duration in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let e = Quintic::new(&[0.0], &[1.0], duration).unwrap_err();
        assert!(message(e).starts_with("duration: expected a finite duration > 0 s"));
    }
    assert!(Quintic::new(&[f64::NAN], &[1.0], 1.0).is_err());
    assert!(Quintic::new(&[0.0], &[f64::INFINITY], 1.0).is_err());
    let quintic = Quintic::new(&[0.0], &[1.0], 1.0).unwrap();
    for dt in [0.0, -1e-3, f64::NAN] {
        let e = quintic.schedules(dt, 3).unwrap_err();
        assert!(message(e).starts_with("dt: expected a finite step > 0 s"));
    }
    let wide = Quintic::new(&[0.0; 4], &[1.0; 4], 1.0).unwrap();
    match wide.schedules(1e-3, usize::MAX / 2) {
        Err(Error::OutOfMemory { what, .. }) => assert_eq!(what, "reference"),
        other => panic!("{other:?}"),
    }
}
