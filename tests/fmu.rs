//! The FMU's Rust half: the variable table, the model description, the resources round trip
//! and one instance's state machine (the C exports are tested through FMPy in Python).

use orbitflex::fmu::{Causality, FmiVersion, FmuInstance, FmuModel, Mode, Slot, VariableTable};
use orbitflex::{
    FlexibleArm, FlexibleJoints, Robot, Simulator, StateSpec, UrdfOptions, SPACE_ARM_URDF,
};
use std::collections::HashSet;

fn model() -> FmuModel {
    FmuModel::new(
        SPACE_ARM_URDF,
        &UrdfOptions::default(),
        &FlexibleJoints::space_arm(),
        1e-3,
        "space_arm",
    )
    .unwrap()
}

fn vr(m: &FmuModel, name: &str) -> u32 {
    m.table
        .value_reference(name)
        .unwrap_or_else(|| panic!("no variable {name}"))
}

#[test]
fn the_table_names_every_variable_once() {
    let m = model();
    let t = &m.table;
    let names: HashSet<_> = t.variables.iter().map(|v| v.name.as_str()).collect();
    assert_eq!(names.len(), t.variables.len(), "duplicate names");
    assert_eq!(t.variables[0].name, "time");
    assert_eq!(t.variables[0].causality, Causality::Independent);
    let n = 7;
    let count = |c: Causality| t.variables.iter().filter(|v| v.causality == c).count();
    assert_eq!(count(Causality::Parameter), 5 * n);
    assert_eq!(count(Causality::Input), n + 6);
    // 6 per joint, base 3 + 4 + 3 + 3, one EE 3 + 4, momentum 6, energy 1
    assert_eq!(count(Causality::Output), 6 * n + 13 + 7 + 6 + 1);
    for name in [
        "motor_torque.shoulder_yaw",
        "base_force.x",
        "base_moment.z",
        "q.wrist_roll",
        "theta.elbow_pitch",
        "deflection.shoulder_yaw",
        "spring_torque.shoulder_yaw",
        "base_position.z",
        "base_quaternion.w",
        "base_angular_velocity.y",
        "ee_position.ee.x",
        "momentum.angular.x",
        "momentum.linear.z",
        "stiffness.shoulder_yaw",
        "q0.elbow_pitch",
    ] {
        vr(&m, name);
    }
    assert!(t.get(t.variables.len() as u32).is_err());
}

#[test]
fn the_description_is_well_formed_and_declares_every_variable() {
    let m = model();
    for version in [FmiVersion::V3, FmiVersion::V2] {
        let xml = orbitflex::fmu::model_description(&m, version);
        let mut reader = quick_xml::Reader::from_str(&xml);
        let (mut variables, mut outputs) = (0, 0);
        loop {
            match reader.read_event().expect("well-formed XML") {
                quick_xml::events::Event::Eof => break,
                quick_xml::events::Event::Start(e) | quick_xml::events::Event::Empty(e) => {
                    match e.name().as_ref() {
                        b"Float64" | b"ScalarVariable" => variables += 1,
                        b"Output" => outputs += 1,
                        _ => {}
                    }
                }
                _ => {}
            }
        }
        let declared = m.table.variables.len() - usize::from(version == FmiVersion::V2);
        assert_eq!(variables, declared);
        if version == FmiVersion::V3 {
            let n_out = m
                .table
                .variables
                .iter()
                .filter(|v| v.causality == Causality::Output)
                .count();
            assert_eq!(outputs, n_out);
            assert!(xml.contains("instantiationToken=\"{"));
            assert!(xml.contains("fixedInternalStepSize=\"0.001\""));
            assert!(xml.contains("canGetAndSetFMUState=\"true\""));
        } else {
            assert!(xml.contains("guid=\"{"));
            assert!(xml.contains("canGetAndSetFMUstate=\"true\""));
            assert!(!xml.contains("index=\"0\""), "FMI 2.0 indices start at 1");
        }
        assert!(xml.contains("dependencies=\"\""));
        assert!(xml.contains(&m.token()));
    }
}

