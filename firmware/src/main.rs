//! RTIC 2 firmware of the gantry controller (STM32F407VGT6), and its QEMU rig.
//!
//! Tasks, highest priority first:
//!
//! | task | priority | trigger | does |
//! | --- | --- | --- | --- |
//! | `y_index` | 6 (hardware) | EXTI1 (PB1 rising: Y's encoder index) | reads TIM5_CNT as Y's index capture, hands it to `control` (lock-free, `board::index`); not in the QEMU build |
//! | `host_uart` | 5 (hardware) | USART2 | moves bytes between the UART and the link's byte queues |
//! | `control` | 4 (hardware) | TIM4 update, 10 kHz | button commands, the core's machine (link requests, supervisor, the planner's executor, servo step), snapshot |
//! | `plan` | 3 (software) | spawned by `control` every period | the planner's planning half: segments in, look-ahead, spans and steps out (controller-core `motion::planner::split`) |
//! | `link` | 2 (software) | every 1 ms | the host link: frames, settings requests, queues to and from the machine |
//! | `button` | 2 (software) | every 1 ms | debounces the arm button, posts its commands to the mailbox |
//! | `telemetry` | 1 (software) | every 100 ms | copies the snapshot, logs it with defmt |
//!
//! The control task never logs, allocates or blocks; it publishes the core's snapshot and
//! its own timing through an RTIC resource (its own lock is free: it has the ceiling
//! priority), hands the overrun flag to the next period's safety inputs, and feeds the
//! independent watchdog when its period ran on time. Idle sleeps.
//!
//! With the `qemu` feature the same application runs on QEMU's netduinoplus2 with the
//! rig of `qemu/`: the control task runs a scenario of host-sim's against the core's
//! simulated world, and at the end the telemetry task prints the figures and exits QEMU.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

/// The firmware only runs on the microcontroller; a host build (e.g. `cargo test
/// --workspace`, clippy) gets this stub entry point and the library's unit tests.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("build the firmware for the target: cargo fw (or cargo fw-qemu)");
}

#[cfg(target_os = "none")]
mod board;
#[cfg(target_os = "none")]
mod link;
#[cfg(target_os = "none")]
mod logger;
#[cfg(target_os = "none")]
mod machine_slot;
#[cfg(all(target_os = "none", not(feature = "qemu")))]
mod period;
#[cfg(all(target_os = "none", feature = "qemu"))]
mod qemu;
#[cfg(all(target_os = "none", feature = "qemu"))]
mod qemu_exit;
#[cfg(target_os = "none")]
mod stack;

// The panic handler is the board's own (`board::shutdown`: outputs off first).
#[cfg(all(target_os = "none", not(feature = "qemu")))]
use defmt_rtt as _;

#[cfg(all(target_os = "none", feature = "qemu"))]
use defmt_semihosting as _;

#[cfg(target_os = "none")]
rtic_monotonics::systick_monotonic!(Mono, 1_000);

#[cfg(target_os = "none")]
#[rtic::app(device = stm32f4xx_hal::pac, peripherals = true, dispatchers = [USART6, UART4, UART5])]
mod app {
    use rtic_monotonics::fugit::ExtU32 as MonoExtU32;
    use rtic_monotonics::Timebase as _;

    use controller_core::servo::ServoState;
    use firmware::config::CONTROL_RATE_HZ;
    use firmware::telemetry::Telemetry;

    use crate::board::{self, cycles, leds::Leds, tick::ControlTick, SYSCLK_HZ};
    use crate::logger::Logger;
    use crate::Mono;

    use crate::board::serial::{HostUart, RxQueue, TxQueue};
    use crate::link::LinkTask;
    /// Where the link task writes settings saves: the board's flash sectors, or in QEMU
    /// (no flash controller model) a store in RAM. Chosen here, where the build's parts
    /// are assembled, so the link task knows neither.
    #[cfg(not(feature = "qemu"))]
    type Saver = crate::board::flash::BoardSaver;
    #[cfg(feature = "qemu")]
    type Saver = crate::qemu::link::RamSaver;
    use crate::machine_slot::PlanTask;
    #[cfg(not(feature = "qemu"))]
    use crate::period::{BoardPeriod as Period, End};
    /// Where init builds what the control interrupt drives: the board's machine.
    #[cfg(not(feature = "qemu"))]
    type Slot = Option<crate::machine_slot::FwMachine>;
    #[cfg(feature = "qemu")]
    use crate::qemu::{End, Rig as Period};
    /// Where init builds what the control interrupt drives: QEMU's simulated run.
    #[cfg(feature = "qemu")]
    type Slot = Option<crate::qemu::FwRun>;
    use controller_core::machine::Channels;

