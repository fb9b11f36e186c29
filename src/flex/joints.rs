//! [`FlexibleJoints`]: the per-joint Spong parameters, from arrays, gear data or a TOML file.

use crate::args::check_vector;
pub(crate) use crate::args::{check_parameter, Domain};
use crate::error::{Error, Result};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

/// Per-joint Spong parameters, all on the link side (model §3).
///
/// ```
/// use orbitflex::FlexibleJoints;
/// // j = N² J_rotor = 160² · 4e-5 = 1.024 kg·m²
/// let joints = FlexibleJoints::from_gear(vec![2e4; 2], &[160.0; 2], &[4e-5; 2], vec![2.0; 2], vec![1.0; 2])?;
/// assert!((joints.motor_inertia[0] - 1.024).abs() < 1e-12);
/// # Ok::<(), orbitflex::Error>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct FlexibleJoints {
    /// `k_i` > 0, joint stiffness (N·m/rad).
    pub stiffness: Vec<f64>,
    /// `j_i` > 0, motor inertia reflected to the link side, `N² J_rotor` (kg·m²).
    pub motor_inertia: Vec<f64>,
    /// `d_i` ≥ 0, joint (spring) damping (N·m·s/rad).
    pub damping: Vec<f64>,
    /// `β_i` ≥ 0, motor viscous friction (N·m·s/rad).
    pub motor_damping: Vec<f64>,
}

/// The motor inertia reflected to the link side, `j = N² J_rotor` (kg·m²), from the gear ratio
/// `N > 0` and the rotor inertia `J_rotor > 0` (kg·m²). `what` names the joint in messages.
pub fn reflected_inertia(what: &str, gear_ratio: f64, rotor_inertia: f64) -> Result<f64> {
    for (name, value) in [("gear_ratio", gear_ratio), ("rotor_inertia", rotor_inertia)] {
        if !(value.is_finite() && value > 0.0) {
            return Err(Error::InvalidArgument {
                what: format!("{what}{name}"),
                message: format!("expected a finite number > 0, given {value}"),
            });
        }
    }
    let j = gear_ratio * gear_ratio * rotor_inertia;
    if !(j.is_finite() && j > 0.0) {
        return Err(Error::InvalidArgument {
            what: format!("{what}gear_ratio"),
            message: format!(
                "gear_ratio² · rotor_inertia = {gear_ratio:e}² · {rotor_inertia:e} is not a \
                 finite positive number ({j:e})"
            ),
        });
    }
    Ok(j)
}

impl FlexibleJoints {
    /// Validated parameters for `n` joints: `k > 0`, `j > 0`, `d ≥ 0`, `β ≥ 0`, each of length n.
    pub fn new(
        stiffness: Vec<f64>,
        motor_inertia: Vec<f64>,
        damping: Vec<f64>,
        motor_damping: Vec<f64>,
    ) -> Result<Self> {
        let n = stiffness.len();
        check_parameter("stiffness", &stiffness, n, Domain::Positive)?;
        check_parameter("motor_inertia", &motor_inertia, n, Domain::Positive)?;
        check_parameter("damping", &damping, n, Domain::NonNegative)?;
        check_parameter("motor_damping", &motor_damping, n, Domain::NonNegative)?;
        Ok(Self {
            stiffness,
            motor_inertia,
            damping,
            motor_damping,
        })
    }

    /// The same scalar parameters for all `n` joints.
    pub fn uniform(
        n: usize,
        stiffness: f64,
        motor_inertia: f64,
        damping: f64,
        motor_damping: f64,
    ) -> Result<Self> {
        Self::new(
            vec![stiffness; n],
            vec![motor_inertia; n],
            vec![damping; n],
            vec![motor_damping; n],
        )
    }

    /// From gearbox data: `j_i = N_i² J_rotor,i` ([`reflected_inertia`]). `u` and `θ` are then
    /// link-side quantities: `u = N × (motor torque)`, `θ = (motor angle) / N`.
    pub fn from_gear(
        stiffness: Vec<f64>,
        gear_ratio: &[f64],
        rotor_inertia: &[f64],
        damping: Vec<f64>,
        motor_damping: Vec<f64>,
    ) -> Result<Self> {
        let n = stiffness.len();
        check_vector("gear_ratio", gear_ratio, n)?;
        check_vector("rotor_inertia", rotor_inertia, n)?;
        let j = gear_ratio
            .iter()
            .zip(rotor_inertia)
            .enumerate()
            .map(|(i, (&g, &r))| reflected_inertia(&format!("joint {i}: "), g, r))
            .collect::<Result<Vec<f64>>>()?;
        Self::new(stiffness, j, damping, motor_damping)
    }