#[test]
fn resources_read_back_to_the_same_model() {
    let mut joints = FlexibleJoints::space_arm();
    joints.damping[2] = 0.123_456_789_012_345_68;
    let options = UrdfOptions {
        locked_joints: vec!["wrist_roll".into()],
        ..UrdfOptions::default()
    };
    let robot = Robot::from_urdf_string(SPACE_ARM_URDF, &options).unwrap();
    let n = robot.dof();
    let joints = FlexibleJoints::new(
        joints.stiffness[..n].to_vec(),
        joints.motor_inertia[..n].to_vec(),
        joints.damping[..n].to_vec(),
        joints.motor_damping[..n].to_vec(),
    )
    .unwrap();
    let m = FmuModel::new(SPACE_ARM_URDF, &options, &joints, 2e-3, "arm6").unwrap();
    let dir = std::env::temp_dir().join(format!("orbitflex_fmu_test_{}", std::process::id()));
    std::fs::create_dir_all(dir.join("resources")).unwrap();
    for (path, bytes) in m.files(FmiVersion::V3) {
        std::fs::write(dir.join(path), bytes).unwrap();
    }
    let back = FmuModel::from_resources(&dir.join("resources")).unwrap();
    assert_eq!(back.token(), m.token());
    assert_eq!(back.arm.joints(), &joints, "joint parameters bit for bit");
    assert_eq!(back.arm.dof(), 6);
    assert_eq!(back.table, m.table);
    // an edited resource changes the token (the runtime refuses the description's)
    let toml = dir.join("resources/joints.toml");
    let text = std::fs::read_to_string(&toml).unwrap();
    std::fs::write(&toml, text.replace("0.12345678901234568", "0.2")).unwrap();
    let edited = FmuModel::from_resources(&dir.join("resources")).unwrap();
    assert_ne!(edited.token(), m.token());
    std::fs::remove_file(&toml).unwrap();
    let missing = FmuModel::from_resources(&dir.join("resources")).unwrap_err();
    assert!(missing.to_string().contains("joints.toml"), "{missing}");
    std::fs::remove_dir_all(&dir).unwrap();

    let bad = FmuModel::new(
        SPACE_ARM_URDF,
        &UrdfOptions::default(),
        &FlexibleJoints::space_arm(),
        1e-3,
        "9lives",
    );
    assert!(bad.unwrap_err().to_string().contains("C identifier"));
}

fn started(m: &FmuModel) -> FmuInstance {
    let mut fmu = FmuInstance::new(m.clone());
    fmu.enter_initialization(0.0).unwrap();
    fmu.exit_initialization().unwrap();
    fmu
}

#[test]
fn steps_equal_the_simulator() {
    let m = model();
    let mut fmu = FmuInstance::new(m.clone());
    fmu.enter_initialization(0.0).unwrap();
    let q0: Vec<f64> = (0..7).map(|i| 0.1 * i as f64).collect();
    let names = m.arm.robot().joint_names();
    let q0_vrs: Vec<u32> = names.iter().map(|j| vr(&m, &format!("q0.{j}"))).collect();
    fmu.set(&q0_vrs, &q0).unwrap();
    let k_vr = vr(&m, "stiffness.elbow_pitch");
    fmu.set(&[k_vr], &[7000.0]).unwrap();
    fmu.exit_initialization().unwrap();

    let mut joints = FlexibleJoints::space_arm();
    joints.stiffness[3] = 7000.0;
    let arm = FlexibleArm::new(Robot::space_arm(), joints).unwrap();
    let x0 = arm
        .state(&StateSpec {
            q: Some(&q0),
            ..StateSpec::default()
        })
        .unwrap();
    let mut sim = Simulator::new(arm, &x0, 1e-3).unwrap();
    let u_vrs: Vec<u32> = names
        .iter()
        .map(|j| vr(&m, &format!("motor_torque.{j}")))
        .collect();
    let out_vrs: Vec<u32> = names.iter().map(|j| vr(&m, &format!("q.{j}"))).collect();
    let mut q = vec![0.0; 7];
    for k in 0..20 {
        let u: Vec<f64> = (0..7).map(|i| ((k * 7 + i) as f64).sin()).collect();
        fmu.set(&u_vrs, &u).unwrap();
        fmu.set(&[vr(&m, "base_force.y")], &[0.5]).unwrap();
        fmu.do_step(fmu.time(), 5e-3).unwrap();
        sim.set_motor_torque(&u).unwrap();
        sim.set_base_wrench(&[0.0, 0.0, 0.0, 0.0, 0.5, 0.0])
            .unwrap();
        sim.step(5).unwrap();
        fmu.get(&out_vrs, &mut q).unwrap();
        let layout = sim.arm().layout();
        let expected = &sim.state()[layout.q()];
        assert!(
            q.iter()
                .zip(expected)
                .all(|(a, b)| a.to_bits() == b.to_bits()),
            "step {k}"
        );
    }
    let mut t = [0.0];
    fmu.get(&[0], &mut t).unwrap();
    assert_eq!(t[0], 20.0 * 5e-3);
    let mut energy = [0.0];
    fmu.get(&[vr(&m, "energy")], &mut energy).unwrap();
    assert_eq!(energy[0], sim.outputs().energy);
}

