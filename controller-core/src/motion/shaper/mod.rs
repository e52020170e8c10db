//! Input shaping of the reference, per axis: the planner's samples are convolved with a
//! short train of impulses so that the reference no longer excites the machine's
//! resonances (issue 24, item 4). The kinds and their impulses are Klipper's (ZV, MZV,
//! ZVD, EI, 2-hump EI, 3-hump EI; `klippy/extras/shaper_defs.py`, see [`impulses`]),
//! tuned from the measured modes (frequency, damping ratio).
//!
//! - [`impulses`]: [`ShaperKind`], [`ShaperConfig`] and the impulse sequences;
//! - [`block`]: [`InputShaper`] (validated taps of the three axes) and its
//!   [`ShaperState`] (the history), `process` once per control period;
//! - [`bound`]: the contour deviation the shaping adds, and how it is counted inside the
//!   path tolerance.
//!
//! # What it computes
//!
//! A shaper is linear: `y(t) = Σᵢ Aᵢ r(t − tᵢ)` with `Aᵢ > 0`, `Σ Aᵢ = 1`. It is applied
//! to position, velocity and acceleration alike (each sample of the history holds all
//! three), so the shaped velocity and acceleration are exactly the derivatives of the
//! shaped position: the servo's feed-forward stays consistent.
//!
//! **One delay for all axes.** A shaper delays a slow signal by its centroid
//! `cᵢ = Σ Aᵢ tᵢ`; different shapers per axis would delay the axes differently and skew
//! the path by velocity × the centroid difference (ZV at 35 Hz on Y against MZV at 90 Hz
//! on X: 2.4 ms, 0.6 mm at 250 mm/s). So every axis is delayed to the common centroid
//! `D = max` over the shaped axes of `cᵢ`, rounded up to a whole period: axis i's impulse
//! times are shifted by `D − cᵢ`, and an axis without a shaper is a pure delay of `D`
//! (one tap). The whole reference is then late by `D` and the axes stay in step.
//!
//! **Between samples.** An impulse time that is not on a period boundary is split
//! linearly between the two neighbouring samples (`A(1 − f)` and `A f`): weights stay
//! non-negative and sum to 1, and the split keeps the impulse's time as their mean, so the
//! axis' centroid stays at `D`. Offsets and weights are computed once (`f64`) at
//! construction; a period reads only the taps (two per impulse at most).
//!
//! **Limits.** Each shaped value is a convex combination of the last `N` samples, so per
//! axis `|shaped vel| ≤ max |vel|` and `|shaped acc| ≤ max |acc|` over the window (up to
//! the number type's rounding, a few ulp): the planner's per-axis velocity and
//! acceleration limits hold after shaping. (A limit on the norm of the 3-D vector holds
//! too when every axis carries the same shaper; with different shapers it can be
//! exceeded by up to √3 in theory; the planner's limits are per axis.) Jerk likewise is
//! a convex combination of jerks, but it is not carried by the samples.
//!
//! **Contour deviation.** `½ √(Σᵢ (aᵢ Mᵢ)²)` with `Mᵢ` the axis' second moment about `D`
//! and `aᵢ` its acceleration bound ([`bound`], [`InputShaper::deviation_bound_mm`]); it
//! is counted inside the path tolerance by blending within the tolerance minus it
//! ([`DeviationBound::blend_tolerance_mm`]).
//!
//! # The history: capacity and memory
//!
//! [`ShaperState`] holds `N` periods (a power of two: the ring index is a mask) of
//! `[pos, vel, acc]` per axis: `36·N` bytes in `f32`. The board's capacity is
//! [`BOARD_SHAPER_HISTORY`] = 512 periods = 51.2 ms at 10 kHz, 18 432 bytes, a quarter
//! of the ~70 KB of SRAM the firmware leaves free. It holds every kind down to Klipper's
//! own minimum frequency of the kind (`min_freq` in shaper_defs.py: zv 21, mzv 23,
//! zvd/ei 29, 2hump_ei 39, 3hump_ei 48 Hz; the longest, 3hump_ei at 48 Hz, lasts 41 ms),
//! and every kind but 3hump_ei at this gantry's lowest mode (Y, 35 Hz; the modes are
//! 35 Hz Y, 55 Hz Z, 90 Hz X). Half of it (256 periods, 9 KB) would not hold EI at 35 Hz
//! (28.7 ms) beside a second axis' delay with margin for a mode identified lower; 1024
//! (36 KB) would take half the free SRAM for 3hump_ei below 39 Hz, which Klipper does
//! not recommend below 48 Hz anyway.
//!
//! Lowest frequency of each kind in that history (ζ = 0.1, 10 kHz, one shaped axis;
//! [`min_freq_hz`], checked by the tests; the frequencies scale with the control rate,
//! double them at 20 kHz):
//!
//! | kind | zv | mzv | zvd | ei | 2hump_ei | 3hump_ei |
//! |---|---|---|---|---|---|---|
//! | min `freq_hz` | 9.86 | 14.78 | 19.71 | 19.71 | 29.20 | 38.89 |
//!
//! A set whose window (`D` plus the longest shifted impulse of any axis) exceeds `N − 1`
//! periods is refused with `ConfigError::OutOfRange("shaper.<axis> (<kind>) longer than
//! the shaper history …")`. The highest accepted mode is 1/20 of the control rate
//! ([`block::MAX_FREQ_OF_RATE`], 500 Hz at 10 kHz).
//!
//! # Start, jumps, end
//!
//! The history starts filled with the first sample, so a machine at rest stays exactly at
//! rest. [`ShaperState::reset`] refills it when the reference jumps (homing re-bases the
//! axes, a mode change): nothing is interpolated across a jump. When the input has been
//! constant for the whole window, [`ShaperState::is_settled`] is true and the output is
//! the input bit for bit; [`ShaperState::pending_periods`] tells how long a program's
//! end or a stop still has to wait for the shaped reference to arrive.
//!
//! Inputs must be finite (the planner's are): a non-finite sample would stay in the
//! output for the window, where the servo's non-finite check catches it.
//!
//! # Cost
//!
//! Per period: the new sample is compared with the previous one and stored (9 values),
//! then per axis and tap one index, one weight and three multiply-adds on a contiguous
//! `[pos, vel, acc]`. `cargo insns` (insns/README.md), one period on the Cortex-M4:
//!
//! | kernel | taps | instructions | cycles_est |
//! |---|---|---|---|
//! | `shaper3_f32`: MZV X 90 Hz, ZV Y 35 Hz, ZVD Z 55 Hz (the board's set) | 16 | 383 | 668 |
//! | `shaper3_f32_on_grid`: the same kinds with every impulse on a period | 8 | 277 | 458 |
//!
//! About 26 cycles per tap (a weight, three loads, three `VMLA` of 3 cycles each, the
//! index) over ~250 of bookkeeping (the compare and store of the sample, three tap
//! loops, the returned sample). The split between samples doubles the taps: 668 against
//! 458 cycles. 668 cycles are 4.0 µs at 168 MHz, 4.0 % of the 10 kHz period. Issue 24's
//! budget of 150 cycles for filters and shaper together cannot hold three shaped
//! channels per axis: 16 taps × 3 channels × (a 2-cycle load and a 3-cycle `VMLA`) are
//! 240 cycles before any index, weight or bookkeeping.

pub mod block;
pub mod bound;
pub mod impulses;

pub use block::{AxisShapers, InputShaper, ShaperState, MAX_TAPS};
pub use bound::DeviationBound;
pub use impulses::{min_freq_hz, Impulses, ShaperConfig, ShaperKind};

/// The board's history capacity (periods): 51.2 ms at 10 kHz, 18 432 bytes in `f32`
/// (module docs, "The history").
pub const BOARD_SHAPER_HISTORY: usize = 512;

#[cfg(test)]
mod tests;
