//! The board twin's plant (`twin-plant`): the simulated physical gantry of `gantry --sim`
//! ([`crate::sim_gantry::gantry_world`], the same world, amplifiers, brakes, switches and
//! encoders) stepped by the twin (firmware/twin) over a pipe, one control period per
//! request. The twin reads what the board's pins drive (TIM1's duty and the DIR, enable
//! and brake pins), asks for one period, and puts the answer back on the board: the
//! counts into the encoder timers, the limit switches and amplifier faults onto their
//! input pins, and each index pulse the period passed onto its index pin, with the count
//! the encoder gave there (the world's own index model, [`World::index_counts`]: what
//! `read_index` gives host-sim's servo, before the counter's width).
//!
//! The protocol (little-endian, fixed-size records; `twin-plant` answers every request
//! before it reads the next):
//!
//! | request | bytes | answer |
//! |---|---|---|
//! | `S` step one period | `S`, u8 enable mask, u8 brake-released mask, 3 × f64 signed duty (−1..1, + = DIR low) | 3 × i64 encoder counts, u8 limits (bit 2i: axis i's min switch, 2i+1: max), u8 amplifier faults, u8 index mask (bit i: axis i passed its index in the period), 3 × i64 the count at that index (0 where none) |
//! | `T` true state | `T` | 3 × f64 position mm, 3 × f64 velocity mm/s |
//! | `J` inject a fault | `J`, u16 length, that many bytes of one [`Injection`] as JSON | u8 0 taken, 1 refused |
//!
//! A request the plant does not understand ends it with exit code 2 and a message on
//! stderr: the twin stops its run with that message.

use std::io::{Read, Write};

use anyhow::{anyhow, bail, Context, Result};
use controller_core::axes::AXES;
use controller_core::servo::io::ServoIo;
use controller_core::sim::world::{Injection, World};

/// Bytes of an `S` request after its tag.
pub const STEP_REQUEST_BYTES: usize = 2 + 8 * AXES;
/// Bytes of an `S` answer.
pub const STEP_ANSWER_BYTES: usize = 8 * AXES + 3 + 8 * AXES;
/// Largest `J` payload.
const INJECTION_MAX_BYTES: usize = 1024;

/// One period's drive as the board's pins give it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drive {
    /// Per axis: the amplifier's enable pin is high.
    pub enabled: [bool; AXES],
    /// Per axis: the brake coil is energised (brake open).
    pub brake_released: [bool; AXES],
    /// Per axis the duty the amplifier applies, signed by the DIR pin (−1..1).
    pub duty: [f64; AXES],
}

/// What the board's inputs see after the period.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Sensed {
    pub counts: [i64; AXES],
    /// Per axis `[min, max]` switch active.
    pub limits: [[bool; 2]; AXES],
    pub amp_fault: [bool; AXES],
    /// Per axis the index pulse passed in the period, as the encoder count there (the
    /// frame of `counts`); `None`: none passed.
    pub index: [Option<i64>; AXES],
}

/// The amplifiers and the axes.
pub struct TwinPlant {
    world: World,
    full_scale: [f64; AXES],
}

impl TwinPlant {
    pub fn new(world: World) -> Self {
        let full_scale = world.full_scale();
        Self { world, full_scale }
    }

    /// One control period with `drive` held: an amplifier whose enable is low (or whose
    /// duty is not a number) applies nothing.
    pub fn step(&mut self, drive: &Drive) -> Sensed {
        let io: &mut dyn ServoIo<f64> = &mut self.world;
        if drive.enabled.iter().any(|&e| e) {
            let mut effort = [0.0; AXES];
            for (i, e) in effort.iter_mut().enumerate() {
                let d = drive.duty[i];
                if drive.enabled[i] && d.is_finite() {
                    *e = d.clamp(-1.0, 1.0) * self.full_scale[i];
                }
            }
            io.write_outputs(&effort);
        } else {
            io.disable_outputs();
        }
        io.write_brakes(drive.brake_released);
        self.world.advance();
        let inputs = <World as ServoIo<f64>>::read_inputs(&mut self.world);
        Sensed {
            counts: self.world.reported_counts(),
            limits: inputs.limits,
            amp_fault: inputs.amp_fault,
            index: self.world.index_counts(),
        }
    }