#[test]
fn bad_calls_are_refused_with_a_message() {
    let m = model();
    let mut fmu = FmuInstance::new(m.clone());
    let err = fmu.do_step(0.0, 1e-3).unwrap_err();
    assert!(
        err.contains("cannot do a step in Instantiated mode"),
        "{err}"
    );
    let mut v = [0.0];
    let err = fmu.get(&[vr(&m, "q.elbow_pitch")], &mut v).unwrap_err();
    assert!(err.contains("before initialization"), "{err}");
    fmu.enter_initialization(0.0).unwrap();
    // outputs can be read in initialization mode
    fmu.get(&[vr(&m, "q.elbow_pitch")], &mut v).unwrap();
    let err = fmu
        .set(&[vr(&m, "stiffness.elbow_pitch")], &[-1.0])
        .unwrap_err();
    assert!(err.contains("expected > 0"), "{err}");
    let err = fmu
        .set(&[vr(&m, "damping.elbow_pitch")], &[-1.0])
        .unwrap_err();
    assert!(err.contains("expected >= 0"), "{err}");
    fmu.exit_initialization().unwrap();
    let u = vr(&m, "motor_torque.elbow_pitch");
    let err = fmu.set(&[u, 9999], &[1.0, 1.0]).unwrap_err();
    assert!(err.contains("unknown value reference 9999"), "{err}");
    let err = fmu.set(&[u], &[f64::NAN]).unwrap_err();
    assert!(err.contains("must be finite"), "{err}");
    let err = fmu.set(&[vr(&m, "q.elbow_pitch")], &[1.0]).unwrap_err();
    assert!(err.contains("is an output"), "{err}");
    let err = fmu.set(&[0], &[1.0]).unwrap_err();
    assert!(err.contains("independent"), "{err}");
    let err = fmu.set(&[vr(&m, "q0.elbow_pitch")], &[1.0]).unwrap_err();
    assert!(err.contains("fixed parameter"), "{err}");
    let err = fmu.set(&[u], &[1.0, 2.0]).unwrap_err();
    assert!(err.contains("2 values for 1 value references"), "{err}");
    // a refused batch sets nothing
    fmu.set(&[u, u + 1], &[3.0, f64::INFINITY]).unwrap_err();
    fmu.get(&[u], &mut v).unwrap();
    assert_eq!(v[0], 0.0);
    let err = fmu.do_step(0.0, 1.5e-3).unwrap_err();
    assert!(err.contains("not a whole multiple"), "{err}");
    let err = fmu.do_step(0.0, 0.0).unwrap_err();
    assert!(err.contains("not a whole multiple"), "{err}");
    let err = fmu.do_step(0.0, f64::NAN).unwrap_err();
    assert!(err.contains("not a whole multiple"), "{err}");
    let err = fmu.do_step(0.5, 1e-3).unwrap_err();
    assert!(err.contains("is not the FMU's time"), "{err}");
    // float noise in k h is not a fraction of a step
    for k in 0..10 {
        fmu.do_step(k as f64 * 0.1 * 0.03, 0.1 * 0.03).unwrap();
    }
    assert_eq!(fmu.time(), 30.0 * 1e-3);
    fmu.terminate().unwrap();
    assert_eq!(fmu.mode(), Mode::Terminated);
    assert!(fmu.do_step(fmu.time(), 1e-3).is_err());
    fmu.reset();
    assert_eq!(fmu.mode(), Mode::Instantiated);
    assert_eq!(fmu.time(), 0.0);
}

