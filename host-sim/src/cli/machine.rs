//! Which machine a session talks to: the options `gantry` and `gantry gui` share
//! (`--sim`, `--served PTY`, `--qemu [--elf ELF]`, `--twin PTY`, `--port DEV`,
//! `--factory`, `--telemetry-hz`), checked once, and the connected session with its
//! telemetry subscription, behind one boxed [`Transport`] whatever the machine.

use super::client::Client;
use super::port::BoardPort;
use super::qemu::{QemuMachine, DEFAULT_ELF};
use super::sim::{SimMachine, SimModels};
use super::Transport;
use anyhow::{bail, Result};
use clap::{ArgGroup, Args};
use std::path::PathBuf;

/// The fastest telemetry a session may ask for, Hz: one sample per period at the
/// project's usual control rate (host-sim/scenarios/gcode.toml, the firmware's default
/// `GANTRY_CONTROL_HZ`). Checked before connecting, so it cannot be the machine's own
/// rate; the decimation is computed from the rate the machine reports in the handshake
/// ([`MachineArgs::decimation`]), at least one period.
pub const MAX_TELEMETRY_HZ: u32 = 10_000;

/// A session's transport, whatever the machine.
pub type AnyTransport = Box<dyn Transport + Send>;

/// The machine options.
#[derive(Args, Clone, Debug, Default)]
#[command(group(ArgGroup::new("machine").args(["sim", "qemu", "port", "twin", "served"])))]
pub struct MachineArgs {
    /// The simulated gantry in-process.
    #[arg(long)]
    pub sim: bool,
    /// The firmware's QEMU build (its link rig: the simulated gantry behind the real
    /// firmware's USART2 link), booted on qemu-system-arm.
    #[arg(long)]
    pub qemu: bool,
    /// A board: its UART's device (921,600 baud 8N1), e.g. /dev/ttyACM0.
    #[arg(long, value_name = "DEV")]
    pub port: Option<String>,
    /// The board twin: the release firmware ELF on the emulated STM32F407, serving its
    /// USART2 at PTY (`firmware/twin/run --serve PTY`); timeouts count its machine clock.
    #[arg(long, value_name = "PTY")]
    pub twin: Option<String>,
    /// A machine that stays: the simulated gantry served at PTY by `gantry sim serve PTY`
    /// (settings, homing and arming kept between commands); timeouts count its clock.
    #[arg(long, value_name = "PTY")]
    pub served: Option<String>,
    /// The firmware ELF for --qemu (default: what `cargo fw-qemu-build` builds).
    #[arg(long, requires = "qemu")]
    pub elf: Option<PathBuf>,
    /// Start the simulated machine with factory settings (no axis model: identify first).
    #[arg(long, requires = "sim")]
    pub factory: bool,
    /// The simulated machine's axes from a machine file instead of the rigid gantry's,
    /// e.g. host-sim/machines/gantry_flexible.toml (its frame modes, backlash and lead
    /// error).
    /// (Its id is not `machine`: that is the name of the group these options form in
    /// `gantry`'s command line.)
    #[arg(
        long = "machine",
        id = "machine_file",
        value_name = "FILE",
        requires = "sim"
    )]
    pub machine: Option<PathBuf>,
    /// Telemetry rate of the session, Hz (1-10000).
    #[arg(long, default_value_t = 1000, allow_negative_numbers = true)]
    pub telemetry_hz: u32,
}

impl MachineArgs {
    /// A machine was named.
    pub fn any(&self) -> bool {
        self.sim || self.qemu || self.port.is_some() || self.twin.is_some() || self.served.is_some()
    }

