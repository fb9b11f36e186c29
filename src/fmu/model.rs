//! [`FmuModel`]: what an FMU carries in `resources/` (the URDF, the joint parameters and
//! `fmu.toml`), written by `orbitflex fmu` and read back by the runtime at instantiation.
//!
//! One generic runtime library serves every model: nothing is compiled per model. The
//! instantiation token is a hash of the three resource files, so a runtime given another
//! model's description, or resources edited after export, refuses to instantiate.

use super::variables::VariableTable;
use crate::error::{Error, Result};
use crate::flex::{FlexibleArm, FlexibleJoints, ReactionWheels, Wheel};
use crate::integrate::simulator::{arm_fingerprint, fnv1a};
use crate::model::{Robot, UrdfOptions};
use crate::spatial::{Inertia, Mat3, Vec3};
use crate::Method;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The version of the `fmu.toml` layout; the runtime reads this one and the ones before it
/// (version 2 added `method`, `[base]` and the `[[wheels]]`; a version-1 file has none of them:
/// the recursive method, the URDF's base, no wheels) and refuses a newer one.
pub const CONFIG_VERSION: u32 = 2;

/// The resource files, as named in the FMU (under `resources/`).
pub const URDF_FILE: &str = "model.urdf";
/// The joint parameters, one `[joints.<name>]` table per joint (see
/// [`FlexibleJoints::from_toml_file`]).
pub const JOINTS_FILE: &str = "joints.toml";
/// The export settings ([`FmuConfig`]).
pub const CONFIG_FILE: &str = "fmu.toml";

/// Which FMI standard an FMU follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FmiVersion {
    /// FMI 2.0 co-simulation (`binaries/linux64`).
    V2,
    /// FMI 3.0 co-simulation (`binaries/x86_64-linux`).
    V3,
}

/// The export settings kept in `resources/fmu.toml`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FmuConfig {
    /// [`CONFIG_VERSION`].
    pub version: u32,
    /// The model's name (the URDF's robot name).
    pub model_name: String,
    /// The model identifier: the binary's file name, a C identifier.
    pub model_identifier: String,
    /// The internal RK4 step (s); every communication step is a whole multiple of it.
    pub dt: f64,
    /// The end-effector links, in order.
    pub ee_links: Vec<String>,
    /// The joints held at zero.
    pub locked_joints: Vec<String>,
    /// The dynamics method, `"recursive"` or `"operator"` ([`Method::name`]).
    #[serde(default = "recursive")]
    pub method: String,
    /// The variable names in value-reference order, as the description declares them: the
    /// runtime rebuilds the table from the model and refuses a different one.
    pub variables: Vec<String>,
    /// The bus the arm is mounted on, when its inertia replaces the URDF root link's (none:
    /// the URDF's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<BaseConfig>,
    /// The reaction wheels on the bus, in order, their axes as the arm holds them (normalised)
    /// and limits `inf` for none (none: an arm without wheels).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub wheels: Vec<Wheel>,
}

fn recursive() -> String {
    Method::Recursive.name().into()
}

/// The base body's inertia as the model holds it (every number in its round-trip form, so that
/// the runtime rebuilds the same bus bit for bit).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BaseConfig {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the base frame (m).
    pub com: [f64; 3],
    /// Rotational inertia about the base ORIGIN (not the centre of mass), base axes, row-major
    /// (kg·m²).
    pub rotational: [f64; 9],
}

impl BaseConfig {
    fn of(inertia: &Inertia) -> Self {
        let r = &inertia.rotational;
        Self {
            mass: inertia.mass,
            com: [inertia.com[0], inertia.com[1], inertia.com[2]],
            rotational: std::array::from_fn(|k| r[(k / 3, k % 3)]),
        }
    }

    fn inertia(&self) -> Inertia {
        Inertia {
            mass: self.mass,
            com: Vec3::from(self.com),
            rotational: Mat3::from_row_slice(&self.rotational),
        }
    }
}

/// An arm as an FMU carries it: its files, and the arm and variables they make.
#[derive(Debug, Clone)]
pub struct FmuModel {
    /// The settings.
    pub config: FmuConfig,
    /// The URDF text.
    pub urdf: String,
    /// The joint-parameter TOML text.
    pub joints_toml: String,
    /// The arm built from them.
    pub arm: FlexibleArm,
    /// Its variables.
    pub table: VariableTable,
}

impl FmuModel {
    /// The model of an FMU for the arm made of `urdf` (loaded with `options`) and `joints`,
    /// stepping `dt` (s), whose binary is `model_identifier` (a C identifier, at most 64
    /// characters).
    pub fn new(
        urdf: &str,
        options: &UrdfOptions,
        joints: &FlexibleJoints,
        dt: f64,
        model_identifier: &str,
    ) -> Result<Self> {
        crate::args::check_dt(dt)?;
        check_identifier(model_identifier)?;
        let robot = Robot::from_urdf_string(urdf, options)?;
        let arm = FlexibleArm::new(robot, joints.clone())?;
        Self::of_arm(urdf, options, &arm, dt, model_identifier)
    }