#[test]
fn a_diverging_step_is_refused_and_undone() {
    let m = model();
    let mut fmu = started(&m);
    let all: Vec<u32> = (0..m.table.variables.len() as u32)
        .filter(|&v| matches!(m.table.variables[v as usize].slot, Slot::Output(..)))
        .collect();
    let mut before = vec![0.0; all.len()];
    fmu.set(&[vr(&m, "motor_torque.wrist_roll")], &[1e300])
        .unwrap();
    fmu.get(&all, &mut before).unwrap();
    let err = fmu.do_step(0.0, 1e-3).unwrap_err();
    assert!(err.contains("diverged"), "{err}");
    let mut after = vec![0.0; all.len()];
    fmu.get(&all, &mut after).unwrap();
    assert_eq!(before, after);
    assert_eq!(fmu.time(), 0.0);
}

#[test]
fn saved_states_restore_bit_for_bit() {
    let m = model();
    let mut fmu = FmuInstance::new(m.clone());
    assert!(fmu.save().is_err(), "nothing to save before initialization");
    fmu.setup(2.0).unwrap();
    fmu.enter_initialization(2.0).unwrap();
    fmu.exit_initialization().unwrap();
    let u = vr(&m, "motor_torque.shoulder_pitch");
    fmu.set(&[u], &[2.0]).unwrap();
    fmu.do_step(2.0, 0.05).unwrap();
    let blob = fmu.save().unwrap();
    let outputs: Vec<u32> = (0..m.table.variables.len() as u32).collect();
    let mut mid = vec![0.0; outputs.len()];
    fmu.get(&outputs, &mut mid).unwrap();
    fmu.set(&[u], &[-1.0]).unwrap();
    fmu.do_step(2.05, 0.05).unwrap();
    let mut end = vec![0.0; outputs.len()];
    fmu.get(&outputs, &mut end).unwrap();
    fmu.restore(&blob).unwrap();
    let mut back = vec![0.0; outputs.len()];
    fmu.get(&outputs, &mut back).unwrap();
    assert_eq!(bits(&back), bits(&mid));
    fmu.set(&[u], &[-1.0]).unwrap();
    fmu.do_step(2.05, 0.05).unwrap();
    fmu.get(&outputs, &mut back).unwrap();
    assert_eq!(bits(&back), bits(&end));

    // another instance, other parameters: refused, unchanged
    let mut other = FmuInstance::new(m.clone());
    other.enter_initialization(0.0).unwrap();
    other
        .set(&[vr(&m, "stiffness.shoulder_yaw")], &[123.0])
        .unwrap();
    other.exit_initialization().unwrap();
    let err = other.restore(&blob).unwrap_err();
    assert!(err.contains("another arm"), "{err}");
    assert_eq!(other.time(), 0.0);
    assert!(other.restore(b"OFXFMU\0\0junk").is_err());
    // the same parameters in a second instance: restored there too
    let mut twin = started(&m);
    twin.restore(&blob).unwrap();
    assert_eq!(twin.time(), 2.05);
}

fn bits(x: &[f64]) -> Vec<u64> {
    x.iter().map(|v| v.to_bits()).collect()
}

#[test]
fn a_tree_has_one_pose_per_end_effector() {
    let m = FmuModel::new(
        orbitflex::DUAL_ARM_URDF,
        &UrdfOptions::default(),
        &FlexibleJoints::dual_arm(),
        1e-3,
        "dual",
    )
    .unwrap();
    let t = VariableTable::new(&m.arm);
    for name in ["ee_position.left_ee.x", "ee_quaternion.right_ee.w"] {
        assert!(t.value_reference(name).is_some(), "{name}");
    }
}

