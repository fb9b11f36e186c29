//! The files of an FMI co-simulation FMU (`orbitflex fmu`, `orbitflex._core._fmu_files`): the
//! model description and the resources, made by [`crate::fmu::FmuModel`]. The Python side
//! zips them with the runtime library (`liborbitflex_c`).

use super::arm::PyFlexibleArm;
use crate::error::Error;
use crate::fmu::{FmiVersion, FmuModel};
use crate::model::UrdfOptions;
use pyo3::prelude::*;
use pyo3::types::PyBytes;

/// ``[(path in the archive, bytes)]`` of the FMU of ``arm`` (its joint parameters, bus,
/// reaction wheels and method), whose robot is ``urdf`` (text, loaded with ``ee_links`` and
/// ``locked_joints``) but for the base's inertia, stepping ``dt`` (s), for FMI ``fmi`` (2 or
/// 3); the binary is not among them.
#[pyfunction]
#[pyo3(name = "_fmu_files", signature = (urdf, arm, ee_links, locked_joints, dt, model_identifier, fmi))]
pub fn py_fmu_files<'py>(
    py: Python<'py>,
    urdf: &str,
    arm: &Bound<'py, PyFlexibleArm>,
    ee_links: Vec<String>,
    locked_joints: Vec<String>,
    dt: f64,
    model_identifier: &str,
    fmi: u32,
) -> PyResult<Vec<(String, Bound<'py, PyBytes>)>> {
    let version = match fmi {
        2 => FmiVersion::V2,
        3 => FmiVersion::V3,
        other => {
            return Err(Error::InvalidArgument {
                what: "fmi".into(),
                message: format!("expected 2 or 3, given {other}"),
            }
            .into())
        }
    };
    let options = UrdfOptions {
        ee_link: None,
        ee_links,
        locked_joints,
    };
    let model = FmuModel::of_arm(urdf, &options, &arm.get().arm, dt, model_identifier)?;
    Ok(model
        .files(version)
        .into_iter()
        .map(|(path, bytes)| (path, PyBytes::new(py, &bytes)))
        .collect())
}
