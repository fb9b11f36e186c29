//! Frequency response `H(jω) = C (jωI − A)⁻¹ B + D` of a [`StateSpace`] by Laub's method: `A` is
//! balanced and reduced once to Hessenberg form, `D⁻¹ A D = Q H Qᵀ`, so that
//! `H(jω) = (C D Q) (jωI − H)⁻¹ (Qᵀ D⁻¹ B) + D`; each frequency then costs one LU factorisation of
//! the Hessenberg `jωI − H` with partial pivoting (`O(N²)`: only one subdiagonal to eliminate)
//! and a triangular solve per input (`O(N²)` each). No inverse is formed. (Laub, "Efficient
//! multivariable frequency response computations", IEEE TAC 26(2), 1981.)

use super::linear::StateSpace;
use crate::error::{Error, Result};
use nalgebra::{Complex, DMatrix};

type C64 = Complex<f64>;

/// `A`, `B`, `C`, `D` of a state-space model in the Hessenberg coordinates of Laub's method,
/// ready to be evaluated at any frequency ([`HessenbergForm::evaluate`]).
#[derive(Debug, Clone)]
pub struct HessenbergForm {
    /// `H = Qᵀ D⁻¹ A D Q`, upper Hessenberg.
    h: DMatrix<f64>,
    /// `Qᵀ D⁻¹ B`.
    b: DMatrix<f64>,
    /// `C D Q`.
    c: DMatrix<f64>,
    d: DMatrix<f64>,
}

impl HessenbergForm {
    /// Balances and reduces `ss.a` (`O(N³)`, once).
    pub fn new(ss: &StateSpace) -> Self {
        let size = ss.a.nrows();
        if size == 0 {
            return Self {
                h: ss.a.clone(),
                b: ss.b.clone(),
                c: ss.c.clone(),
                d: ss.d.clone(),
            };
        }
        let mut a = ss.a.clone();
        let scale = crate::linalg::balance(&mut a);
        let (q, h) = nalgebra::linalg::Hessenberg::new(a).unpack();
        let scaled_b = DMatrix::from_fn(size, ss.b.ncols(), |r, c| ss.b[(r, c)] / scale[r]);
        let scaled_c = DMatrix::from_fn(ss.c.nrows(), size, |r, c| ss.c[(r, c)] * scale[c]);
        Self {
            h,
            b: q.transpose() * scaled_b,
            c: scaled_c * q,
            d: ss.d.clone(),
        }
    }

    /// `H(jω)` at `omega` (rad/s) into `out` (outputs × inputs, column-major), with the buffers
    /// `lu` (N × N) and `x` (N × inputs). Errs when `jωI − A` is singular (a pole at `jω`).
    fn evaluate_into(
        &self,
        omega: f64,
        lu: &mut DMatrix<C64>,
        x: &mut DMatrix<C64>,
        out: &mut DMatrix<C64>,
    ) -> std::result::Result<(), ()> {
        let size = self.h.nrows();
        let inputs = self.b.ncols();
        let s = C64::new(0.0, omega);
        for c in 0..size {
            for r in 0..size {
                // only the Hessenberg band is read below
                lu[(r, c)] = if r <= c + 1 {
                    C64::new(-self.h[(r, c)], 0.0)
                } else {
                    C64::new(0.0, 0.0)
                };
            }
            lu[(c, c)] += s;
        }
        for c in 0..inputs {
            for r in 0..size {
                x[(r, c)] = C64::new(self.b[(r, c)], 0.0);
            }
        }
        // elimination of the subdiagonal, with the larger of rows k, k+1 as pivot
        for k in 0..size.saturating_sub(1) {
            if lu[(k + 1, k)].norm() > lu[(k, k)].norm() {
                lu.swap_rows(k, k + 1);
                x.swap_rows(k, k + 1);
            }
            let pivot = lu[(k, k)];
            if pivot.norm() == 0.0 {
                continue; // the subdiagonal is zero too: nothing to eliminate
            }
            let factor = lu[(k + 1, k)] / pivot;
            if factor.norm() == 0.0 {
                continue;
            }
            for c in k + 1..size {
                let v = lu[(k, c)];
                lu[(k + 1, c)] -= factor * v;
            }
            for c in 0..inputs {
                let v = x[(k, c)];
                x[(k + 1, c)] -= factor * v;
            }
        }
        // back-substitution in the upper triangle
        for c in 0..inputs {
            for r in (0..size).rev() {
                let mut sum = x[(r, c)];
                for k in r + 1..size {
                    sum -= lu[(r, k)] * x[(k, c)];
                }
                let pivot = lu[(r, r)];
                if pivot.norm() == 0.0 {
                    return Err(());
                }
                x[(r, c)] = sum / pivot;
            }
        }
        for i in 0..inputs {
            for o in 0..self.c.nrows() {
                let mut sum = C64::new(self.d[(o, i)], 0.0);
                for r in 0..size {
                    sum += x[(r, i)] * self.c[(o, r)];
                }
                out[(o, i)] = sum;
            }
        }
        Ok(())
    }

