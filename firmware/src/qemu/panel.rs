//! The simulated machine's operator panel on USART1 (QEMU link rig only): QEMU's
//! netduinoplus2 models USARTs but no GPIO, so the e-stop a host presses arrives as a
//! byte on USART1 (`-serial` 0) instead of a level on PB12. The bytes are
//! `firmware::panel`'s (`E` press, `e` release, each acknowledged with the period it
//! takes effect in; `T` answered with the machine's link clock; others ignored).
//!
//! [`Panel::poll`] runs in the control interrupt: a status register read, and only when
//! a byte waits, at most [`BYTES_PER_PERIOD`] data register reads and acknowledgements
//! of [`ACK_LEN`] bytes. It polls (no USART1 interrupt): the e-stop takes effect at the
//! period boundary either way, and the control interrupt's work stays bounded. The board
//! build has no panel (its e-stop is the pin, `board::inputs`).

use firmware::panel::{ack, clock, estop_command, ACK_LEN, BYTES_PER_PERIOD, CLOCK_QUERY};
use stm32f4xx_hal::pac::USART1;

/// USART1 as the operator panel.
pub struct Panel {
    usart: USART1,
}

impl Panel {
    /// Receiver and transmitter on. QEMU's USART model drops received bytes unless CR1's
    /// UE and RE are set; it ignores the baud rate (bytes arrive without timing), so BRR
    /// is left at reset. No interrupt is enabled: [`Panel::poll`] reads the flags.
    pub fn new(usart: USART1) -> Self {
        usart
            .cr1()
            .write(|w| w.ue().set_bit().re().set_bit().te().set_bit());
        Self { usart }
    }

    /// The e-stop state the bytes received since the last call command (the last one
    /// wins), if any; each command byte is acknowledged as applied for the servo step of
    /// `period` (the caller sets the state before that step), and a clock query is
    /// answered with `link_ms`, the link's clock now.
    #[inline]
    pub fn poll(&mut self, period: u32, link_ms: u32) -> Option<bool> {
        let mut estop = None;
        for _ in 0..BYTES_PER_PERIOD {
            let sr = self.usart.sr().read();
            if sr.rxne().bit_is_clear() {
                break;
            }
            // (reading DR clears RXNE; the register holds 9 data bits, a byte at 8N1)
            let byte = self.usart.dr().read().dr().bits() as u8;
            if let Some(pressed) = estop_command(byte) {
                estop = Some(pressed);
                self.send(&ack(byte, period));
            } else if byte == CLOCK_QUERY {
                self.send(&clock(link_ms));
            }
        }
        estop
    }

    /// Write `bytes` without waiting: QEMU takes each written byte at once (its TXE is
    /// always set); a byte the transmitter could not take is dropped, never waited for.
    #[inline]
    fn send(&mut self, bytes: &[u8; ACK_LEN]) {
        for b in bytes {
            if self.usart.sr().read().txe().bit_is_clear() {
                return;
            }
            self.usart.dr().write(|w| w.dr().set(u16::from(*b)));
        }
    }
}
