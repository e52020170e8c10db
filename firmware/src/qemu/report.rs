//! The end of a QEMU run: human-readable figures and interrupt statistics, then one
//! machine-readable line for host-sim's `qemu-verdict`, then the exit code.
//!
//! The machine-readable line carries every figure as the IEEE-754 bits of its `f64` in
//! lower-case hex (`f64::to_bits`, no `0x`), so the host compares bit for bit:
//!
//! ```text
//! gantry-figures name=<name> samples=<u64> itse=<h>,<h>,<h> itse_window=<h>,<h>,<h>
//!   iae=<h>,<h>,<h> max_abs_error=<h>,<h>,<h> contour_max=<h> contour_rms=<h>
//!   tv_u=<h>,<h>,<h> peak_u=<h>,<h>,<h> fault=<fault> injected=<period>
//! ```
//!
//! (one line). `fault` is the first latched fault, `<kind>:<axis>:<period>` (the kind's
//! `FaultKind::name`, the axis `x`/`y`/`z` or `-` for a system fault, the servo's period
//! counter at detection), or `none`; `injected` is the run's period of the scripted fault
//! injection (`SimRun::injected_at`), or `none`.

use core::fmt::Write as _;

use controller_core::servo::faults::FaultRecord;
use firmware::telemetry::Telemetry;

use super::scenario::End;
use crate::qemu_exit::{exit, EXIT_COMPLETED, EXIT_FAULT, EXIT_UNDETECTED};

/// `<kind>:<axis or ->:<period>` or `none`.
fn fault_field(f: Option<FaultRecord>) -> heapless::String<48> {
    let mut s = heapless::String::new();
    let _ = match f {
        Some(r) => write!(
            s,
            "{}:{}:{}",
            r.fault.kind.name(),
            r.fault.axis.map_or("-", |a| a.name()),
            r.period
        ),
        None => s.push_str("none").map_err(|_| core::fmt::Error),
    };
    s
}

/// `<period>` or `none`.
fn injected_field(k: Option<u32>) -> heapless::String<16> {
    let mut s = heapless::String::new();
    let _ = match k {
        Some(k) => write!(s, "{k}"),
        None => s.push_str("none").map_err(|_| core::fmt::Error),
    };
    s
}

/// Prints the figures and exits: 0 if the run completed (with the injected fault
/// detected, if it injects one), 3 if a run without injection ended in a fault, 4 if an
/// injected fault went undetected.
pub fn finish(t: &Telemetry, end: &End) -> ! {
    let f = &end.figures;
    defmt::info!(
        "{=str}: {=u32} periods; true-state figures: ITSE=[{=f64}, {=f64}, {=f64}] IAE=[{=f64}, {=f64}, {=f64}] max|e|=[{=f64}, {=f64}, {=f64}] contour max={=f64} rms={=f64} peak|u|=[{=f64}, {=f64}, {=f64}]",
        end.name,
        end.periods,
        f.itse[0],
        f.itse[1],
        f.itse[2],
        f.iae[0],
        f.iae[1],
        f.iae[2],
        f.max_abs_error[0],
        f.max_abs_error[1],
        f.max_abs_error[2],
        f.contour_max,
        f.contour_rms,
        f.peak_u[0],
        f.peak_u[1],
        f.peak_u[2]
    );
    let tm = &t.timing;
    defmt::info!(
        "control ISR (the whole handler but the simulated world's step, QEMU -icount instructions): min={=u32} mean={=u32} max={=u32} over {=u32} periods, {=u32} overruns of the emulated period",
        tm.min,
        tm.mean(),
        tm.max,
        tm.periods,
        tm.overruns
    );
    defmt::info!(
        "gantry-figures name={=str} samples={=u64} itse={=u64:x},{=u64:x},{=u64:x} itse_window={=u64:x},{=u64:x},{=u64:x} iae={=u64:x},{=u64:x},{=u64:x} max_abs_error={=u64:x},{=u64:x},{=u64:x} contour_max={=u64:x} contour_rms={=u64:x} tv_u={=u64:x},{=u64:x},{=u64:x} peak_u={=u64:x},{=u64:x},{=u64:x} fault={=str} injected={=str}",
        end.name,
        f.samples,
        f.itse[0].to_bits(),
        f.itse[1].to_bits(),
        f.itse[2].to_bits(),
        f.itse_window[0].to_bits(),
        f.itse_window[1].to_bits(),
        f.itse_window[2].to_bits(),
        f.iae[0].to_bits(),
        f.iae[1].to_bits(),
        f.iae[2].to_bits(),
        f.max_abs_error[0].to_bits(),
        f.max_abs_error[1].to_bits(),
        f.max_abs_error[2].to_bits(),
        f.contour_max.to_bits(),
        f.contour_rms.to_bits(),
        f.tv_u[0].to_bits(),
        f.tv_u[1].to_bits(),
        f.tv_u[2].to_bits(),
        f.peak_u[0].to_bits(),
        f.peak_u[1].to_bits(),
        f.peak_u[2].to_bits(),
        fault_field(end.fault).as_str(),
        injected_field(end.injected_at).as_str()
    );
    match (end.injects, end.fault) {
        (true, Some(f)) => {
            defmt::info!(
                "{=str}: run completed; injected fault detected: {} (state {})",
                end.name,
                f,
                t.snapshot.state
            );
            exit(EXIT_COMPLETED)
        }
        (true, None) => {
            defmt::error!("{=str}: the injected fault was not detected", end.name);
            exit(EXIT_UNDETECTED)
        }
        (false, Some(f)) => {
            defmt::error!("{=str}: the run ended in fault {}", end.name, f);
            exit(EXIT_FAULT)
        }
        (false, None) => {
            defmt::info!("{=str}: run completed", end.name);
            exit(EXIT_COMPLETED)
        }
    }
}