#[test]
fn every_output_equals_the_simulators_outputs() {
    // parts of the state are read from it directly; the rest from the outputs: both are
    // bit for bit what Simulator::outputs gives
    let m = model();
    let mut fmu = FmuInstance::new(m.clone());
    fmu.enter_initialization(0.0).unwrap();
    let q0: Vec<f64> = (0..7).map(|i| 0.2 - 0.05 * i as f64).collect();
    let names = m.arm.robot().joint_names();
    let q0_vrs: Vec<u32> = names.iter().map(|j| vr(&m, &format!("q0.{j}"))).collect();
    fmu.set(&q0_vrs, &q0).unwrap();
    fmu.exit_initialization().unwrap();
    let u_vrs: Vec<u32> = names
        .iter()
        .map(|j| vr(&m, &format!("motor_torque.{j}")))
        .collect();
    fmu.set(&u_vrs, &[3.0, -2.0, 1.0, 0.5, -0.5, 0.2, 0.1])
        .unwrap();
    fmu.do_step(0.0, 0.02).unwrap();
    let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm()).unwrap();
    let x0 = arm
        .state(&StateSpec {
            q: Some(&q0),
            ..StateSpec::default()
        })
        .unwrap();
    let mut sim = Simulator::new(arm, &x0, 1e-3).unwrap();
    sim.set_motor_torque(&[3.0, -2.0, 1.0, 0.5, -0.5, 0.2, 0.1])
        .unwrap();
    sim.step(20).unwrap();
    let out = sim.outputs();
    for (v, var) in m.table.variables.iter().enumerate() {
        if let Slot::Output(quantity, i) = var.slot {
            let mut value = [0.0];
            fmu.get(&[v as u32], &mut value).unwrap();
            assert_eq!(
                value[0].to_bits(),
                quantity.read(&out, i).to_bits(),
                "{}",
                var.name
            );
        }
    }
}

#[test]
fn parameters_read_back_and_the_start_time_is_kept() {
    let m = model();
    let mut fmu = FmuInstance::new(m.clone());
    let names = m.arm.robot().joint_names();
    let joints = FlexibleJoints::space_arm();
    for (i, j) in names.iter().enumerate() {
        let vrs = [
            vr(&m, &format!("stiffness.{j}")),
            vr(&m, &format!("motor_inertia.{j}")),
            vr(&m, &format!("damping.{j}")),
            vr(&m, &format!("motor_damping.{j}")),
            vr(&m, &format!("q0.{j}")),
        ];
        let mut v = [f64::NAN; 5];
        fmu.get(&vrs, &mut v).unwrap();
        let exported = [
            joints.stiffness[i],
            joints.motor_inertia[i],
            joints.damping[i],
            joints.motor_damping[i],
            0.0,
        ];
        assert_eq!(v, exported, "{j}");
    }
    let k = vr(&m, "stiffness.wrist_yaw");
    fmu.set(&[k], &[1234.5]).unwrap();
    let mut v = [0.0];
    fmu.get(&[k], &mut v).unwrap();
    assert_eq!(v[0], 1234.5);
    // FMI 2.0: fmi2SetupExperiment gives the start time, fmi2EnterInitializationMode keeps it
    fmu.setup(1.5).unwrap();
    assert_eq!(fmu.time(), 1.5);
    fmu.enter_initialization(fmu.time()).unwrap();
    fmu.exit_initialization().unwrap();
    fmu.do_step(1.5, 1e-3).unwrap();
    assert_eq!(fmu.time(), 1.5 + 1e-3);
    assert!(fmu.setup(0.0).is_err(), "setup only before initialization");
    // a communication step of more than 1e15 steps is refused before it starts
    let err = fmu.do_step(fmu.time(), 1e13).unwrap_err();
    assert!(err.contains("too long"), "{err}");
}

