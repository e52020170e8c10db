//! The last line of software defence: switching every servo output off from any context
//! (a panic, a HardFault, any other exception, the clock security system's NMI) by
//! direct register writes, before anything else runs.
//!
//! [`outputs_off_raw`] writes three things, each a single store (no read-modify-write, so
//! it cannot be torn by whatever it interrupted):
//!
//! 1. TIM1 BDTR = [`BDTR_SAFE`]: main output enable (MOE) off, so all three PWM pins go
//!    to their idle level (low; OSSI keeps them driven) in one write;
//! 2. TIM1 CCR1..CCR3 = 0: zero duty, should anything turn MOE on again;
//! 3. GPIOD BSRR = reset bits of [`OFF_PINS`], PD0..PD2 and PD4..PD6: the drive enables
//!    low and the holding brakes de-energised, gripping (BSRR sets the output data
//!    register's bits atomically, so no other pin of the port is touched).
//!
//! It needs no RAM, no stack beyond the call and no peripheral driver, and works before
//! `init` too (writes to a peripheral whose clock is still off are ignored; the pins are
//! then still in their reset state). The HardFault and default-handler entries are naked
//! functions that make the same stores in assembly before anything else (no stack use, so
//! a stack overflow cannot stop them); the panic
//! handler masks interrupts and calls it first. Then each logs what happened (defmt, if
//! the logger is free) and:
//!
//! - on the board: spins with interrupts masked, so the control interrupt stops feeding
//!   the independent watchdog and the chip resets within the watchdog timeout
//!   (`firmware::watchdog`); it boots with the outputs disabled;
//! - in QEMU: exits with 101 (panic), 102 (HardFault) or 103 (any other exception).
//!
//! Below this layer: a fault *inside* a fault handler locks the core up (the watchdog
//! still resets it); TIM1's break input switches the PWM off in hardware on the e-stop
//! line whatever the CPU does; the drives' enable chain should include the e-stop too.

use core::sync::atomic::{AtomicBool, Ordering};

use stm32f4xx_hal::pac;

/// TIM1's base address (APB2; RM0090 table 1, the PAC's `TIM1::PTR`) and the offsets of
/// BDTR and CCR1..CCR3 (RM0090 17.4.21).
const TIM1_BASE: u32 = 0x4001_0000;
const TIM1_CCR1: u32 = 0x34;
const TIM1_CCR2: u32 = 0x38;
const TIM1_CCR3: u32 = 0x3C;
const TIM1_BDTR: u32 = 0x44;
/// GPIOD's bit set/reset register (AHB1; RM0090 table 1 and 8.4.7).
const GPIOD_BSRR: u32 = 0x4002_0C00 + 0x18;

/// TIM1 BDTR bits (RM0090 17.4.18).
const BDTR_OSSI: u32 = 1 << 10;
const BDTR_OSSR: u32 = 1 << 11;
const BDTR_BKE: u32 = 1 << 12;
const BDTR_BKP: u32 = 1 << 13;
const BDTR_MOE: u32 = 1 << 15;
/// LOCK level 1: BKE, BKP, AOE, DTG (and CR2's idle levels) can no longer be written until
/// reset, so nothing can switch the break input off or turn automatic output enable on.
const BDTR_LOCK_1: u32 = 0b01 << 8;

/// TIM1 BDTR with the outputs off: break input enabled and active high (the e-stop line,
/// high = stop, see `inputs`), automatic output enable (AOE) off (only software turns
/// the outputs on again, never the end of a break), OSSI/OSSR set (a disabled output is
/// driven to its idle level, low, rather than left floating), no dead time (sign-magnitude
/// drive, no complementary outputs), LOCK level 1.
pub const BDTR_SAFE: u32 = BDTR_OSSI | BDTR_OSSR | BDTR_BKE | BDTR_BKP | BDTR_LOCK_1;

/// TIM1 BDTR with the outputs on.
pub const BDTR_ON: u32 = BDTR_SAFE | BDTR_MOE;

/// The drive enables' GPIOD pin numbers (X, Y, Z: PD0, PD1, PD2; board::mod's pin table,
/// checked by `ServoOutputs::new`).
pub const ENABLE_PIN_IDS: [u8; 3] = [0, 1, 2];
/// The holding-brake outputs' GPIOD pin numbers (X, Y, Z: PD4, PD5, PD6; high = released).
pub const BRAKE_PIN_IDS: [u8; 3] = [4, 5, 6];
/// GPIOD's port number (the HAL's `PinExt::port_id`: A is 0).
pub const GPIOD_PORT_ID: u8 = 3;
/// The drive enables as GPIOD bit positions.
pub const ENABLE_PINS: u32 = pin_mask(ENABLE_PIN_IDS);
/// The holding brakes as GPIOD bit positions.
pub const BRAKE_PINS: u32 = pin_mask(BRAKE_PIN_IDS);

const fn pin_mask(ids: [u8; 3]) -> u32 {
    (1 << ids[0]) | (1 << ids[1]) | (1 << ids[2])
}

