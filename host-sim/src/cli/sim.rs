//! `gantry --sim`: the machine's supervisor ([`Machine`]), planner and servo step
//! in-process against the simulated physical gantry, behind the device end of the link
//! ([`Endpoint`]). The host talks to it in link frames, byte for byte what a board gets on
//! its USART, and the endpoint reaches the machine through the same lock-free queues as
//! the firmware's link task and control interrupt ([`Channels`]); simulated time advances
//! only when the host waits ([`Transport::wait`]), one control period after another.
//! Settings saves go to a flash in RAM through the same store and lock as on the board;
//! it lasts as long as the simulated machine (one `gantry --sim` invocation).

use super::Transport;
use crate::sim_gantry::{designed_settings, gantry_world_on, machine_and_planner};
use anyhow::{anyhow, bail, Result};
use controller_core::link::device::DEFAULT_DEVICE_LINK_CONFIG;
use controller_core::link::LinkClock;
use controller_core::machine::{
    save_due_into, Channels, Endpoint, LinkSide, LinkState, Machine, MachineMemory,
};
use controller_core::servo::faults::FaultKind;
use controller_core::settings::store::{
    block_on, BlockingFlash, LoadOutcome, RamFlash, SettingsStore,
};
use controller_core::settings::FACTORY;
use controller_core::sim::world::{Injection, World};
use std::path::Path;

/// Simulated time one [`Transport::wait`] advances, ms.
const WAIT_MS: u32 = 1;

/// Bytes of the simulated settings flash (two pages of 4 KiB, like the QEMU rig's).
const STORE_BYTES: u32 = 8192;

/// The simulated machine's settings flash.
pub type SimStore = SettingsStore<BlockingFlash<RamFlash<{ STORE_BYTES as usize }, 4096>>>;

/// The simulated machine and its link end.
pub struct SimMachine {
    world: World,
    machine: Machine<Box<MachineMemory>>,
    channels: Box<Channels>,
    link: LinkState,
    endpoint: Endpoint,
    rate_hz: u32,
    periods: u64,
    /// The link's clock, counted from the periods run (as the firmware's).
    clock: LinkClock,
    to_host: Vec<u8>,
    store: Box<SimStore>,
}

/// How the simulated machine starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SimModels {
    /// The designed gantry's axis models are entered (every law can arm).
    Designed,
    /// Factory settings: no axis model (identify first).
    Factory,
}

impl SimMachine {
    /// The physical gantry (host-sim/scenarios/gcode.toml: travel ±150/±150/±50 mm
    /// around where it starts) with limit switches where the factory homing expects
    /// them; telemetry every `telemetry_periods` control periods.
    pub fn new(models: SimModels, telemetry_periods: u32) -> Result<Self> {
        Ok(Self::boot(models, telemetry_periods, None, None)?.0)
    }

    /// [`Self::new`] on the axes of a machine file (`None`: the gantry's,
    /// host-sim/machines/gantry.toml), e.g. host-sim/machines/gantry_flexible.toml.
    pub fn on_machine(
        models: SimModels,
        telemetry_periods: u32,
        machine: Option<&Path>,
    ) -> Result<Self> {
        Ok(Self::boot(models, telemetry_periods, None, machine)?.0)
    }

    /// Power on with the settings flash `image` (what a served machine kept in its
    /// `--flash` file; `None`: erased), loading the settings from it as the board does
    /// at boot: a valid record is what runs; an erased store gives `models`' settings; an
    /// unusable one the factory settings and a `settings_corrupt` fault. Also how they
    /// were found.
    pub fn boot(
        models: SimModels,
        telemetry_periods: u32,
        image: Option<&[u8]>,
        machine: Option<&Path>,
    ) -> Result<(Self, LoadOutcome)> {
        let mut ram = RamFlash::new();
        if let Some(bytes) = image {
            if bytes.len() != STORE_BYTES as usize {
                bail!(
                    "settings flash image: {} bytes, the simulated store has {STORE_BYTES}",
                    bytes.len()
                );
            }
            ram.bytes_mut().copy_from_slice(bytes);
        }
        let flash = BlockingFlash::new(ram, 0, STORE_BYTES)
            .map_err(|e| anyhow!("settings flash: {e:?}"))?;
        let mut store = SettingsStore::new(flash, 0..STORE_BYTES)
            .map_err(|e| anyhow!("settings store: {e}"))?;
        // (the scenario's control rate: the settings are checked at the rate they run)
        let rate_hz = machine_and_planner(machine)?.0.servo.rate_hz;
        let (stored, outcome) = block_on(store.load(rate_hz));
        let settings = match outcome {
            LoadOutcome::Stored => stored,
            LoadOutcome::Empty => match models {
                SimModels::Designed => designed_settings(),
                SimModels::Factory => FACTORY,
            },
            _ => FACTORY,
        };
        let (world, rate_hz) = gantry_world_on(machine, &settings, Some(rate_hz), false)?;
        let mut machine = Machine::new(
            &settings,
            rate_hz,
            world.counter_registers(),
            world.counts(),
            Box::new(MachineMemory::BLANK),
        )
        .map_err(|e| anyhow!("machine: {e:?}"))?;
        machine.set_telemetry_every(telemetry_periods);
        if outcome.is_fault() {
            machine.latch_board_fault(FaultKind::SettingsCorrupt);
        }
        let endpoint = Endpoint::new(&DEFAULT_DEVICE_LINK_CONFIG, rate_hz)
            .map_err(|e| anyhow!("link: {e}"))?;
        let sim = Self {
            world,
            machine,
            channels: Box::new(Channels::new()),
            link: LinkState::new(&settings, rate_hz),
            endpoint,
            rate_hz,
            periods: 0,
            clock: LinkClock::new(rate_hz),
            to_host: Vec::new(),
            store: Box::new(store),
        };
        Ok((sim, outcome))
    }

