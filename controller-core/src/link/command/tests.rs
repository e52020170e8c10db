extern crate std;
use std::collections::VecDeque;
use std::vec::Vec;

use proptest::prelude::*;

use super::*;

const CFG: CommandConfig = CommandConfig {
    retransmit_timeout_ms: 50,
    max_retries: 3,
};

fn sent_by<const W: usize>(tx: &mut CommandSender<u32, W>, now: u32) -> Vec<(Seq, u32)> {
    let mut out = Vec::new();
    tx.poll(now, |s, c| out.push((s, *c))).unwrap();
    out
}

#[test]
fn credits_and_window_limit_what_is_in_flight() {
    let mut tx = CommandSender::<u32, 4>::new(&CFG, Seq(0)).unwrap();
    // No credits before the device's first ack.
    assert!(!tx.can_push());
    assert_eq!(tx.push(1), Err((CommandError::WouldBlock, 1)));
    assert_eq!(tx.on_ack(Seq(65535), 2), AckOutcome::Acked(0));
    assert_eq!(tx.push(1), Ok(Seq(0)));
    assert_eq!(tx.push(2), Ok(Seq(1)));
    assert_eq!(tx.push(3), Err((CommandError::WouldBlock, 3)));
    assert_eq!(sent_by(&mut tx, 0), [(Seq(0), 1), (Seq(1), 2)]);
    // More credits than the window: the window limits.
    assert_eq!(tx.on_ack(Seq(0), 100), AckOutcome::Acked(1));
    for c in 3..=5 {
        tx.push(c).unwrap();
    }
    assert_eq!(tx.in_flight(), 4);
    assert!(!tx.can_push());
    assert_eq!(sent_by(&mut tx, 1), [(Seq(2), 3), (Seq(3), 4), (Seq(4), 5)]);
}

#[test]
fn goes_back_exactly_at_the_timeout_then_gives_up() {
    let mut tx = CommandSender::<u32, 4>::new(&CFG, Seq(0)).unwrap();
    tx.on_ack(Seq(65535), 4);
    tx.push(10).unwrap();
    tx.push(11).unwrap();
    assert_eq!(sent_by(&mut tx, 100).len(), 2);
    assert!(sent_by(&mut tx, 149).is_empty());
    assert_eq!(sent_by(&mut tx, 150), [(Seq(0), 10), (Seq(1), 11)]);
    // First one acked: the second is now the oldest, its own retries start at 0.
    tx.on_ack(Seq(0), 4);
    assert_eq!(sent_by(&mut tx, 200), [(Seq(1), 11)]);
    assert_eq!(sent_by(&mut tx, 250), [(Seq(1), 11)]);
    assert_eq!(sent_by(&mut tx, 300), [(Seq(1), 11)]);
    assert_eq!(tx.stats().retransmitted, 5);
    // Three retransmissions as the oldest were the last allowed.
    assert_eq!(
        tx.poll(350, |_, _| {}),
        Err(CommandError::RetriesExhausted { seq: Seq(1) })
    );
}

#[test]
fn a_nak_goes_back_at_once() {
    let mut tx = CommandSender::<u32, 4>::new(&CFG, Seq(0)).unwrap();
    tx.on_ack(Seq(65535), 4);
    for c in 0..4 {
        tx.push(c).unwrap();
    }
    assert_eq!(sent_by(&mut tx, 0).len(), 4);
    // Frame 0 lost: the device naks 1 (and acks 2 and 3 plainly).
    assert_eq!(tx.on_nak(Seq(65535), 4, Seq(1)), AckOutcome::Acked(0));
    assert_eq!(
        sent_by(&mut tx, 1),
        [(Seq(0), 0), (Seq(1), 1), (Seq(2), 2), (Seq(3), 3)]
    );
    assert!(sent_by(&mut tx, 2).is_empty());
    // A nak that also acks 0 and 1: go back from 2.
    assert_eq!(tx.on_nak(Seq(1), 4, Seq(3)), AckOutcome::Acked(2));
    assert_eq!(sent_by(&mut tx, 3), [(Seq(2), 2), (Seq(3), 3)]);
    // A nak for a number no longer in flight changes nothing.
    assert_eq!(tx.on_nak(Seq(3), 4, Seq(2)), AckOutcome::Acked(2));
    assert!(sent_by(&mut tx, 4).is_empty());
    assert_eq!(tx.stats().retransmitted, 6);
}