#[test]
fn a_master_accumulating_its_time_is_followed_and_short_states_are_refused() {
    let m = model();
    let mut fmu = started(&m);
    // a master that adds h to its time (t += h) drifts from k h by float noise: still the
    // FMU's time, not a fraction of a step
    let (mut t, h) = (0.0_f64, 0.003);
    for _ in 0..1000 {
        fmu.do_step(t, h).unwrap();
        t += h;
    }
    assert_ne!(t, fmu.time(), "the test needs a drifted time");
    assert_eq!(fmu.time(), 3000.0 * 1e-3);
    // a stiffness must be > 0, a damping >= 0: zero is refused for the one, taken by the other
    let mut fresh = FmuInstance::new(m.clone());
    let err = fresh
        .set(&[vr(&m, "stiffness.elbow_pitch")], &[0.0])
        .unwrap_err();
    assert!(err.contains("expected > 0"), "{err}");
    fresh.set(&[vr(&m, "damping.elbow_pitch")], &[0.0]).unwrap();
    // saved states shorter than their header: refused, never read past the end
    for short in [&b"OFXFMU\0\0"[..], b"OFXFMU\0\0\x01\0\0\0\x02", b"OFX"] {
        assert!(fmu.restore(short).is_err());
    }
    assert_eq!(fmu.time(), 3000.0 * 1e-3);
}

#[test]
fn the_description_escapes_names_and_declares_starts_and_units() {
    // a joint name with XML's special characters comes back from the parsed description as is
    let urdf = SPACE_ARM_URDF.replace(
        "name=\"elbow_pitch\"",
        "name=\"elbow&amp;pitch&lt;1&gt;&quot;\"",
    );
    let m = FmuModel::new(
        &urdf,
        &UrdfOptions::default(),
        &FlexibleJoints::space_arm(),
        1e-3,
        "odd",
    )
    .unwrap();
    assert!(m.table.value_reference("q.elbow&pitch<1>\"").is_some());
    for version in [FmiVersion::V3, FmiVersion::V2] {
        let xml = orbitflex::fmu::model_description(&m, version);
        let mut reader = quick_xml::Reader::from_str(&xml);
        let (mut names, mut starts, mut units) = (Vec::new(), Vec::new(), Vec::new());
        let mut current = String::new();
        loop {
            let event = reader.read_event().expect("well-formed XML");
            let e = match &event {
                quick_xml::events::Event::Eof => break,
                quick_xml::events::Event::Start(e) | quick_xml::events::Event::Empty(e) => e,
                _ => continue,
            };
            let attr = |key: &str| {
                e.attributes()
                    .map(|a| a.unwrap())
                    .find(|a| a.key.as_ref() == key.as_bytes())
                    .map(|a| a.unescape_value().unwrap().into_owned())
            };
            match e.name().as_ref() {
                b"Float64" | b"ScalarVariable" => {
                    current = attr("name").unwrap();
                    names.push(current.clone());
                    if let Some(s) = attr("start") {
                        starts.push((current.clone(), s.parse::<f64>().unwrap()));
                    }
                }
                b"Real" => {
                    if let Some(s) = attr("start") {
                        starts.push((current.clone(), s.parse::<f64>().unwrap()));
                    }
                }
                b"Unit" => current = attr("name").unwrap(),
                b"BaseUnit" => {
                    let exponents: Vec<Option<String>> =
                        ["kg", "m", "s", "rad"].iter().map(|k| attr(k)).collect();
                    units.push((current.clone(), exponents));
                }
                _ => {}
            }
        }
        let expected: Vec<String> = m
            .table
            .variables
            .iter()
            .filter(|v| version == FmiVersion::V3 || v.causality != Causality::Independent)
            .map(|v| v.name.clone())
            .collect();
        assert_eq!(names, expected);
        // every input starts at 0, every parameter at its exported value, no output has a start
        let start = |name: &str| starts.iter().find(|(n, _)| n == name).map(|(_, s)| *s);
        assert_eq!(start("motor_torque.shoulder_roll"), Some(0.0));
        assert_eq!(start("base_force.z"), Some(0.0));
        assert_eq!(start("stiffness.elbow&pitch<1>\""), Some(5e3));
        let j = FlexibleJoints::space_arm();
        assert_eq!(start("motor_inertia.wrist_roll"), Some(j.motor_inertia[6]));
        assert_eq!(start("q0.wrist_roll"), Some(0.0));
        assert_eq!(start("q.wrist_roll"), None);
        let n = starts.len();
        assert_eq!(n, 5 * 7 + 7 + 6, "parameters and inputs only");
        // base-unit exponents: N.m = kg m2 s-2, N.m.s/rad = kg m2 s-1 rad-1, rad = rad
        let unit = |name: &str| units.iter().find(|(n, _)| n == name).unwrap().1.clone();
        let some = |v: &[&str]| -> Vec<Option<String>> {
            v.iter()
                .map(|s| (!s.is_empty()).then(|| s.to_string()))
                .collect()
        };
        assert_eq!(unit("N.m"), some(&["1", "2", "-2", ""]));
        assert_eq!(unit("N.m.s/rad"), some(&["1", "2", "-1", "-1"]));
        assert_eq!(unit("rad"), some(&["", "", "", "1"]));
    }
}

