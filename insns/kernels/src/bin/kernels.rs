//! The Cortex-M4 ELF (and the Cortex-M3 one, `thumbv7m-none-eabi`) that `cargo insns`
//! runs in the emulator.
//!
//! Every kernel is exported as two C functions, `insns_setup_<name>()` (builds the state
//! in a static slot; not counted) and `insns_kernel_<name>()` (one counted step). The
//! replay entry points run a recorded input sequence for the bit-exactness check.
//! `main` only references every export so the linker keeps them; the emulator calls the
//! symbols directly after running the reset handler up to `main` (which initialises
//! `.data`/`.bss` and enables the FPU).
#![no_std]
#![no_main]

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use cortex_m_rt::entry;
use insns_kernels::{replay, Dsmc3, REPLAY_IN, REPLAY_OUT};

use controller_core::num::fixed::{FxQ16, FxQ32};
use controller_core::LibmF32;

/// A statically allocated kernel state. Only the emulator calls into this binary, one
/// function at a time, so there is never concurrent access.
struct Slot<T>(UnsafeCell<MaybeUninit<T>>);

// SAFETY: single-threaded use only (see the type's docs).
unsafe impl<T> Sync for Slot<T> {}

impl<T> Slot<T> {
    const fn new() -> Self {
        Self(UnsafeCell::new(MaybeUninit::uninit()))
    }
}

/// Export a kernel: `kernel!(name, StateType, setup_expr, |state| step_expr)`.
/// `setup_expr` evaluates to `Option<StateType>`; the exported setup returns 1 when it
/// built the state and 0 otherwise (the runner then reports the kernel as failed and
/// never calls its step).
macro_rules! kernel {
    ($name:ident, $state:ty, $setup:expr, |$s:ident| $step:expr) => {
        mod $name {
            use super::*;
            static SLOT: Slot<$state> = Slot::new();

            #[export_name = concat!("insns_setup_", stringify!($name))]
            pub extern "C" fn setup() -> u32 {
                match $setup {
                    Some(v) => {
                        // SAFETY: single-threaded; see `Slot`.
                        unsafe { (*SLOT.0.get()).write(v) };
                        1
                    }
                    None => 0,
                }
            }

            #[export_name = concat!("insns_kernel_", stringify!($name))]
            pub extern "C" fn kernel() {
                // SAFETY: the runner only calls this after `setup` returned 1.
                let $s = unsafe { (*SLOT.0.get()).assume_init_mut() };
                core::hint::black_box($step);
            }
        }
    };
}

/// The Cortex-M4F kernels (`thumbv7em-none-eabihf`): the control period and its parts.
#[cfg(target_abi = "eabihf")]
mod cortex_m4 {
    use super::*;
    use controller_core::estimator::{EstimatorConfig, PAPER_SIM_KALMAN, PAPER_SIM_PLL};
    use controller_core::motion::shaper::BOARD_SHAPER_HISTORY;
    use insns_kernels::filters::Filters3;
    use insns_kernels::link::{LinkDecode, LinkEncode};
    use insns_kernels::machine_period::MachinePeriod;
    use insns_kernels::parts::{PartChecks, PartCoupling, PartEstimators, PartLaws, PartReference};
    use insns_kernels::plan_task::{PlanTask, Program};
    use insns_kernels::planner::PlannerState;
    use insns_kernels::shaper::{Shaper3, REST_HISTORY};
    use insns_kernels::{Estimator3, Law3, LawKind, ServoPeriod};

    kernel!(dsmc3_f32, Dsmc3<f32>, Dsmc3::<f32>::setup(), |k| k.step());
    kernel!(
        dsmc3_f32_libm,
        Dsmc3<LibmF32>,
        Dsmc3::<LibmF32>::setup(),
        |k| k.step()
    );
    kernel!(dsmc3_fixed, Dsmc3<FxQ32>, Dsmc3::<FxQ32>::setup(), |k| k
        .step());
    kernel!(
        dsmc3_fixed_q16,
        Dsmc3<FxQ16>,
        Dsmc3::<FxQ16>::setup(),
        |k| k.step()
    );
    kernel!(
        estimator_pll,
        Estimator3<f32>,
        Estimator3::<f32>::setup(EstimatorConfig::Pll(PAPER_SIM_PLL)),
        |k| k.step()
    );
    kernel!(
        estimator_kalman,
        Estimator3<f32>,
        Estimator3::<f32>::setup(EstimatorConfig::Kalman(PAPER_SIM_KALMAN)),
        |k| k.step()
    );

