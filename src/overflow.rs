//! Results that overflow: finite inputs too large for floating point.
//!
//! Every public call checks that its inputs are finite; inputs that are finite but huge (a joint
//! rate of 1e200 rad/s, a step of 1e300 s) can still make the result overflow to infinity or NaN.
//! Each public call therefore scans its result once, at the end (never inside the recursions or
//! the RK4 stages, which run allocation-free and unchecked), and turns a non-finite result into
//! an [`Error::InvalidArgument`] naming the input that made it overflow.
//!
//! Which input? A result grows with each input raised to some power: the bias forces as the
//! square of the rates, the accelerations linearly with the torques and wrenches, a step's
//! Jacobians as the fourth power of the step. The input blamed is the one whose largest
//! magnitude, raised to its power, is largest.

use crate::error::{Error, Result};

/// An input of a call, for [`check_result`]: its name, its values, and the power of its size
/// that the result grows with.
pub(crate) type Input<'a> = (&'a str, &'a [f64], i32);

/// `Ok` when every number of `results` is finite; otherwise the error naming the input of
/// `inputs` that made the result of `call` overflow (the call's name alone when no input is
/// large).
#[inline]
pub(crate) fn check_result(call: &str, results: &[&[f64]], inputs: &[Input<'_>]) -> Result<()> {
    check_result_named(call, results, inputs, &|_, _| None)
}

/// [`check_result`], with `element(input, index)` naming an element of an input in the message
/// (`x[33]` is `qd[wrist_roll]`), or `None`.
#[inline]
pub(crate) fn check_result_named(
    call: &str,
    results: &[&[f64]],
    inputs: &[Input<'_>],
    element: &dyn Fn(&str, usize) -> Option<String>,
) -> Result<()> {
    if results.iter().all(|r| all_finite(r)) {
        return Ok(());
    }
    Err(overflow_error(call, results, inputs, element))
}

/// Whether every number is finite. A sum with an infinite or NaN term is never finite, so a
/// finite sum proves every term finite in one vectorised add per number (a derivative call's
/// result has hundreds, so the scan must cost well under a few instructions each); only a sum
/// that is not finite (a bad number, or huge finite ones that overflow together) is looked at
/// number by number.
#[inline]
pub(crate) fn all_finite(values: &[f64]) -> bool {
    let mut lanes = [0.0f64; 8];
    let mut chunks = values.chunks_exact(8);
    for chunk in &mut chunks {
        for (lane, v) in lanes.iter_mut().zip(chunk) {
            *lane += v;
        }
    }
    let sum = lanes.iter().sum::<f64>() + chunks.remainder().iter().sum::<f64>();
    sum.is_finite() || values.iter().all(|v| v.is_finite())
}

#[cold]
#[inline(never)]
fn overflow_error(
    call: &str,
    results: &[&[f64]],
    inputs: &[Input<'_>],
    element: &dyn Fn(&str, usize) -> Option<String>,
) -> Error {
    let total: usize = results.iter().map(|r| r.len()).sum();
    let bad: usize = results
        .iter()
        .map(|r| r.iter().filter(|v| !v.is_finite()).count())
        .sum();
    // log10 of the largest magnitude, times the power, per input
    let culprit = inputs
        .iter()
        .filter_map(|&(name, values, power)| {
            let (index, size) = values
                .iter()
                .map(|v| v.abs())
                .enumerate()
                .max_by(|a, b| a.1.total_cmp(&b.1))?;
            (size > 1.0).then(|| (name, index, size, power as f64 * size.log10()))
        })
        .max_by(|a, b| a.3.total_cmp(&b.3));
    let what = format!("{bad} of its {total} numbers are not finite");
    match culprit {
        Some((name, index, size, _)) => {
            let many = inputs
                .iter()
                .any(|(n, values, _)| *n == name && values.len() > 1);
            let element = match (many, element(name, index)) {
                (false, _) => String::new(),
                (true, None) => format!("[{index}]"),
                (true, Some(label)) => format!("[{index}] ({label})"),
            };
            Error::InvalidArgument {
                what: name.into(),
                message: format!(
                    "too large for floating point: the result of {call} overflowed ({what}) \
                     with {name}{element} = {}",
                    signed(inputs, name, index, size)
                ),
            }
        }
        None => Error::InvalidArgument {
            what: call.into(),
            message: format!("the result overflowed ({what})"),
        },
    }
}

/// The value of `name[index]` with its sign, for the message.
fn signed(inputs: &[Input<'_>], name: &str, index: usize, size: f64) -> String {
    let value = inputs
        .iter()
        .find(|(n, _, _)| *n == name)
        .map_or(size, |(_, values, _)| values[index]);
    crate::args::number(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finite_results_pass() {
        assert!(check_result("f", &[&[1.0, 2.0]], &[("qd", &[1e200], 2)]).is_ok());
    }

    #[test]
    fn any_non_finite_number_anywhere_is_found() {
        for len in [0, 1, 7, 8, 9, 17, 64] {
            let finite: Vec<f64> = (0..len).map(|i| (i as f64 - 3.0) * 1e300).collect();
            assert!(all_finite(&finite));
            for at in 0..len {
                for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
                    let mut v = finite.clone();
                    v[at] = bad;
                    assert!(!all_finite(&v), "{len} {at} {bad}");
                }
            }
        }
        // a sum of huge finite numbers overflows, but their differences are zeros
        assert!(all_finite(&[f64::MAX; 20]));
    }

    #[test]
    fn the_input_that_grows_fastest_is_named() {
        // qd² = 1e308 outweighs tau = 1e200
        let e = check_result(
            "forward_dynamics",
            &[&[f64::NAN, 1.0], &[f64::INFINITY]],
            &[("tau", &[0.0, 1e200], 1), ("qd", &[-1e154, 3.0], 2)],
        )
        .unwrap_err();
        assert_eq!(
            e.to_string(),
            "qd: too large for floating point: the result of forward_dynamics overflowed (2 of \
             its 3 numbers are not finite) with qd[0] = -1e154"
        );
        // a scalar is named without an index
        let inputs = [("dt", &[1e300][..], 4), ("x", &[0.0, 2.0][..], 2)];
        let e = check_result("step", &[&[f64::NAN]], &inputs).unwrap_err();
        assert!(
            e.to_string().starts_with("dt: too large") && e.to_string().ends_with(" dt = 1e300")
        );
        // the size counts to its power: 100⁴ = 1e8 is less than 1e50
        let inputs = [("dt", &[100.0][..], 4), ("u", &[1e50][..], 1)];
        let e = check_result("step", &[&[f64::NAN]], &inputs).unwrap_err();
        assert!(e.to_string().starts_with("u: too large"), "{e}");
        // nothing larger than 1 to blame: the call is named
        let e = check_result("energy", &[&[f64::NAN]], &[("x", &[0.5, 1.0], 2)]).unwrap_err();
        assert_eq!(
            e.to_string(),
            "energy: the result overflowed (1 of its 1 numbers are not finite)"
        );
    }
}
