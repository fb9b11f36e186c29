//! The joint-parameter TOML reader on arbitrary text, for a model with three joints.
#![no_main]

use libfuzzer_sys::fuzz_target;
use orbitflex::FlexibleJoints;

fuzz_target!(|bytes: &[u8]| {
    let Ok(text) = std::str::from_utf8(bytes) else {
        return;
    };
    if let Ok(joints) = FlexibleJoints::from_toml_str(text, &["shoulder", "elbow", "wrist"], "fuzz") {
        // whatever is accepted is physical
        assert_eq!(joints.len(), 3);
        for i in 0..3 {
            assert!(joints.stiffness[i] > 0.0 && joints.stiffness[i].is_finite());
            assert!(joints.motor_inertia[i] > 0.0 && joints.motor_inertia[i].is_finite());
            assert!(joints.damping[i] >= 0.0 && joints.damping[i].is_finite());
            assert!(joints.motor_damping[i] >= 0.0 && joints.motor_damping[i].is_finite());
        }
    }
});
