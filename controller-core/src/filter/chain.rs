//! The filters of the control output: a chain of biquads per axis ([`FilterChain`]) and
//! the three axes' chains ([`OutputFilters`]), built from their validated configuration
//! and holding their state.
//!
//! Cost in the period: one test for an axis without filters (its output is its input, bit
//! for bit), else one biquad per configured stage and one finiteness test; at most
//! [`MAX_STAGES`] per axis (`filters3_f32`, `filters3_fixed` in `insns`).

use super::biquad::Biquad;
use super::design::{AxisFilterConfig, MAX_STAGES};
use super::response::{FrequencyResponse, C64};
use crate::axes::AXES;
use crate::config::{positive, ConfigError};
use crate::{Real, Vec3};

/// One stage: its section and the section's state, side by side in memory.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Stage<R> {
    section: Biquad<R>,
    state: [R; 2],
}

/// Up to `N` biquads in series on one signal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterChain<R, const N: usize> {
    stages: [Stage<R>; N],
    count: usize,
}

impl<R: Real, const N: usize> FilterChain<R, N> {
    /// No filter: [`Self::process`] returns its input unchanged.
    pub fn none() -> Self {
        Self {
            stages: [Stage {
                section: Biquad::identity(0.0),
                state: [R::ZERO; 2],
            }; N],
            count: 0,
        }
    }

    /// The axis' stages designed for the control period `period_s`, at rest at 0.
    /// More stages than `N`: `Err(OutOfRange("filters"))`.
    pub fn new(cfg: &AxisFilterConfig, period_s: f32) -> Result<Self, ConfigError> {
        positive(period_s, "period_s")?;
        let mut chain = Self::none();
        for (i, stage) in cfg.stages().iter().enumerate() {
            let slot = chain
                .stages
                .get_mut(i)
                .ok_or(ConfigError::OutOfRange("filters"))?;
            slot.section = Biquad::new(&stage.design(period_s)?, period_s);
            chain.count = i + 1;
        }
        Ok(chain)
    }

    /// Number of configured stages.
    pub fn len(&self) -> usize {
        self.count
    }

    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// The configured sections, in order.
    pub fn sections(&self) -> impl Iterator<Item = &Biquad<R>> {
        self.stages.iter().take(self.count).map(|s| &s.section)
    }

    /// One sample through the chain. Without stages the input is returned as it is. A
    /// non-finite output (a non-finite input, or an overflow of a float state) clears
    /// the states and gives 0, so the chain never latches a NaN.
    #[inline(always)]
    pub fn process(&mut self, x: R) -> R {
        if self.count == 0 {
            return x;
        }
        let mut y = x;
        for st in self.stages.iter_mut().take(self.count) {
            y = st.section.process(&mut st.state, y);
        }
        if y.is_finite() {
            y
        } else {
            self.reset(R::ZERO);
            R::ZERO
        }
    }

    /// Put every stage at rest under the constant input `level` (0 for a non-finite
    /// level): fed `level` from now on, the chain outputs its DC gain times `level` (1 for
    /// the notch and the low-pass, up to the coefficients' rounding) without a transient.
    pub fn reset(&mut self, level: R) {
        let mut v = level.finite_or_zero();
        for st in self.stages.iter_mut().take(self.count) {
            let (state, y) = st.section.steady_state(v);
            st.state = state;
            v = y;
        }
    }

    /// Complex gain of the whole chain at `freq_hz`, in `f64`.
    pub fn response_c64(&self, freq_hz: f32) -> C64 {
        self.sections()
            .fold(C64::ONE, |h, s| h.times(s.response_c64(freq_hz)))
    }
}

impl<R: Real, const N: usize> FrequencyResponse for FilterChain<R, N> {
    /// The chain's discrete gain at `freq_hz`: the product of its sections' (1 without).
    fn response(&self, freq_hz: f32) -> (f32, f32) {
        self.response_c64(freq_hz).to_pair()
    }
}

/// The output filters of the three axes (X, Y, Z), each up to [`MAX_STAGES`] biquads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputFilters<R> {
    axes: [FilterChain<R, MAX_STAGES>; AXES],
}

impl<R: Real> Default for OutputFilters<R> {
    fn default() -> Self {
        Self::none()
    }
}

impl<R: Real> OutputFilters<R> {
    /// No filter on any axis.
    pub fn none() -> Self {
        Self {
            axes: [FilterChain::none(); AXES],
        }
    }

    /// The three axes' chains for the control period `period_s`, at rest at 0.
    pub fn new(cfg: &[AxisFilterConfig; AXES], period_s: f32) -> Result<Self, ConfigError> {
        let [x, y, z] = cfg;
        Ok(Self {
            axes: [
                FilterChain::new(x, period_s)?,
                FilterChain::new(y, period_s)?,
                FilterChain::new(z, period_s)?,
            ],
        })
    }

    /// Filter the three axes' control outputs.
    #[inline(always)]
    pub fn process(&mut self, u: Vec3<R>) -> Vec3<R> {
        let [x, y, z] = &mut self.axes;
        Vec3::new(x.process(u.x), y.process(u.y), z.process(u.z))
    }

    /// Put every axis at rest under the constant output `u` (see [`FilterChain::reset`]).
    pub fn reset(&mut self, u: Vec3<R>) {
        let [x, y, z] = &mut self.axes;
        x.reset(u.x);
        y.reset(u.y);
        z.reset(u.z);
    }

    /// The chain of axis `i` (0-2).
    pub fn axis(&self, i: usize) -> Option<&FilterChain<R, MAX_STAGES>> {
        self.axes.get(i)
    }

    /// No axis has a filter.
    pub fn is_empty(&self) -> bool {
        self.axes.iter().all(FilterChain::is_empty)
    }
}