#[test]
fn receiver_naks_once_per_gap_until_the_sender_goes_back() {
    let mut rx = CommandReceiver::new(Seq(0));
    let a = Ack {
        seq: Seq(65535),
        credits: 5,
    };
    assert_eq!(rx.on_command(Seq(1), 5), Receipt::OutOfOrder(a));
    assert_eq!(rx.on_command(Seq(2), 5), Receipt::Ahead(a));
    assert_eq!(rx.on_command(Seq(3), 5), Receipt::Ahead(a));
    // The go-back's frame 0 is lost again; its frame 1 shows the go-back: nak again.
    assert_eq!(rx.on_command(Seq(1), 5), Receipt::OutOfOrder(a));
    assert_eq!(rx.on_command(Seq(2), 5), Receipt::Ahead(a));
    assert_eq!(
        rx.on_command(Seq(0), 5),
        Receipt::Accept(Ack {
            seq: Seq(0),
            credits: 4
        })
    );
    assert_eq!(
        rx.on_command(Seq(2), 4),
        Receipt::OutOfOrder(Ack {
            seq: Seq(0),
            credits: 4
        })
    );
}

#[test]
fn stale_and_bogus_acks_are_ignored() {
    let mut tx = CommandSender::<u32, 4>::new(&CFG, Seq(10)).unwrap();
    tx.on_ack(Seq(9), 4);
    tx.push(1).unwrap();
    tx.push(2).unwrap();
    assert_eq!(tx.on_ack(Seq(10), 3), AckOutcome::Acked(1));
    assert_eq!(tx.on_ack(Seq(9), 4), AckOutcome::Stale);
    assert_eq!(tx.credits(), 3);
    assert_eq!(tx.on_ack(Seq(15), 4), AckOutcome::Bogus);
    assert_eq!(tx.in_flight(), 1);
    assert_eq!((tx.stats().stale_acks, tx.stats().bogus_acks), (1, 1));
}

#[test]
fn receiver_accepts_in_order_reacks_duplicates_drops_the_rest() {
    let mut rx = CommandReceiver::new(Seq(65534));
    let a = |seq, credits| Ack {
        seq: Seq(seq),
        credits,
    };
    assert_eq!(rx.on_command(Seq(65534), 5), Receipt::Accept(a(65534, 4)));
    assert_eq!(rx.on_command(Seq(0), 4), Receipt::OutOfOrder(a(65534, 4)));
    assert_eq!(rx.on_command(Seq(65535), 4), Receipt::Accept(a(65535, 3)));
    assert_eq!(
        rx.on_command(Seq(65534), 3),
        Receipt::Duplicate(a(65535, 3))
    );
    assert_eq!(rx.on_command(Seq(0), 0), Receipt::QueueFull(a(65535, 0)));
    assert_eq!(rx.on_command(Seq(0), 1), Receipt::Accept(a(0, 0)));
    let s = rx.stats();
    assert_eq!(
        (s.accepted, s.duplicates, s.out_of_order, s.queue_full),
        (3, 1, 1, 1)
    );
}

#[test]
fn bad_config_is_rejected_by_name() {
    let bad = CommandConfig {
        retransmit_timeout_ms: 0,
        max_retries: 3,
    };
    assert_eq!(
        CommandSender::<u8, 4>::new(&bad, Seq(0)).err(),
        Some(LinkConfigError::OutOfRange("retransmit_timeout_ms"))
    );
    let bad = CommandConfig {
        retransmit_timeout_ms: 10,
        max_retries: 0,
    };
    assert_eq!(
        CommandSender::<u8, 4>::new(&bad, Seq(0)).err(),
        Some(LinkConfigError::OutOfRange("max_retries"))
    );
    // WINDOW = 0 does not compile (heapless::Deque asserts N > 0); too large a window
    // would break the serial-number comparison.
    assert_eq!(
        CommandSender::<u8, 40000>::new(&CFG, Seq(0)).err(),
        Some(LinkConfigError::OutOfRange("WINDOW"))
    );
}

/// A frame-level channel that drops, duplicates and reorders (by holding frames back).
struct Lossy {
    rng: u64,
    loss: u32,
    dup: u32,
    delay: u32,
}