/// One store to GPIOD BSRR: the pins of `set` high and those of `reset` low together
/// (RM0090 8.4.7; a pin in both is set). No other pin of the port changes.
#[inline(always)]
pub fn gpiod_set_reset(set: u32, reset: u32) {
    // SAFETY: one store to GPIOD BSRR (fixed address, checked by `addresses_match`): an
    // atomic set/reset of the port's output bits that touches no other pin.
    unsafe { (GPIOD_BSRR as usize as *mut u32).write_volatile((set & 0xFFFF) | (reset << 16)) }
}
/// Every GPIOD pin a fault drives low: the drive enables off and the brakes gripping.
pub const OFF_PINS: u32 = ENABLE_PINS | BRAKE_PINS;

/// Every servo output off: TIM1 main output off, duties zero, drive enables low, brakes
/// gripping. Callable from any context, before `init` and in fault handlers; idempotent.
/// The control interrupt's own disable (`ServoOutputs::disable`) is this too. (The naked
/// exception entries below do the same stores in assembly.)
#[inline(always)]
pub fn outputs_off_raw() {
    let reg = |addr: u32| addr as usize as *mut u32;
    // SAFETY: single stores to TIM1 BDTR/CCR1..3 and GPIOD BSRR, fixed addresses of the
    // STM32F4 (checked against the PAC by `addresses_match`). BDTR and the CCRs are also
    // written by the control interrupt (`pwm`), always with whole values, so a store here
    // can only win or be overwritten by an equally whole value of the period that was
    // running; BSRR writes are atomic set/reset operations on the port's output bits.
    unsafe {
        reg(TIM1_BASE + TIM1_BDTR).write_volatile(BDTR_SAFE);
        reg(TIM1_BASE + TIM1_CCR1).write_volatile(0);
        reg(TIM1_BASE + TIM1_CCR2).write_volatile(0);
        reg(TIM1_BASE + TIM1_CCR3).write_volatile(0);
        reg(GPIOD_BSRR).write_volatile(OFF_PINS << 16);
    }
}

/// The fixed register addresses above are the PAC's (a mismatch is logged at boot; the
/// comparison folds to a constant).
pub fn addresses_match() -> bool {
    // SAFETY: only the addresses of the register blocks are taken.
    let (tim1, gpiod) = unsafe { (&*pac::TIM1::ptr(), &*pac::GPIOD::ptr()) };
    core::ptr::addr_of!(*tim1.bdtr()) as usize == (TIM1_BASE + TIM1_BDTR) as usize
        && core::ptr::addr_of!(*tim1.ccr1()) as usize == (TIM1_BASE + TIM1_CCR1) as usize
        && core::ptr::addr_of!(*tim1.ccr3()) as usize == (TIM1_BASE + TIM1_CCR3) as usize
        && core::ptr::addr_of!(*gpiod.bsrr()) as usize == GPIOD_BSRR as usize
}

/// The stores of [`outputs_off_raw`] in assembly, for the naked exception entries: only
/// r0 and r1 are used, nothing is read, nothing is pushed.
macro_rules! outputs_off_asm {
    () => {
        concat!(
            "movw r0, #{tim1_lo}\n",
            "movt r0, #{tim1_hi}\n",
            "movw r1, #{bdtr_lo}\n",
            "movt r1, #{bdtr_hi}\n",
            "str r1, [r0, #{bdtr}]\n",
            "movs r1, #0\n",
            "str r1, [r0, #{ccr1}]\n",
            "str r1, [r0, #{ccr2}]\n",
            "str r1, [r0, #{ccr3}]\n",
            "movw r0, #{bsrr_lo}\n",
            "movt r0, #{bsrr_hi}\n",
            "movw r1, #{en_lo}\n",
            "movt r1, #{en_hi}\n",
            "str r1, [r0]\n",
        )
    };
}

/// Set by the first fault handler; a second one (a panic while logging a panic, a fault
/// in a handler) skips the logging.
static IN_FAULT: AtomicBool = AtomicBool::new(false);

/// True for the first fault handler to get here.
fn first_fault() -> bool {
    !IN_FAULT.swap(true, Ordering::Relaxed)
}

