//! What the servo step needs from the machine once per period, and the description of the
//! machine's sensors and actuators as the controller knows them.
//!
//! The board implements [`ServoIo`] with the encoder timers, the safety input pins and
//! TIM1's PWM; the simulator (and the firmware's QEMU rig) with the simulated world
//! ([`crate::sim::world::World`]). Every method runs inside the control interrupt: short,
//! bounded, non-blocking.

use crate::axes::{Axis, AXES};
use crate::config::{limit, positive, ConfigError};
use crate::estimator::CounterWidth;

/// Digital safety inputs sampled once per period, already converted to "active".
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Inputs {
    /// E-stop active (pressed or wire broken).
    pub estop: bool,
    /// Per axis `[min, max]` limit switch active.
    pub limits: [[bool; 2]; AXES],
    /// Per axis: the amplifier's fault output is active.
    pub amp_fault: [bool; AXES],
    /// The previous control period missed its deadline (the board's timer had already
    /// fired again when it ended).
    pub overrun: bool,
}

impl Inputs {
    /// The first active limit switch: (axis, high end).
    pub fn first_limit(&self) -> Option<(Axis, bool)> {
        // the common case (no switch) in one test; the search only when one is on
        if !self.limits.iter().flatten().any(|&on| on) {
            return None;
        }
        Axis::ALL
            .into_iter()
            .zip(self.limits)
            .find_map(|(axis, sides)| match sides {
                [true, _] => Some((axis, false)),
                [_, true] => Some((axis, true)),
                _ => None,
            })
    }
}

/// Per-period access to sensors and actuators.
pub trait ServoIo<R> {
    /// Samples e-stop, limit switches, amplifier faults and the deadline flag.
    fn read_inputs(&mut self) -> Inputs;

    /// Raw encoder counter registers, X, Y, Z (each meaningful in its timer's width).
    fn read_counters(&mut self) -> [u32; AXES];

    /// Per axis: the counter register captured at the encoder's index pulse, when one
    /// came since the last call (read only while homing on the index; `None` where the
    /// encoder or the board has no index input).
    fn read_index(&mut self) -> [Option<u32>; AXES] {
        [None; AXES]
    }

    /// Drives the axes with the (already saturated) efforts and turns the output stage on
    /// if it is off.
    fn write_outputs(&mut self, effort: &[R; AXES]);

    /// Switches every output off (PWM main output disabled, duties zero, drive enables
    /// low). Idempotent; safe to call in every period.
    fn disable_outputs(&mut self);

    /// Drives the holding brakes: `released[i]` energises axis i's brake coil (brake
    /// open), `false` de-energises it (brake gripping, the fail-safe state). Called once
    /// per period after the outputs (and again, all `false`, whenever the outputs go off
    /// early in a period); idempotent. The default does nothing: a machine without brake
    /// outputs ([`super::brake`]).
    fn write_brakes(&mut self, released: [bool; AXES]) {
        let _ = released;
    }

    /// The simulated plant's true velocities, for [`crate::estimator::EstimatorConfig::Exact`]
    /// (`None` on hardware, which has no such oracle).
    fn true_velocity(&self) -> Option<[f64; AXES]> {
        None
    }
}

/// One axis' quadrature encoder as the controller reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct EncoderConfig {
    /// Counts per unit of length (per mm on a machine; per normalised unit for the paper's
    /// axis). 2000 lines × 4 on a 5 mm lead: 1600 counts/mm.
    pub counts_per_mm: f32,
    /// Width of the hardware counter (TIM2/TIM5: 32 bits, TIM3: 16 bits).
    pub counter: CounterWidth,
    /// Counts between two index pulses (one revolution of the encoder: 2000 lines × 4 =
    /// 8000), 0 where the encoder has no index or the board does not capture it. With
    /// it, counts lost or gained between index passes are corrected or faulted
    /// (`servo::index_check`).
    #[cfg_attr(feature = "serde", serde(default))]
    pub index_period_counts: u32,
    /// The counter counts down when the axis moves forward (A and B swapped in the wiring,
    /// or the encoder mounted facing the other way): the servo negates its steps, so the
    /// machine's coordinates stay as the axis moves (setting `axis.<a>.encoder.invert`).
    #[cfg_attr(feature = "serde", serde(default))]
    pub invert: bool,
}

impl EncoderConfig {
    /// Length of one count in `f64` (`1 / counts_per_mm`).
    pub fn count_len(&self) -> Result<f64, ConfigError> {
        Ok(1.0 / f64::from(positive(self.counts_per_mm, "encoder.counts_per_mm")?))
    }
}

/// One axis' amplifier as the controller drives it.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct AmplifierConfig {
    /// Effort at full command (100 % PWM duty), in the laws' units (mN·m of motor torque
    /// on the machine); commands are saturated to `±full_scale` (`inf`: ideal amplifier).
    pub full_scale: f32,
    /// Command resolution in bits over `±full_scale` (TIM1's duty resolution: 12 bits at
    /// 20 kHz PWM from 168 MHz... up to 13); 0: ideal (no quantisation). Used by the
    /// simulated amplifier; the board's is what its timer gives.
    #[cfg_attr(feature = "serde", serde(default))]
    pub resolution_bits: u8,
    /// A positive command turns the motor backwards (its phases or the amplifier's
    /// direction input wired the other way): the servo negates the effort it writes
    /// (setting `axis.<a>.motor.invert`). The simulated amplifier ignores it: it models the
    /// wiring, not the setting.
    #[cfg_attr(feature = "serde", serde(default))]
    pub invert: bool,
}

impl AmplifierConfig {
    /// Validated full scale.
    pub fn checked_full_scale(&self) -> Result<f32, ConfigError> {
        if self.resolution_bits > 24 {
            return Err(ConfigError::OutOfRange(
                "amplifier.resolution_bits (0..=24)",
            ));
        }
        if self.resolution_bits > 0 && !self.full_scale.is_finite() {
            return Err(ConfigError::NotFinite(
                "amplifier.full_scale (finite when resolution_bits > 0)",
            ));
        }
        limit(self.full_scale, "amplifier.full_scale")
    }
}
