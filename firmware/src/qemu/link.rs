//! The link rig's driver (QEMU, command-line name `link`): the machine a host commands
//! over USART2 — the core's [`Machine`] (supervisor, planner, servo step) with factory
//! settings and the designed axis models, against the simulated physical gantry of
//! `gantry --sim` (host-sim/scenarios/gcode.toml, with limit switches where homing
//! expects them, both built by controller-core's `sim::gantry` as host-sim builds them;
//! the rig's world has no encoder index pulses), in a linked simulated run
//! (`SimRun::linked`, the rig's one run, [`super::rig`]). Each period runs
//! [`Machine::linked_period_seen`] and the world advances; the link task (`crate::link`)
//! talks to the host. It runs until QEMU is stopped.
//!
//! The simulated machine's e-stop is pressed and released on its operator panel, USART1
//! ([`super::panel`]): each period, before the servo step, what the panel received sets
//! the world's e-stop input ([`World::set_estop`], as `gantry --sim`'s `SimMachine`
//! does). The panel also answers the host's clock question with the link's clock
//! ([`LINK_CLOCK_MS`]): `gantry --qemu` counts its link timeouts in it.
//!
//! Every input the machine takes is recorded, with a digest of what it did
//! (controller-core `machine::record`): each period's records (the link's events as
//! [`Machine::linked_period_seen`] shows them, the panel's e-stop, the planning half's
//! runs when not exactly one) as a `machine-record <period> [bytes]` line, and every
//! [`BLOCK_PERIODS`] periods a `machine-digest <period> <running digest> [tags]` line with
//! each period's 16-bit tag. host-sim replays them into the same machine and world and
//! compares bit for bit (`host-sim machine-replay`, firmware/README-firmware.md).
//!
//! [`Machine`]: controller_core::machine::Machine
//! [`Machine::linked_period_seen`]: controller_core::machine::Machine::linked_period_seen
//! [`World::set_estop`]: controller_core::sim::world::World::set_estop

use core::sync::atomic::Ordering;

use controller_core::link::LinkClock;
use controller_core::machine::record::{Digest, RecordRef, Recorder, BLOCK_PERIODS};
use controller_core::machine::{save_due_into, ControlSide, LinkSide, Machine};
use controller_core::servo::snapshot::Snapshot;
use controller_core::settings::store::{BlockingFlash, RamFlash, SettingsStore};
use controller_core::settings::Settings;
use controller_core::sim::gantry::{designed_settings, gantry_world, GantryOptions};
use controller_core::sim::run::{RunConfig, SimRun};

use super::panel::Panel;
use crate::link::{SettingsSaver, LINK_CLOCK_MS};
use crate::machine_slot::{self, FwRun};
use crate::qemu_exit::{exit, EXIT_CONFIG};

/// The link rig's settings flash: two 4 KiB pages in RAM (QEMU models no flash
/// controller), empty at boot; saves go through the same store and lock as on the board.
pub struct RamSaver {
    store: Option<SettingsStore<BlockingFlash<&'static mut RamFlash<8192, 4096>>>>,
}

impl RamSaver {
    /// The saver on `flash` (a static: 8 KiB are not passed through `init`'s stack).
    pub fn new(flash: Option<&'static mut RamFlash<8192, 4096>>) -> Self {
        let store = flash
            .and_then(|f| BlockingFlash::new(f, 0, 8192).ok())
            .and_then(|f| SettingsStore::new(f, 0..8192).ok());
        Self { store }
    }
}

impl SettingsSaver for RamSaver {
    /// Write a save that is due on `port`.
    fn save_due(&mut self, port: &mut LinkSide<'_, '_>) {
        match self.store.as_mut() {
            Some(store) => {
                save_due_into(port, store);
            }
            None => {
                if port.save_due().is_some() {
                    let mut t = heapless::String::new();
                    let _ = t.push_str("save failed: the RAM store could not be made");
                    port.save_finished(controller_core::machine::messages::Outcome::Refused(t));
                }
            }
        }
    }
}

/// Bytes of one period's records (a settings tree is about 630).
const RECORD_BYTES: usize = 2048;

/// What the link rig adds to its run: the operator panel, the link's control side and
/// clock, the recording of the machine's inputs.
pub struct LinkDriver {
    /// The operator panel: the world's e-stop.
    panel: Panel,
    control: ControlSide<'static>,
    rate_hz: u32,
    periods: u64,
    /// The link's clock, counted from the periods run.
    clock: LinkClock,
    /// This period's inputs, for the log.
    recorder: Recorder<RECORD_BYTES>,
    digest: Digest,
    /// The block's per-period tags (u16, little-endian).
    tags: [u8; 2 * BLOCK_PERIODS],
}

