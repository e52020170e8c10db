//! The input shaper kernel (`shaper3_f32`): one period of
//! [`controller_core::motion::shaper::InputShaper`] on three axes with the board's history
//! (`BOARD_SHAPER_HISTORY`, 512 periods) at 10 kHz: MZV on X at 90 Hz, ZV on Y at 35 Hz,
//! ZVD on Z at 55 Hz (the gantry's modes; 16 taps in all), the reference a 20 mm circle
//! at 100 mm/s in XY rising 5 mm/s in Z, every axis moving (the shaper is not settled, so
//! every tap is read).
//!
//! `shaper3_f32_on_grid` is the same period with every impulse on a period boundary (one
//! tap per impulse, 8 taps): undamped shapers (ζ = 0) at frequencies whose impulses and
//! centroids fall on the 10 kHz grid, MZV at 3750/42 = 89.29 Hz, ZV at 2500/71 =
//! 35.21 Hz, ZVD at 5000/91 = 54.95 Hz. It prices the alternative of rounding the
//! impulse times to whole periods instead of splitting them. Its history is 256 periods
//! (its window is 182): the cost does not depend on the capacity (the ring index is a
//! mask), and a second 18 KB history would leave the emulator's RAM too little stack for
//! the `plan_task_*` setups.

use controller_core::axes::Axis;
use controller_core::motion::shaper::{
    AxisShapers, InputShaper, ShaperConfig, ShaperKind, ShaperState, BOARD_SHAPER_HISTORY,
};
use controller_core::motion::trajectory::RefSample;
use controller_core::Vec3;

/// The board's control period (10 kHz).
const PERIOD_S: f32 = 1.0e-4;
const RADIUS_MM: f32 = 20.0;
const SPEED_MM_S: f32 = 100.0;
const Z_RATE_MM_S: f32 = 5.0;
/// Periods run before counting: longer than the shaper's window.
const WARMUP_PERIODS: u32 = 2000;

/// The history of `shaper3_f32_on_grid` (periods).
pub const ON_GRID_HISTORY: usize = 256;

/// The shaper with a history of `N` periods, its history and the next period's input.
pub struct Shaper3<const N: usize> {
    shaper: InputShaper<f32, N>,
    state: ShaperState<f32, N>,
    input: RefSample<f32>,
}

/// The reference at period `n`.
fn circle(n: u32) -> RefSample<f32> {
    let om = SPEED_MM_S / RADIUS_MM;
    let t = n as f32 * PERIOD_S;
    let (s, c) = (libm::sinf(om * t), libm::cosf(om * t));
    let a = RADIUS_MM * om * om;
    RefSample {
        pos: Vec3::new(RADIUS_MM * s, RADIUS_MM * c, Z_RATE_MM_S * t),
        vel: Vec3::new(SPEED_MM_S * c, -SPEED_MM_S * s, Z_RATE_MM_S),
        acc: Vec3::new(-a * s, -a * c, 0.0),
    }
}

/// An undamped shaper of `kind` at `freq_hz`.
fn undamped(kind: ShaperKind, freq_hz: f32) -> Option<ShaperConfig> {
    let mut c = ShaperConfig::new(kind, freq_hz);
    c.damping_ratio = 0.0;
    Some(c)
}

impl Shaper3<BOARD_SHAPER_HISTORY> {
    /// The board's set, warmed up on the circle.
    pub fn setup() -> Option<Self> {
        Self::with(&AxisShapers {
            x: Some(ShaperConfig::new(ShaperKind::Mzv, 90.0)),
            y: Some(ShaperConfig::new(ShaperKind::Zv, 35.0)),
            z: Some(ShaperConfig::new(ShaperKind::Zvd, 55.0)),
        })
        .filter(|s| s.taps() == 16)
    }
}

impl Shaper3<ON_GRID_HISTORY> {
    /// The set whose impulses all fall on the period grid (8 taps).
    pub fn setup_on_grid() -> Option<Self> {
        Self::with(&AxisShapers {
            x: undamped(ShaperKind::Mzv, 3750.0 / 42.0),
            y: undamped(ShaperKind::Zv, 2500.0 / 71.0),
            z: undamped(ShaperKind::Zvd, 5000.0 / 91.0),
        })
        .filter(|s| s.taps() == 8)
    }
}

impl<const N: usize> Shaper3<N> {
    fn taps(&self) -> usize {
        Axis::ALL.iter().map(|a| self.shaper.taps(*a)).sum()
    }

    fn with(cfg: &AxisShapers) -> Option<Self> {
        let shaper = InputShaper::<f32, N>::new(cfg, PERIOD_S).ok()?;
        let mut state = shaper.state(&circle(0));
        for n in 1..WARMUP_PERIODS {
            shaper.process(&mut state, &circle(n));
        }
        let input = circle(WARMUP_PERIODS);
        (!state.is_settled()).then_some(Self {
            shaper,
            state,
            input,
        })
    }

    /// One period; returns a sum of the shaped values (so none is optimised away).
    #[inline(never)]
    pub fn step(&mut self) -> f32 {
        let y = self.shaper.process(&mut self.state, &self.input);
        y.pos.x + y.pos.y + y.pos.z + y.vel.x + y.vel.y + y.vel.z + y.acc.x + y.acc.y + y.acc.z
    }
}