    kernel!(law_pid3, Law3<f32>, Law3::<f32>::setup(LawKind::Pid), |k| k
        .step());
    kernel!(
        law_dsmc3,
        Law3<f32>,
        Law3::<f32>::setup(LawKind::Dsmc),
        |k| k.step()
    );
    kernel!(
        law_dob_smc3,
        Law3<f32>,
        Law3::<f32>::setup(LawKind::DobSmc),
        |k| k.step()
    );
    kernel!(
        law_adaptive_smc3,
        Law3<f32>,
        Law3::<f32>::setup(LawKind::AdaptiveSmc),
        |k| k.step()
    );
    kernel!(servo_period, ServoPeriod, ServoPeriod::setup(), |k| k
        .step());
    kernel!(
        servo_period_filtered,
        ServoPeriod,
        ServoPeriod::setup_filtered(),
        |k| k.step()
    );
    kernel!(filters3_f32, Filters3<f32>, Filters3::<f32>::setup(), |k| k
        .step());
    kernel!(
        filters3_fixed,
        Filters3<FxQ32>,
        Filters3::<FxQ32>::setup(),
        |k| k.step()
    );
    kernel!(
        servo_part_estimators,
        PartEstimators,
        PartEstimators::setup(),
        |k| k.step()
    );
    kernel!(
        servo_part_reference,
        PartReference,
        PartReference::setup(),
        |k| k.step()
    );
    kernel!(
        servo_part_coupling,
        PartCoupling,
        PartCoupling::setup(),
        |k| k.step()
    );
    kernel!(servo_part_laws, PartLaws, PartLaws::setup(), |k| k.step());
    kernel!(
        planner_sample,
        PlannerState,
        PlannerState::setup_sample(),
        |k| k.sample()
    );
    kernel!(
        planner_segment,
        PlannerState,
        PlannerState::setup_segment(),
        |k| k.add_segment()
    );
    kernel!(
        plan_task_period,
        PlanTask,
        PlanTask::setup_period(Program::Chords),
        |k| k.run()
    );
    kernel!(
        plan_task_segment,
        PlanTask,
        PlanTask::setup_segment(Program::Chords),
        |k| k.run()
    );
    kernel!(
        plan_task_arc,
        PlanTask,
        PlanTask::setup_segment(Program::Arcs),
        |k| k.run()
    );
    kernel!(
        machine_period_program,
        MachinePeriod,
        MachinePeriod::setup_program(),
        |k| k.step()
    );
    kernel!(
        machine_period_shaped,
        MachinePeriod,
        MachinePeriod::setup_shaped(),
        |k| k.step()
    );
    kernel!(
        machine_period_idle,
        MachinePeriod,
        MachinePeriod::setup_idle(),
        |k| k.step()
    );
    kernel!(servo_part_checks, PartChecks, PartChecks::setup(), |k| k
        .step());
    kernel!(
        shaper3_f32,
        Shaper3<BOARD_SHAPER_HISTORY>,
        Shaper3::setup(),
        |k| k.step()
    );
    kernel!(
        shaper3_f32_rest,
        Shaper3<REST_HISTORY>,
        Shaper3::setup_rest(),
        |k| k.step()
    );
    kernel!(link_decode_segment, LinkDecode, LinkDecode::setup(), |k| k
        .step());
    kernel!(
        link_encode_telemetry,
        LinkEncode,
        LinkEncode::setup(),
        |k| k.telemetry()
    );
    kernel!(link_encode_status, LinkEncode, LinkEncode::setup(), |k| k
        .status());
}

/// The FPU-less Cortex-M3 kernels (`thumbv7m-none-eabi`, e.g. STM32F1): the 3-axis DSMC
/// step in soft-float `f32` and in fixed point, names suffixed `_m3`.
#[cfg(target_abi = "eabi")]
mod cortex_m3 {
    use super::*;

    kernel!(dsmc3_f32_m3, Dsmc3<f32>, Dsmc3::<f32>::setup(), |k| k
        .step());
    kernel!(dsmc3_fixed_m3, Dsmc3<FxQ32>, Dsmc3::<FxQ32>::setup(), |k| k
        .step());
    kernel!(
        dsmc3_fixed_q16_m3,
        Dsmc3<FxQ16>,
        Dsmc3::<FxQ16>::setup(),
        |k| k.step()
    );
}

/// Replay `n` records from `inp` (REPLAY_IN f32 each) through the Q32.32 controller,
/// writing REPLAY_OUT raw u64 per record to `out`. Returns the steps run.
///
/// # Safety
/// `inp` and `out` must point to `n` records of the sizes above.
#[no_mangle]
pub unsafe extern "C" fn insns_replay_fixed(inp: *const f32, n: u32, out: *mut u64) -> u32 {
    let (i, o) = unsafe { buffers(inp, n, out) };
    replay::<FxQ32>(i, o) as u32
}

/// As [`insns_replay_fixed`], Q16.16.
///
/// # Safety
/// As [`insns_replay_fixed`].
#[no_mangle]
pub unsafe extern "C" fn insns_replay_fixed_q16(inp: *const f32, n: u32, out: *mut u64) -> u32 {
    let (i, o) = unsafe { buffers(inp, n, out) };
    replay::<FxQ16>(i, o) as u32
}

/// As [`insns_replay_fixed`], `f32` with the fast powers.
///
/// # Safety
/// As [`insns_replay_fixed`].
#[no_mangle]
pub unsafe extern "C" fn insns_replay_f32(inp: *const f32, n: u32, out: *mut u64) -> u32 {
    let (i, o) = unsafe { buffers(inp, n, out) };
    replay::<f32>(i, o) as u32
}

/// As [`insns_replay_fixed`], `f32` with libm's `powf`.
///
/// # Safety
/// As [`insns_replay_fixed`].
#[no_mangle]
pub unsafe extern "C" fn insns_replay_f32_libm(inp: *const f32, n: u32, out: *mut u64) -> u32 {
    let (i, o) = unsafe { buffers(inp, n, out) };
    replay::<LibmF32>(i, o) as u32
}

/// # Safety
/// See [`insns_replay_fixed`].
unsafe fn buffers<'a>(inp: *const f32, n: u32, out: *mut u64) -> (&'a [f32], &'a mut [u64]) {
    let n = n as usize;
    unsafe {
        (
            core::slice::from_raw_parts(inp, n * REPLAY_IN),
            core::slice::from_raw_parts_mut(out, n * REPLAY_OUT),
        )
    }
}

#[entry]
fn main() -> ! {
    // Nothing to do: the emulator runs the reset handler up to here, then calls the
    // exported functions itself (exported symbols survive LTO and section GC).
    loop {
        core::hint::black_box(());
    }
}

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    // The emulator stops on this symbol and reports the kernel as failed.
    loop {
        core::hint::black_box(());
    }
}