impl LinkDriver {
    /// The linked run built in `slot` (in place: it is too large to pass around on the
    /// stack), its operator panel on `panel_usart`; exits QEMU with [`EXIT_CONFIG`] if
    /// the machine description is rejected.
    // (never inlined into `Rig::boot` with the other rig's: their frames would add up
    // on the boot stack)
    #[inline(never)]
    pub fn boot(
        slot: &'static mut Option<FwRun>,
        control: ControlSide<'static>,
        panel_usart: stm32f4xx_hal::pac::USART1,
    ) -> (&'static mut FwRun, Self) {
        let run: RunConfig = match postcard::from_bytes(firmware::scenarios::LINK_RUN) {
            Ok(r) => r,
            Err(_) => {
                defmt::error!("link rig: the machine description does not decode");
                exit(EXIT_CONFIG)
            }
        };
        let settings = designed_settings();
        let rate_hz = run.servo.rate_hz;
        // no index pulses, as the rig has always run (host-sim's world keeps the machine
        // file's: the replay still matches while no encoder count is lost)
        let options = GantryOptions {
            index_pulses: false,
            board_amplifier: false,
        };
        let Ok(world) = gantry_world(&run.world, &settings, rate_hz, options) else {
            defmt::error!("link rig: the simulated machine is rejected");
            exit(EXIT_CONFIG)
        };
        let (raw, counts) = (world.counter_registers(), world.counts());
        let machine = machine_slot::memory()
            .ok()
            .and_then(|m| Machine::new(&settings, rate_hz, raw, counts, m).ok());
        let Some(machine) = machine else {
            defmt::error!("link rig: the machine cannot be built from the factory settings");
            exit(EXIT_CONFIG)
        };
        let run = slot.insert(SimRun::linked(machine, world));
        defmt::info!(
            "link rig: the simulated gantry at {=u32} Hz, host link on USART2, operator panel on USART1",
            rate_hz
        );
        let driver = Self {
            panel: Panel::new(panel_usart),
            control,
            rate_hz,
            periods: 0,
            clock: LinkClock::new(rate_hz),
            recorder: Recorder::new(),
            digest: Digest::new(),
            tags: [0; 2 * BLOCK_PERIODS],
        };
        (run, driver)
    }

    /// The machine's period: the operator panel, then the link's events, supervisor,
    /// planner, servo step. `plan`: the planning half's runs since the last period and
    /// whether it is running (recorded when not exactly one run).
    #[inline]
    pub fn control<'r>(&mut self, run: &'r mut FwRun, plan: (u32, bool)) -> &'r Snapshot {
        // (the servo counts the period at the start of its step: this one is the next)
        let period = run.servo().snapshot().period.wrapping_add(1);
        // (the link's clock as the link task reads it: the periods finished so far)
        let link_ms = LINK_CLOCK_MS.load(Ordering::Acquire);
        let (ran, busy) = plan;
        if ran != 1 || busy {
            self.recorder.note(RecordRef::Plan { runs: ran, busy });
        }
        if let Some(pressed) = self.panel.poll(period, link_ms) {
            run.world_mut().set_estop(pressed);
            self.recorder.note(RecordRef::Estop(pressed));
        }
        let recorder = &mut self.recorder;
        run.linked_period(&mut self.control, |seen| recorder.note(seen.into()))
    }

    /// The settings the machine runs and its control rate.
    pub fn machine_settings(&self, run: &FwRun) -> (Settings, u32) {
        (*run.machine().settings(), self.rate_hz)
    }

    /// The world advances; the link's clock follows the machine's.
    #[inline]
    pub fn finish(&mut self, run: &mut FwRun) {
        run.advance();
        self.periods += 1;
        self.record(run);
        LINK_CLOCK_MS.store(self.clock.period(), Ordering::Release);
    }

    /// The period's records and its tag in the log; the digest every [`BLOCK_PERIODS`].
    fn record(&mut self, run: &FwRun) {
        let p = self.periods as u32;
        let tag = self.digest.fold(run.servo().snapshot());
        let i = (p as usize + BLOCK_PERIODS - 1) % BLOCK_PERIODS;
        self.tags[2 * i..2 * i + 2].copy_from_slice(&tag.to_le_bytes());
        if !self.recorder.is_empty() {
            let (bytes, lost) = self.recorder.take();
            if lost {
                defmt::error!("machine-record {=u32} lost", p);
            } else {
                defmt::info!("machine-record {=u32} {=[u8]}", p, bytes);
            }
        }
        if i == BLOCK_PERIODS - 1 {
            defmt::info!(
                "machine-digest {=u32} {=u64:x} {=[u8]}",
                p,
                self.digest.0,
                &self.tags[..]
            );
        }
    }
}
