//! Host evidence that the servo step cannot panic: [`servo_period`] wraps
//! `controller_core::servo::Servo::<f32>::period_with` with compensation tables (the code the firmware's control
//! interrupt runs, with an IO whose every reading is opaque to the optimiser) in
//! `#[no_panic]`. The attribute makes any unwinding out of the function call an undefined
//! symbol, so this binary only *links* if the optimiser proved that no panic is reachable
//! from the step, for every configuration, state and input. Built with the workspace's
//! release profile (the firmware's: opt-level 3, fat LTO, one codegen unit):
//!
//! ```sh
//! cargo run -p servo-no-panic --release
//! ```
//!
//! The failure is a link error, `undefined symbol: ERROR[no-panic]: detected panic in
//! function `servo_period``. The firmware's own ELF is checked separately (`firmware/tools/check-no-panic`,
//! the call graph of the TIM4 handler), since the board's IO and the thumb code generation
//! differ from this host build.

use std::hint::black_box;

use controller_core::axes::AXES;
use controller_core::motion::compensation::CompTables;
use controller_core::presets::board::{servo_config, BOARD_RATE_HZ};
use controller_core::servo::io::{Inputs, ServoIo};
use controller_core::servo::snapshot::Snapshot;
use controller_core::servo::{Command, Servo};

/// Sensors and actuators the optimiser knows nothing about: every reading comes from a
/// field written through `black_box`, every output goes to one.
struct OpaqueIo {
    inputs: Inputs,
    counters: [u32; AXES],
    effort: [f32; AXES],
    disabled: u32,
}

impl ServoIo<f32> for OpaqueIo {
    #[inline(never)]
    fn read_inputs(&mut self) -> Inputs {
        black_box(self.inputs)
    }

    #[inline(never)]
    fn read_counters(&mut self) -> [u32; AXES] {
        black_box(self.counters)
    }

    #[inline(never)]
    fn write_outputs(&mut self, effort: &[f32; AXES]) {
        self.effort = black_box(*effort);
    }

    #[inline(never)]
    fn disable_outputs(&mut self) {
        self.disabled = black_box(self.disabled.wrapping_add(1));
    }
}

/// The servo step, proven panic-free at link time (release builds; a debug build keeps
/// every unwinding edge, so the attribute is only applied with optimisations and `main`
/// refuses to claim anything without them).
#[cfg_attr(not(debug_assertions), no_panic::no_panic)]
#[inline(never)]
fn servo_period(
    servo: &mut Servo<f32>,
    io: &mut OpaqueIo,
    commands: &[Command],
    tables: &CompTables,
) -> Snapshot {
    *servo.period_with(io, commands, Some(tables))
}

fn main() {
    if cfg!(debug_assertions) {
        eprintln!("servo-no-panic: proves nothing in a debug build: cargo run -p servo-no-panic --release");
        std::process::exit(2);
    }
    let cfg = black_box(servo_config(BOARD_RATE_HZ));
    let mut io = OpaqueIo {
        inputs: black_box(Inputs::default()),
        counters: black_box([0; AXES]),
        effort: [0.0; AXES],
        disabled: 0,
    };
    let Ok(mut servo) = Servo::<f32>::new(&cfg, io.counters, [0; AXES]) else {
        eprintln!("servo-no-panic: the board configuration was rejected");
        std::process::exit(1);
    };
    // the machine's compensation tables, opaque too (the board passes its own)
    let tables = black_box(CompTables::NONE);
    let arm = black_box([Command::Arm, Command::StartPath]);
    let mut snap = servo_period(&mut servo, &mut io, &arm, &tables);
    for k in 1..1000u32 {
        io.counters = black_box([k, k / 2, k / 3]);
        snap = servo_period(&mut servo, &mut io, &[], &tables);
    }
    println!(
        "servo-no-panic: Servo::<f32>::period_with linked under #[no_panic] (no panic path); \
         1000 periods run, state {:?}, {} output switch-offs",
        snap.state, io.disabled
    );
}