    // (RTIC names the types of every local resource, cfg'd ones too.)
    use controller_core::servo::Command;
    use firmware::index_capture::StormGuard;
    use heapless::spsc::Producer;
    #[cfg(not(feature = "qemu"))]
    use {
        crate::board::clock::ClockStart,
        crate::machine_slot,
        controller_core::servo::faults::FaultKind,
        firmware::button::{press_commands, Debounce},
        firmware::config::{ARM_BUTTON_HOLD_SAMPLES, BUTTON_POLL_MS},
        firmware::watchdog::iwdg_setting,
    };

    /// Telemetry log interval (virtual time in QEMU), milliseconds.
    #[cfg(not(feature = "qemu"))]
    const TELEMETRY_PERIOD_MS: u32 = firmware::config::TELEMETRY_PERIOD_MS;
    /// QEMU: one line every 10 emulated seconds (2 500 periods at the 4 ms emulated
    /// period of `board::tick`).
    #[cfg(feature = "qemu")]
    const TELEMETRY_PERIOD_MS: u32 = 10_000;
    /// How many 1 ms ticks the telemetry task waits at most for the control interrupt to
    /// copy its snapshot (it does at its next period; a stalled loop is logged stale).
    const SNAPSHOT_WAIT_TICKS: u32 = 5;

    #[shared]
    struct Shared {
        telemetry: Telemetry,
        /// Set once by a finite run (the QEMU rig) when it is over.
        end: Option<End>,
    }

    #[local]
    struct Local {
        period: Period,
        tick: ControlTick,
        leds: Leds,
        #[cfg(not(feature = "qemu"))]
        arm: board::inputs::ArmButton,
        #[cfg(not(feature = "qemu"))]
        commands: Producer<'static, Command>,
        host_uart: Option<HostUart>,
        link_task: Option<LinkTask<Saver>>,
        plan_task: Option<PlanTask>,
    }

    /// The command mailbox: lock-free single producer (the button task), single consumer
    /// (the control task); holds 7 commands. Unused by the QEMU rig, whose commands are
    /// scripted by the simulated run.
    type Mailbox = heapless::spsc::Queue<Command, 8>;

