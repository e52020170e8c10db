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
//! `D`, the largest of the shaped axes' centroids on whole periods (below): each axis is
//! shifted by whole periods onto `D`, and an axis without a shaper is a pure delay of `D`
//! (one tap, a plain copy). The whole reference is then late by `D` and the axes stay in
//! step.
//!
//! **Whole periods.** Every impulse time is rounded to the nearest control period, so
//! each impulse is one tap reading one sample. (The first version split an impulse
//! between its two neighbouring samples; that doubled the taps, 16 instead of 8 on the
//! board, and was dropped.) The rounding moves an impulse by at most half a period `T`
//! from its time after the first one: 50 µs at 10 kHz, 0.35 % of ZV's half period at
//! 35 Hz (14.36 ms) and 0.17 % of the mode's period, so the shaper is tuned at most
//! 0.35 % off 35 Hz, a tenth of the narrowest band (ZV's, ±3.7 %). Rounded times move the
//! centroid `c` (in periods) off a whole period; the amplitudes are then tilted,
//! `Aᵢ' = Aᵢ (1 + (kᵢ − c)(round(c) − c)/M)` (`kᵢ` the rounded times, `M` their second
//! moment about `c`): the smallest change that keeps their sum at 1 and puts the
//! centroid on `round(c)` exactly, so the axes stay in step and the contour bound holds
//! as derived. It changes an amplitude by at most `½ |kᵢ − c| / M` relative (1.0 % on the
//! board's set), and `Σ |Aᵢ' − Aᵢ| ≤ 2.04 f T` (ZV: exactly `2 |round(c) − c|` over the
//! spacing, ≤ 2 f T; 2.04 f T is the largest over every kind and damping ratio,
//! computed).
//!
//! What it costs in residual vibration: each term of Klipper's `V = |Σ Aᵢ g(tᵢ)|` has
//! `|g| ≤ 1` and `|g'| ≤ ω` up to the last impulse (`g(t) = e^{−ζω(T_N − t)} e^{iω_d t}`),
//! so the rounding changes `V` by at most
//! `Σ |Aᵢ' − Aᵢ| + ω Σ Aᵢ |tᵢ' − tᵢ| ≤ 2.04 f T + π f T ≤ 5.2 f T`: 1.8 % at 35 Hz and
//! 10 kHz, 5.2 % at the highest mode accepted, 1/100 of the rate
//! ([`block::MAX_FREQ_OF_RATE`], 100 Hz at 10 kHz; the shortest spacing of any kind is
//! then 37.5 periods, a tuning at most 1.3 % off). At 35 Hz (ζ = 0.1, tests/shaper.rs,
//! measured on the simulated mode) the bound of each kind is 0.3 … 0.8 %, and the taps
//! leave at the design frequency:
//!
//! | kind | zv | mzv | zvd | ei | 2hump_ei | 3hump_ei |
//! |---|---|---|---|---|---|---|
//! | V, Klipper's impulses | 0 | 0 | 0 | 5.06 % | 0.05 % | 4.92 % |
//! | V, taps on whole periods | 0.54 % | 0.43 % | 0.39 % | 5.08 % | 0.28 % | 4.82 % |
//!
//! A tilted amplitude that would not be positive is refused
//! (`shaper.<axis>.damping_ratio (too high …)`): a tiny impulse of a heavily damped mode,
//! e.g. ZV at ζ = 0.9 and 100 Hz, whose second impulse (0.15 %) cannot put the centroid
//! on a whole period. Offsets and weights are computed once (`f64`) at construction; a
//! period only reads them.
//!
//! **Limits.** Each shaped value is a convex combination of the last `N` samples
//! (computed as `x₀ + Σ wᵢ (xᵢ − x₀)` from the axis' newest tap `x₀`: the same
//! combination with `x₀`'s weight `1 − Σ wᵢ`, exact on a constant input), so per
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
//! [`ShaperState`] holds `N` periods (a power of two: the ring index is a mask, which
//! also keeps every read in range without a bound check) of the reference sample as the
//! planner gives it (`RefSample`: positions, velocities, accelerations): `36·N` bytes in
//! `f32`, one 36-byte copy per period. The board's capacity is [`BOARD_SHAPER_HISTORY`]
//! = 256 periods = 25.6 ms at 10 kHz, 9 216 bytes, in the machine's memory
//! (`MachineMemory::shaper`, [`stage`]). It holds the board's set (its window is 183
//! periods: ZVD's 1/55 Hz on Z), ZV and MZV at this gantry's lowest mode (Y, 35 Hz; the
//! modes are 35 Hz Y, 55 Hz Z, 90 Hz X), ZVD and EI from 39.4 Hz, 2hump_ei from
//! 58.4 Hz. Twice that (512 periods, 18 432 bytes) would hold ZVD and EI at 35 Hz (they
//! last one damped period there, 287 periods) and every kind down to Klipper's own
//! minimum frequencies (`min_freq` in shaper_defs.py: zv 21, mzv 23, zvd/ei 29, 2hump_ei
//! 39, 3hump_ei 48 Hz), but the board's SRAM is allotted (40 KiB of stack, the statics,
//! the planner in the CCM): with 512 the QEMU build's RAM overflowed by 4.9 KiB. The
//! capacity hardly matters per period (the index is masked whatever `N`; at 256 the
//! compiler's byte form of the mask is one instruction more per index).
//!
//! Lowest frequency of each kind in a 512-period history (ζ = 0.1, 10 kHz, one shaped
//! axis: its duration within `N − 1` periods; [`min_freq_hz`], checked by the tests; the
//! frequencies scale with the control rate, double them at 20 kHz; in the board's 256
//! periods they are 2.004 times these: zv 19.7, mzv 29.6, zvd and ei 39.4, 2hump_ei
//! 58.4, 3hump_ei 77.8 Hz):
//!
//! | kind | zv | mzv | zvd | ei | 2hump_ei | 3hump_ei |
//! |---|---|---|---|---|---|---|
//! | min `freq_hz` | 9.84 | 14.76 | 19.67 | 19.67 | 29.14 | 38.81 |
//!
//! A set whose window (the oldest tap of any axis, after the shifts onto `D`) exceeds
//! `N − 1` periods is refused with `ConfigError::OutOfRange("shaper.<axis> (<kind>)
//! longer than the shaper history …")`. The highest accepted mode is 1/100 of the control
//! rate ([`block::MAX_FREQ_OF_RATE`], 100 Hz at 10 kHz: "Whole periods" above).
//!
//! # Start, jumps, end
//!
//! The history starts filled with the first sample, so a machine at rest stays exactly at
//! rest. [`ShaperState::reset`] refills it when the reference jumps (homing re-bases the
//! axes, a mode change): nothing is interpolated across a jump. When the input has been
//! constant for the whole window, [`ShaperState::is_settled`] is true and the output is
//! the input bit for bit (every difference from the reference tap is zero);
//! [`ShaperState::pending_periods`] tells how long a program's end or a stop still has
//! to wait for the shaped reference to arrive.
//!
//! Inputs must be finite (the planner's are): a non-finite sample would stay in the
//! output for the window, where the servo's non-finite check catches it.
//!
//! # Cost
//!
//! Per period: the head moves (a mask), the new sample is compared with the previous one
//! (for [`ShaperState::is_settled`]; the comparison stops at the first value that
//! differs) and copied into the history (`LDM`/`STM`); then per axis the reference tap's
//! three values, and per other tap its offset and weight, the masked index, three loads,
//! three differences and three products, the taps unrolled (one compare per tap, no
//! loop); nothing is recomputed from the configuration. `cargo insns`
//! (insns/README.md), one period of the board's set (MZV X 90 Hz, ZV Y 35 Hz, ZVD Z
//! 55 Hz, 10 kHz; 8 taps), the call from the kernel included:
//!
//! | kernel | instructions | cycles_est |
//! |---|---|---|
//! | `shaper3_f32`: every axis moving (the comparison stops at the first value) | 176 | 301 |
//! | `shaper3_f32_rest`: at rest (all nine values compared; nothing is skipped) | 230 | 372 |
//! | the first version: 16 split taps, a loop per axis | 383 | 668 |
//! | the first version with its impulses on the grid: 8 taps, a loop per axis | 277 | 458 |
//!
//! (`shaper3_f32_rest` runs on a 256-period history, whose mask the compiler writes as a
//! byte extension: one instruction more per index, 8 cycles.) Where the 301 cycles go:
//! the call, the saved registers and the nine results stored ≈ 60; head, comparison,
//! copy and age ≈ 50; per axis the reference tap ≈ 14, each other tap ≈ 27 (offset and
//! weight 4, index 4, three loads 6, three differences 3, three products 3 or, from the
//! second on, three multiply-adds the compiler fuses into `VMLA`, 9) and the final three
//! sums with the branch to the next axis ≈ 7: X (3 taps) 73, Y (2) 44, Z (3) 72. 301
//! cycles are 1.8 µs at 168 MHz, 1.8 % of the 10 kHz period. Storing the history per
//! axis (`[pos, vel, acc]` contiguous) was measured too: 4 cycles more, as the compiler
//! still loads a tap's three values one by one (no `VLDM`) and the sample's copy becomes
//! nine loads and nine stores.
//!
//! Issue 24's budget (notch filters and shaper ≤ 150 cycles, the shaper ≤ ~90) does not
//! hold for three shaped channels of three axes in the control interrupt: reading the
//! board's 8 taps alone takes 8 × (index 6 + three loads 6) = 96 cycles, their 5 × 3
//! differences and products ≥ 30, the sample's copy 22 and the nine results 18: ≥ 166
//! cycles before any call, compare or branch (and ≥ 40 with no tap at all). It takes
//! either a budget of ~300 cycles for the shaper or shaping outside the interrupt (in the
//! planning task, ahead of the executor).

pub mod block;
pub mod bound;
pub mod impulses;
pub mod stage;

pub use block::{AxisShapers, InputShaper, ShaperState, MAX_TAPS};
pub use bound::DeviationBound;
pub use impulses::{min_freq_hz, Impulses, ShaperConfig, ShaperKind};
pub use stage::{shaped_planner_config, ShapedPlannerError, ShaperStage};

/// The board's history capacity (periods): 25.6 ms at 10 kHz, 9 216 bytes in `f32`
/// (module docs, "The history": it holds ZV and MZV at Y's 35 Hz, ZVD and EI from
/// 39.4 Hz; 512 does not fit the board's SRAM).
pub const BOARD_SHAPER_HISTORY: usize = 256;

#[cfg(test)]
mod tests;
