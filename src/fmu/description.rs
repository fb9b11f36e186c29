//! `modelDescription.xml` for FMI 3.0 and FMI 2.0 co-simulation, written from the
//! [`VariableTable`](super::VariableTable) the runtime uses.
//!
//! Choices the standards leave to the exporter:
//! - parameters are `causality="parameter" variability="fixed"`: set before initialisation
//!   (FMI's "tunable" would mean changeable during the run, which the arm does not support);
//! - inputs are `variability="continuous"` with `start="0"`;
//! - outputs are `initial="calculated"` and declare `dependencies=""`: they are functions of the
//!   state only, with no direct feedthrough from the inputs, so a master (or Simulink) closing a
//!   loop around the FMU sees no algebraic loop;
//! - `canHandleVariableCommunicationStepSize="true"`, but every communication step must be a
//!   whole multiple of the internal step dt (FMI 3.0 `fixedInternalStepSize`; FMI 2.0's
//!   `DefaultExperiment stepSize`);
//! - `variableNamingConvention="flat"`, so joint names need no quoting.

use super::model::{FmiVersion, FmuModel};
use super::variables::{Causality, Slot, Variable, DAMPING_UNIT, UNITS};
use std::fmt::Write;

/// The model description of `model` for FMI `version`.
pub fn model_description(model: &FmuModel, version: FmiVersion) -> String {
    let v3 = version == FmiVersion::V3;
    let mut x = String::from("<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n");
    header(&mut x, model, v3);
    unit_definitions(&mut x);
    x.push_str(
        "  <LogCategories>\n    <Category name=\"logStatusError\" description=\"errors: refused \
         calls and failed steps\"/>\n  </LogCategories>\n",
    );
    let _ = writeln!(
        x,
        "  <DefaultExperiment startTime=\"0\" stopTime=\"1\" stepSize=\"{}\"/>",
        number(model.config.dt)
    );
    model_variables(&mut x, model, v3);
    model_structure(&mut x, model, v3);
    x.push_str("</fmiModelDescription>\n");
    x
}

/// The `fmiModelDescription` start tag and the `CoSimulation` element.
fn header(x: &mut String, model: &FmuModel, v3: bool) {
    let c = &model.config;
    let wheels = match model.arm.layout().wheels {
        0 => String::new(),
        1 => ", 1 reaction wheel".into(),
        k => format!(", {k} reaction wheels"),
    };
    let description = format!(
        "{}: floating-base arm with {} Spong flexible joints{wheels}, RK4 at dt = {} s (orbitflex)",
        c.model_name,
        model.arm.dof(),
        number(c.dt)
    );
    let (version_attr, token_attr) = if v3 {
        ("3.0", "instantiationToken")
    } else {
        ("2.0", "guid")
    };
    let _ = write!(
        x,
        "<fmiModelDescription fmiVersion=\"{version_attr}\" modelName=\"{}\" {token_attr}=\"{}\"\n  \
         description=\"{}\" generationTool=\"orbitflex {}\" variableNamingConvention=\"flat\"{}>\n",
        escape(&c.model_name),
        model.token(),
        escape(&description),
        env!("CARGO_PKG_VERSION"),
        if v3 { "" } else { " numberOfEventIndicators=\"0\"" },
    );
    let id = escape(&c.model_identifier);
    if v3 {
        let _ = writeln!(
            x,
            "  <CoSimulation modelIdentifier=\"{id}\" canHandleVariableCommunicationStepSize=\"true\" \
             fixedInternalStepSize=\"{}\"\n    canGetAndSetFMUState=\"true\" canSerializeFMUState=\"true\" \
             canBeInstantiatedOnlyOncePerProcess=\"false\"/>",
            number(c.dt)
        );
    } else {
        let _ = writeln!(
            x,
            "  <CoSimulation modelIdentifier=\"{id}\" canHandleVariableCommunicationStepSize=\"true\"\n    \
             canGetAndSetFMUstate=\"true\" canSerializeFMUstate=\"true\" \
             canNotUseMemoryManagementFunctions=\"true\" canBeInstantiatedOnlyOncePerProcess=\"false\"/>"
        );
    }
}