    #[init(local = [mailbox: Mailbox = Mailbox::new()])]
    fn init(cx: init::Context) -> (Shared, Local) {
        let mut core = cx.core;
        core.DCB.enable_trace();
        core.DWT.enable_cycle_counter();

        // why the chip reset, before anything else touches RCC (cleared for the next boot)
        #[cfg(not(feature = "qemu"))]
        let reset_cause = board::take_reset_cause();
        let board = board::init(cx.device);
        #[cfg(not(feature = "qemu"))]
        let brownout = board.brownout;
        Mono::start(core.SYST, SYSCLK_HZ);
        // SysTick (the 1 ms monotonic) below the control interrupt: at its reset priority
        // 0 it would preempt every period. At the plan task's level it still runs before
        // the link, button and telemetry tasks that wait on it.
        // SAFETY: init runs with interrupts disabled; no priority-based critical section
        // depends on SysTick's priority (the monotonic uses critical sections).
        unsafe {
            core.SCB.set_priority(
                cortex_m::peripheral::scb::SystemHandler::SysTick,
                board::SYSTICK_PRIORITY_HW,
            )
        };

        // The link's queues and the machine's place (init runs once: each `singleton!`
        // yields its static).
        let (Some(channels), Some(rx_queue), Some(tx_queue), Some(machine)) = (
            cortex_m::singleton!(: Channels = Channels::new()),
            cortex_m::singleton!(: RxQueue = RxQueue::new()),
            cortex_m::singleton!(: TxQueue = TxQueue::new()),
            cortex_m::singleton!(: Slot = None),
        ) else {
            halt("init ran twice")
        };
        let (port, control) = channels.split();
        let (rx_in, rx_out) = rx_queue.split();
        let (tx_in, tx_out) = tx_queue.split();

        #[cfg(not(feature = "qemu"))]
        let (mut period, arm, commands, host_uart, link_task) = {
            let (producer, consumer) = cx.local.mailbox.split();
            // the stored settings (before the watchdog starts: a load may repair an
            // interrupted erase), the factory ones and a fault if the store is corrupt
            let (settings, load, store) =
                crate::board::flash::load_settings(board.flash, CONTROL_RATE_HZ);
            let io =
                board::io::BoardIo::new(board.encoders, board.index, board.servo, board.safety);
            let mut period =
                board_period(machine, &settings, io, control, consumer, board.watchdog);
            latch_boot_faults(&mut period, &load, board.clock);
            let host_uart = board.host_uart.map(|s| HostUart::new(s, rx_in, tx_out));
            let link_task = board_link(port, &settings, store, rx_out, tx_in);
            (period, board.arm, producer, host_uart, link_task)
        };
        #[cfg(feature = "qemu")]
        let (period, host_uart, link_task) = {
            let _ = cx.local.mailbox;
            // The encoder timers and TIM1 are configured (and TIM1's outputs disabled)
            // but not used: the simulated world stands in for them.
            let _ = (board.encoders, board.servo, board.arm, board.clock);
            let period = Period::boot(board.safety, machine, control, board.panel_usart);
            let link = period.link_machine();
            let host_uart = board
                .host_uart
                .filter(|_| link.is_some())
                .map(|s| HostUart::new(s, rx_in, tx_out));
            let link_task = link.and_then(|(settings, rate)| {
                let flash = cortex_m::singleton!(
                    : controller_core::settings::store::RamFlash<8192, 4096> =
                        controller_core::settings::store::RamFlash::new()
                );
                let saver = Saver::new(flash);
                LinkTask::new(port, &settings, rate, rx_out, tx_in, saver)
            });
            (period, host_uart, link_task)
        };

        // the machine's planning half
        let plan_task = crate::machine_slot::take_plan_task();

        let mut tick = board.tick;
        tick.start(board::tick::CONTROL_TICK_PROGRAMMED_HZ);
        // Last: the watchdog (from here on the control task must run on time).
        #[cfg(not(feature = "qemu"))]
        start_watchdog(&mut period);
        defmt::info!(
            "gantry firmware up: control {=u32} Hz, outputs disabled until armed",
            CONTROL_RATE_HZ
        );
        #[cfg(not(feature = "qemu"))]
        log_boot(reset_cause, brownout);
        spawn_tasks(link_task.is_some());
        (
            Shared {
                telemetry: Telemetry::boot(),
                end: None,
            },
            Local {
                period,
                tick,
                leds: board.leds,
                #[cfg(not(feature = "qemu"))]
                arm,
                #[cfg(not(feature = "qemu"))]
                commands,
                host_uart,
                link_task,
                plan_task,
            },
        )
    }

    #[cfg(not(feature = "qemu"))]
    use crate::period::BoardPeriod;

    /// The board's machine, built in `slot` from `settings` at the board's control rate
    /// (halts, outputs off, when the settings give none), and the control interrupt's
    /// state around it.
    #[cfg(not(feature = "qemu"))]
    fn board_period(
        slot: &'static mut Slot,
        settings: &controller_core::settings::Settings,
        io: board::io::BoardIo,
        control: controller_core::machine::ControlSide<'static>,
        commands: heapless::spsc::Consumer<'static, Command>,
        watchdog: board::watchdog::Watchdog,
    ) -> BoardPeriod {
        let machine =
            match machine_slot::build(slot, settings, CONTROL_RATE_HZ, io.encoder_raw(), [0; 3]) {
                Ok(m) => m,
                Err(e) => {
                    defmt::error!("machine: {}", defmt::Debug2Format(&e));
                    halt("the settings give no machine (outputs stay off)")
                }
            };
        BoardPeriod::new(machine, control, io, commands, watchdog, CONTROL_RATE_HZ)
    }

