//! The input shaper kernel (`shaper3_f32`): one period of
//! [`controller_core::motion::shaper::InputShaper`] on three axes with the board's history
//! (`BOARD_SHAPER_HISTORY`) at 10 kHz: MZV on X at 90 Hz, ZV on Y at 35 Hz, ZVD on Z at
//! 55 Hz (the gantry's modes; one tap per impulse on whole periods, 8 taps in all), the
//! reference a 20 mm circle at 100 mm/s in XY rising 5 mm/s in Z, every axis moving (the
//! shaper is not settled, and every tap reads a different sample). `shaper3_f32_rest`: the
//! same set with the input at rest for longer than the window (the same work, and the
//! longest path of the comparison with the previous sample), on a history of 256
//! periods ([`REST_HISTORY`]; the set's window is 183): a second 18 KB history would
//! leave the emulator's RAM too little stack for the `plan_task_*` setups, and the cost
//! hardly depends on the capacity (the ring index is masked; the compiler's byte form of
//! the 256 mask is one instruction more per tap).

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

/// The history of `shaper3_f32_rest` (periods).
pub const REST_HISTORY: usize = 256;

/// The board's shaper with a history of `N` periods, its history and the next period's
/// input. In this order (`repr(C)`): the input and the taps within an immediate offset of
/// the kernel's one base address, as a caller's would be, not behind the 18 KB history.
#[repr(C)]
pub struct Shaper3<const N: usize> {
    input: RefSample<f32>,
    shaper: InputShaper<f32, N>,
    state: ShaperState<f32, N>,
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

impl Shaper3<BOARD_SHAPER_HISTORY> {
    /// The board's set, warmed up on the circle.
    pub fn setup() -> Option<Self> {
        Self::with(circle)
    }
}

impl Shaper3<REST_HISTORY> {
    /// The board's set at rest (the input constant for longer than the window): the
    /// comparison of the new sample with the previous one sees all nine values equal,
    /// its longest path.
    pub fn setup_rest() -> Option<Self> {
        Self::with(|_| circle(0))
    }
}

impl<const N: usize> Shaper3<N> {
    fn with(input_at: impl Fn(u32) -> RefSample<f32>) -> Option<Self> {
        let cfg = AxisShapers {
            x: Some(ShaperConfig::new(ShaperKind::Mzv, 90.0)),
            y: Some(ShaperConfig::new(ShaperKind::Zv, 35.0)),
            z: Some(ShaperConfig::new(ShaperKind::Zvd, 55.0)),
        };
        let shaper = InputShaper::new(&cfg, PERIOD_S).ok()?;
        let taps: usize = Axis::ALL.iter().map(|a| shaper.taps(*a)).sum();
        let mut state = shaper.state(&input_at(0));
        for n in 1..WARMUP_PERIODS {
            shaper.process(&mut state, &input_at(n));
        }
        let input = input_at(WARMUP_PERIODS);
        (taps == 8).then_some(Self {
            shaper,
            state,
            input,
        })
    }

    /// One period; returns the shaped reference (the kernel keeps it: nothing is
    /// optimised away, and no arithmetic on it is counted).
    #[inline(never)]
    pub fn step(&mut self) -> RefSample<f32> {
        self.shaper.process(&mut self.state, &self.input)
    }
}