    /// Plausible harmonic-drive parameters for the built-in space arm ([`crate::Robot::space_arm`],
    /// 7 joints), link side.
    ///
    /// Stiffness 1e4 N·m/rad at the shoulder, 5e3 at the elbow, 2e3 in the wrist (space-arm
    /// joints are compliant: long output shafts and light gearboxes); reflected motor inertia from
    /// gear ratio 160 and rotor inertias 4e-5 … 1.5e-5 kg·m² (j = 1.02 … 0.38 kg·m²); light joint
    /// damping (0.2 N·m·s/rad) so that residual vibration shows; motor friction 1 N·m·s/rad.
    pub fn space_arm() -> Self {
        let stiffness = vec![1.0e4, 1.0e4, 1.0e4, 5.0e3, 2.0e3, 2.0e3, 2.0e3];
        let rotor = [4.0e-5, 4.0e-5, 4.0e-5, 3.0e-5, 1.5e-5, 1.5e-5, 1.5e-5];
        Self::from_gear(stiffness, &[160.0; 7], &rotor, vec![0.2; 7], vec![1.0; 7])
            .expect("the built-in joint parameters are valid")
    }

    /// [`space_arm`](Self::space_arm)'s parameters for each arm of [`crate::Robot::dual_arm`]:
    /// the left arm's seven joints, then the right arm's.
    pub fn dual_arm() -> Self {
        let one = Self::space_arm();
        let twice = |v: &[f64]| [v, v].concat();
        Self::new(
            twice(&one.stiffness),
            twice(&one.motor_inertia),
            twice(&one.damping),
            twice(&one.motor_damping),
        )
        .expect("the built-in joint parameters are valid")
    }

    /// Parameters for a robot with no actuator data, scaled to its links (the CLI's default
    /// when no `--params` file is given). Each joint `i` sees the link-side inertia
    /// `m_i = 1/(𝓜⁻¹)_ii` at `q = 0` (the inertia it would drive with every other joint free);
    /// then
    ///
    /// - stiffness `k_i = (2π · 5 Hz)² m_i`: with its motor held, the joint rings at 5 Hz, the
    ///   low end of what space arms show;
    /// - motor inertia `j_i = m_i`;
    /// - joint damping `d_i = 2 · 0.05 · √(k_i m_i)`: 5 % of critical;
    /// - motor friction `β_i = 0`.
    ///
    /// ```
    /// use orbitflex::{FlexibleJoints, Robot};
    /// let joints = FlexibleJoints::defaults_for(&Robot::space_arm())?;
    /// assert_eq!(joints.len(), 7);
    /// # Ok::<(), orbitflex::Error>(())
    /// ```
    pub fn defaults_for(robot: &crate::Robot) -> Result<Self> {
        use crate::{algorithms, Loads, RigidState};
        let n = robot.dof();
        let mut data = algorithms::Data::new(robot);
        let zeros = vec![0.0; n];
        let mut unit = vec![0.0; n];
        let omega = 2.0 * std::f64::consts::PI * 5.0;
        let mut columns: [Vec<f64>; 4] = Default::default();
        for i in 0..n {
            unit[i] = 1.0;
            let rest = RigidState::at_rest(&zeros, &zeros);
            let m = 1.0 / algorithms::aba(robot, &mut data, &rest, &unit, &Loads::ZERO)?[6 + i];
            unit[i] = 0.0;
            let k = omega * omega * m;
            for (column, value) in columns.iter_mut().zip([k, m, 0.1 * (k * m).sqrt(), 0.0]) {
                column.push(value);
            }
        }
        let [k, j, d, beta] = columns;
        Self::new(k, j, d, beta)
    }

    /// Number of joints.
    pub fn len(&self) -> usize {
        self.stiffness.len()
    }

    /// True when there are no joints.
    pub fn is_empty(&self) -> bool {
        self.stiffness.is_empty()
    }

    /// Reads parameters keyed by joint name from TOML text (see [`FlexibleJoints::from_toml_file`]);
    /// `source` names the text in messages.
    pub fn from_toml_str(text: &str, joint_names: &[&str], source: &str) -> Result<Self> {
        let malformed = |message: String| Error::Malformed {
            source_name: source.to_string(),
            format: "joint-parameter TOML",
            message,
        };
        let file: TomlFile = toml::from_str(text).map_err(|e| malformed(toml_error(text, &e)))?;
        if let Some(name) = file
            .joints
            .keys()
            .find(|name| !joint_names.contains(&name.as_str()))
        {
            return Err(Error::UnknownName {
                source_name: source.to_string(),
                what: "joint ([joints.<name>] table)",
                name: name.clone(),
                available: joint_names.join(", "),
            });
        }
        let default_inertia = file
            .defaults
            .motor_inertia("[defaults]")
            .map_err(&malformed)?;
        let mut columns: [Vec<f64>; 4] = Default::default();
        for name in joint_names {
            let row = file.joint(name, default_inertia).map_err(&malformed)?;
            for (column, value) in columns.iter_mut().zip(row) {
                column.push(value);
            }
        }
        let [k, j, d, beta] = columns;
        Self::new(k, j, d, beta).map_err(|e| malformed(e.to_string()))
    }