    /// The board's link task: the machine's link `port`, the UART's byte queues, and the
    /// settings saves written to `store` with the watchdog stretched around them.
    #[cfg(not(feature = "qemu"))]
    fn board_link(
        port: controller_core::machine::LinkEnds<'static>,
        settings: &controller_core::settings::Settings,
        store: Option<
            controller_core::settings::store::SettingsStore<crate::board::flash::SettingsFlash>,
        >,
        rx: heapless::spsc::Consumer<'static, u8>,
        tx: Producer<'static, u8>,
    ) -> Option<LinkTask<Saver>> {
        // SAFETY: the control task's `Watchdog` (feeds only) is the IWDG's other user
        let stretch = unsafe {
            board::watchdog::WatchdogStretch::new(
                iwdg_setting(CONTROL_RATE_HZ),
                firmware::watchdog::iwdg_save_setting(),
            )
        };
        let saver = Saver::new(store, stretch);
        LinkTask::new(port, settings, CONTROL_RATE_HZ, rx, tx, saver)
    }

    /// The board's faults found while booting, latched before anything can arm: a
    /// corrupt settings store (factory settings run) and a crystal that did not start.
    #[cfg(not(feature = "qemu"))]
    fn latch_boot_faults(
        period: &mut BoardPeriod,
        load: &controller_core::settings::store::LoadOutcome,
        clock: ClockStart,
    ) {
        if load.is_fault() {
            defmt::error!(
                "settings store: {}; factory settings, fault latched",
                defmt::Debug2Format(load)
            );
            period.latch_board_fault(FaultKind::SettingsCorrupt);
        }
        if clock == ClockStart::HsiFallback {
            defmt::error!(
                "crystal did not start within {=u32} ms: running on the HSI, clock fault latched",
                board::clock::HSE_STARTUP_TIMEOUT_MS
            );
            period.latch_board_fault(FaultKind::ClockFault);
        }
    }

    /// `init`'s last step on the board: the independent watchdog starts, then the
    /// configuration of every peripheral is read back against the register table (a
    /// mismatch, or IWDG registers that never settled, latch a `board_config` fault).
    #[cfg(not(feature = "qemu"))]
    fn start_watchdog(period: &mut BoardPeriod) {
        let setting = iwdg_setting(CONTROL_RATE_HZ);
        period.start_watchdog(setting);
        defmt::info!(
            "watchdog: {=u32} us at the fastest LSI ({=u32} us typical)",
            setting.timeout_us(firmware::watchdog::LSI_MAX_HZ),
            setting.timeout_us(firmware::watchdog::LSI_TYP_HZ)
        );
        // every peripheral is configured (the NVIC priorities were set before init):
        // read the configuration back against the register table
        let settled = board::watchdog::updates_settled();
        match board::self_check::first_mismatch() {
            None if settled => defmt::info!(
                "board configuration: {=usize} register fields as expected",
                board::self_check::entries()
            ),
            None => {
                defmt::error!("board configuration: the IWDG's PR/RLR never settled; board_config fault latched");
                period.latch_board_fault(FaultKind::BoardConfig);
            }
            Some((e, v)) => {
                defmt::error!(
                    "board configuration: 0x{=u32:08x} bits {=u8}+{=u8} = {=u32:#x}, expected {=u32:#x} ({=str}); board_config fault latched",
                    e.addr,
                    e.shift,
                    e.width,
                    v,
                    e.value,
                    e.what
                );
                period.latch_board_fault(FaultKind::BoardConfig);
            }
        }
    }

    /// The board's boot report: why it reset, and the brown-out reset level.
    #[cfg(not(feature = "qemu"))]
    fn log_boot(
        reset_cause: firmware::reset_cause::ResetCause,
        brownout: board::brownout::BorSetting,
    ) {
        defmt::info!("reset cause: {=str}", reset_cause.name());
        match brownout {
            board::brownout::BorSetting::Kept => defmt::info!("brown-out reset: 2.7 V"),
            board::brownout::BorSetting::Programmed { was } => {
                defmt::info!(
                    "brown-out reset: programmed to 2.7 V (BOR_LEV was {=u8:02b})",
                    was
                )
            }
            board::brownout::BorSetting::Failed { now } => {
                defmt::error!(
                    "brown-out reset: programming failed, BOR_LEV {=u8:02b}",
                    now
                )
            }
        }
    }

