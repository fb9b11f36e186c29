//! Many runs at once in SIMD lanes: a [`LaneGroup`] holds `W` runs of one arm as structure of
//! arrays and advances them through one flexible RK4 step together, each lane with the bits of
//! the scalar step.
//!
//! **Why the bits agree.** The lane kernel groups every operation as the scalar code does
//! (`lane::L` applies the `f64` operation lane by lane; Rust never fuses a multiply and an add),
//! and what it does not vectorise it calls per lane from the scalar code itself: each joint's
//! `sin_cos` (the platform's libm, as the scalar path), the base attitude matrix, the
//! quaternion's renormalisation. The scalar path keeps libm's `sin`/`cos` rather than moving both
//! paths to a vectorisable implementation of our own: that would change every scalar result in
//! the last bits (the runs already recorded and the bit-for-bit agreement of the RK4 step with
//! Pinocchio's, which calls libm too), for a part that costs about a tenth of the step.
//!
//! **Width.** `W = 8` with AVX-512F, `W = 4` with AVX2, chosen at run time ([`width`]); the same
//! generic code compiled without either is the portable fallback. `ORBITFLEX_LANES` forces a
//! width (`1` asks callers for the scalar path, `4`, `8`), `ORBITFLEX_PORTABLE=1` the portable
//! code (both read once per process).

// lanes, rows and columns are the indices of the equations
#![allow(clippy::needless_range_loop)]

mod lane;
mod spatial;
mod step;

pub use lane::L;
pub use spatial::{Sv, V3};
pub use step::{LaneGroup, LaneInputs};

/// The instruction set the lane kernels run with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Level {
    /// Baseline x86-64 (or another architecture).
    Portable,
    /// AVX2, 256-bit registers.
    Avx2,
    /// AVX-512F, 512-bit registers (only if this build's compiler supports it).
    Avx512,
}

fn env_lanes() -> Option<usize> {
    std::env::var("ORBITFLEX_LANES").ok()?.trim().parse().ok()
}

/// The instruction set of this processor that the lane kernels use (cached; AVX-512F needs a
/// compiler of Rust 1.89 or later at build time). `ORBITFLEX_PORTABLE` selects the portable code,
/// as for the scalar recursions (`crate::simd`).
pub fn level() -> Level {
    use std::sync::atomic::{AtomicU8, Ordering};
    static STATE: AtomicU8 = AtomicU8::new(0);
    match STATE.load(Ordering::Relaxed) {
        1 => Level::Portable,
        2 => Level::Avx2,
        3 => Level::Avx512,
        _ => {
            let level = detect();
            let code = match level {
                Level::Portable => 1,
                Level::Avx2 => 2,
                Level::Avx512 => 3,
            };
            STATE.store(code, Ordering::Relaxed);
            level
        }
    }
}

fn detect() -> Level {
    #[cfg(target_arch = "x86_64")]
    {
        if !crate::simd::avx2() {
            return Level::Portable;
        }
        #[cfg(orbitflex_avx512)]
        if std::is_x86_feature_detected!("avx512f") {
            return Level::Avx512;
        }
        Level::Avx2
    }
    #[cfg(not(target_arch = "x86_64"))]
    Level::Portable
}

/// The lane width for this process: `ORBITFLEX_LANES` if set to 1, 4 or 8, otherwise 8 where the
/// kernels run AVX-512F and 4 elsewhere (AVX2 or portable).
pub fn width() -> usize {
    match env_lanes() {
        Some(w @ (1 | 4 | 8)) => w,
        _ if level() == Level::Avx512 => 8,
        _ => 4,
    }
}

#[cfg(test)]
mod tests;