    /// The options make sense together (clap's `requires` counts a default as given).
    pub fn check(&self) -> Result<()> {
        if !self.any() {
            bail!(
                "which machine? --sim (in-process, fresh each command), --served PTY (one `gantry sim serve PTY` keeps), --qemu, --twin PTY or --port DEV"
            );
        }
        if self.elf.is_some() && !self.qemu {
            bail!("--elf is the firmware for --qemu; it does nothing with --sim, --port or --twin");
        }
        if self.factory && !self.sim {
            bail!("--factory starts the simulated machine; it goes with --sim only");
        }
        if self.machine.is_some() && !self.sim {
            bail!("--machine is the simulated machine's file; it goes with --sim only (`gantry sim serve --machine FILE` for a served one)");
        }
        if self.telemetry_hz == 0 || self.telemetry_hz > MAX_TELEMETRY_HZ {
            bail!(
                "--telemetry-hz must be within 1-{MAX_TELEMETRY_HZ}, got {}",
                self.telemetry_hz
            );
        }
        Ok(())
    }

    /// The options as given on a command line (`gantry gui` passes them on).
    pub fn to_args(&self) -> Vec<String> {
        let mut out = Vec::new();
        let mut flag = |on: bool, name: &str| {
            if on {
                out.push(format!("--{name}"));
            }
        };
        flag(self.sim, "sim");
        flag(self.qemu, "qemu");
        flag(self.factory, "factory");
        for (name, v) in [
            ("port", &self.port),
            ("twin", &self.twin),
            ("served", &self.served),
        ] {
            if let Some(v) = v {
                out.extend([format!("--{name}"), v.clone()]);
            }
        }
        if let Some(elf) = &self.elf {
            out.extend(["--elf".to_string(), elf.display().to_string()]);
        }
        if let Some(m) = &self.machine {
            out.extend(["--machine".to_string(), m.display().to_string()]);
        }
        out.extend(["--telemetry-hz".to_string(), self.telemetry_hz.to_string()]);
        out
    }

    /// Control periods between telemetry samples on a machine whose control loop runs at
    /// `control_rate_hz` (what it reported: [`Client::control_rate_hz`]); at least 1.
    pub fn decimation(&self, control_rate_hz: u32) -> u32 {
        let rate_hz = control_rate_hz.max(1);
        rate_hz / self.telemetry_hz.clamp(1, rate_hz)
    }

    /// How the simulated machine starts.
    pub fn models(&self) -> SimModels {
        if self.factory {
            SimModels::Factory
        } else {
            SimModels::Designed
        }
    }

    /// A session with the machine, telemetry subscribed at `--telemetry-hz` (decimated
    /// from the control rate the machine reports: [`Client::control_rate_hz`]).
    pub fn open(&self) -> Result<Client<AnyTransport>> {
        self.check()?;
        let subscribed = |t: AnyTransport| -> Result<Client<AnyTransport>> {
            let mut c = Client::connect(t)?;
            let decimation = self.decimation(c.control_rate_hz());
            super::subscribe(&mut c, decimation)?;
            Ok(c)
        };
        if let Some(pty) = self.twin.as_ref().or(self.served.as_ref()) {
            subscribed(Box::new(BoardPort::open_twin(pty)?))
        } else if let Some(dev) = &self.port {
            subscribed(Box::new(BoardPort::open(dev)?))
        } else if self.qemu {
            let elf = self
                .elf
                .clone()
                .unwrap_or_else(|| PathBuf::from(DEFAULT_ELF));
            subscribed(Box::new(QemuMachine::boot(&elf)?))
        } else {
            // (the simulated machine starts with the subscription, decimated from the rate
            // it runs at: the rate its handshake reports)
            let mut sim = SimMachine::on_machine(self.models(), 0, self.machine.as_deref())?;
            sim.set_telemetry_every(self.decimation(sim.rate_hz()));
            Client::connect(Box::new(sim))
        }
    }
}

impl<T: Transport + ?Sized> Transport for Box<T> {
    fn send(&mut self, bytes: &[u8]) -> Result<()> {
        (**self).send(bytes)
    }
    fn recv(&mut self, buf: &mut Vec<u8>) -> Result<()> {
        (**self).recv(buf)
    }
    fn now_ms(&self) -> u32 {
        (**self).now_ms()
    }
    fn wait(&mut self) -> Result<()> {
        (**self).wait()
    }
    fn clock_runs_alone(&self) -> bool {
        (**self).clock_runs_alone()
    }
}
