//! Run-time selection of an AVX2 build of the hot recursions.
//!
//! The crate is compiled for the baseline x86-64 (SSE2), as wheels are shipped. On processors
//! with AVX2 the recursions run a second copy of the same code compiled with AVX2 enabled:
//! three-operand instructions save the register copies of SSE2, and 256-bit registers halve
//! some arithmetic. Fused multiply-add stays off (Rust never contracts `a * b + c` by itself),
//! and floating-point operations are not reordered, so both copies give the same bits; the
//! tests compare them (`aba`, `rnea`, `crba` here, `apply_inverse` and the product kernel of
//! `crate::linalg` beside their code) on every machine that has AVX2.

/// Calls `kernel(args…)`, an `#[inline(always)]` function, through a copy compiled for AVX2
/// when the processor has it, and directly otherwise: `dispatch!(kernel(a: A, b: B) -> R)`
/// names each argument (a variable in scope) with its type. The detection is cached
/// ([`avx2`]).
macro_rules! dispatch {
    ($kernel:ident ( $($arg:ident : $ty:ty),* $(,)? ) $(-> $ret:ty)?) => {{
        #[cfg(target_arch = "x86_64")]
        {
            #[target_feature(enable = "avx2")]
            // the kernel's own parameters, whatever their number
            #[allow(clippy::too_many_arguments)]
            unsafe fn avx2($($arg: $ty),*) $(-> $ret)? {
                $kernel($($arg),*)
            }
            if $crate::simd::avx2() {
                // SAFETY: the processor has AVX2, checked just above.
                unsafe { avx2($($arg),*) }
            } else {
                $kernel($($arg),*)
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            $kernel($($arg),*)
        }
    }};
}
pub(crate) use dispatch;

/// Whether the AVX2 copies run: the processor has AVX2 and `ORBITFLEX_PORTABLE` was not set to
/// a non-empty value other than `0` when the first dispatch happened (it is read once per
/// process). The variable exists for tools that do not decode every AVX instruction (valgrind
/// 3.19) and for timing the portable code.
#[inline(always)]
#[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
pub(crate) fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        use std::sync::atomic::{AtomicU8, Ordering};
        static STATE: AtomicU8 = AtomicU8::new(0);
        match STATE.load(Ordering::Relaxed) {
            1 => true,
            2 => false,
            _ => {
                let portable = std::env::var_os("ORBITFLEX_PORTABLE")
                    .is_some_and(|v| !v.is_empty() && v != "0");
                let on = std::is_x86_feature_detected!("avx2") && !portable;
                STATE.store(if on { 1 } else { 2 }, Ordering::Relaxed);
                on
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

#[cfg(test)]
mod tests {
    use crate::algorithms::{aba::aba_kernel, crba::crba_kernel, rnea::rnea_kernel, Data};
    use crate::args::{Loads, RigidState};
    use crate::spatial::{Force, Motion};
    use crate::testing::{random_chain, random_state, random_tree, TREE_THREE_ARMS};
    use crate::Robot;

    /// The dispatched recursions (the AVX2 copy where the processor has it) give the same bits
    /// as the portable code, called directly here.
    #[test]
    fn both_copies_give_the_same_bits() {
        if !super::avx2() {
            eprintln!("no AVX2 here: only the portable copy runs");
        }
        for robot in [
            Robot::space_arm(),
            random_chain(13, 4),
            random_tree(TREE_THREE_ARMS, 2),
        ] {
            let n = robot.dof();
            let (q, v, qd) = random_state(&robot, 9);
            let state = RigidState::new(&q, &v, &qd);
            let tau: Vec<f64> = (0..n).map(|k| 0.3 * k as f64 - 1.0).collect();
            let loads = Loads {
                base_wrench: Force::from_slice(&[1.0, -2.0, 0.5, 3.0, 0.2, -1.0]),
                ee_wrench: &[0.1, 0.4, -0.3, 2.0, -1.0, 0.7],
            };
            let (mut fast, mut portable) = (Data::new(&robot), Data::new(&robot));
            crate::algorithms::aba::aba_unchecked(&robot, &mut fast, &state, &tau, &loads).unwrap();
            aba_kernel(&robot, &mut portable, &state, &tau, &loads).unwrap();
            assert_eq!(fast.ddq, portable.ddq);
            let acc = Motion::from_slice(&[0.2, -0.1, 0.3, 1.0, -0.5, 0.25]);
            let qdd: Vec<f64> = (0..n).map(|k| 1.0 - 0.2 * k as f64).collect();
            let f = loads.ee_wrench;
            crate::algorithms::rnea::rnea_unchecked(&robot, &mut fast, &state, acc, Some(&qdd), f);
            rnea_kernel(&robot, &mut portable, &state, acc, Some(&qdd), f);
            assert_eq!(fast.tau, portable.tau);
            crate::algorithms::crba(&robot, &mut fast, &q).unwrap();
            portable.mass_matrix_buffer().unwrap();
            crba_kernel(&robot, &mut portable, &q);
            assert_eq!(fast.mass_matrix, portable.mass_matrix);
        }
    }
}