    /// The software tasks that run from the start: telemetry, the arm button (board) and
    /// the host link when it has one.
    fn spawn_tasks(link: bool) {
        if telemetry::spawn().is_err() {
            defmt::error!("telemetry task already running");
        }
        #[cfg(not(feature = "qemu"))]
        if button::spawn().is_err() {
            defmt::error!("button task already running");
        }
        if link && link::spawn().is_err() {
            defmt::error!("link task already running");
        }
    }

    /// Nothing can run: outputs stay off (board: until reset; QEMU: exit 2).
    fn halt(why: &str) -> ! {
        defmt::error!("{=str}", why);
        #[cfg(feature = "qemu")]
        crate::qemu_exit::exit(crate::qemu_exit::EXIT_CONFIG);
        #[cfg(not(feature = "qemu"))]
        loop {
            cortex_m::asm::wfi();
        }
    }

    #[idle]
    fn idle(_: idle::Context) -> ! {
        loop {
            cortex_m::asm::wfi();
        }
    }

    /// The control period. Highest priority; never logs, allocates or blocks.
    #[task(binds = TIM4, priority = 4, local = [period, tick, leds], shared = [telemetry, end])]
    fn control(mut cx: control::Context) {
        let start = cycles::start();
        cx.local.tick.acknowledge();
        let period = cx.local.period;
        period.control();
        let measured = cycles::since(start);
        // Board: nothing. QEMU: the period's figures, then the simulated world advances
        // (the emulator's stand-in for the board's physics: not counted).
        let end = period.finish();
        let resumed = cycles::start();
        let overran = cx.local.tick.overran();
        // Board: the next period's `Inputs::overrun`, and the watchdog is fed only if this
        // period ran on time. QEMU: see `Rig::end_of_period`.
        period.end_of_period(overran);
        let snap = period.snapshot();
        cx.local
            .leds
            .show(snap.outputs_on, snap.state == ServoState::Fault);
        // The planning half runs once the interrupt returns. Still running from the last
        // period (it has 32 buffered steps of slack): it is simply not spawned again.
        let _ = plan::spawn();
        cx.shared.telemetry.lock(|t| {
            t.state = snap.state;
            // the 200-byte snapshot only when the telemetry task asked for it (and at a
            // run's end): a copy every period cost ~200 cycles of every period
            if t.snapshot_wanted || end.is_some() {
                t.snapshot = *snap;
                t.snapshot_wanted = false;
            }
            // the whole handler but its entry, this lock's exit and the return
            // (docs/performance.md: what `isr_cyc` counts)
            t.timing
                .record(measured.wrapping_add(cycles::since(resumed)), overran);
        });
        if let Some(e) = end {
            // A finite run (QEMU scenario) is over: stop the control interrupt.
            cx.local.tick.stop();
            cx.shared.end.lock(|x| *x = Some(e));
        }
    }

    /// The planner's planning half (controller-core `motion::planner::SplitPlanner`), after
    /// every control period: the commands the period passed on, then look-ahead, spans
    /// and steps. Below the control interrupt, above the link: a run is bounded (at most
    /// `SPLIT_COMMANDS` segments' look-ahead) and the executor underruns — a jerk-limited
    /// stop on the path — if it ever falls 32 periods behind.
    #[task(priority = 3, local = [plan_task])]
    async fn plan(cx: plan::Context) {
        if let Some(t) = cx.local.plan_task {
            // (QEMU's rig watches when the planning half ran: qemu::plan_watch)
            #[cfg(feature = "qemu")]
            crate::qemu::plan_watch::plan_started();
            t.run();
            #[cfg(feature = "qemu")]
            crate::qemu::plan_watch::plan_finished();
        }
    }

