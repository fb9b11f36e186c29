//! [`Sampled`]: any controller run at its own rate, as flight software runs, with zero-order
//! hold between samples and a delay of whole samples; the dynamics keep their RK4 step.
//!
//! Sample `j` is due at `t_j = j / rate_hz`. It is taken at the first step whose start time
//! `t = k dt` is at or after `t_j` (within 1e-9 of the period, so that `k dt` rounding below a
//! whole multiple of the period does not slip a step): the wrapped controller is asked for its
//! row there, from that step's `(k, t, x)`. With `delay = d` the row computed at sample `j` is
//! applied from sample `j + d` on (zero until the first one arrives), and between samples the
//! applied row is held. When the period is a whole number `m` of steps, samples fall on steps
//! `0, m, 2m, …` exactly: the run equals the same run driven by the hand-held table.

use super::controller::{Controller, Feedback};
use crate::error::{Error, Result};

/// A controller sampled at `rate_hz` with a delay of `delay` samples: sample `j` is taken at the
/// first step starting at or after `j / rate_hz` (to 1e-9 of the period), its row applied from
/// sample `j + delay` on (zero before), held between samples.
pub struct Sampled<'a> {
    inner: Box<dyn Controller + Send + 'a>,
    rate_hz: f64,
    delay: usize,
    /// The next sample's index `j`.
    next: usize,
    /// The row applied now.
    held: Vec<f64>,
    /// The rows computed and not yet applied, oldest first (a ring of `delay` rows).
    queue: Vec<f64>,
    /// Where the oldest queued row starts, and how many rows are queued.
    head: usize,
    queued: usize,
    /// The row the wrapped controller writes at a sample.
    fresh: Vec<f64>,
}

impl<'a> Sampled<'a> {
    /// `inner` sampled at `rate_hz` (finite, > 0) with `delay` whole samples of delay.
    pub fn new(inner: Box<dyn Controller + Send + 'a>, rate_hz: f64, delay: usize) -> Result<Self> {
        if !(rate_hz.is_finite() && rate_hz > 0.0) {
            return Err(Error::InvalidArgument {
                what: "rate_hz".into(),
                message: format!("expected a finite rate > 0 (Hz), given {rate_hz}"),
            });
        }
        Ok(Self {
            inner,
            rate_hz,
            delay,
            next: 0,
            held: Vec::new(),
            queue: Vec::new(),
            head: 0,
            queued: 0,
            fresh: Vec::new(),
        })
    }

    /// The sample rate (Hz).
    pub fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// The delay (whole samples).
    pub fn delay(&self) -> usize {
        self.delay
    }

    /// The number of RK4 steps of `dt` per sample when the period is a whole number of them
    /// (to 1e-9), else `None`.
    pub fn steps_per_sample(&self, dt: f64) -> Option<usize> {
        let ratio = 1.0 / (self.rate_hz * dt);
        let m = ratio.round();
        ((ratio - m).abs() <= 1e-9 * ratio && m >= 1.0).then_some(m as usize)
    }

    /// Whether a sample is due at time `t` (s).
    #[inline]
    fn due(&self, t: f64) -> bool {
        t * self.rate_hz >= self.next as f64 - 1e-9
    }

    fn reset(&mut self, width: usize) {
        self.next = 0;
        self.held.clear();
        self.held.resize(width, 0.0);
        self.fresh.clear();
        self.fresh.resize(width, 0.0);
        self.queue.clear();
        self.queue.resize(self.delay * width, 0.0);
        self.head = 0;
        self.queued = 0;
    }
}

