//! Hardware-free pieces of the gantry firmware; they build for the microcontroller and
//! for the host (unit tests). The control sequence, its safety state machine and the
//! simulated machine are controller-core's (`servo`, `sim`); the binary (`main.rs`,
//! `board/`, `qemu/`) adds the board glue and the RTIC tasks.
//!
//! - [`blank_static`]: the machine's large statics zero-filled and made blank in place
//!   at boot (no initial image in flash);
//! - [`config`]: the board's rates, scaling and servo configuration;
//! - [`button`]: the debounced arm/reset button and the commands a press sends;
//! - [`drive`]: effort to PWM duty and direction;
//! - [`telemetry`]: what the telemetry task gets besides the core's snapshot (interrupt
//!   timing);
//! - [`scenarios`] (feature `qemu`): the QEMU rig's scenario table;
//! - [`panel`] (feature `qemu`): the bytes of the QEMU link rig's operator panel (e-stop
//!   press and release on USART1);
//! - [`watchdog`]: the independent watchdog's timeout for the control rate;
//! - [`reset_cause`]: why the chip last reset (RCC_CSR), logged at boot;
//! - [`stall`]: control-loop stalls (a flash erase) longer than a 16-bit encoder counter
//!   can follow: that axis must be homed again;
//! - [`encoder_filter`]: the encoder timers' input filter and the count rate it passes;
//! - [`index_capture`]: an encoder index capture handed from its interrupt to the control
//!   period (the board's Y axis), and the guard against a noisy index line.
#![cfg_attr(not(test), no_std)]
// `!(x > 0.0)` is deliberate: it is also true for NaN, which must give no output.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod blank_static;
pub mod button;
pub mod config;
pub mod drive;
pub mod encoder_filter;
pub mod index_capture;
#[cfg(feature = "qemu")]
pub mod panel;
pub mod reset_cause;
#[cfg(feature = "qemu")]
pub mod scenarios;
pub mod stall;
pub mod telemetry;
pub mod watchdog;
