//! The stepped sine: the frequency grid, each frequency's schedule (settling periods,
//! measured periods holding a whole number of cycles) and the phase-continuous
//! oscillator.

use super::config::ValidResponseConfig;
use crate::Real;

/// One frequency of the grid as it is run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Step {
    /// The frequency, moved so that `measure_periods` hold exactly `cycles` cycles, Hz.
    pub(crate) freq_hz: f32,
    pub(crate) settle_periods: u32,
    pub(crate) measure_periods: u32,
    pub(crate) cycles: u32,
}

impl Step {
    /// The `i`-th frequency measured (`i < points`): the grid runs from the highest
    /// frequency down (see [`super::measure`]).
    pub(crate) fn of(s: &ValidResponseConfig, i: usize) -> Self {
        let c = &s.c;
        let t = c.period_s;
        let f = c.freq_max_hz * libm::expf(-s.log_step * i as f32);
        // max/min, not clamp: clamp panics on crossed or NaN bounds
        let settle_s = (c.settle_cycles / f)
            .max(c.settle_min_s)
            .min(c.settle_max_s);
        let cycles = libm::ceilf((f * c.measure_s).max(f32::from(c.measure_min_cycles))).max(1.0);
        // whole periods for whole cycles: f = cycles / (periods · T)
        let periods = libm::roundf(cycles / (f * t)).max(1.0);
        Self {
            freq_hz: cycles / (periods * t),
            settle_periods: libm::roundf(settle_s / t) as u32,
            measure_periods: periods as u32,
            cycles: cycles as u32,
        }
    }

    /// Periods to settle at this frequency when at least `min_s` is needed (after a start
    /// or a reversal), at least one.
    pub(crate) fn settle_after(&self, min_s: f32, period_s: f32) -> u32 {
        self.settle_periods
            .max(libm::roundf(min_s / period_s) as u32)
            .max(1)
    }

    /// Time this frequency takes after a reversal (the longer settling), s.
    pub(crate) fn duration_s(&self, period_s: f32, reverse_settle_s: f32) -> f32 {
        (self.settle_periods as f32 * period_s).max(reverse_settle_s)
            + self.measure_periods as f32 * period_s
    }
}

/// A sine whose phase runs on across frequency changes (no step in the effort when the
/// frequency changes: the transient it leaves is the settling's to wait out).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Oscillator {
    /// Phase in `[-π, π)`, rad.
    phase: f32,
    /// Phase step per period, rad.
    step: f32,
}

impl Oscillator {
    pub(crate) fn new() -> Self {
        Self {
            phase: 0.0,
            step: 0.0,
        }
    }

    pub(crate) fn set_freq(&mut self, freq_hz: f32, period_s: f32) {
        self.step = 2.0 * core::f32::consts::PI * freq_hz * period_s;
    }

    /// Advance one period; `(sin, cos)` of the new phase (the crate's f32 sine: no
    /// software double on the M4).
    pub(crate) fn advance(&mut self) -> (f32, f32) {
        let pi = core::f32::consts::PI;
        self.phase += self.step;
        if self.phase >= pi {
            self.phase -= 2.0 * pi;
        }
        if !self.phase.is_finite() {
            self.phase = 0.0;
        }
        <f32 as Real>::sin_cos(self.phase)
    }
}

#[cfg(test)]
mod tests {
    use super::super::config::{ValidResponseConfig, RESPONSE_DEFAULTS};
    use super::*;

    #[test]
    fn the_grid_is_log_spaced_and_each_step_holds_whole_cycles() {
        let s = ValidResponseConfig::new(&RESPONSE_DEFAULTS).unwrap();
        let first = Step::of(&s, 0);
        let last = Step::of(&s, s.points - 1);
        assert!((first.freq_hz - 300.0).abs() < 1.0, "{first:?}");
        assert!((last.freq_hz - 5.0).abs() < 0.01, "{last:?}");
        let mut prev = f32::INFINITY;
        for i in 0..s.points {
            let st = Step::of(&s, i);
            let nominal = 300.0 * libm::expf(-s.log_step * i as f32);
            assert!((st.freq_hz / nominal - 1.0).abs() < 0.005, "{i}: {st:?}");
            // whole cycles in the measured periods
            let cycles = st.freq_hz * st.measure_periods as f32 * 1e-4;
            assert!((cycles - st.cycles as f32).abs() < 1e-3, "{i}: {cycles}");
            assert!(st.measure_periods as f32 * 1e-4 >= 0.3 - 1e-4 || st.cycles == 2);
            assert!(st.freq_hz * 1.06 < prev, "{i}");
            prev = st.freq_hz;
        }
        // settling: 20 cycles within [0.1, 0.6] s
        assert_eq!(first.settle_periods, 1000);
        assert_eq!(last.settle_periods, 6000);
    }

    #[test]
    fn the_oscillator_keeps_its_phase_across_a_frequency_change() {
        let mut o = Oscillator::new();
        o.set_freq(100.0, 1e-4);
        let mut last = 0.0;
        for _ in 0..1234 {
            last = o.advance().0;
        }
        o.set_freq(50.0, 1e-4);
        let next = o.advance().0;
        // one step of at most 2π·100·1e-4 rad
        assert!((next - last).abs() < 0.07, "{last} -> {next}");
        // after a whole number of cycles the sine repeats
        let a = o.advance();
        for _ in 0..199 {
            o.advance();
        }
        let b = o.advance();
        assert!(
            (a.0 - b.0).abs() < 1e-4 && (a.1 - b.1).abs() < 1e-4,
            "{a:?} {b:?}"
        );
    }
}
