//! Output-filter kernels (`filters3_f32`, `filters3_fixed`): one period of the three
//! axes' output filters ([`OutputFilters::process`]) at the board's 10 kHz, with a
//! notch on every axis and a low-pass behind Z's: four biquads, the set an axis of the
//! flexible gantry gets (host-sim/machines/gantry_flexible.toml: X 90 Hz, Y 35 Hz,
//! Z 52 Hz modes).

use controller_core::filter::{AxisFilterConfig, FilterConfig, OutputFilters};
use controller_core::presets::board::BOARD_RATE_HZ;
use controller_core::{Real, Vec3};

fn notch(freq_hz: f32, width_hz: f32, depth_db: f32) -> FilterConfig {
    FilterConfig::Notch {
        freq_hz,
        width_hz,
        depth_db,
    }
}

/// Periods run before the counted one, under a varying input: every state non-zero.
const WARMUP_PERIODS: u32 = 500;

/// The filters and the output they are fed.
pub struct Filters3<R> {
    filters: OutputFilters<R>,
    u: Vec3<R>,
}

/// The kernels' filter set: a notch per axis and a low-pass behind Z's (four biquads).
pub fn flexible_filters() -> Option<[AxisFilterConfig; 3]> {
    Some([
        AxisFilterConfig::new(&[notch(90.0, 20.0, 15.0)]).ok()?,
        AxisFilterConfig::new(&[notch(35.0, 14.0, 13.0)]).ok()?,
        AxisFilterConfig::new(&[notch(52.0, 15.0, 18.0), FilterConfig::low_pass(400.0)]).ok()?,
    ])
}

impl<R: Real> Filters3<R> {
    pub fn setup() -> Option<Self> {
        let cfg = flexible_filters()?;
        let mut filters = OutputFilters::new(&cfg, 1.0 / BOARD_RATE_HZ as f32).ok()?;
        let mut u = Vec3::zero();
        for k in 0..WARMUP_PERIODS {
            let t = R::from_f32(k as f32 * 1.0e-3);
            let (s, c) = t.sin_cos();
            u = Vec3::new(s, c, s - c).scale(R::from_f32(250.0));
            filters.process(u);
        }
        Some(Self { filters, u })
    }

    /// One period: the three axes' outputs through their filters.
    #[inline(never)]
    pub fn step(&mut self) -> Vec3<R> {
        self.filters.process(self.u)
    }
}