/// The built-in arm on a heavier bus (its centre of mass off the base origin) with four wheels
/// whose axes are not unit to the last bit before `ReactionWheels::new` normalises them.
fn wheel_arm(method: orbitflex::Method) -> FlexibleArm {
    use orbitflex::flex::{ReactionWheels, Wheel};
    use orbitflex::spatial::{Inertia, Mat3, Vec3};
    let bus = Inertia::from_com(
        812.5,
        Vec3::new(0.01, -0.02, -0.7),
        Mat3::from_diagonal(&Vec3::new(301.0, 295.0, 280.0)),
    );
    let robot = Robot::space_arm().with_base_inertia(bus).unwrap();
    let wheels = (0..4)
        .map(|w| {
            let phi = 0.3 + std::f64::consts::FRAC_PI_2 * w as f64;
            Wheel {
                axis: [0.8165 * phi.cos(), 0.8165 * phi.sin(), 0.57735],
                position: [0.3 * phi.cos(), 0.3 * phi.sin(), -0.4],
                mass: 4.0,
                spin_inertia: 0.04,
                transverse_inertia: 0.025,
                max_torque: 0.2,
                max_speed: if w == 3 { f64::INFINITY } else { 600.0 },
                friction: if w == 2 { 1e-3 } else { 0.0 },
            }
        })
        .collect();
    FlexibleArm::new(robot, FlexibleJoints::space_arm())
        .unwrap()
        .with_method(method)
        .with_wheels(ReactionWheels::new(wheels).unwrap())
        .unwrap()
}