    pub fn world(&self) -> &World {
        &self.world
    }

    pub fn inject(&mut self, inj: &Injection) {
        self.world.inject(inj);
    }
}

/// Decode an `S` request's payload.
pub fn decode_step(b: &[u8; STEP_REQUEST_BYTES]) -> Drive {
    let bit = |m: u8, i: usize| m >> i & 1 == 1;
    let mut duty = [0.0; AXES];
    for (i, d) in duty.iter_mut().enumerate() {
        let mut w = [0u8; 8];
        w.copy_from_slice(&b[2 + 8 * i..10 + 8 * i]);
        *d = f64::from_le_bytes(w);
    }
    Drive {
        enabled: core::array::from_fn(|i| bit(b[0], i)),
        brake_released: core::array::from_fn(|i| bit(b[1], i)),
        duty,
    }
}

/// Encode an `S` answer.
pub fn encode_sensed(s: &Sensed) -> [u8; STEP_ANSWER_BYTES] {
    let mut out = [0u8; STEP_ANSWER_BYTES];
    for (i, c) in s.counts.iter().enumerate() {
        out[8 * i..8 * i + 8].copy_from_slice(&c.to_le_bytes());
    }
    let mut limits = 0u8;
    let mut faults = 0u8;
    for i in 0..AXES {
        limits |= u8::from(s.limits[i][0]) << (2 * i) | u8::from(s.limits[i][1]) << (2 * i + 1);
        faults |= u8::from(s.amp_fault[i]) << i;
    }
    out[8 * AXES] = limits;
    out[8 * AXES + 1] = faults;
    let mut index = 0u8;
    for (i, n) in s.index.iter().enumerate() {
        if let Some(n) = n {
            index |= 1 << i;
            let at = 8 * AXES + 3 + 8 * i;
            out[at..at + 8].copy_from_slice(&n.to_le_bytes());
        }
    }
    out[8 * AXES + 2] = index;
    out
}