impl Controller for Sampled<'_> {
    fn output(&mut self, step: usize, t: f64, x: &[f64], out: &mut [f64]) -> Result<()> {
        let width = out.len();
        if step == 0 || self.held.len() != width {
            self.reset(width);
        }
        if self.due(t) {
            self.inner.output(step, t, x, &mut self.fresh)?;
            // the next sample after t (several periods may fit in one step)
            self.next = (t * self.rate_hz + 1e-9).floor() as usize + 1;
            if self.delay == 0 {
                self.held.copy_from_slice(&self.fresh);
            } else {
                let d = self.delay;
                if self.queued == d {
                    // the oldest row arrives; the fresh one takes its place at the back
                    let slot = self.head * width;
                    self.held.copy_from_slice(&self.queue[slot..slot + width]);
                    self.queue[slot..slot + width].copy_from_slice(&self.fresh);
                    self.head = (self.head + 1) % d;
                } else {
                    let slot = ((self.head + self.queued) % d) * width;
                    self.queue[slot..slot + width].copy_from_slice(&self.fresh);
                    self.queued += 1;
                }
            }
        }
        out.copy_from_slice(&self.held);
        Ok(())
    }

    /// Unknown: a sampled, delayed loop is not the per-step closed loop that
    /// [`Feedback::MotorPd`] describes, so the stability limit falls back to the open loop and
    /// says so (see [`Sampled::steps_per_sample`] for the period in steps).
    fn feedback(&self) -> Feedback<'_> {
        Feedback::Unknown
    }

    fn check_run(&self, what: &str, width: usize, steps: usize) -> Result<()> {
        self.inner.check_run(what, width, steps)
    }

    fn is_zero(&self) -> bool {
        self.inner.is_zero()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::control::Schedule;

    /// A table of rows 1, 2, 3, … sampled every 3 steps with a delay of 2 samples.
    #[test]
    fn holds_and_delays_whole_samples() {
        let values: Vec<f64> = (1..13).map(f64::from).collect();
        let table = Schedule::Table { values, width: 1 };
        let mut s = Sampled::new(Box::new(table), 1.0 / 0.003, 2).unwrap();
        let dt = 1e-3;
        assert_eq!(s.steps_per_sample(dt), Some(3));
        let mut got = Vec::new();
        for k in 0..12 {
            let mut out = [f64::NAN];
            s.output(k, k as f64 * dt, &[], &mut out).unwrap();
            got.push(out[0]);
        }
        // samples at steps 0, 3, 6, 9 read 1, 4, 7, 10; each applied two samples later, zero
        // before the first arrives
        assert_eq!(got, [0., 0., 0., 0., 0., 0., 1., 1., 1., 4., 4., 4.]);
        let mut none = Sampled::new(Box::new(Schedule::Zero), 0.0, 0);
        assert!(none.is_err());
        none = Sampled::new(Box::new(Schedule::Zero), 30.0, 0);
        assert_eq!(none.unwrap().steps_per_sample(dt), None);
    }

    /// A table whose row `k` is `k + 1`, for `rows` rows.
    fn counting(rows: usize) -> Box<dyn Controller + Send> {
        let values = (1..=rows).map(|v| v as f64).collect();
        Box::new(Schedule::Table { values, width: 1 })
    }

    /// The outputs of `s` over `steps` steps of `dt`.
    fn run(s: &mut Sampled, dt: f64, steps: usize) -> Vec<f64> {
        (0..steps)
            .map(|k| {
                let mut out = [f64::NAN];
                s.output(k, k as f64 * dt, &[], &mut out).unwrap();
                out[0]
            })
            .collect()
    }

    /// Every `m` steps (`m` = 1, 2, 3) with `d` = 0 to 3 samples of delay: sample `j` is taken
    /// at step `jm` (reading row `jm + 1`) and applied over steps `(j + d)m` to `(j + d + 1)m − 1`,
    /// zero before; a second run from step 0 starts afresh and repeats the first.
    #[test]
    fn whole_periods_sample_every_m_steps_and_delay_d_samples() {
        let dt = 1e-3;
        for m in 1..=3 {
            for d in 0..=3 {
                let mut s = Sampled::new(counting(24), 1.0 / (m as f64 * dt), d).unwrap();
                assert_eq!(s.steps_per_sample(dt), Some(m), "m {m}");
                let expected: Vec<f64> = (0..24)
                    .map(|k| match (k / m).checked_sub(d) {
                        Some(j) => (j * m + 1) as f64,
                        None => 0.0,
                    })
                    .collect();
                assert_eq!(run(&mut s, dt, 24), expected, "m {m} d {d}");
                assert_eq!(run(&mut s, dt, 24), expected, "m {m} d {d}, second run");
            }
        }
    }

    /// Rows of three columns (`[k + 1, −(k + 1), 10(k + 1)]` at step `k`), sampled every 2
    /// steps with 1 to 3 samples of delay, come out whole and in order.
    #[test]
    fn rows_of_several_columns_are_delayed_whole() {
        let dt = 1e-3;
        let row = |k: usize| {
            let v = (k + 1) as f64;
            [v, -v, 10.0 * v]
        };
        let values: Vec<f64> = (0..16).flat_map(row).collect();
        for d in 1..=3 {
            let table = Schedule::Table {
                values: values.clone(),
                width: 3,
            };
            let mut s = Sampled::new(Box::new(table), 500.0, d).unwrap();
            for k in 0..16 {
                let mut out = [f64::NAN; 3];
                s.output(k, k as f64 * dt, &[], &mut out).unwrap();
                let expected = (k / 2).checked_sub(d).map_or([0.0; 3], |j| row(2 * j));
                assert_eq!(out, expected, "d {d} step {k}");
            }
        }
    }

    /// At 400 Hz with steps of 1 ms the period is 2.5 steps: the samples due at 0, 2.5, 5, 7.5,
    /// … ms are taken at the first step at or after them, steps 0, 3, 5, 8, 10, …
    #[test]
    fn a_period_of_non_whole_steps_samples_at_the_next_step() {
        let dt = 1e-3;
        let taken = [0, 3, 5, 8, 10, 13, 15, 18, 20, 23];
        for d in 0..=2 {
            let mut s = Sampled::new(counting(24), 400.0, d).unwrap();
            assert_eq!(s.steps_per_sample(dt), None);
            let expected: Vec<f64> = (0..24)
                .map(|k| {
                    let j = taken.iter().filter(|&&t| t <= k).count() - 1;
                    j.checked_sub(d).map_or(0.0, |i| (taken[i] + 1) as f64)
                })
                .collect();
            assert_eq!(run(&mut s, dt, 24), expected, "d {d}");
        }
        // faster than the steps (2.5 samples a step): one sample a step, the step's row
        for d in 0..=1 {
            let mut s = Sampled::new(counting(8), 2500.0, d).unwrap();
            let expected: Vec<f64> = (0..8)
                .map(|k: usize| k.checked_sub(d).map_or(0.0, |i| (i + 1) as f64))
                .collect();
            assert_eq!(run(&mut s, dt, 8), expected, "d {d}");
        }
    }

    /// Whole to 1e-9 of the period: 2 steps exactly, 3 steps within 0.5e-9, not within 2e-9.
    #[test]
    fn steps_per_sample_is_whole_to_a_part_in_a_billion() {
        let dt = 1e-3;
        let at = |rate: f64| Sampled::new(counting(1), rate, 0).unwrap();
        assert_eq!(at(500.0).steps_per_sample(dt), Some(2));
        assert_eq!(at(1000.0).steps_per_sample(dt), Some(1));
        assert_eq!(
            at(1.0 / (3.0 * dt * (1.0 + 0.5e-9))).steps_per_sample(dt),
            Some(3)
        );
        assert_eq!(
            at(1.0 / (3.0 * dt * (1.0 + 2e-9))).steps_per_sample(dt),
            None
        );
        assert_eq!(
            at(1.0 / (3.0 * dt * (1.0 - 2e-9))).steps_per_sample(dt),
            None
        );
    }

    /// The rate and delay read back; the run's checks and `is_zero` are the wrapped
    /// controller's; the feedback is unknown; bad rates are refused by name.
    #[test]
    fn the_wrapper_reports_its_rate_and_its_inner_controller() {
        let s = Sampled::new(counting(3), 250.0, 4).unwrap();
        assert_eq!((s.rate_hz(), s.delay()), (250.0, 4));
        assert!(s.check_run("u", 1, 3).is_ok());
        let inner = Schedule::Table {
            values: vec![1.0, 2.0, 3.0],
            width: 1,
        };
        assert_eq!(
            s.check_run("u", 1, 5).unwrap_err().to_string(),
            inner.check_run("u", 1, 5).unwrap_err().to_string()
        );
        assert!(!s.is_zero());
        assert!(Sampled::new(Box::new(Schedule::Zero), 250.0, 0)
            .unwrap()
            .is_zero());
        assert!(matches!(s.feedback(), Feedback::Unknown));
        for rate in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = Sampled::new(counting(1), rate, 0).err().unwrap();
            assert_eq!(
                e.to_string(),
                format!("rate_hz: expected a finite rate > 0 (Hz), given {rate}")
            );
        }
    }
}