impl Lossy {
    fn next(&mut self) -> u32 {
        // splitmix64
        self.rng = self.rng.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.rng;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) % 1000) as u32
    }

    /// Deliver `x` into `q` at some time later: returns (delivery tick offset, copies).
    fn send<T: Copy>(&mut self, x: T, now: u32, q: &mut VecDeque<(u32, T)>) {
        if self.next() < self.loss {
            return;
        }
        let copies = if self.next() < self.dup { 2 } else { 1 };
        for _ in 0..copies {
            let late = if self.next() < self.delay {
                1 + self.next() % 30
            } else {
                1
            };
            q.push_back((now + late, x));
        }
    }
}

fn take_due<T>(q: &mut VecDeque<(u32, T)>, now: u32) -> Vec<T> {
    let mut due = Vec::new();
    let mut keep = VecDeque::new();
    while let Some((t, x)) = q.pop_front() {
        if t <= now {
            due.push(x);
        } else {
            keep.push_back((t, x));
        }
    }
    *q = keep;
    due
}

/// Sender and receiver through a lossy, duplicating, reordering channel both ways; the
/// device consumes one queued command per tick. Returns (executed, retransmissions).
fn exchange(n: u32, first: u16, seed: u64, loss: u32, dup: u32, delay: u32) -> (Vec<u32>, u32) {
    const QUEUE: u16 = 6;
    let mut tx = CommandSender::<u32, 8>::new(
        &CommandConfig {
            retransmit_timeout_ms: 40,
            max_retries: 50,
        },
        Seq(first),
    )
    .unwrap();
    let mut rx = CommandReceiver::new(Seq(first));
    let mut ch = Lossy {
        rng: seed,
        loss,
        dup,
        delay,
    };
    let mut down: VecDeque<(u32, (Seq, u32))> = VecDeque::new();
    let mut up: VecDeque<(u32, (Ack, Option<Seq>))> = VecDeque::new();
    let mut queue: VecDeque<u32> = VecDeque::new();
    let mut executed = Vec::new();
    let mut next_cmd = 0;
    // The device's first ack (what the heartbeat answer carries).
    tx.on_ack(Seq(first).prev(), QUEUE);
    for now in 0..2_000_000u32 {
        while next_cmd < n && tx.can_push() {
            tx.push(next_cmd).unwrap();
            next_cmd += 1;
        }
        let mut out = Vec::new();
        tx.poll(now, |s, c| out.push((s, *c))).unwrap();
        for f in out {
            ch.send(f, now, &mut down);
        }
        for (seq, cmd) in take_due(&mut down, now) {
            let free = QUEUE - queue.len() as u16;
            let r = rx.on_command(seq, free);
            let nak = match r {
                Receipt::Accept(_) => {
                    queue.push_back(cmd);
                    None
                }
                Receipt::OutOfOrder(_) => Some(seq),
                _ => None,
            };
            ch.send((r.ack(), nak), now, &mut up);
        }
        if let Some(c) = queue.pop_front() {
            executed.push(c);
            // Credit update every 4 freed slots, as DeviceLink does.
            if (now % 4) == 0 {
                ch.send((rx.ack(QUEUE - queue.len() as u16), None), now, &mut up);
            }
        }
        for (a, nak) in take_due(&mut up, now) {
            match nak {
                Some(got) => tx.on_nak(a.seq, a.credits, got),
                None => tx.on_ack(a.seq, a.credits),
            };
        }
        if executed.len() as u32 == n && tx.in_flight() == 0 {
            break;
        }
        // Periodic ack refresh (the device's answer to the host heartbeat).
        if now % 100 == 0 {
            ch.send((rx.ack(QUEUE - queue.len() as u16), None), now, &mut up);
        }
    }
    (executed, tx.stats().retransmitted)
}

#[test]
fn lossy_exchange_delivers_everything_once_in_order_across_the_wrap() {
    // 5 % loss, 5 % duplicates, 10 % delayed (reordered), starting 100 before the wrap.
    let (executed, retx) = exchange(2000, 65436, 1, 50, 50, 100);
    assert_eq!(executed, (0..2000).collect::<Vec<_>>());
    assert!(retx > 50, "retransmissions {retx}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn any_loss_pattern_delivers_everything_once_in_order(
        seed in any::<u64>(),
        first in any::<u16>(),
        loss in 0u32..300,
        dup in 0u32..300,
        delay in 0u32..300,
    ) {
        let (executed, _) = exchange(300, first, seed, loss, dup, delay);
        prop_assert_eq!(executed, (0..300).collect::<Vec<_>>());
    }
}
