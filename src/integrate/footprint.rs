//! The memory a run needs, counted before anything is allocated, so that a run which cannot fit
//! is refused up front with its size, part by part, instead of failing an allocation half way.
//!
//! A run of `steps` steps of an arm of `n` joints, keeping `rows` rows
//! ([`recorded_rows`](super::recorded_rows) with `record_every`), needs, in bytes (8 per `f64`):
//!
//! | part | what holds it | bytes |
//! |---|---|---|
//! | reference tables | the caller's tabulated motor reference (`MotorPD` with `θ_ref`, `θ̇_ref` tables, as the CLI's quintic slew): two tables of `steps × n` | `2 · steps · n · 8` |
//! | record | the [`Trajectory`](super::Trajectory) `simulate` fills: per row `t` and `x` (`1 + 13 + 4n + k` numbers), per row but the last the inputs (`n + k`) | `rows (14 + 4n + k) 8 + (rows − 1)(n + k) 8` |
//! | diagnostics | what a caller computes along the record (the CLI's summary and files): per row the momentum (6), the energy (1), an EE pose (7), the deflection and spring torque (`n` each) and `2n` of working arrays | `rows (14 + 4n) 8` |
//!
//! with `k` reaction wheels (0 without). The record's count is the one
//! [`Trajectory::reserved`](super::Trajectory::reserved) asks for.
//!
//! **Counts past any integer type.** A step count comes from a duration over a step, and
//! 10³⁰⁰ s over 1 ms is 10³⁰³ steps. A [`Count`] is exact while it fits in a `u128` (3.4·10³⁸,
//! far past any memory) and a float past that, so such a run is still refused with its size:
//!
//! ```
//! use orbitflex::integrate::footprint::{Count, RunBytes};
//! use orbitflex::StateLayout;
//! let run = RunBytes::new(Count::Exact(20_000_000_000), StateLayout::new(7), 1)?;
//! assert_eq!(run.record, Count::Exact(20_000_000_001 * 42 * 8 + 20_000_000_000 * 7 * 8));
//! let message = run.check(Some(16_000_000_000)).unwrap_err();
//! assert!(message.starts_with("20,000,000,000 steps of 7 joints need about 16.8 TB (reference \
//!                              tables 2.24 TB, record 7.84 TB, diagnostics 6.72 TB) but 16 GB"));
//! let absurd = RunBytes::new(Count::from_f64(1e303), StateLayout::new(7), 1)?;
//! assert!(absurd.check(Some(1 << 40)).unwrap_err().starts_with("1e+303 steps of 7 joints need about 8.4e+293 TB"));
//! # Ok::<(), orbitflex::Error>(())
//! ```

use super::record::check_record_every;
use crate::error::Result;
use crate::flex::StateLayout;
use std::fmt;

/// A count (of steps, rows or bytes) that may exceed any integer type: exact while it fits in a
/// `u128`, a float (to 16 digits) in units of 2¹²⁸ past that, so that even `f64::MAX` steps
/// times the bytes of a step stays finite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Count {
    /// Exactly this many.
    Exact(u128),
    /// More than `u128::MAX`: about this many times 2¹²⁸ (≥ 1).
    Beyond(f64),
}

/// 2¹²⁸, the unit of [`Count::Beyond`].
const BEYOND: f64 = 340_282_366_920_938_463_463_374_607_431_768_211_456.0;

impl Count {
    /// The count a whole, non-negative float holds (a float step count such as
    /// `round(duration / dt)`): exact below 2¹²⁸. A fraction is dropped; a negative or NaN value
    /// is 0.
    pub fn from_f64(x: f64) -> Count {
        if x >= BEYOND {
            Count::Beyond(x / BEYOND)
        } else {
            // `as` saturates: NaN and negatives are 0
            Count::Exact(x as u128)
        }
    }

