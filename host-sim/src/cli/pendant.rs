//! `gantry pendant`: keyboard jog at a terminal, as a handwheel pendant is used to set up a
//! job. The arrows jog X (left, right) and Y (down, up), Page Up and Page Down jog Z; `s`
//! switches between steps (each key one move of the step size, exact) and continuous
//! jog (the axis moves while the key repeats, and stops by the machine's own jog timeout
//! when it is released); `1`..`4` choose the step (0.01, 0.1, 1, 10 mm) and the speed (1,
//! 5, 20, 50 mm/s); `q` or Ctrl-C ends it. One read-out line shows where the machine is.

use super::client::Client;
use super::keys::SingleKeys;
use super::{interrupt, move_to, ready, view, Transport};
use anyhow::{bail, Result};
use std::io::Write;
use std::time::{Duration, Instant};

/// A key as the terminal sends it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Key {
    Left,
    Right,
    Up,
    Down,
    PageUp,
    PageDown,
    Char(char),
}

/// The keys in `bytes` (ANSI escape sequences for the arrows and the page keys, as
/// xterm and the Linux console send them; an incomplete sequence at the end is left for
/// the next read: its length is returned).
pub fn decode(bytes: &[u8]) -> (Vec<Key>, usize) {
    let mut keys = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            0x1b => {
                let rest = &bytes[i..];
                let Some(&intro) = rest.get(1) else {
                    // (a lone escape at the end of a read: the rest may follow)
                    return (keys, rest.len());
                };
                if intro != b'[' && intro != b'O' {
                    // an escape before another key (Alt+key): the key stands alone
                    i += 1;
                    continue;
                }
                // CSI or SS3: parameters, then a final byte in 0x40..=0x7E
                let Some(end) = rest.iter().skip(2).position(|b| (0x40..=0x7e).contains(b)) else {
                    return (keys, rest.len());
                };
                let seq = &rest[..end + 3];
                keys.extend(match seq {
                    [_, _, b'A'] => Some(Key::Up),
                    [_, _, b'B'] => Some(Key::Down),
                    [_, _, b'C'] => Some(Key::Right),
                    [_, _, b'D'] => Some(Key::Left),
                    [_, b'[', b'5', b'~'] => Some(Key::PageUp),
                    [_, b'[', b'6', b'~'] => Some(Key::PageDown),
                    // another key's sequence (a function key): skipped whole
                    _ => None,
                });
                i += seq.len();
            }
            b if b.is_ascii_graphic() => {
                keys.push(Key::Char(b as char));
                i += 1;
            }
            _ => i += 1,
        }
    }
    (keys, 0)
}

/// The axis and direction a key jogs.
fn jog_of(k: Key) -> Option<(usize, f32)> {
    match k {
        Key::Left => Some((0, -1.0)),
        Key::Right => Some((0, 1.0)),
        Key::Down => Some((1, -1.0)),
        Key::Up => Some((1, 1.0)),
        Key::PageDown => Some((2, -1.0)),
        Key::PageUp => Some((2, 1.0)),
        Key::Char(_) => None,
    }
}

/// Step sizes, mm, and continuous speeds, mm/s, by level `1`..`4`.
const STEPS_MM: [f32; 4] = [0.01, 0.1, 1.0, 10.0];
const SPEEDS_MM_S: [f32; 4] = [1.0, 5.0, 20.0, 50.0];
/// A held key's first repeat comes after the terminal's auto-repeat delay (250-660 ms on
/// common systems): the jog is kept alive that long after a first press, then this long
/// after each repeat. Released, the axis stops within this plus the machine's jog timeout.
const FIRST_HOLD: Duration = Duration::from_millis(550);
const REPEAT_HOLD: Duration = Duration::from_millis(120);
/// How often a held jog is sent again (well inside the machine's jog timeout, 0.3 s).
const RESEND: Duration = Duration::from_millis(100);