/// An FMU of an arm on a bus with reaction wheels: the resources carry the bus, the wheels (axes
/// bit for bit, an infinite limit) and the method; the wheel variables sit where the table says;
/// an instance steps bit for bit as a `Simulator` of the arm, wheel commands saturated; a URDF
/// that does not make the arm's robot is refused.
#[test]
fn a_bus_with_wheels_travels_in_the_resources_and_steps_as_the_arm() {
    for method in [orbitflex::Method::Recursive, orbitflex::Method::Operator] {
        let arm = wheel_arm(method);
        let options = UrdfOptions::default();
        let m = FmuModel::of_arm(SPACE_ARM_URDF, &options, &arm, 1e-3, "bus").unwrap();
        assert_eq!(m.config.wheels.len(), 4);
        assert!(m.config.base.is_some());
        assert_eq!(
            orbitflex::integrate::arm_fingerprint(&m.arm),
            orbitflex::integrate::arm_fingerprint(&arm)
        );
        let files = m.files(FmiVersion::V2);
        let text = |name: &str| {
            let (_, bytes) = files.iter().find(|(p, _)| p.ends_with(name)).unwrap();
            String::from_utf8(bytes.clone()).unwrap()
        };
        let config = text("fmu.toml");
        assert!(config.contains("max_speed = inf"), "{config}");
        let back =
            FmuModel::from_texts(text("model.urdf"), text("joints.toml"), &config, "fmu.toml")
                .unwrap();
        assert_eq!(back.token(), m.token());
        assert_eq!(
            orbitflex::integrate::arm_fingerprint(&back.arm),
            orbitflex::integrate::arm_fingerprint(&arm),
            "bus, wheels and method bit for bit"
        );
        let names = m.table.names();
        let at = |name: &str| names.iter().position(|n| n == name).unwrap();
        assert!(at("wheel_speed0.3") < at("motor_torque.shoulder_yaw"));
        assert!(at("base_force.z") < at("wheel_torque.0"));
        assert!(at("wheel_torque.3") < at("q.shoulder_yaw"));
        assert_eq!(at("applied_wheel_torque.3"), names.len() - 1);
        assert_eq!(at("wheel_speed.0"), at("energy") + 1);

        let mut fmu = FmuInstance::new(back.clone());
        fmu.enter_initialization(0.0).unwrap();
        fmu.set(&[vr(&m, "wheel_speed0.1")], &[599.99]).unwrap();
        fmu.exit_initialization().unwrap();
        let mut x0 = arm.rest_state();
        x0[42] = 599.99;
        let mut sim = Simulator::new(arm.clone(), &x0, 1e-3).unwrap();
        let torque: Vec<u32> = (0..4)
            .map(|w| vr(&m, &format!("wheel_torque.{w}")))
            .collect();
        let speed: Vec<u32> = (0..4)
            .map(|w| vr(&m, &format!("wheel_speed.{w}")))
            .collect();
        let applied: Vec<u32> = (0..4)
            .map(|w| vr(&m, &format!("applied_wheel_torque.{w}")))
            .collect();
        let (mut got, mut held) = (vec![0.0; 4], vec![0.0; 4]);
        for k in 0..30 {
            // beyond ±0.2 N·m half the time; wheel 1 pushed past its max_speed
            let w: Vec<f64> = (0..4).map(|i| 0.3 * ((k * 4 + i) as f64).cos()).collect();
            let w = [w[0], 0.25, w[2], w[3]];
            fmu.set(&torque, &w).unwrap();
            fmu.do_step(fmu.time(), 3e-3).unwrap();
            sim.set_wheel_torque(&w).unwrap();
            sim.step(3).unwrap();
            fmu.get(&speed, &mut got).unwrap();
            assert_eq!(bits(&got), bits(&sim.state()[41..45]), "step {k}");
            fmu.get(&applied, &mut got).unwrap();
            assert_eq!(bits(&got), bits(sim.applied_wheel_torque()), "step {k}");
            fmu.get(&torque, &mut held).unwrap();
            assert_eq!(held, w);
        }
        assert!(sim.state()[42] >= 600.0 && sim.applied_wheel_torque()[1] == 0.0);
        let mut all = vec![0.0; m.table.variables.len()];
        let every: Vec<u32> = (0..all.len() as u32).collect();
        fmu.get(&every, &mut all).unwrap();
        assert_eq!(all[vr(&m, "energy") as usize], sim.outputs().energy);

        // a URDF that makes another robot (a joint locked) is not this arm's
        let locked = UrdfOptions {
            locked_joints: vec!["wrist_roll".into()],
            ..UrdfOptions::default()
        };
        let e = FmuModel::of_arm(SPACE_ARM_URDF, &locked, &arm, 1e-3, "bus")
            .unwrap_err()
            .to_string();
        assert!(e.contains("does not make the arm's robot"), "{e}");
    }
}

/// A version-1 `fmu.toml` (no method, bus or wheels) still reads; a newer version is refused,
/// saying which versions the runtime reads.
#[test]
fn configuration_versions() {
    let m = model();
    let files = m.files(FmiVersion::V3);
    let text = |name: &str| {
        let (_, bytes) = files.iter().find(|(p, _)| p.ends_with(name)).unwrap();
        String::from_utf8(bytes.clone()).unwrap()
    };
    let config = text("fmu.toml");
    let v1 = config
        .replace("version = 2", "version = 1")
        .replace("method = \"recursive\"\n", "");
    let back = FmuModel::from_texts(text("model.urdf"), text("joints.toml"), &v1, "fmu.toml");
    assert_eq!(back.unwrap().table, m.table);
    let v3 = config.replace("version = 2", "version = 3");
    let e = FmuModel::from_texts(text("model.urdf"), text("joints.toml"), &v3, "fmu.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("reads versions 1 to 2"), "{e}");
}
