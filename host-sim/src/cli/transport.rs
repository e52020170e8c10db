//! What every machine the command line talks to is to the host: bytes in and out, and the
//! link's millisecond clock (the simulated machine, QEMU, a board, a served machine).

use anyhow::Result;

/// Bytes to and from a machine, and its clock.
pub trait Transport {
    /// Send bytes (whole frames).
    fn send(&mut self, bytes: &[u8]) -> Result<()>;
    /// Append what arrived.
    fn recv(&mut self, buf: &mut Vec<u8>) -> Result<()>;
    /// The link's millisecond clock, which every host timeout counts (the link's
    /// watchdog, heartbeats and retransmissions, the replies' timeouts): the machine's
    /// own clock for the simulated machine and for QEMU (a starved emulator is then slow,
    /// never lost: [`qemu`](super::qemu)), the wall clock for a board (it runs in real
    /// time).
    fn now_ms(&self) -> u32;
    /// Let time pass (about a millisecond); fails when the machine is gone.
    fn wait(&mut self) -> Result<()>;
    /// The machine's clock runs whether or not the host waits (a board, the board twin,
    /// QEMU): work on the host between requests then has to keep the link serviced
    /// ([`Client::while_busy`](super::client::Client::while_busy)), or the machine's link
    /// watchdog (500 ms of its time) ends the session. The simulated machine's clock moves
    /// only in [`Transport::wait`].
    fn clock_runs_alone(&self) -> bool;
}
