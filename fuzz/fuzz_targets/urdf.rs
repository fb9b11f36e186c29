//! The URDF loader on arbitrary bytes: decoded as a file would be, then loaded; any model that
//! loads is exercised by the dynamics. Nothing may panic, hang or exhaust memory.
#![no_main]

use libfuzzer_sys::fuzz_target;
use orbitflex::{Robot, UrdfOptions};

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = orbitflex::io::decode(bytes) else {
        return;
    };
    if let Ok(robot) = Robot::from_urdf_string(&text, &UrdfOptions::default()) {
        orbitflex_fuzz_exercise(&robot);
    }
});

/// Runs the dynamics once at a fixed state.
fn orbitflex_fuzz_exercise(robot: &Robot) {
    use orbitflex::{algorithms, Loads, RigidState};
    let n = robot.dof();
    if n > 200 {
        return;
    }
    let q: Vec<f64> = (0..n).map(|i| 0.3 * (i as f64).sin()).collect();
    let qd = vec![0.1; n];
    let state = RigidState::new(&q, &[0.01, -0.02, 0.03, 0.1, 0.0, -0.1], &qd);
    let mut data = algorithms::Data::new(robot);
    let _ = algorithms::aba(robot, &mut data, &state, &vec![1.0; n], &Loads::ZERO);
    let _ = algorithms::rnea(robot, &mut data, &state, &[0.0; 6], &vec![0.0; n], &[0.0; 6]);
    let _ = algorithms::crba(robot, &mut data, &q);
}