    /// `H(j 2π f)` for each frequency `f` of `freqs_hz` (Hz, finite, ≥ 0): one outputs × inputs
    /// matrix per frequency.
    pub fn evaluate(&self, freqs_hz: &[f64]) -> Result<Vec<DMatrix<C64>>> {
        crate::args::check_finite("freqs_hz", freqs_hz)?;
        if let Some(i) = freqs_hz.iter().position(|f| *f < 0.0) {
            return Err(Error::InvalidArgument {
                what: "freqs_hz".into(),
                message: format!("element {i} is {} Hz; expected ≥ 0", freqs_hz[i]),
            });
        }
        let size = self.h.nrows();
        let (outputs, inputs) = (self.c.nrows(), self.b.ncols());
        let zero = C64::new(0.0, 0.0);
        let mut lu = DMatrix::from_element(size, size, zero);
        let mut x = DMatrix::from_element(size, inputs, zero);
        let mut result = Vec::with_capacity(freqs_hz.len());
        for (i, &f) in freqs_hz.iter().enumerate() {
            let mut out = DMatrix::from_element(outputs, inputs, zero);
            let finite = self
                .evaluate_into(std::f64::consts::TAU * f, &mut lu, &mut x, &mut out)
                .is_ok()
                && out.iter().all(|v| v.re.is_finite() && v.im.is_finite());
            if !finite {
                return Err(Error::InvalidArgument {
                    what: "freqs_hz".into(),
                    message: format!(
                        "element {i} ({f} Hz) is a pole of the model: jωI − A is singular there \
                         (at 0 Hz: a rigid-body mode, a free base or free motors); leave it out"
                    ),
                });
            }
            result.push(out);
        }
        Ok(result)
    }
}

/// `H(j 2π f) = C (j 2π f I − A)⁻¹ B + D` of `ss` at each frequency of `freqs_hz` (Hz): one
/// outputs × inputs matrix per frequency ([`HessenbergForm`]).
///
/// ```
/// use orbitflex::analysis::{frequency_response, state_space, InputGroup, LinearSpec, OutputGroup};
/// use orbitflex::planning::BaseMode;
/// use orbitflex::{FlexibleArm, FlexibleJoints, Robot};
/// let arm = FlexibleArm::new(Robot::space_arm(), FlexibleJoints::space_arm())?;
/// let spec = LinearSpec {
///     base: BaseMode::Held,
///     inputs: &[InputGroup::MotorTorque],
///     outputs: &[OutputGroup::Q],
///     ..LinearSpec::default()
/// };
/// let ss = state_space(&arm, &mut arm.workspace(), &arm.rest_state(), &spec)?;
/// let h = frequency_response(&ss, &[0.1, 1.0, 10.0])?;
/// assert_eq!((h.len(), h[0].nrows(), h[0].ncols()), (3, 7, 7));
/// # Ok::<(), orbitflex::Error>(())
/// ```
pub fn frequency_response(ss: &StateSpace, freqs_hz: &[f64]) -> Result<Vec<DMatrix<C64>>> {
    HessenbergForm::new(ss).evaluate(freqs_hz)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// At 0 Hz, `−A` of two undamped oscillators has zeros on its diagonal: the elimination must
    /// exchange rows k and k+1 to solve it; without the exchange it would report a pole that is
    /// not there. The result equals `C (−A)⁻¹ B` in closed form.
    #[test]
    fn zero_diagonal_needs_the_row_exchange() {
        // ẍ₁ = −4 x₁ + u₁ and ẍ₂ = −9 x₂ + u₂, the outputs x₁, x₂
        let a = DMatrix::from_row_slice(
            4,
            4,
            &[
                0.0, 1.0, 0.0, 0.0, //
                -4.0, 0.0, 0.0, 0.0, //
                0.0, 0.0, 0.0, 1.0, //
                0.0, 0.0, -9.0, 0.0,
            ],
        );
        let b = DMatrix::from_row_slice(4, 2, &[0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        let c = DMatrix::from_row_slice(2, 4, &[1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
        let ss = StateSpace {
            a,
            b,
            c,
            d: DMatrix::zeros(2, 2),
            states: vec![],
            inputs: vec![],
            outputs: vec![],
            tangent_index: vec![],
        };
        // static gains 1/4 and 1/9; at 1/(2π) Hz (ω = 1): 1/(4 − 1), 1/(9 − 1)
        let h = frequency_response(&ss, &[0.0, 1.0 / std::f64::consts::TAU]).unwrap();
        for (m, (g1, g2)) in h.iter().zip([(0.25, 1.0 / 9.0), (1.0 / 3.0, 0.125)]) {
            assert!((m[(0, 0)] - C64::new(g1, 0.0)).norm() < 1e-15);
            assert!((m[(1, 1)] - C64::new(g2, 0.0)).norm() < 1e-15);
            assert!(m[(0, 1)].norm() < 1e-15 && m[(1, 0)].norm() < 1e-15);
        }
        // at ω = 2 the first oscillator has its pole
        let err = frequency_response(&ss, &[1.0 / std::f64::consts::PI]).unwrap_err();
        assert!(err.to_string().contains("is a pole"), "{err}");
    }
}