    /// The model of an FMU of `arm` whose robot is `urdf` loaded with `options`, but for the
    /// base's inertia, which may replace the root link's (a bus the arm is mounted on,
    /// [`Robot::with_base_inertia`]): the FMU carries that bus, the arm's reaction wheels, its
    /// joint parameters and its dynamics method, and steps exactly as `arm` does. An error if
    /// the URDF makes another robot.
    pub fn of_arm(
        urdf: &str,
        options: &UrdfOptions,
        arm: &FlexibleArm,
        dt: f64,
        model_identifier: &str,
    ) -> Result<Self> {
        crate::args::check_dt(dt)?;
        check_identifier(model_identifier)?;
        let loaded = Robot::from_urdf_string(urdf, options)?;
        let bus = arm.robot().inertias()[0];
        let base = (loaded.inertias()[0] != bus).then_some(bus);
        let robot = match base {
            Some(inertia) => loaded.with_base_inertia(inertia)?,
            None => loaded,
        };
        if rigid_model(&robot) != rigid_model(arm.robot()) {
            return Err(Error::InvalidArgument {
                what: "urdf".into(),
                message: format!(
                    "it does not make the arm's robot '{}' ({} joints, end-effectors {:?}): \
                     loaded with the given end-effector links and locked joints, its links, \
                     joints, inertias and end-effectors must be the arm's (only the base's \
                     inertia may differ, for a bus); it makes '{}' ({} joints, end-effectors \
                     {:?})",
                    arm.robot().name(),
                    arm.dof(),
                    arm.robot().ee_links(),
                    robot.name(),
                    robot.dof(),
                    robot.ee_links()
                ),
            });
        }
        let mut made = FlexibleArm::new(robot, arm.joints().clone())?.with_method(arm.method());
        if let Some(wheels) = arm.wheels() {
            made = made.with_wheels(wheels.clone())?;
        }
        debug_assert_eq!(arm_fingerprint(&made), arm_fingerprint(arm));
        let arm = made;
        let table = VariableTable::new(&arm);
        let robot = arm.robot();
        let config = FmuConfig {
            version: CONFIG_VERSION,
            model_name: robot.name().to_string(),
            model_identifier: model_identifier.to_string(),
            dt,
            ee_links: robot.ee_links().iter().map(|s| s.to_string()).collect(),
            locked_joints: options.locked_joints.clone(),
            method: arm.method().name().into(),
            variables: table.names(),
            base: base.as_ref().map(BaseConfig::of),
            wheels: arm.wheels().map_or(Vec::new(), |w| w.wheels().to_vec()),
        };
        let joints = arm.joints();
        let joints_toml = joints_toml(&robot.joint_names(), joints);
        Ok(Self {
            config,
            urdf: urdf.to_string(),
            joints_toml,
            arm,
            table,
        })
    }

    /// Reads the model back from an FMU's `resources/` folder, checking that it makes the
    /// variables the description declares.
    pub fn from_resources(dir: &Path) -> Result<Self> {
        let read = |name: &str, what: &'static str| crate::io::read_text(&dir.join(name), what);
        let urdf = read(URDF_FILE, "URDF")?;
        let joints_toml = read(JOINTS_FILE, "joint-parameter TOML")?;
        let config_path = dir.join(CONFIG_FILE);
        let config_text = read(CONFIG_FILE, "FMU configuration")?;
        Self::from_texts(
            urdf,
            joints_toml,
            &config_text,
            &config_path.display().to_string(),
        )
    }

    /// [`from_resources`](Self::from_resources) from the three texts; `source` names the
    /// configuration in messages.
    pub fn from_texts(
        urdf: String,
        joints_toml: String,
        config_text: &str,
        source: &str,
    ) -> Result<Self> {
        let malformed = |message: String| Error::Malformed {
            source_name: source.to_string(),
            format: "FMU configuration",
            message,
        };
        let config: FmuConfig =
            toml::from_str(config_text).map_err(|e| malformed(e.to_string()))?;
        if !(1..=CONFIG_VERSION).contains(&config.version) {
            return Err(malformed(format!(
                "version {}; this runtime reads versions 1 to {CONFIG_VERSION} (export the FMU \
                 again with this orbitflex)",
                config.version
            )));
        }
        let options = UrdfOptions {
            ee_link: None,
            ee_links: config.ee_links.clone(),
            locked_joints: config.locked_joints.clone(),
        };
        let mut robot = Robot::from_urdf_string(&urdf, &options)?;
        if let Some(base) = &config.base {
            robot = robot.with_base_inertia(base.inertia())?;
        }
        let joints =
            FlexibleJoints::from_toml_str(&joints_toml, &robot.joint_names(), JOINTS_FILE)?;
        let method = Method::from_name(&config.method).map_err(|e| malformed(e.to_string()))?;
        let mut arm = FlexibleArm::new(robot, joints)?.with_method(method);
        if !config.wheels.is_empty() {
            let wheels = ReactionWheels::normalised(config.wheels.clone())?;
            arm = arm.with_wheels(wheels)?;
        }
        let model = Self::of_arm(&urdf, &options, &arm, config.dt, &config.model_identifier)?;
        if model.config.variables != config.variables {
            return Err(malformed(
                "its variables are not those this runtime makes of the model (an FMU exported \
                 by another orbitflex version?)"
                    .into(),
            ));
        }
        Ok(Self {
            config,
            joints_toml,
            ..model
        })
    }