/// Run the pendant until `q` or Ctrl-C (homes and arms first).
pub fn pendant<T: Transport>(c: &mut Client<T>) -> Result<()> {
    let Some(_single) = SingleKeys::start() else {
        bail!("gantry pendant needs a terminal (its keys are read one by one): use `gantry jog` or `gantry move` in scripts");
    };
    ready(c, true)?;
    let (tx, rx) = std::sync::mpsc::channel::<u8>();
    std::thread::spawn(move || {
        use std::io::Read;
        let mut buf = [0u8; 32];
        while let Ok(n @ 1..) = std::io::stdin().read(&mut buf) {
            for b in &buf[..n] {
                if tx.send(*b).is_err() {
                    return;
                }
            }
        }
    });
    eprintln!(
        "pendant: arrows X/Y, PgUp/PgDn Z; s steps/continuous; 1-4 step {STEPS_MM:?} mm or speed {SPEEDS_MM_S:?} mm/s; q quits"
    );
    let (mut continuous, mut level) = (false, 2usize);
    let mut pending: Vec<u8> = Vec::new();
    // the held jog: axis, direction, until when, last sent
    let mut held: Option<(usize, f32, Instant, Instant)> = None;
    let mut last_target: Option<[f32; 3]> = None;
    'session: loop {
        while let Ok(b) = rx.try_recv() {
            pending.push(b);
        }
        let (keys, left) = decode(&pending);
        pending.drain(..pending.len() - left);
        for k in keys {
            match (k, jog_of(k)) {
                (Key::Char('q'), _) => break 'session,
                (Key::Char('s'), _) => {
                    continuous = !continuous;
                    last_target = None;
                }
                (Key::Char(d @ '1'..='4'), _) => level = d as usize - '1' as usize,
                (_, Some((axis, dir))) if continuous => {
                    let now = Instant::now();
                    let same = held.is_some_and(|(a, d, _, _)| a == axis && d == dir);
                    let until = now + if same { REPEAT_HOLD } else { FIRST_HOLD };
                    if !same {
                        super::jog(c, axis, dir * SPEEDS_MM_S[level])?;
                        held = Some((axis, dir, until, now));
                    } else if let Some(h) = held.as_mut() {
                        h.2 = h.2.max(until);
                    }
                }
                (_, Some((axis, dir))) => {
                    let mut target = match last_target {
                        Some(t) => t,
                        None => c.status()?.pos_mm,
                    };
                    target[axis] += dir * STEPS_MM[level];
                    match move_to(c, target) {
                        Ok(_) => last_target = Some(target),
                        // (outside the travel: said, nothing moved)
                        Err(e) => eprintln!("\r\n{e}"),
                    }
                }
                _ => {}
            }
        }
        if interrupt::requested() {
            break;
        }
        if let Some((axis, dir, until, sent)) = held {
            let now = Instant::now();
            if now >= until {
                super::jog(c, axis, 0.0)?;
                held = None;
            } else if now.duration_since(sent) >= RESEND {
                super::jog(c, axis, dir * SPEEDS_MM_S[level])?;
                held = Some((axis, dir, until, now));
            }
        }
        let s = c.status()?;
        let mode = if continuous {
            format!("jog {} mm/s", SPEEDS_MM_S[level])
        } else {
            format!("step {} mm", STEPS_MM[level])
        };
        eprint!("\r{}  [{mode}]\x1b[K", view::dro_line(&s));
        let _ = std::io::stderr().flush();
        c.sleep_ms(20)?;
    }
    if let Some((axis, _, _, _)) = held {
        super::jog(c, axis, 0.0)?;
    }
    let s = c.status()?;
    eprintln!(
        "\r\npendant: at x {:.3} y {:.3} z {:.3} mm",
        s.pos_mm[0], s.pos_mm[1], s.pos_mm[2]
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arrows_page_keys_and_letters_decode_and_a_cut_sequence_waits() {
        let (k, left) = decode(b"\x1b[A\x1b[B\x1bOC\x1b[D\x1b[5~\x1b[6~s2q");
        assert_eq!(
            k,
            [
                Key::Up,
                Key::Down,
                Key::Right,
                Key::Left,
                Key::PageUp,
                Key::PageDown,
                Key::Char('s'),
                Key::Char('2'),
                Key::Char('q')
            ]
        );
        assert_eq!(left, 0);
        // an arrow split across two reads
        let (k, left) = decode(b"a\x1b[");
        assert_eq!((k, left), (vec![Key::Char('a')], 2));
        let (k, left) = decode(b"\x1b[5");
        assert_eq!((k, left), (vec![], 3));
        // a function key's sequence is skipped whole (its digits are no step keys)
        let (k, left) = decode(b"\x1b[15~x");
        assert_eq!((k, left), (vec![Key::Char('x')], 0));
        // Alt+a: the key alone
        assert_eq!(decode(b"\x1ba").0, [Key::Char('a')]);
    }

    #[test]
    fn each_arrow_jogs_its_axis_its_way() {
        assert_eq!(jog_of(Key::Left), Some((0, -1.0)));
        assert_eq!(jog_of(Key::Up), Some((1, 1.0)));
        assert_eq!(jog_of(Key::PageDown), Some((2, -1.0)));
        assert_eq!(jog_of(Key::Char('x')), None);
    }
}