    /// The count as a float, rounded to nearest (infinite past `f64::MAX`).
    pub fn as_f64(self) -> f64 {
        match self {
            Count::Exact(c) => c as f64,
            Count::Beyond(x) => x * BEYOND,
        }
    }

    /// The count in units of 2¹²⁸.
    fn scaled(self) -> f64 {
        match self {
            Count::Exact(c) => c as f64 / BEYOND,
            Count::Beyond(x) => x,
        }
    }

    /// `self · k`, exact while it fits.
    pub fn times(self, k: u128) -> Count {
        match self {
            Count::Exact(a) => a
                .checked_mul(k)
                .map_or(Count::Beyond(self.scaled() * k as f64), Count::Exact),
            Count::Beyond(x) => Count::Beyond(x * k as f64),
        }
    }

    /// `self + other`, exact while it fits.
    pub fn plus(self, other: Count) -> Count {
        match (self, other) {
            (Count::Exact(a), Count::Exact(b)) => a
                .checked_add(b)
                .map_or(Count::Beyond(self.scaled() + other.scaled()), Count::Exact),
            (a, b) => Count::Beyond(a.scaled() + b.scaled()),
        }
    }

    /// `⌊self / k⌋` (k ≥ 1), exact for an exact count.
    fn over(self, k: u128) -> Count {
        match self {
            Count::Exact(a) => Count::Exact(a / k),
            Count::Beyond(x) if x / k as f64 >= 1.0 => Count::Beyond(x / k as f64),
            Count::Beyond(x) => Count::from_f64((x / k as f64 * BEYOND).floor()),
        }
    }

    /// `self − 1`, at least 0 (a float past `u128` is unchanged by one).
    fn minus_one(self) -> Count {
        match self {
            Count::Exact(a) => Count::Exact(a.saturating_sub(1)),
            beyond => beyond,
        }
    }

    /// Whether the count is more than `limit`.
    pub fn exceeds(self, limit: u64) -> bool {
        match self {
            Count::Exact(a) => a > u128::from(limit),
            Count::Beyond(_) => true,
        }
    }
}

/// Rows a complete run of `steps` steps keeps with `record_every = every` (≥ 1): the rule of
/// [`recorded_rows`](super::recorded_rows), on a [`Count`].
pub fn recorded_rows(steps: Count, every: usize) -> Count {
    let k = every as u128;
    let divides = match steps {
        Count::Exact(s) => s % k == 0,
        // a float this large is a whole number; `%` on floats is exact
        Count::Beyond(x) => (x * BEYOND) % k as f64 == 0.0,
    };
    steps.over(k).plus(Count::Exact(1 + u128::from(!divides)))
}

/// The bytes a run allocates, by part (the table in the [module docs](self)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RunBytes {
    /// The steps of the run.
    pub steps: Count,
    /// Its joints `n`.
    pub joints: usize,
    /// The tabulated motor reference, `θ_ref` and `θ̇_ref`: `2 · steps · n` numbers.
    pub reference_tables: Count,
    /// The [`Trajectory`](super::Trajectory): `t`, `x` and the inputs of the kept rows.
    pub record: Count,
    /// The per-row quantities computed along the record: `14 + 4n` numbers a row.
    pub diagnostics: Count,
}

impl RunBytes {
    /// The bytes of a run of `steps` steps of an arm with this `layout`, keeping one row in
    /// `record_every` (≥ 1) and the final row.
    pub fn new(steps: Count, layout: StateLayout, record_every: usize) -> Result<RunBytes> {
        check_record_every(record_every)?;
        let rows = recorded_rows(steps, record_every);
        let (n, len, inputs) = (
            layout.n as u128,
            layout.len() as u128,
            layout.inputs_len() as u128,
        );
        Ok(RunBytes {
            steps,
            joints: layout.n,
            reference_tables: steps.times(2).times(n).times(8),
            record: (rows.times(1 + len).plus(rows.minus_one().times(inputs))).times(8),
            diagnostics: rows.times(14 + 4 * n).times(8),
        })
    }