    /// The `fmu.toml` text.
    pub fn config_toml(&self) -> String {
        toml::to_string(&self.config).expect("the configuration serialises")
    }

    /// The instantiation token (FMI 3.0 `instantiationToken`, FMI 2.0 `guid`): a hash of the
    /// three resource files, written as a GUID.
    pub fn token(&self) -> String {
        let config = self.config_toml();
        let mut bytes = Vec::new();
        for part in [self.urdf.as_str(), &self.joints_toml, &config] {
            bytes.extend_from_slice(&(part.len() as u64).to_le_bytes());
            bytes.extend_from_slice(part.as_bytes());
        }
        let a = fnv1a(&bytes);
        bytes.push(0x5a);
        let b = fnv1a(&bytes);
        format!(
            "{{{:08x}-{:04x}-{:04x}-{:04x}-{:012x}}}",
            a >> 32,
            (a >> 16) & 0xffff,
            a & 0xffff,
            b >> 48,
            b & 0xffff_ffff_ffff
        )
    }

    /// The files of the FMU but its binary, as `(path in the archive, contents)`: the model
    /// description for `version` and the three resources.
    pub fn files(&self, version: FmiVersion) -> Vec<(String, Vec<u8>)> {
        vec![
            (
                "modelDescription.xml".into(),
                super::description::model_description(self, version).into_bytes(),
            ),
            (
                format!("resources/{URDF_FILE}"),
                self.urdf.clone().into_bytes(),
            ),
            (
                format!("resources/{JOINTS_FILE}"),
                self.joints_toml.clone().into_bytes(),
            ),
            (
                format!("resources/{CONFIG_FILE}"),
                self.config_toml().into_bytes(),
            ),
        ]
    }
}

/// Everything of `robot` its dynamics depend on, as text (numbers in round-trip form): two
/// robots with the same text step alike.
fn rigid_model(robot: &Robot) -> String {
    format!(
        "{:?}|{:?}|{:?}|{:?}",
        robot.joints(),
        robot.parents(),
        robot.inertias(),
        robot.end_effectors()
    )
}

/// A C identifier of at most 64 characters (the binary's name and the model identifier).
fn check_identifier(id: &str) -> Result<()> {
    let mut chars = id.chars();
    let ok = id.len() <= 64
        && chars
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_')
        && chars.all(|c| c.is_ascii_alphanumeric() || c == '_');
    if ok {
        return Ok(());
    }
    Err(Error::InvalidArgument {
        what: "model_identifier".into(),
        message: format!(
            "expected a C identifier (letters, digits and '_', not starting with a digit, at \
             most 64 characters), given '{id}'"
        ),
    })
}

/// The joint parameters as TOML, one table per joint, every number in its shortest round-trip
/// form (read back bit for bit).
pub fn joints_toml(names: &[&str], joints: &FlexibleJoints) -> String {
    let mut out = String::from("# Spong joint parameters, link side (written by orbitflex)\n");
    for (i, name) in names.iter().enumerate() {
        let key = toml_key(name);
        out.push_str(&format!(
            "\n[joints.{key}]\nstiffness = {:?}\nmotor_inertia = {:?}\ndamping = {:?}\n\
             motor_damping = {:?}\n",
            joints.stiffness[i],
            joints.motor_inertia[i],
            joints.damping[i],
            joints.motor_damping[i]
        ));
    }
    out
}

/// A TOML key: bare when it can be, quoted otherwise.
fn toml_key(name: &str) -> String {
    let bare = !name.is_empty()
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if bare {
        return name.to_string();
    }
    let mut quoted = String::from("\"");
    for c in name.chars() {
        match c {
            '"' => quoted.push_str("\\\""),
            '\\' => quoted.push_str("\\\\"),
            c if c.is_control() => quoted.push_str(&format!("\\u{:04X}", c as u32)),
            c => quoted.push(c),
        }
    }
    quoted.push('"');
    quoted
}