/// Serve requests from `input` until it ends (the twin is done).
pub fn serve(plant: &mut TwinPlant, input: &mut impl Read, output: &mut impl Write) -> Result<()> {
    let mut tag = [0u8; 1];
    loop {
        match input.read_exact(&mut tag) {
            Ok(()) => {}
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(()),
            Err(e) => return Err(e).context("reading the twin's request"),
        }
        match tag[0] {
            b'S' => {
                let mut b = [0u8; STEP_REQUEST_BYTES];
                input
                    .read_exact(&mut b)
                    .context("a step request cut short")?;
                let sensed = plant.step(&decode_step(&b));
                output.write_all(&encode_sensed(&sensed))?;
            }
            b'T' => {
                let mut out = Vec::with_capacity(16 * AXES);
                let st = plant.world().state();
                for s in st {
                    out.extend_from_slice(&s.pos.to_le_bytes());
                }
                for s in st {
                    out.extend_from_slice(&s.vel.to_le_bytes());
                }
                output.write_all(&out)?;
            }
            b'J' => {
                let mut n = [0u8; 2];
                input.read_exact(&mut n)?;
                let n = usize::from(u16::from_le_bytes(n));
                if n > INJECTION_MAX_BYTES {
                    bail!("an injection of {n} bytes (at most {INJECTION_MAX_BYTES})");
                }
                let mut b = vec![0u8; n];
                input.read_exact(&mut b)?;
                let taken = match serde_json::from_slice::<Injection>(&b) {
                    Ok(inj) => {
                        plant.inject(&inj);
                        0u8
                    }
                    Err(e) => {
                        eprintln!("twin-plant: injection refused: {e}");
                        1u8
                    }
                };
                output.write_all(&[taken])?;
            }
            t => return Err(anyhow!("unknown request 0x{t:02x}")),
        }
        output.flush()?;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim_gantry::gantry_world;
    use controller_core::settings::FACTORY;

    fn plant() -> TwinPlant {
        TwinPlant::new(gantry_world(&FACTORY, None, true).unwrap().0)
    }

    fn step(drive: Drive) -> Vec<u8> {
        let mut req = vec![b'S', 0, 0];
        let mask = |m: [bool; AXES]| {
            m.iter()
                .enumerate()
                .fold(0u8, |a, (i, &b)| a | u8::from(b) << i)
        };
        req[1] = mask(drive.enabled);
        req[2] = mask(drive.brake_released);
        for d in drive.duty {
            req.extend_from_slice(&d.to_le_bytes());
        }
        req
    }

    #[test]
    fn a_positive_duty_on_an_enabled_axis_moves_it_forward_and_a_disabled_one_not_at_all() {
        let mut p = plant();
        let mut input = Vec::new();
        for _ in 0..2000 {
            input.extend(step(Drive {
                enabled: [true, false, false],
                brake_released: [false; AXES],
                duty: [0.3, 0.3, 0.0],
            }));
        }
        let mut out = Vec::new();
        serve(&mut p, &mut input.as_slice(), &mut out).unwrap();
        assert_eq!(out.len(), 2000 * STEP_ANSWER_BYTES);
        let last = &out[out.len() - STEP_ANSWER_BYTES..];
        let x = i64::from_le_bytes(last[0..8].try_into().unwrap());
        let y = i64::from_le_bytes(last[8..16].try_into().unwrap());
        // 0.2 s at 30 % torque: X travels (well over 1 mm = 1600 counts), Y stays put
        assert!(x > 1600, "x counts {x}");
        assert_eq!(y, p.world().reported_counts()[1]);
        assert!(y.abs() <= 1, "y counts {y}");
        assert!(p.world().state()[0].vel > 0.0);
    }

    /// X driven forward across several revolutions: each index pulse is reported once, in
    /// the period that passed it, at the encoder's count there (a multiple of the
    /// revolution's 8000 counts: the simulated encoder has no jitter), between the
    /// period's start and end counts; Y, at rest, reports none.
    #[test]
    fn a_step_that_passes_the_index_reports_the_count_there() {
        let mut p = plant();
        let drive = Drive {
            enabled: [true, false, false],
            brake_released: [false; AXES],
            duty: [0.5, 0.0, 0.0],
        };
        let mut last = p.world().reported_counts()[0];
        let mut seen = Vec::new();
        for _ in 0..20_000 {
            let s = p.step(&drive);
            let x = s.counts[0];
            if let Some(n) = s.index[0] {
                assert!(last < n && n <= x, "index at {n} outside ({last}, {x}]");
                seen.push(n);
            }
            assert_eq!(s.index[1], None);
            let raw = encode_sensed(&s);
            assert_eq!(raw[8 * AXES + 2] & 1, u8::from(s.index[0].is_some()));
            last = x;
        }
        assert!(seen.len() >= 3, "index pulses {seen:?} over {last} counts");
        for (k, n) in seen.iter().enumerate() {
            assert_eq!(*n, 8000 * (k as i64 + 1), "{seen:?}");
        }
    }

    #[test]
    fn an_injection_is_taken_and_a_bad_one_refused_without_ending_the_plant() {
        let mut p = plant();
        let good = br#"{"encoder_stuck":{"axis":"x"}}"#;
        let bad = br#"{"no_such_fault":{}}"#;
        let mut input = Vec::new();
        for j in [&good[..], &bad[..]] {
            input.push(b'J');
            input.extend_from_slice(&(j.len() as u16).to_le_bytes());
            input.extend_from_slice(j);
        }
        let mut out = Vec::new();
        serve(&mut p, &mut input.as_slice(), &mut out).unwrap();
        assert_eq!(out, [0, 1]);
    }

    #[test]
    fn an_unknown_request_is_an_error_that_names_it() {
        let mut p = plant();
        let err = serve(&mut p, &mut &b"Q"[..], &mut Vec::new()).unwrap_err();
        assert!(err.to_string().contains("0x51"), "{err}");
    }
}
