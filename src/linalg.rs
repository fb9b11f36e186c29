//! Eigenvalues and eigenvectors of a real, non-symmetric matrix: balancing, Hessenberg
//! reduction, the Francis double-shift QR iteration with exceptional shifts to the real Schur form
//! `A = Z T Zᵀ`, and back-substitution in the quasi-triangular `T` for the eigenvectors (the
//! EISPACK `hqr2` algorithm). Also the matrix–vector kernel of the derivative chains
//! (`scaled_product`).
//!
//! nalgebra's `complex_eigenvalues` runs the same QR iteration without exceptional shifts and
//! without an iteration limit: on the step matrices of a free-floating arm, whose eigenvalues
//! cluster at 1, it can loop for ever. This version takes an exceptional shift every ten
//! iterations without a deflation, and gives up (and says so) after as many iterations as
//! LAPACK allows.

use nalgebra::{Complex, DMatrix};

/// `out = scale · A w` for `A` stored column by column (`rows` per column, `w.len()` columns)
/// in `a`: the inner product of the derivative chains, whose matrices are too small for a
/// packing GEMM to pay.
///
/// On x86-64 processors with AVX2 (detected at run time; `ORBITFLEX_PORTABLE` turns it off, see
/// `crate::simd`) the same code runs compiled for 256-bit registers. It multiplies and adds separately (no fused multiply-add) in the same
/// order, so both versions give the same bits.
pub(crate) fn scaled_product(scale: f64, a: &[f64], rows: usize, w: &[f64], out: &mut [f64]) {
    assert_eq!(
        a.len(),
        rows * w.len(),
        "scaled_product: A has rows × w.len() entries"
    );
    assert_eq!(
        out.len(),
        rows,
        "scaled_product: out has one entry per row of A"
    );
    #[cfg(target_arch = "x86_64")]
    if crate::simd::avx2() {
        // SAFETY: the processor has AVX2 (`simd::avx2` checks it), checked just above.
        unsafe { scaled_product_avx2(scale, a, rows, w, out) };
        return;
    }
    scaled_product_kernel(scale, a, rows, w, out);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn scaled_product_avx2(scale: f64, a: &[f64], rows: usize, w: &[f64], out: &mut [f64]) {
    scaled_product_kernel(scale, a, rows, w, out);
}

/// Eight rows at a time (then four, then one) are summed in registers over the columns, so each
/// output is written once.
#[inline(always)]
fn scaled_product_kernel(scale: f64, a: &[f64], rows: usize, w: &[f64], out: &mut [f64]) {
    let mut r = 0;
    while r + 8 <= rows {
        rows_block::<8>(scale, a, rows, w, r, out);
        r += 8;
    }
    if r + 4 <= rows {
        rows_block::<4>(scale, a, rows, w, r, out);
        r += 4;
    }
    while r < rows {
        rows_block::<1>(scale, a, rows, w, r, out);
        r += 1;
    }
}

/// Rows `r..r + B` of `out = scale · A w`.
#[inline(always)]
fn rows_block<const B: usize>(
    scale: f64,
    a: &[f64],
    rows: usize,
    w: &[f64],
    r: usize,
    out: &mut [f64],
) {
    let mut sum = [0.0; B];
    for (&weight, column) in w.iter().zip(a.chunks_exact(rows)) {
        for (s, x) in sum.iter_mut().zip(&column[r..r + B]) {
            *s += weight * x;
        }
    }
    for (o, s) in out[r..r + B].iter_mut().zip(sum) {
        *o = scale * s;
    }
}

/// Iterations allowed per deflation, as LAPACK allows: 30 per row of the matrix (at least 300).
fn max_iterations(n: usize) -> usize {
    30 * n.max(10)
}

/// The eigenvalues of the square matrix `a`, in no particular order, or `None` when the
/// iteration does not converge (or `a` holds non-finite numbers).
///
/// ```
/// use nalgebra::DMatrix;
/// // a rotation by 90° and a scaling by 3: eigenvalues ±i and 3
/// let a = DMatrix::from_row_slice(3, 3, &[0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 3.0]);
/// let mut ev = orbitflex::linalg::eigenvalues(&a).unwrap();
/// ev.sort_by(|x, y| x.re.total_cmp(&y.re).then(x.im.total_cmp(&y.im)));
/// assert!((ev[0].im + 1.0).abs() < 1e-14 && (ev[1].im - 1.0).abs() < 1e-14);
/// assert!((ev[2].re - 3.0).abs() < 1e-14);
/// ```
pub fn eigenvalues(a: &DMatrix<f64>) -> Option<Vec<Complex<f64>>> {
    assert!(a.is_square(), "eigenvalues of a non-square matrix");
    if a.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let n = a.nrows();
    if n == 0 {
        return Some(Vec::new());
    }
    let mut b = a.clone();
    balance(&mut b);
    let mut h = nalgebra::linalg::Hessenberg::new(b).h();
    francis(&mut h, None)
}

/// The eigenvalues of a real square matrix and a right eigenvector for each: `A v_j = λ_j v_j`.
#[derive(Debug, Clone, PartialEq)]
pub struct Eigen {
    /// The eigenvalues; complex ones come in conjugate pairs, the one with positive imaginary
    /// part first.
    pub values: Vec<Complex<f64>>,
    /// Column `j` is an eigenvector of `values[j]`, of unit 2-norm (conjugate pairs have
    /// conjugate vectors).
    pub vectors: DMatrix<Complex<f64>>,
}

/// The eigenvalues and right eigenvectors of the square matrix `a`, or `None` when the QR
/// iteration does not converge within its bound (30 iterations per row, as LAPACK allows) or `a`
/// holds non-finite numbers.
///
/// Balancing `D⁻¹ A D` (exact powers of two), the Hessenberg reduction `Q H Qᵀ`, the Francis
/// iteration to the real Schur form `H = Z' T Z'ᵀ` with its rotations accumulated, then the
/// eigenvectors `y` of the quasi-triangular `T` by back-substitution, and `v = D Q Z' y`. For a
/// defective eigenvalue (a Jordan block, as a floating base's rigid-body modes give) the
/// computed vectors of the block are nearly parallel: the eigenvalues are then accurate only to
/// about `√ε ‖A‖`, as with any backward-stable method.
///
/// ```
/// use nalgebra::DMatrix;
/// // a rotation by 90° and a scaling by 3
/// let a = DMatrix::from_row_slice(3, 3, &[0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 3.0]);
/// let e = orbitflex::linalg::eigen(&a).unwrap();
/// for (j, lambda) in e.values.iter().enumerate() {
///     let v = e.vectors.column(j);
///     let residual = a.map(|x| nalgebra::Complex::new(x, 0.0)) * v - v * *lambda;
///     assert!(residual.norm() < 1e-14);
/// }
/// ```
pub fn eigen(a: &DMatrix<f64>) -> Option<Eigen> {
    assert!(a.is_square(), "eigen of a non-square matrix");
    if a.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let n = a.nrows();
    if n == 0 {
        return Some(Eigen {
            values: Vec::new(),
            vectors: DMatrix::zeros(0, 0),
        });
    }
    let mut b = a.clone();
    let scale = balance(&mut b);
    let (mut z, mut t) = nalgebra::linalg::Hessenberg::new(b).unpack();
    let values = francis(&mut t, Some(&mut z))?;
    let y = schur_vectors(&mut t, &values);
    // v = D Z y, then each to unit norm
    let zy = z * y;
    let mut vectors = DMatrix::from_element(n, n, Complex::new(0.0, 0.0));
    let mut j = 0;
    while j < n {
        let lambda = values[j];
        if lambda.im == 0.0 {
            for i in 0..n {
                vectors[(i, j)] = Complex::new(scale[i] * zy[(i, j)], 0.0);
            }
            j += 1;
        } else {
            // columns j, j+1 of y hold the real and imaginary parts of the vector of the
            // eigenvalue with positive imaginary part (stored first)
            for i in 0..n {
                let v = Complex::new(scale[i] * zy[(i, j)], scale[i] * zy[(i, j + 1)]);
                vectors[(i, j)] = v;
                vectors[(i, j + 1)] = v.conj();
            }
            j += 2;
        }
    }
    for mut column in vectors.column_iter_mut() {
        let norm = column.iter().map(|c| c.norm_sqr()).sum::<f64>().sqrt();
        if norm > 0.0 {
            column.iter_mut().for_each(|c| *c /= norm);
        }
    }
    Some(Eigen { values, vectors })
}

/// Scales rows and columns by powers of two (a diagonal similarity `D⁻¹ A D`, exact in floating
/// point) so that each row and its column have similar norms; this improves the accuracy of the
/// eigenvalues of badly scaled matrices. Returns `D`'s diagonal.
pub(crate) fn balance(a: &mut DMatrix<f64>) -> Vec<f64> {
    let n = a.nrows();
    let radix = 2.0_f64;
    let mut scale = vec![1.0; n];
    let mut done = false;
    while !done {
        done = true;
        for i in 0..n {
            let (mut r, mut c) = (0.0, 0.0);
            for j in (0..n).filter(|&j| j != i) {
                c += a[(j, i)].abs();
                r += a[(i, j)].abs();
            }
            if c == 0.0 || r == 0.0 {
                continue;
            }
            let (mut g, mut f, s) = (r / radix, 1.0, c + r);
            while c < g {
                f *= radix;
                c *= radix * radix;
            }
            g = r * radix;
            while c > g {
                f /= radix;
                c /= radix * radix;
            }
            if (c + r) / f < 0.95 * s {
                done = false;
                scale[i] *= f;
                let g = 1.0 / f;
                for j in 0..n {
                    a[(i, j)] *= g;
                }
                for j in 0..n {
                    a[(j, i)] *= f;
                }
            }
        }
    }
    scale
}

/// `|a|` with the sign of `b`.
fn with_sign(a: f64, b: f64) -> f64 {
    if b >= 0.0 {
        a.abs()
    } else {
        -a.abs()
    }
}

/// The eigenvalues of an upper Hessenberg matrix by the Francis double-shift QR iteration on
/// its active block, deflating one or two eigenvalues at a time.
///
/// With `z` (the Hessenberg reduction's `Q` on entry), the transformations are applied to the
/// whole matrix and accumulated into `z`, so that `h` ends in real Schur form `T` (2×2 blocks
/// for complex pairs only, the real pairs split by a rotation) with `A = z T zᵀ`. Without it
/// only the active block is updated, which is all the eigenvalues need.
#[allow(clippy::many_single_char_names)]
fn francis(h: &mut DMatrix<f64>, mut z: Option<&mut DMatrix<f64>>) -> Option<Vec<Complex<f64>>> {
    let n = h.nrows();
    let mut out = vec![Complex::new(0.0, 0.0); n];
    let norm = hessenberg_norm(h);
    // `last` is the index of the bottom row of the active block; `shift` accumulates the
    // exceptional shifts applied to the diagonal.
    let mut last = n as isize - 1;
    let mut shift = 0.0;
    while last >= 0 {
        let nn = last as usize;
        let mut iterations = 0;
        loop {
            // The top of the active block: the lowest negligible subdiagonal element.
            let mut l = nn;
            while l >= 1 {
                let mut s = h[(l - 1, l - 1)].abs() + h[(l, l)].abs();
                if s == 0.0 {
                    s = norm;
                }
                if h[(l, l - 1)].abs() + s == s {
                    h[(l, l - 1)] = 0.0;
                    break;
                }
                l -= 1;
            }
            let x = h[(nn, nn)];
            if l == nn {
                // one real eigenvalue deflates
                out[nn] = Complex::new(x + shift, 0.0);
                h[(nn, nn)] = x + shift;
                last -= 1;
                break;
            }
            let y = h[(nn - 1, nn - 1)];
            let w = h[(nn, nn - 1)] * h[(nn - 1, nn)];
            if l == nn - 1 {
                // a 2×2 block deflates: two real eigenvalues or a complex pair
                let p = 0.5 * (y - x);
                let q = p * p + w;
                let zz = q.abs().sqrt();
                let x = x + shift;
                h[(nn, nn)] = x;
                h[(nn - 1, nn - 1)] = y + shift;
                if q >= 0.0 {
                    let zz = p + with_sign(zz, p);
                    out[nn - 1] = Complex::new(x + zz, 0.0);
                    out[nn] = Complex::new(if zz != 0.0 { x - w / zz } else { x + zz }, 0.0);
                    if let Some(z) = z.as_deref_mut() {
                        split_real_pair(h, z, nn, zz);
                    }
                } else {
                    out[nn - 1] = Complex::new(x + p, zz);
                    out[nn] = Complex::new(x + p, -zz);
                }
                last -= 2;
                break;
            }
            if iterations == max_iterations(n) {
                return None;
            }
            let (mut x, mut y, mut w) = (x, y, w);
            if iterations > 0 && iterations % 10 == 0 {
                // exceptional shift, to break a cycle
                shift += x;
                for i in 0..=nn {
                    h[(i, i)] -= x;
                }
                let s = h[(nn, nn - 1)].abs() + h[(nn - 1, nn - 2)].abs();
                x = 0.75 * s;
                y = x;
                w = -0.4375 * s * s;
            }
            iterations += 1;
            double_shift_step(h, z.as_deref_mut(), l, nn, x, y, w);
        }
    }
    Some(out)
}

/// `Σ |h_ij|` over the Hessenberg band.
fn hessenberg_norm(h: &DMatrix<f64>) -> f64 {
    let n = h.nrows();
    (0..n)
        .flat_map(|i| (i.saturating_sub(1)..n).map(move |j| (i, j)))
        .map(|(i, j)| h[(i, j)].abs())
        .sum()
}

/// Turns the deflated 2×2 block at rows `nn − 1, nn` with two real eigenvalues into upper
/// triangular form by a rotation applied to the whole matrix and accumulated in `z` (`zz` is the
/// `p ± √q` of the deflation).
fn split_real_pair(h: &mut DMatrix<f64>, z: &mut DMatrix<f64>, nn: usize, zz: f64) {
    let n = h.nrows();
    let x = h[(nn, nn - 1)];
    let s = x.abs() + zz.abs();
    let (mut p, mut q) = (x / s, zz / s);
    let r = (p * p + q * q).sqrt();
    p /= r;
    q /= r;
    for j in nn - 1..n {
        let a = h[(nn - 1, j)];
        h[(nn - 1, j)] = q * a + p * h[(nn, j)];
        h[(nn, j)] = q * h[(nn, j)] - p * a;
    }
    for i in 0..=nn {
        let a = h[(i, nn - 1)];
        h[(i, nn - 1)] = q * a + p * h[(i, nn)];
        h[(i, nn)] = q * h[(i, nn)] - p * a;
    }
    for i in 0..n {
        let a = z[(i, nn - 1)];
        z[(i, nn - 1)] = q * a + p * z[(i, nn)];
        z[(i, nn)] = q * z[(i, nn)] - p * a;
    }
    h[(nn, nn - 1)] = 0.0;
}

/// One implicit double-shift QR step (the Francis step: EISPACK `hqr`, Golub and Van
/// Loan's Algorithm 7.5.1) on rows and columns `l..=nn` of the Hessenberg matrix `h`,
/// with the shifts given by `x = h[nn][nn]`, `y = h[nn-1][nn-1]` and
/// `w = h[nn][nn-1] h[nn-1][nn]`. It starts where two consecutive subdiagonal elements are
/// small enough to split the block. With `z`, the reflections also update the rows right of
/// the block and the columns above it, and are accumulated into `z`.
#[allow(clippy::many_single_char_names)]
fn double_shift_step(
    h: &mut DMatrix<f64>,
    mut z: Option<&mut DMatrix<f64>>,
    l: usize,
    nn: usize,
    x: f64,
    y: f64,
    w: f64,
) {
    let n = h.nrows();
    let (row_end, column_start) = if z.is_some() { (n - 1, 0) } else { (nn, l) };
    let (mut p, mut q, mut r);
    let mut m = nn - 2;
    loop {
        let zm = h[(m, m)];
        let rr = x - zm;
        let s = y - zm;
        p = (rr * s - w) / h[(m + 1, m)] + h[(m, m + 1)];
        q = h[(m + 1, m + 1)] - zm - rr - s;
        r = h[(m + 2, m + 1)];
        let scale = p.abs() + q.abs() + r.abs();
        if scale > 0.0 {
            p /= scale;
            q /= scale;
            r /= scale;
        }
        if m == l {
            break;
        }
        let u = h[(m, m - 1)].abs() * (q.abs() + r.abs());
        let v = p.abs() * (h[(m - 1, m - 1)].abs() + zm.abs() + h[(m + 1, m + 1)].abs());
        if u + v == v {
            break;
        }
        m -= 1;
    }
    for i in m + 2..=nn {
        h[(i, i - 2)] = 0.0;
        if i != m + 2 {
            h[(i, i - 3)] = 0.0;
        }
    }
    let mut xk = 0.0;
    for k in m..nn {
        if k != m {
            p = h[(k, k - 1)];
            q = h[(k + 1, k - 1)];
            r = if k != nn - 1 { h[(k + 2, k - 1)] } else { 0.0 };
            xk = p.abs() + q.abs() + r.abs();
            if xk != 0.0 {
                p /= xk;
                q /= xk;
                r /= xk;
            }
        }
        let s = with_sign((p * p + q * q + r * r).sqrt(), p);
        if s == 0.0 {
            continue;
        }
        if k == m {
            if l != m {
                h[(k, k - 1)] = -h[(k, k - 1)];
            }
        } else {
            h[(k, k - 1)] = -s * xk;
        }
        p += s;
        let (a, b, c) = (p / s, q / s, r / s);
        q /= p;
        r /= p;
        // rows k, k+1, k+2
        for j in k..=row_end {
            let mut t = h[(k, j)] + q * h[(k + 1, j)];
            if k != nn - 1 {
                t += r * h[(k + 2, j)];
                h[(k + 2, j)] -= t * c;
            }
            h[(k + 1, j)] -= t * b;
            h[(k, j)] -= t * a;
        }
        // columns k, k+1, k+2
        let bottom = nn.min(k + 3);
        for i in column_start..=bottom {
            let mut t = a * h[(i, k)] + b * h[(i, k + 1)];
            if k != nn - 1 {
                t += c * h[(i, k + 2)];
                h[(i, k + 2)] -= t * r;
            }
            h[(i, k + 1)] -= t * q;
            h[(i, k)] -= t;
        }
        if let Some(z) = z.as_deref_mut() {
            for i in 0..n {
                let mut t = a * z[(i, k)] + b * z[(i, k + 1)];
                if k != nn - 1 {
                    t += c * z[(i, k + 2)];
                    z[(i, k + 2)] -= t * r;
                }
                z[(i, k + 1)] -= t * q;
                z[(i, k)] -= t;
            }
        }
    }
}

/// The eigenvectors of the real Schur form `t` (quasi-upper-triangular, 2×2 blocks for the
/// complex pairs `values`), by back-substitution from the bottom: column `j` for a real
/// eigenvalue; columns `j`, `j + 1` the real and imaginary parts of the vector of `values[j]`
/// (positive imaginary part) for a pair. A zero pivot (a repeated eigenvalue) is replaced by
/// `ε ‖T‖`, and columns are rescaled when they grow past `1/√ε`, as EISPACK's `hqr2` does. `t`
/// is overwritten.
#[allow(clippy::many_single_char_names)]
fn schur_vectors(t: &mut DMatrix<f64>, values: &[Complex<f64>]) -> DMatrix<f64> {
    let n = t.nrows();
    let eps = f64::EPSILON;
    let norm = hessenberg_norm(t);
    let mut y = DMatrix::zeros(n, n);
    if norm == 0.0 {
        // the zero matrix: every unit vector is an eigenvector
        return DMatrix::identity(n, n);
    }
    let mut nn = n;
    while nn > 0 {
        let j = nn - 1;
        let (p, q) = (values[j].re, values[j].im);
        if q == 0.0 {
            // real eigenvalue p: solve (T − p) y = 0 with y_j = 1, upwards
            y[(j, j)] = 1.0;
            let mut i = j;
            while i > 0 {
                i -= 1;
                if values[i].im < 0.0 {
                    // rows i − 1, i: a 2×2 block (solved when i − 1 is reached; a pair's
                    // second eigenvalue is never at row 0)
                    continue;
                }
                if values[i].im > 0.0 {
                    // rows i, i + 1 form a 2×2 block
                    let (w, x, yy, zz) = (
                        t[(i, i)] - p,
                        t[(i, i + 1)],
                        t[(i + 1, i)],
                        t[(i + 1, i + 1)] - p,
                    );
                    let r = (i + 2..=j).map(|k| t[(i, k)] * y[(k, j)]).sum::<f64>();
                    let s = (i + 2..=j).map(|k| t[(i + 1, k)] * y[(k, j)]).sum::<f64>();
                    // [w x; yy zz] [a; b] = −[r; s]
                    let det = w * zz - x * yy;
                    let det = if det == 0.0 { eps * norm } else { det };
                    y[(i, j)] = (-r * zz + s * x) / det;
                    y[(i + 1, j)] = (-s * w + r * yy) / det;
                } else {
                    let r = (i + 1..=j).map(|k| t[(i, k)] * y[(k, j)]).sum::<f64>();
                    let w = t[(i, i)] - p;
                    let w = if w == 0.0 { eps * norm } else { w };
                    y[(i, j)] = -r / w;
                }
                rescale(&mut y, i, j, j, None);
            }
            nn -= 1;
        } else {
            // the pair at rows j − 1, j: values[j − 1] = p' + i q' with q' > 0
            let jr = j - 1;
            solve_pair(t, &mut y, values, jr, eps * norm);
            nn -= 2;
        }
    }
    y
}

/// The eigenvector of the complex pair at rows `jr`, `jr + 1` of `t`, for the eigenvalue
/// `values[jr]` (positive imaginary part), into columns `jr` (real part) and `jr + 1` (imaginary
/// part) of `y`, by complex back-substitution; `tiny` replaces a zero pivot.
fn solve_pair(
    t: &DMatrix<f64>,
    y: &mut DMatrix<f64>,
    values: &[Complex<f64>],
    jr: usize,
    tiny: f64,
) {
    type C = Complex<f64>;
    let (ji, lambda) = (jr + 1, values[jr]);
    let get = |y: &DMatrix<f64>, k: usize| C::new(y[(k, jr)], y[(k, ji)]);
    let set = |y: &mut DMatrix<f64>, k: usize, v: C| {
        y[(k, jr)] = v.re;
        y[(k, ji)] = v.im;
    };
    // the 2×2 block [a b; c d] (v_ji = 1): c v_jr + (d − λ) = 0
    let (a, b, c, d) = (t[(jr, jr)], t[(jr, ji)], t[(ji, jr)], t[(ji, ji)]);
    if c.abs() > b.abs() {
        set(y, jr, (lambda - d) / c);
        set(y, ji, C::new(1.0, 0.0));
    } else {
        // (a − λ) v_jr + b v_ji = 0 with v_jr = 1 … scaled: v_jr = b, v_ji = λ − a
        set(y, jr, C::new(b, 0.0));
        set(y, ji, lambda - a);
    }
    let mut i = jr;
    while i > 0 {
        i -= 1;
        let sum = |y: &DMatrix<f64>, row: usize, from: usize| -> C {
            (from..=ji).fold(C::new(0.0, 0.0), |acc, k| acc + get(y, k) * t[(row, k)])
        };
        if values[i].im < 0.0 {
            // rows i − 1, i: a 2×2 block, solved when i − 1 is reached
            continue;
        }
        if values[i].im > 0.0 {
            // rows i, i + 1: a 2×2 block of another pair: solve the 2×2 complex system
            let r = sum(y, i, i + 2);
            let s = sum(y, i + 1, i + 2);
            let (w, x, yy, zz) = (
                C::new(t[(i, i)], 0.0) - lambda,
                C::new(t[(i, i + 1)], 0.0),
                C::new(t[(i + 1, i)], 0.0),
                C::new(t[(i + 1, i + 1)], 0.0) - lambda,
            );
            let mut det = w * zz - x * yy;
            if det.norm() == 0.0 {
                det = C::new(tiny, 0.0);
            }
            set(y, i, (-r * zz + s * x) / det);
            set(y, i + 1, (-s * w + r * yy) / det);
        } else {
            let r = sum(y, i, i + 1);
            let mut w = C::new(t[(i, i)], 0.0) - lambda;
            if w.norm() == 0.0 {
                w = C::new(tiny, 0.0);
            }
            set(y, i, -r / w);
        }
        rescale(y, i, jr, ji, Some(()));
    }
}

/// Divides rows `from..` of column `j` (and `j2` for a pair) by their largest entry when it grows
/// past `1/√ε`, so that the back-substitution cannot overflow.
fn rescale(y: &mut DMatrix<f64>, from: usize, j: usize, j2: usize, pair: Option<()>) {
    let n = y.nrows();
    let mut t = 0.0_f64;
    for k in from..n {
        t = t.max(y[(k, j)].abs());
        if pair.is_some() {
            t = t.max(y[(k, j2)].abs());
        }
    }
    if f64::EPSILON * t * t > 1.0 {
        for k in 0..n {
            y[(k, j)] /= t;
            if pair.is_some() {
                y[(k, j2)] /= t;
            }
        }
    }
}
#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// `scale · A w` against the textbook sum, for every row count the blocks split
    /// differently (8, 4 and single rows), and the AVX2 build against the portable one bit for bit.
    #[test]
    fn scaled_product_is_the_matrix_vector_product() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for rows in [1, 3, 4, 5, 8, 12, 13, 17, 60] {
            for columns in [1, 2, 7] {
                let a: Vec<f64> = (0..rows * columns)
                    .map(|_| rng.gen_range(-1.0..1.0))
                    .collect();
                let w: Vec<f64> = (0..columns).map(|_| rng.gen_range(-1.0..1.0)).collect();
                let mut out = vec![f64::NAN; rows];
                scaled_product(-2.5, &a, rows, &w, &mut out);
                for (r, value) in out.iter().enumerate() {
                    let want: f64 =
                        (0..columns).map(|c| a[c * rows + r] * w[c]).sum::<f64>() * -2.5;
                    assert!(
                        (value - want).abs() <= 1e-14,
                        "rows {rows}, columns {columns}, row {r}"
                    );
                }
                let mut portable = vec![f64::NAN; rows];
                scaled_product_kernel(-2.5, &a, rows, &w, &mut portable);
                assert_eq!(out, portable);
            }
        }
    }

    fn sorted(mut v: Vec<Complex<f64>>) -> Vec<Complex<f64>> {
        v.sort_by(|a, b| a.re.total_cmp(&b.re).then(a.im.total_cmp(&b.im)));
        v
    }

    fn random(rng: &mut ChaCha8Rng, n: usize) -> DMatrix<f64> {
        DMatrix::from_fn(n, n, |_, _| rng.gen_range(-1.0..1.0))
    }

    /// A random orthogonal matrix (QR of a random matrix).
    fn orthogonal(rng: &mut ChaCha8Rng, n: usize) -> DMatrix<f64> {
        random(rng, n).qr().q()
    }

    #[test]
    fn symmetric_matrices_match_the_symmetric_solver() {
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        for n in 1..30 {
            let a = random(&mut rng, n);
            let s = &a + a.transpose();
            let mut want: Vec<f64> = s.clone().symmetric_eigenvalues().iter().copied().collect();
            want.sort_by(f64::total_cmp);
            let got = sorted(eigenvalues(&s).unwrap());
            for (g, w) in got.iter().zip(&want) {
                assert!((g.re - w).abs() < 1e-11 * (1.0 + w.abs()), "{g} vs {w}");
                assert!(g.im.abs() < 1e-11);
            }
        }
    }

    /// `Q D Qᵀ` with `D` block-diagonal: known real eigenvalues and complex pairs `a ± ib`.
    #[test]
    fn similar_block_diagonal_matrices_give_their_blocks() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for n in [2usize, 5, 8, 17, 40] {
            let mut d = DMatrix::zeros(n, n);
            let mut want = Vec::new();
            let mut i = 0;
            while i < n {
                if i + 1 < n && rng.gen_bool(0.5) {
                    let (a, b) = (rng.gen_range(-3.0..3.0), rng.gen_range(0.1..3.0));
                    d[(i, i)] = a;
                    d[(i + 1, i + 1)] = a;
                    d[(i, i + 1)] = b;
                    d[(i + 1, i)] = -b;
                    want.extend([Complex::new(a, b), Complex::new(a, -b)]);
                    i += 2;
                } else {
                    let a = rng.gen_range(-3.0..3.0);
                    d[(i, i)] = a;
                    want.push(Complex::new(a, 0.0));
                    i += 1;
                }
            }
            let q = orthogonal(&mut rng, n);
            let a = &q * d * q.transpose();
            let got = sorted(eigenvalues(&a).unwrap());
            for (g, w) in got.iter().zip(sorted(want)) {
                assert!((g - w).norm() < 1e-10, "n = {n}: {g} vs {w}");
            }
        }
    }

    /// Companion matrices: the roots of `(z − 1)(z + 2)(z² + 1)(z − 0.5)` and a repeated root.
    #[test]
    fn companion_matrices_give_the_polynomial_roots() {
        // z⁵ + 0.5 z⁴ − 1.5 z³ + 1.5 z² − 2.5 z + 1  = (z − 1)(z + 2)(z² + 1)(z − 0.5)
        let c = [1.0, -2.5, 1.5, -1.5, 0.5];
        let mut a = DMatrix::zeros(5, 5);
        for i in 1..5 {
            a[(i, i - 1)] = 1.0;
        }
        for (i, ci) in c.iter().enumerate() {
            a[(i, 4)] = -ci;
        }
        let got = sorted(eigenvalues(&a).unwrap());
        let want = sorted(vec![
            Complex::new(-2.0, 0.0),
            Complex::new(0.0, -1.0),
            Complex::new(0.0, 1.0),
            Complex::new(0.5, 0.0),
            Complex::new(1.0, 0.0),
        ]);
        for (g, w) in got.iter().zip(&want) {
            assert!((g - w).norm() < 1e-12, "{g} vs {w}");
        }
    }

    /// Jordan blocks and many equal eigenvalues (the free-floating arm's step matrices have
    /// eigenvalues clustered at 1): it converges, to the accuracy a defective matrix allows.
    #[test]
    fn defective_and_clustered_matrices_converge() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        for n in [4usize, 12, 30] {
            let mut j = DMatrix::identity(n, n);
            for i in 0..n - 1 {
                if i % 2 == 0 {
                    j[(i, i + 1)] = 1.0;
                }
            }
            let q = orthogonal(&mut rng, n);
            let a = &q * j * q.transpose();
            let got = eigenvalues(&a).unwrap();
            assert!(
                got.iter()
                    .all(|g| (g - Complex::new(1.0, 0.0)).norm() < 1e-6),
                "{got:?}"
            );
        }
        // a nilpotent 4×4 Jordan block among ordinary eigenvalues (the free-floating closed loop
        // has such zero eigenvalues; without repeated exceptional shifts the iteration cycled)
        let mut nil = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![
            0.0, 0.0, 0.0, 0.0, -3.0, 2.0, -0.5,
        ]));
        for i in 0..3 {
            nil[(i, i + 1)] = 1.0;
        }
        let q = orthogonal(&mut rng, 7);
        let got = eigenvalues(&(&q * nil * q.transpose())).unwrap();
        assert_eq!(got.iter().filter(|g| g.norm() < 1e-3).count(), 4, "{got:?}");
        let permutation = DMatrix::from_fn(6, 6, |i, j| if (i + 1) % 6 == j { 1.0 } else { 0.0 });
        let got = eigenvalues(&permutation).unwrap();
        assert!(
            got.iter().all(|g| (g.norm() - 1.0).abs() < 1e-12),
            "{got:?}"
        );
    }

    /// `‖A v − λ v‖ / (‖A‖ ‖v‖)` over every eigenpair.
    fn worst_residual(a: &DMatrix<f64>, e: &Eigen) -> f64 {
        let ac = a.map(|x| Complex::new(x, 0.0));
        let scale = a.norm().max(f64::MIN_POSITIVE);
        (0..a.nrows())
            .map(|j| {
                let v = e.vectors.column(j);
                ((&ac * v) - v * e.values[j]).norm() / (scale * v.norm())
            })
            .fold(0.0, f64::max)
    }

    /// Random matrices, block-diagonal ones with known eigenvalues, matrices with 2×2 real
    /// blocks (split by a rotation in the Schur form) and a badly scaled one: every pair satisfies
    /// `A v = λ v` to round-off, the vectors have unit norm, pairs are conjugate, and the
    /// eigenvalues are those of [`eigenvalues`].
    #[test]
    fn eigenvectors_satisfy_the_eigen_equation() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let mut cases: Vec<DMatrix<f64>> =
            (1..=40).step_by(3).map(|n| random(&mut rng, n)).collect();
        for n in [2usize, 6, 13, 40] {
            let d = DMatrix::from_fn(n, n, |i, j| {
                if i == j {
                    (i as f64) - 3.0
                } else if j == i + 1 && i % 2 == 0 {
                    1.5
                } else if i == j + 1 && j % 2 == 0 {
                    -0.5 - j as f64
                } else {
                    0.0
                }
            });
            let q = orthogonal(&mut rng, n);
            cases.push(&q * d * q.transpose());
        }
        // rows and columns scaled over twelve orders of magnitude
        let mut scaled = random(&mut rng, 12);
        for i in 0..12 {
            let f = 10f64.powi(i as i32 - 6);
            scaled.row_mut(i).scale_mut(f);
            scaled.column_mut(i).scale_mut(1.0 / f);
        }
        cases.push(scaled);
        for a in &cases {
            let e = eigen(a).unwrap();
            assert!(
                worst_residual(a, &e) < 1e-12,
                "n = {}: {}",
                a.nrows(),
                worst_residual(a, &e)
            );
            for (j, column) in e.vectors.column_iter().enumerate() {
                assert!((column.norm() - 1.0).abs() < 1e-12);
                if e.values[j].im > 0.0 {
                    assert_eq!(e.values[j + 1], e.values[j].conj());
                    assert_eq!(e.vectors.column(j + 1), column.map(|c| c.conj()));
                }
            }
            let (got, want) = (sorted(e.values.clone()), sorted(eigenvalues(a).unwrap()));
            for (g, w) in got.iter().zip(&want) {
                assert!((g - w).norm() < 1e-10 * (1.0 + w.norm()), "{g} vs {w}");
            }
        }
    }

    /// Defective matrices (Jordan blocks at zero, as the rigid-body modes of a floating base
    /// give) and the zero matrix: the iteration converges and the residuals stay at round-off.
    #[test]
    fn eigenvectors_of_defective_matrices() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let mut nil = DMatrix::from_diagonal(&nalgebra::DVector::from_vec(vec![
            0.0, 0.0, 0.0, 0.0, -3.0, 2.0, -0.5, 0.0, 0.0,
        ]));
        for i in [0, 2, 7] {
            nil[(i, i + 1)] = 1.0;
        }
        nil[(5, 6)] = 4.0;
        let q = orthogonal(&mut rng, 9);
        let a = &q * nil * q.transpose();
        let e = eigen(&a).unwrap();
        assert!(worst_residual(&a, &e) < 1e-12);
        let e = eigen(&DMatrix::zeros(4, 4)).unwrap();
        assert_eq!(
            e.vectors,
            DMatrix::identity(4, 4).map(|x: f64| Complex::new(x, 0.0))
        );
        assert!(eigen(&DMatrix::zeros(0, 0)).unwrap().values.is_empty());
        let mut bad = DMatrix::identity(3, 3);
        bad[(0, 2)] = f64::INFINITY;
        assert!(eigen(&bad).is_none());
    }

    #[test]
    fn non_finite_input_is_refused() {
        let mut a = DMatrix::identity(3, 3);
        a[(1, 2)] = f64::NAN;
        assert!(eigenvalues(&a).is_none());
        assert_eq!(eigenvalues(&DMatrix::zeros(0, 0)), Some(vec![]));
    }
}