    /// The parts, named as the messages name them.
    pub fn parts(&self) -> [(&'static str, Count); 3] {
        [
            ("reference tables", self.reference_tables),
            ("record", self.record),
            ("diagnostics", self.diagnostics),
        ]
    }

    /// All the parts together.
    pub fn total(&self) -> Count {
        self.reference_tables
            .plus(self.record)
            .plus(self.diagnostics)
    }

    /// `Ok` if the run fits in `available` bytes (`None`, a system that does not say: it is
    /// assumed to fit), else what it needs against what is free:
    /// `"20,000,000,000 steps of 7 joints need about 16.8 TB (reference tables 2.24 TB, record
    /// 7.84 TB, diagnostics 6.72 TB) but 13.2 GB of memory is free"`.
    pub fn check(&self, available: Option<u64>) -> std::result::Result<(), String> {
        let need = self.total();
        match available {
            Some(free) if need.exceeds(free) => {
                let sizes = self
                    .parts()
                    .iter()
                    .map(|(name, size)| format!("{name} {}", Size(*size)))
                    .collect::<Vec<_>>()
                    .join(", ");
                Err(format!(
                    "{} steps of {} joints need about {} ({sizes}) but {} of memory is free",
                    Steps(self.steps),
                    self.joints,
                    Size(need),
                    Size(Count::Exact(u128::from(free)))
                ))
            }
            _ => Ok(()),
        }
    }
}

/// A step count for a message: every digit, grouped by thousands, below 10¹²
/// (`20,000,000,000`); three significant digits from there (`1e+12`).
pub struct Steps(pub Count);

impl fmt::Display for Steps {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Count::Exact(s) if s < 1_000_000_000_000 => {
                let digits = s.to_string();
                let mut grouped = String::new();
                for (i, c) in digits.chars().enumerate() {
                    if i > 0 && (digits.len() - i) % 3 == 0 {
                        grouped.push(',');
                    }
                    grouped.push(c);
                }
                f.write_str(&grouped)
            }
            count => f.write_str(&three_digits(count.as_f64())),
        }
    }
}

/// A byte count for a message: in GB below 10¹² bytes, in TB from there, to three significant
/// digits (`13.6 GB`, `216 TB`, `8.4e+293 TB`: an absurd size stays short).
pub struct Size(pub Count);

impl fmt::Display for Size {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (value, unit) = match self.0 {
            Count::Exact(b) if b < 1_000_000_000_000 => (b as f64 / 1e9, "GB"),
            Count::Exact(b) => (b as f64 / 1e12, "TB"),
            Count::Beyond(x) => (x * (BEYOND / 1e12), "TB"),
        };
        write!(f, "{} {unit}", three_digits(value))
    }
}

/// `x` to three significant digits, written as C's and Python's `%.3g` write it: fixed notation
/// for a decimal exponent from −4 to 2 (`0.000123`, `16.8`, `216`), scientific with a signed,
/// two-digit exponent otherwise (`1e+12`, `8.4e+293`, `1.23e-05`); trailing zeros dropped. The
/// rounding is the correct one of the decimal value, ties to even (Rust's and Python's both).
pub fn three_digits(x: f64) -> String {
    if !x.is_finite() {
        return match x {
            x if x.is_nan() => "nan".into(),
            x if x > 0.0 => "inf".into(),
            _ => "-inf".into(),
        };
    }
    let scientific = format!("{x:.2e}");
    let (mantissa, exponent) = scientific
        .split_once('e')
        .expect("`{:e}` writes an exponent");
    let exponent: i32 = exponent.parse().expect("`{:e}` writes an integer exponent");
    if (-4..3).contains(&exponent) {
        without_trailing_zeros(&format!("{x:.*}", (2 - exponent) as usize))
    } else {
        let sign = if exponent < 0 { '-' } else { '+' };
        format!(
            "{}e{sign}{:02}",
            without_trailing_zeros(mantissa),
            exponent.abs()
        )
    }
}