    /// The settings flash's bytes (what a served machine keeps in its `--flash` file).
    pub fn flash_image(&self) -> &[u8] {
        self.store.flash().inner().bytes()
    }

    /// The control rate, Hz.
    pub fn rate_hz(&self) -> u32 {
        self.rate_hz
    }

    /// Telemetry every `periods` control periods from now on (as `new`'s
    /// `telemetry_periods`; 0: none): the subscription an in-process machine starts with.
    pub fn set_telemetry_every(&mut self, periods: u32) {
        self.machine.set_telemetry_every(periods);
    }

    /// The link's millisecond clock: machine time since power-on.
    pub fn clock_ms(&self) -> u32 {
        self.clock.ms()
    }

    /// The true state of the simulated axes (what no host sees over the link).
    pub fn world(&self) -> &World {
        &self.world
    }

    /// Inject a fault into the simulated machine (e-stop pressed, a switch, a sensor).
    pub fn inject(&mut self, inj: &Injection) {
        self.world.inject(inj);
    }

    /// Press (`true`) or release the e-stop: the same world input as the QEMU link rig's
    /// operator panel sets (`QemuMachine::press_estop`). The control period whose servo
    /// step reads it first (the next one; the period of the link's status and telemetry).
    pub fn press_estop(&mut self, pressed: bool) -> u32 {
        self.world.set_estop(pressed);
        self.machine.servo().snapshot().period.wrapping_add(1)
    }

    /// Control periods run so far.
    pub fn periods(&self) -> u64 {
        self.periods
    }

    pub fn machine(&self) -> &Machine<Box<MachineMemory>> {
        &self.machine
    }

    /// The settings flash (what the next boot would load).
    pub fn store(&mut self) -> &mut SimStore {
        &mut self.store
    }

    /// Run `n` control periods.
    pub fn advance(&mut self, n: u32) {
        let mut out = std::mem::take(&mut self.to_host);
        for _ in 0..n {
            let (ends, mut control) = self.channels.split();
            let mut link = LinkSide::new(ends, &mut self.link);
            self.machine.linked_period(&mut self.world, &mut control);
            self.world.advance();
            self.periods += 1;
            let now = self.clock.period();
            self.endpoint
                .poll(&mut link, now, &mut |b: &[u8]| out.extend_from_slice(b));
            save_due_into(&mut link, &mut self.store);
        }
        self.to_host = out;
    }
}

impl Transport for SimMachine {
    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        let now = self.clock.ms();
        let mut out = std::mem::take(&mut self.to_host);
        let (ends, _) = self.channels.split();
        let mut link = LinkSide::new(ends, &mut self.link);
        self.endpoint
            .on_bytes(&mut link, bytes, now, &mut |b: &[u8]| {
                out.extend_from_slice(b)
            });
        self.to_host = out;
        Ok(())
    }

    fn recv(&mut self, buf: &mut Vec<u8>) -> Result<()> {
        buf.append(&mut self.to_host);
        Ok(())
    }

    fn now_ms(&self) -> u32 {
        self.clock.ms()
    }

    /// Its clock moves only in `wait`.
    fn clock_runs_alone(&self) -> bool {
        false
    }

    fn wait(&mut self) -> Result<()> {
        self.advance(self.rate_hz * WAIT_MS / 1000);
        Ok(())
    }
}