    /// Reads parameters keyed by joint name from a TOML file, kept beside a robot's URDF:
    ///
    /// ```toml
    /// [defaults]              # optional; used for every joint not given below
    /// stiffness = 2.0e4       # N·m/rad
    /// motor_inertia = 0.5     # kg·m², link side; or gear_ratio and rotor_inertia
    /// damping = 5.0           # N·m·s/rad (default 0)
    /// motor_damping = 0.0     # N·m·s/rad (default 0)
    ///
    /// [joints.elbow_pitch]
    /// stiffness = 1.0e4
    /// gear_ratio = 160.0
    /// rotor_inertia = 2.0e-5  # j = gear_ratio² · rotor_inertia
    /// ```
    pub fn from_toml_file(path: impl AsRef<Path>, joint_names: &[&str]) -> Result<Self> {
        let path = path.as_ref();
        let text = crate::io::read_text(path, "joint-parameter TOML")?;
        Self::from_toml_str(&text, joint_names, &path.display().to_string())
    }
}

/// One `[defaults]` or `[joints.<name>]` table.
#[derive(Deserialize, Default, Clone, Copy)]
#[serde(deny_unknown_fields)]
struct TomlEntry {
    stiffness: Option<f64>,
    motor_inertia: Option<f64>,
    gear_ratio: Option<f64>,
    rotor_inertia: Option<f64>,
    damping: Option<f64>,
    motor_damping: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TomlFile {
    #[serde(default)]
    defaults: TomlEntry,
    #[serde(default)]
    joints: BTreeMap<String, TomlEntry>,
}

impl TomlEntry {
    /// `motor_inertia`, or `gear_ratio² · rotor_inertia`; `None` if the table gives neither.
    fn motor_inertia(&self, table: &str) -> std::result::Result<Option<f64>, String> {
        match (self.motor_inertia, self.gear_ratio, self.rotor_inertia) {
            (Some(value), None, None) => Ok(Some(value)),
            (None, Some(g), Some(r)) => reflected_inertia(&format!("{table}: "), g, r)
                .map(Some)
                .map_err(|e| e.to_string()),
            (None, None, None) => Ok(None),
            _ => Err(format!(
                "{table}: give either motor_inertia, or both gear_ratio and rotor_inertia"
            )),
        }
    }
}

impl TomlFile {
    /// `[k, j, d, β]` for joint `name`: its own table first, then `[defaults]`.
    fn joint(
        &self,
        name: &str,
        default_inertia: Option<f64>,
    ) -> std::result::Result<[f64; 4], String> {
        let own = self.joints.get(name).copied().unwrap_or_default();
        let defaults = &self.defaults;
        let missing = |key: &str| {
            format!("joint '{name}': no {key} (give it in [joints.{name}] or [defaults])")
        };
        let stiffness = own
            .stiffness
            .or(defaults.stiffness)
            .ok_or_else(|| missing("stiffness"))?;
        let inertia = own
            .motor_inertia(&format!("joint '{name}' ([joints.{name}])"))?
            .or(default_inertia)
            .ok_or_else(|| missing("motor_inertia (or gear_ratio and rotor_inertia)"))?;
        let damping = own.damping.or(defaults.damping).unwrap_or(0.0);
        let motor_damping = own.motor_damping.or(defaults.motor_damping).unwrap_or(0.0);
        let row = [stiffness, inertia, damping, motor_damping];
        let domains = [
            Domain::Positive,
            Domain::Positive,
            Domain::NonNegative,
            Domain::NonNegative,
        ];
        let keys = ["stiffness", "motor_inertia", "damping", "motor_damping"];
        for ((key, value), domain) in keys.iter().zip(row).zip(domains) {
            if !value.is_finite() || !domain.contains(value) {
                return Err(format!(
                    "joint '{name}': {key} must be a finite number {}, given {value}",
                    domain.describe()
                ));
            }
        }
        Ok(row)
    }
}

/// A TOML parse error on one line: `line L, column C: what, expected what` (the parser's own
/// rendering quotes the source over several lines).
fn toml_error(text: &str, e: &toml::de::Error) -> String {
    let what = e
        .message()
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(", ");
    match e.span() {
        Some(span) => {
            // an error at the end of the input points just past its last character
            let start = span.start.min(text.trim_end().len());
            let before = text.get(..start).unwrap_or(text);
            let line = before.matches('\n').count() + 1;
            let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            format!("line {line}, column {column}: {what}")
        }
        None => what,
    }
}
