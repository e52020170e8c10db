//! The QEMU link rig's operator panel protocol (feature `qemu`): the bytes a host sends on
//! USART1 to press and release the simulated machine's e-stop. QEMU's STM32F405 models
//! no GPIO, so the e-stop pin cannot be driven there; a second serial line stands in for
//! the panel's wires. The rig's side (the USART itself) is `src/qemu/panel.rs`; the host's
//! is `QemuMachine::press_estop` in host-sim (`host-sim/src/cli/qemu.rs`), which sends
//! the same bytes.
//!
//! Each byte that commands something is acknowledged once the rig has applied it: the
//! byte itself, then the number of the control period whose servo step reads the new
//! state first (the servo's period counter, as in the link's status and telemetry; u32,
//! little-endian; [`ack`]). So a host knows exactly when the press took effect, however
//! late it reads.
//!
//! [`CLOCK_QUERY`] (`T`) asks for the machine's clock: the answer is the byte, then the
//! link's clock (the control clock in ms, `crate::link::LINK_CLOCK_MS`, which the device's
//! link timeouts count; u32, little-endian) as the control interrupt reads it. It is the
//! host's clock in `gantry --qemu`: the host's link timeouts then count the same emulated
//! time as the device's, so an emulator starved of CPU never reads as a lost link.
//! Every other byte is ignored and not acknowledged.

/// Press the e-stop (`E`).
pub const ESTOP_PRESS: u8 = b'E';
/// Release the e-stop (`e`).
pub const ESTOP_RELEASE: u8 = b'e';

/// Ask for the machine's clock (`T`): answered with [`ack`]`(CLOCK_QUERY, link_ms)`.
pub const CLOCK_QUERY: u8 = b'T';

/// Panel bytes the control interrupt takes at most per period: a bound on its work (a
/// host sends one byte per change; QEMU delivers the next byte only after the data
/// register was read, so more than one per period is rare).
pub const BYTES_PER_PERIOD: usize = 4;

/// Bytes of an acknowledgement.
pub const ACK_LEN: usize = 5;

/// The acknowledgement of command byte `byte`, applied for the servo step of period
/// `period`: the byte, then the period (little-endian).
#[inline]
pub const fn ack(byte: u8, period: u32) -> [u8; ACK_LEN] {
    let p = period.to_le_bytes();
    [byte, p[0], p[1], p[2], p[3]]
}

/// The answer to [`CLOCK_QUERY`] with the link's clock at `link_ms` (little-endian).
#[inline]
pub const fn clock(link_ms: u32) -> [u8; ACK_LEN] {
    ack(CLOCK_QUERY, link_ms)
}

/// The e-stop state a panel byte commands: `Some(true)` pressed, `Some(false)` released,
/// `None` for any other byte (ignored).
#[inline]
pub const fn estop_command(byte: u8) -> Option<bool> {
    match byte {
        ESTOP_PRESS => Some(true),
        ESTOP_RELEASE => Some(false),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_two_command_bytes_do_something() {
        assert_eq!(estop_command(b'E'), Some(true));
        assert_eq!(estop_command(b'e'), Some(false));
        assert_eq!(estop_command(CLOCK_QUERY), None);
        for b in (0..=u8::MAX).filter(|b| *b != b'E' && *b != b'e') {
            assert_eq!(estop_command(b), None, "{b}");
        }
    }

    #[test]
    fn the_ack_is_the_byte_then_the_period_little_endian() {
        assert_eq!(ack(b'E', 0x0403_0201), [b'E', 1, 2, 3, 4]);
    }

    #[test]
    fn the_clock_answer_is_t_then_the_link_ms_little_endian() {
        assert_eq!(clock(0x0403_0201), [b'T', 1, 2, 3, 4]);
        assert_ne!(CLOCK_QUERY, ESTOP_PRESS);
        assert_ne!(CLOCK_QUERY, ESTOP_RELEASE);
    }
}