/// `UnitDefinitions`: each unit of [`UNITS`] and [`DAMPING_UNIT`] with its SI base exponents.
fn unit_definitions(x: &mut String) {
    x.push_str("  <UnitDefinitions>\n");
    for (name, kg, m, s, rad) in UNITS.iter().copied().chain([DAMPING_UNIT]) {
        let mut base = String::new();
        for (key, exponent) in [("kg", kg), ("m", m), ("s", s), ("rad", rad)] {
            if exponent != 0 {
                let _ = write!(base, " {key}=\"{exponent}\"");
            }
        }
        let _ = writeln!(x, "    <Unit name=\"{name}\"><BaseUnit{base}/></Unit>");
    }
    x.push_str("  </UnitDefinitions>\n");
}

/// `ModelVariables`: one element per variable of the table, in value-reference order (FMI 2.0
/// skips `time`).
fn model_variables(x: &mut String, model: &FmuModel, v3: bool) {
    x.push_str("  <ModelVariables>\n");
    let start = |var: &Variable| -> Option<f64> {
        match var.slot {
            Slot::Parameter(p, i) => Some(super::instance::parameter_value(
                model.arm.joints(),
                &Default::default(),
                p,
                i,
            )),
            Slot::MotorTorque(_) | Slot::BaseWrench(_) | Slot::WheelTorque(_) => Some(0.0),
            _ => None,
        }
    };
    for (vr, var) in model.table.variables.iter().enumerate() {
        if !v3 && var.causality == Causality::Independent {
            continue; // FMI 2.0 has no independent variable
        }
        let (causality, variability, initial) = match var.causality {
            Causality::Independent => ("independent", "continuous", ""),
            Causality::Parameter => ("parameter", "fixed", ""),
            Causality::Input => ("input", "continuous", ""),
            Causality::Output => ("output", "continuous", " initial=\"calculated\""),
        };
        let unit = var
            .unit
            .map_or(String::new(), |u| format!(" unit=\"{}\"", escape(u)));
        let start = start(var).map_or(String::new(), |s| format!(" start=\"{}\"", number(s)));
        let common = format!(
            "name=\"{}\" valueReference=\"{vr}\" description=\"{}\" causality=\"{causality}\" \
             variability=\"{variability}\"{initial}",
            escape(&var.name),
            escape(&var.description)
        );
        if v3 {
            let _ = writeln!(x, "    <Float64 {common}{start}{unit}/>");
        } else {
            let _ = writeln!(
                x,
                "    <ScalarVariable {common}><Real{start}{unit}/></ScalarVariable>"
            );
        }
    }
    x.push_str("  </ModelVariables>\n");
}

/// `ModelStructure`: every output, with no dependencies (no direct feedthrough), also as an
/// initial unknown.
fn model_structure(x: &mut String, model: &FmuModel, v3: bool) {
    x.push_str("  <ModelStructure>\n");
    let outputs: Vec<usize> = model
        .table
        .variables
        .iter()
        .enumerate()
        .filter(|(_, v)| v.causality == Causality::Output)
        .map(|(vr, _)| vr)
        .collect();
    if v3 {
        for vr in &outputs {
            let _ = writeln!(x, "    <Output valueReference=\"{vr}\" dependencies=\"\"/>");
        }
        for vr in &outputs {
            let _ = writeln!(x, "    <InitialUnknown valueReference=\"{vr}\"/>");
        }
    } else {
        // FMI 2.0 refers to variables by their 1-based position in ModelVariables; `time`
        // (value reference 0) is not listed, so position = value reference
        x.push_str("    <Outputs>\n");
        for vr in &outputs {
            let _ = writeln!(x, "      <Unknown index=\"{vr}\" dependencies=\"\"/>");
        }
        x.push_str("    </Outputs>\n    <InitialUnknowns>\n");
        for vr in &outputs {
            let _ = writeln!(x, "      <Unknown index=\"{vr}\"/>");
        }
        x.push_str("    </InitialUnknowns>\n");
    }
    x.push_str("  </ModelStructure>\n");
}

/// A number in its shortest round-trip form, as XML's `xs:double` reads it.
fn number(v: f64) -> String {
    format!("{v:?}")
}

/// Text for an XML attribute value.
fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            '\n' => out.push_str("&#10;"),
            '\r' => out.push_str("&#13;"),
            '\t' => out.push_str("&#9;"),
            c => out.push(c),
        }
    }
    out
}