/// `12.50` → `12.5`, `2.00` → `2`; a number without a decimal point is left alone.
fn without_trailing_zeros(number: &str) -> String {
    if number.contains('.') {
        number
            .trim_end_matches('0')
            .trim_end_matches('.')
            .to_string()
    } else {
        number.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn exact(count: Count) -> u128 {
        match count {
            Count::Exact(c) => c,
            beyond => panic!("{beyond:?} is not exact"),
        }
    }

    #[test]
    fn the_parts_are_the_closed_forms() {
        // rows = s/k + 1 (+1 when k does not divide s); record = rows(1 + 13 + 4n + w) +
        // (rows − 1)(n + w) numbers; tables 2 s n; diagnostics rows(14 + 4n)
        for (s, n, w, k) in [
            (1000u128, 7, 0, 1),
            (1001, 7, 0, 10),
            (5, 1, 0, 9),
            (0, 3, 0, 3),
            (12, 6, 3, 4),
        ] {
            let rows = s / k + 1 + u128::from(s % k != 0);
            let layout = StateLayout {
                n: n as usize,
                wheels: w as usize,
            };
            let run = RunBytes::new(Count::Exact(s), layout, k as usize).unwrap();
            assert_eq!(exact(recorded_rows(Count::Exact(s), k as usize)), rows);
            assert_eq!(exact(run.reference_tables), 2 * s * n * 8);
            assert_eq!(
                exact(run.record),
                (rows * (14 + 4 * n + w) + (rows - 1) * (n + w)) * 8
            );
            assert_eq!(exact(run.diagnostics), rows * (14 + 4 * n) * 8);
            assert_eq!(
                exact(run.total()),
                exact(run.reference_tables) + exact(run.record) + exact(run.diagnostics)
            );
        }
        assert_eq!(exact(recorded_rows(Count::Exact(1000), 10)), 101);
        assert_eq!(exact(recorded_rows(Count::Exact(1001), 10)), 102);
    }

    #[test]
    fn the_record_is_what_a_trajectory_reserves() {
        for (steps, every, wheels) in [(100usize, 1usize, 0usize), (101, 7, 0), (50, 3, 3)] {
            let layout = StateLayout { n: 7, wheels };
            let traj = crate::integrate::Trajectory::reserved(layout, steps, every).unwrap();
            let reserved = 8 * (traj.t.capacity() + traj.x.capacity() + traj.u.capacity());
            let run = RunBytes::new(Count::Exact(steps as u128), layout, every).unwrap();
            assert_eq!(run.record, Count::Exact(reserved as u128));
        }
    }

    #[test]
    fn counts_past_u128_overflow_into_floats_not_wrap() {
        let big = Count::Exact(u128::MAX / 2);
        assert_eq!(big.times(2), Count::Exact(u128::MAX - 1));
        // past u128 the count is in units of 2^128: (2^127 − 1) · 3 ≈ 1.5 · 2^128
        assert_eq!(big.times(3), Count::Beyond(1.5));
        // u128::MAX + 1 = 2^128 exactly: one unit
        assert_eq!(
            Count::Exact(u128::MAX).plus(Count::Exact(1)),
            Count::Beyond(1.0)
        );
        assert_eq!(Count::from_f64(1e38), Count::Exact(1e38 as u128));
        assert_eq!(Count::from_f64(1e39), Count::Beyond(1e39 / BEYOND));
        assert_eq!(Count::from_f64(1e39).as_f64(), 1e39);
        assert_eq!(Count::from_f64(-3.0), Count::Exact(0));
        assert!(
            Count::Beyond(1.0).exceeds(u64::MAX)
                && Count::Exact(u128::from(u64::MAX) + 1).exceeds(u64::MAX)
        );
        assert!(!Count::Exact(u128::from(u64::MAX)).exceeds(u64::MAX));
        // 10^303 steps, 7 joints: 112 · 10^303 bytes of tables, one float product
        let run = RunBytes::new(Count::from_f64(1e303), StateLayout::new(7), 1).unwrap();
        assert_eq!(run.reference_tables, Count::Beyond(1e303 / BEYOND * 112.0));
        let rows = |steps: f64, k| recorded_rows(Count::from_f64(steps), k).as_f64();
        assert_eq!(rows(1e303, 1), 1e303);
        assert_eq!(rows(1e303, 1000), 1e300);
        assert_eq!(rows(1e39, 10), 1e38);
        // rows fall back into u128: 2^130 steps, every 2^63rd: 2^67 + 1 rows, exactly
        assert_eq!(
            recorded_rows(Count::from_f64(2f64.powi(130)), 1 << 63),
            Count::Exact((1 << 67) + 1)
        );
        // f64::MAX steps: sizes past f64::MAX bytes are still counted, and refused
        let run = RunBytes::new(Count::from_f64(f64::MAX), StateLayout::new(7), 1).unwrap();
        let message = run.check(Some(u64::MAX)).unwrap_err();
        assert!(
            message.starts_with(
                "1.8e+308 steps of 7 joints need about 1.51e+299 TB (reference tables \
                 2.01e+298 TB"
            ),
            "{message}"
        );
    }

    #[test]
    fn the_check_refuses_only_what_does_not_fit() {
        let run = RunBytes::new(Count::Exact(1000), StateLayout::new(7), 1).unwrap();
        let Count::Exact(need) = run.total() else {
            unreachable!()
        };
        let need = need as u64;
        assert_eq!(run.check(Some(need)), Ok(()));
        assert_eq!(run.check(None), Ok(()));
        assert_eq!(
            run.check(Some(need - 1)).unwrap_err(),
            format!(
                "1,000 steps of 7 joints need about 0.000841 GB (reference tables 0.000112 GB, \
                 record 0.000392 GB, diagnostics 0.000336 GB) but {} GB of memory is free",
                three_digits((need - 1) as f64 / 1e9)
            )
        );
        assert!(RunBytes::new(Count::Exact(5), StateLayout::new(7), 0).is_err());
    }

    #[test]
    fn numbers_are_written_as_percent_3g() {
        // the strings C's printf("%.3g") and Python's format(x, ".3g") give
        for (x, text) in [
            (16.8, "16.8"),
            (216.0, "216"),
            (13.6, "13.6"),
            (2.0, "2"),
            (0.5, "0.5"),
            (999.4, "999"),
            (999.5, "1e+03"),
            (1e12, "1e+12"),
            (8.4e293, "8.4e+293"),
            (1.12e293, "1.12e+293"),
            (0.000123456, "0.000123"),
            (0.0000123456, "1.23e-05"),
            (0.125, "0.125"),
            (2.675, "2.67"),
            (0.0, "0"),
            (-16.84, "-16.8"),
            (123456.0, "1.23e+05"),
            (f64::INFINITY, "inf"),
            (f64::NAN, "nan"),
        ] {
            assert_eq!(three_digits(x), text, "{x}");
        }
        let steps = |s| Steps(Count::Exact(s)).to_string();
        assert_eq!(
            [steps(0), steps(999), steps(1000), steps(20_000_000_000)],
            ["0", "999", "1,000", "20,000,000,000"]
        );
        assert_eq!(
            [steps(999_999_999_999), steps(1_000_000_000_000)],
            ["999,999,999,999", "1e+12"]
        );
        assert_eq!(Steps(Count::from_f64(1e303)).to_string(), "1e+303");
        assert_eq!(Size(Count::from_f64(8.4e305)).to_string(), "8.4e+293 TB");
        let size = |b| Size(Count::Exact(b)).to_string();
        assert_eq!(
            [
                size(13_600_000_000),
                size(999_999_999_999),
                size(1_000_000_000_000)
            ],
            ["13.6 GB", "1e+03 GB", "1 TB"]
        );
    }
}