    /// The arm/reset button, sampled every millisecond: a debounced press posts its
    /// commands (see `firmware::button::press_commands`) to the control task's mailbox.
    #[cfg(not(feature = "qemu"))]
    #[task(priority = 2, local = [arm, commands], shared = [telemetry])]
    async fn button(mut cx: button::Context) {
        let mut debounce = Debounce::new(ARM_BUTTON_HOLD_SAMPLES);
        // a fixed schedule: `delay(1 ms)` waits 2 ticks of the 1 kHz monotonic (it rounds
        // up to guarantee the duration), which made the samples 2 ms apart and the 20 ms
        // hold 40 ms (measured on the board twin)
        let mut next = Mono::now();
        loop {
            next += BUTTON_POLL_MS.millis();
            Mono::delay_until(next).await;
            if debounce.update(cx.local.arm.pressed()) {
                let state = cx.shared.telemetry.lock(|t| t.state);
                for c in press_commands(state, cfg!(feature = "demo-helix")) {
                    if cx.local.commands.enqueue(*c).is_err() {
                        defmt::warn!("command mailbox full: {} dropped", c);
                    }
                }
            }
        }
    }

    /// Y's encoder index (PB1, EXTI1): TIM5 has no free capture channel, so this task reads
    /// TIM5_CNT at the edge (`board::index`: latency about 0.2 µs, under 0.1 count at top
    /// speed). The highest priority, above the host UART, so nothing but SysTick and a
    /// critical section delays the capture; a few dozen cycles per index pulse (one per
    /// encoder revolution, 20 ms apart at top speed), and it masks its line if it is noise
    /// (`StormGuard`).
    #[cfg(not(feature = "qemu"))]
    #[task(binds = EXTI1, priority = 6, local = [guard: StormGuard = StormGuard::new(SYSCLK_HZ)])]
    fn y_index(cx: y_index::Context) {
        board::index::on_y_index(cx.local.guard);
    }

    /// The host link's UART (`board::serial`): above the control interrupt, so that no
    /// received byte waits longer than this handler; a few dozen cycles per byte.
    #[task(binds = USART2, priority = 5, local = [host_uart])]
    fn host_uart(cx: host_uart::Context) {
        if let Some(u) = cx.local.host_uart {
            u.service();
        }
    }

    /// The host link (`link`): every millisecond, what arrived, then replies, acks and
    /// telemetry; pends the UART's interrupt when bytes wait to go out.
    #[task(priority = 2, local = [link_task])]
    async fn link(cx: link::Context) {
        let Some(task) = cx.local.link_task else {
            return;
        };
        // every millisecond on a fixed schedule (see `button`: `delay` would make it 2 ms)
        let mut next = Mono::now();
        loop {
            next += 1.millis();
            Mono::delay_until(next).await;
            if task.run() {
                rtic::pend(stm32f4xx_hal::pac::Interrupt::USART2);
            }
        }
    }

    /// Low-priority telemetry: snapshot copies become defmt log lines.
    #[task(priority = 1, shared = [telemetry, end])]
    async fn telemetry(mut cx: telemetry::Context) {
        let mut logger = Logger::new();
        // on a fixed schedule like the 1 ms tasks (one `delay_until` for all of them)
        let mut next = Mono::now();
        loop {
            next += TELEMETRY_PERIOD_MS.millis();
            Mono::delay_until(next).await;
            // the control interrupt copies its snapshot at its next period once asked
            cx.shared.telemetry.lock(|t| t.snapshot_wanted = true);
            let mut wait = next;
            for _ in 0..SNAPSHOT_WAIT_TICKS {
                wait += 1.millis();
                Mono::delay_until(wait).await;
                if !cx.shared.telemetry.lock(|t| t.snapshot_wanted) {
                    break;
                }
            }
            // `end` first: the control task publishes its last telemetry before `end`.
            let end = cx.shared.end.lock(|e| *e);
            let t = cx.shared.telemetry.lock(|t| *t);
            logger.report(&t);
            #[cfg(feature = "qemu")]
            if let Some(end) = end {
                crate::qemu::report::finish(&t, &end);
            }
            #[cfg(not(feature = "qemu"))]
            let _: Option<End> = end;
        }
    }
}
