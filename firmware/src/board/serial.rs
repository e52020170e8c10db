//! The host link's UART: USART2 on PA2 (TX) / PA3 (RX), 921,600 baud 8N1 — what an
//! ST-Link virtual COM port or any USB-UART adapter gives.
//!
//! [`HostUart::service`] is the whole interrupt handler: it moves received bytes into the
//! link task's receive queue and bytes of the transmit queue into the data register while
//! the register takes them, and listens for "transmit empty" only while bytes wait. The
//! link task never touches the UART: it queues bytes and pends the interrupt. The handler
//! runs above the control interrupt, so a byte never waits longer than the handler itself
//! (at 921,600 baud a byte lasts 10.9 µs; the data register holds one), and it costs the
//! control interrupt a few dozen cycles per byte.
//!
//! QEMU's USART model (7.2) raises the interrupt for received bytes only and takes every
//! written byte at once (its "transmit empty" flag is always set): the pend from the link
//! task then drains the whole transmit queue in one run, the same code path.

use heapless::spsc::{Consumer, Producer};
use stm32f4xx_hal::gpio::{PA2, PA3};
use stm32f4xx_hal::pac::USART2;
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::Rcc;
use stm32f4xx_hal::serial::{self, Event, RxISR, Serial, TxISR};
use stm32f4xx_hal::Listen;

/// The link's baud rate.
pub const HOST_BAUD: u32 = 921_600;

/// Bytes between the UART interrupt and the link task, each way. Receive: 2.7 ms at
/// 921,600 baud, more than the link task's 1 ms period. Transmit: a few frames (a status
/// frame is about 120 bytes).
pub const RX_QUEUE: usize = 256;
pub const TX_QUEUE: usize = 1024;

/// Receive queue type (capacity `RX_QUEUE - 1`).
pub type RxQueue = heapless::spsc::Queue<u8, RX_QUEUE>;
/// Transmit queue type (capacity `TX_QUEUE - 1`).
pub type TxQueue = heapless::spsc::Queue<u8, TX_QUEUE>;

/// USART2 and its ends of the byte queues (the interrupt handler's local state).
pub struct HostUart {
    serial: Serial<USART2>,
    rx: Producer<'static, u8>,
    tx: Consumer<'static, u8>,
    /// Bytes lost: receive queue full, or a receive error (overrun, framing, noise).
    lost: u32,
}

/// [`init`], or none when the baud rate cannot be set (logged: the board runs without its
/// host link).
pub fn init_or_log(
    usart: USART2,
    tx_pin: PA2,
    rx_pin: PA3,
    rcc: &mut Rcc,
) -> Option<Serial<USART2>> {
    match init(usart, tx_pin, rx_pin, rcc) {
        Ok(s) => Some(s),
        Err(_) => {
            defmt::error!("USART2: {=u32} baud cannot be set", HOST_BAUD);
            None
        }
    }
}

/// Configure USART2 (the pins' alternate function, 921,600 baud 8N1, receive interrupt).
pub fn init(
    usart: USART2,
    tx_pin: PA2,
    rx_pin: PA3,
    rcc: &mut Rcc,
) -> Result<Serial<USART2>, serial::config::InvalidConfig> {
    let cfg = serial::Config::default().baudrate(HOST_BAUD.bps());
    let mut s = usart.serial((tx_pin, rx_pin), cfg, rcc)?;
    s.listen(Event::RxNotEmpty);
    Ok(s)
}

impl HostUart {
    pub fn new(
        serial: Serial<USART2>,
        rx: Producer<'static, u8>,
        tx: Consumer<'static, u8>,
    ) -> Self {
        Self {
            serial,
            rx,
            tx,
            lost: 0,
        }
    }

    /// The interrupt handler's work (see the module docs).
    #[inline]
    pub fn service(&mut self) {
        loop {
            if self.serial.is_rx_not_empty() {
                match embedded_hal_nb::serial::Read::read(&mut self.serial) {
                    Ok(b) => {
                        if self.rx.enqueue(b).is_err() {
                            self.lost = self.lost.wrapping_add(1);
                        }
                    }
                    // the HAL clears the error flags by the read; the link's CRC drops the
                    // frame
                    Err(_) => self.lost = self.lost.wrapping_add(1),
                }
            } else if self.serial.flags().contains(serial::Flag::Overrun) {
                // ORE with RXNE clear: a byte completed between the read of SR and the
                // read of DR above, so that read cleared RXNE but not ORE (RM0090 30.6.1:
                // SR then DR). RXNEIE also raises the interrupt on ORE: left set, the
                // line never drops and the handler, above the control interrupt, runs
                // again at once until the watchdog resets the chip. SR then DR clears it.
                self.serial.clear_idle_interrupt();
                self.lost = self.lost.wrapping_add(1);
            } else {
                break;
            }
        }
        while self.serial.is_tx_empty() {
            let Some(b) = self.tx.dequeue() else {
                break;
            };
            let _ = embedded_hal_nb::serial::Write::write(&mut self.serial, b);
        }
        if self.tx.ready() {
            self.serial.listen(Event::TxEmpty);
        } else {
            self.serial.unlisten(Event::TxEmpty);
        }
    }

    /// Bytes lost so far.
    pub fn lost(&self) -> u32 {
        self.lost
    }
}
