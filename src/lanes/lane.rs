//! [`L`]: `W` numbers side by side, one per run of a lane group, with the arithmetic of `f64`
//! applied lane by lane.
//!
//! Every operation is one IEEE operation per lane, in the order written: no fused multiply-add,
//! no reassociation. Compiled inside a `#[target_feature]` function, LLVM turns the loops over
//! `W` into packed instructions (`vaddpd`, `vmulpd`, …), whose lanes round exactly as the
//! scalar instructions do. A lane of a kernel written with `L` therefore gives the bits of the
//! same kernel written with `f64`, as long as it groups the operations the same way.

use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};

/// `W` lanes of `f64`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(transparent)]
pub struct L<const W: usize>(pub [f64; W]);

impl<const W: usize> Default for L<W> {
    #[inline(always)]
    fn default() -> Self {
        Self([0.0; W])
    }
}

impl<const W: usize> L<W> {
    /// The same value in every lane.
    #[inline(always)]
    pub fn splat(v: f64) -> Self {
        Self([v; W])
    }

    /// Zero in every lane.
    #[inline(always)]
    pub fn zero() -> Self {
        Self([0.0; W])
    }

    /// `f` lane by lane.
    #[inline(always)]
    pub fn map(self, f: impl Fn(f64) -> f64) -> Self {
        let mut out = self.0;
        for v in &mut out {
            *v = f(*v);
        }
        Self(out)
    }

    /// `√x` lane by lane (IEEE square root, correctly rounded: the same bits as `f64::sqrt`).
    #[inline(always)]
    pub fn sqrt(self) -> Self {
        self.map(f64::sqrt)
    }

    /// `f(a, b)` lane by lane.
    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        let mut out = self.0;
        for (v, w) in out.iter_mut().zip(o.0) {
            *v = f(*v, w);
        }
        Self(out)
    }

    /// Lane `k`.
    #[inline(always)]
    pub fn get(&self, k: usize) -> f64 {
        self.0[k]
    }
}

macro_rules! binary {
    ($trait:ident, $method:ident, $op:tt) => {
        impl<const W: usize> $trait for L<W> {
            type Output = Self;
            #[inline(always)]
            fn $method(self, o: Self) -> Self {
                self.zip(o, |a, b| a $op b)
            }
        }
        impl<const W: usize> $trait<f64> for L<W> {
            type Output = Self;
            #[inline(always)]
            fn $method(self, o: f64) -> Self {
                self.map(|a| a $op o)
            }
        }
        impl<const W: usize> $trait<L<W>> for f64 {
            type Output = L<W>;
            #[inline(always)]
            fn $method(self, o: L<W>) -> L<W> {
                o.map(|b| self $op b)
            }
        }
    };
}
binary!(Add, add, +);
binary!(Sub, sub, -);
binary!(Mul, mul, *);
binary!(Div, div, /);

impl<const W: usize> Neg for L<W> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|a| -a)
    }
}

impl<const W: usize> AddAssign for L<W> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}

impl<const W: usize> SubAssign for L<W> {
    #[inline(always)]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}