/// HardFault: outputs off before anything else (the entry is naked: two scratch
/// registers, five stores, nothing pushed), then [`exception_report`]. A stack overflow
/// that caused the HardFault cannot stop the outputs going off: the stack sits at the
/// bottom of SRAM (firmware/memory.x), a push below it is a bus fault, and its exception
/// entry still reaches this handler with the stacking lost; the report then runs on the
/// top of the stack.
#[unsafe(naked)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn HardFault() -> ! {
    core::arch::naked_asm!(
        outputs_off_asm!(),
        "mrs r1, ipsr",
        "tst lr, #4",
        "ite eq",
        "mrseq r0, msp",
        "mrsne r0, psp",
        // a stack that overflowed (or nearly: the report needs some) leaves MSP at or
        // below the stack's bottom: the report runs on the top of the stack instead (the
        // frames there are abandoned; the firmware stops)
        "movw r2, :lower16:{stack_bottom}",
        "movt r2, :upper16:{stack_bottom}",
        "adds r2, r2, #{report_stack}",
        "mrs r3, msp",
        "cmp r3, r2",
        "bhs 1f",
        "movw r3, :lower16:{stack_top}",
        "movt r3, :upper16:{stack_top}",
        "msr msp, r3",
        "1:",
        "b {report}",
        tim1_lo = const TIM1_BASE & 0xFFFF,
        tim1_hi = const TIM1_BASE >> 16,
        bdtr_lo = const BDTR_SAFE & 0xFFFF,
        bdtr_hi = const BDTR_SAFE >> 16,
        bdtr = const TIM1_BDTR,
        ccr1 = const TIM1_CCR1,
        ccr2 = const TIM1_CCR2,
        ccr3 = const TIM1_CCR3,
        bsrr_lo = const GPIOD_BSRR & 0xFFFF,
        bsrr_hi = const GPIOD_BSRR >> 16,
        en_lo = const (OFF_PINS << 16) & 0xFFFF,
        en_hi = const (OFF_PINS << 16) >> 16,
        report = sym exception_report,
        stack_bottom = sym _stack_end,
        stack_top = sym _stack_start,
        report_stack = const REPORT_STACK_BYTES,
    )
}

extern "C" {
    /// The stack's top and bottom (firmware/memory.x: the bottom is the start of SRAM).
    static _stack_start: u32;
    static _stack_end: u32;
}

/// Stack the exception report needs (its frame and defmt's), with margin: with less left
/// above the bottom the report moves to the top of the stack.
const REPORT_STACK_BYTES: u32 = 1024;

/// Every other exception and interrupt without a handler of its own (MemManage, BusFault,
/// UsageFault, SVCall, DebugMonitor, PendSV and unused interrupts; the NMI too in the QEMU
/// build): the same as [`HardFault`], by a plain branch to it (nothing pushed, `lr` and
/// the IPSR still this exception's, so the report names it).
#[unsafe(naked)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn DefaultHandler() -> ! {
    core::arch::naked_asm!("b {hard_fault}", hard_fault = sym HardFault)
}

/// Exception number of HardFault in IPSR.
const HARD_FAULT: u32 = 3;

/// After the outputs are off: log the exception and its stacked PC (when the stack
/// pointer is plausible), then stop ([`halt`]).
extern "C" fn exception_report(frame: *const u32, exception: u32) -> ! {
    cortex_m::interrupt::disable();
    let exception = exception & 0x1FF;
    if first_fault() {
        let pc = stacked_pc(frame);
        if (frame as usize) < core::ptr::addr_of!(_stack_end) as usize {
            defmt::error!(
                "stack overflow (frame at {=u32:#x}, below the stack): outputs off",
                frame as u32
            );
        } else if exception == HARD_FAULT {
            defmt::error!("HardFault at pc={=u32:#x}: outputs off", pc);
        } else {
            defmt::error!(
                "unexpected exception {=u32} at pc={=u32:#x}: outputs off",
                exception,
                pc
            );
        }
    }
    halt(if exception == HARD_FAULT {
        Halt::HardFault
    } else {
        Halt::Exception
    })
}

/// The PC of an exception frame at `frame`, or 0 if `frame` is not a word-aligned address
/// with the frame inside SRAM (a corrupt stack pointer must not fault again here).
fn stacked_pc(frame: *const u32) -> u32 {
    const SRAM: core::ops::Range<usize> = 0x2000_0000..0x2002_0000;
    let addr = frame as usize;
    if !addr.is_multiple_of(4) || !SRAM.contains(&addr) || !SRAM.contains(&(addr + 7 * 4)) {
        return 0;
    }
    // SAFETY: an aligned address inside SRAM; word 6 of the frame is the stacked PC.
    unsafe { frame.add(6).read_volatile() }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    // Mask interrupts first (one instruction) so nothing can run between the outputs
    // going off and the end; then the outputs.
    cortex_m::interrupt::disable();
    outputs_off_raw();
    if first_fault() {
        defmt::error!("panic: outputs off: {}", defmt::Display2Format(info));
    }
    halt(Halt::Panic)
}

/// Why the firmware stops.
#[derive(Clone, Copy)]
enum Halt {
    Panic,
    HardFault,
    Exception,
}

/// Board: spin with interrupts masked; the control interrupt no longer feeds the
/// independent watchdog, which resets the chip within its timeout.
#[cfg(not(feature = "qemu"))]
fn halt(_why: Halt) -> ! {
    loop {
        outputs_off_raw();
    }
}

/// QEMU: leave with the exit code of the reason.
#[cfg(feature = "qemu")]
fn halt(why: Halt) -> ! {
    use crate::qemu_exit::{exit, EXIT_EXCEPTION, EXIT_HARD_FAULT, EXIT_PANIC};
    exit(match why {
        Halt::Panic => EXIT_PANIC,
        Halt::HardFault => EXIT_HARD_FAULT,
        Halt::Exception => EXIT_EXCEPTION,
    })
}
