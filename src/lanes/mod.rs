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
//! width (`0` or `1` asks callers for the scalar path, `4`, `8`), `ORBITFLEX_PORTABLE=1` the portable
//! code (both read once per process).

// lanes, rows and columns are the indices of the equations
#![allow(clippy::needless_range_loop)]

mod lane;
mod run;
mod spatial;
mod step;

use crate::flex::FlexibleArm;
pub use lane::L;
pub use run::{lane_capable, shares_kernel, simulate_lanes, LaneRun};
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

/// The lane width for this process: `ORBITFLEX_LANES` if set to 1, 4 or 8 (0 reads as 1, the
/// scalar path), otherwise [`processor_width`].
pub fn width() -> usize {
    match env_lanes() {
        Some(0) => 1,
        Some(w @ (1 | 4 | 8)) => w,
        _ => processor_width(),
    }
}

/// 8 where the kernels run AVX-512F, 4 elsewhere (AVX2 or portable).
pub fn processor_width() -> usize {
    match level() {
        Level::Avx512 => 8,
        _ => 4,
    }
}

/// How a batch uses the lanes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Lanes {
    /// Lanes of [`width`] (the processor's, or `ORBITFLEX_LANES`, whose `0` or `1` forces the
    /// scalar path). The default.
    #[default]
    Auto,
    /// Every run on the scalar path.
    Off,
    /// Lanes of this width (4 or 8, whatever the processor: 8 lanes on AVX2 run two registers
    /// per number), `ORBITFLEX_LANES` ignored.
    Width(usize),
}

impl Lanes {
    /// The width the runs are grouped by (1: the scalar path).
    pub fn width(self) -> usize {
        match self {
            Lanes::Auto => width(),
            Lanes::Off => 1,
            Lanes::Width(w) => w,
        }
    }
}

/// Groups the runs `0..runs` that can run in lanes of `width`: `arm_of(run)` is the run's arm
/// when nothing else keeps it on the scalar path. Runs whose arms [`shares_kernel`] go together,
/// in run order, `width` at a time; a group of one run (and every run when `width` is not 4 or
/// 8) is left to the scalar path, which it equals anyway. Returns the groups and the runs left.
pub fn lane_groups<'a>(
    runs: usize,
    width: usize,
    arm_of: impl Fn(usize) -> Option<&'a FlexibleArm>,
) -> (Vec<Vec<usize>>, Vec<usize>) {
    if !matches!(width, 4 | 8) {
        return (Vec::new(), (0..runs).collect());
    }
    // runs by kernel: one robot each (compared with the first run of the kind)
    let mut kinds: Vec<(&FlexibleArm, Vec<usize>)> = Vec::new();
    let mut scalar = Vec::new();
    for run in 0..runs {
        match arm_of(run).filter(|a| lane_capable(a)) {
            None => scalar.push(run),
            Some(arm) => match kinds.iter_mut().find(|(a, _)| shares_kernel(a, arm)) {
                Some((_, members)) => members.push(run),
                None => kinds.push((arm, vec![run])),
            },
        }
    }
    let mut groups = Vec::new();
    for (_, members) in kinds {
        for chunk in members.chunks(width) {
            match chunk {
                [one] => scalar.push(*one),
                _ => groups.push(chunk.to_vec()),
            }
        }
    }
    scalar.sort_unstable();
    (groups, scalar)
}

#[cfg(test)]
mod tests;
