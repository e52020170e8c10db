//! The machine behind the link in the firmware (the QEMU link rig) against the same machine
//! in host-sim, bit for bit: the rig records every input its machine takes, period by
//! period, and a digest of what the machine did (controller-core `machine::record`,
//! firmware `qemu::link`); [`replay`] feeds the same inputs at the same periods into
//! the same machine — the supervisor, the planner split into its executor and planning
//! half as the firmware splits them (the planning half run when the firmware ran it),
//! the servo step — against the same simulated gantry as `gantry --sim`
//! ([`gantry_world`]), through the same [`Machine::linked_period`], and compares each
//! period's 16-bit tag and the running 64-bit digest. A difference is named by the first
//! period whose tag differs.
//!
//! The log lines (defmt, decoded; `<bytes>` a list `[1, 2, …]` of the decoded u8s):
//!
//! ```text
//! machine-record <period> <bytes>        the period's records (postcard, one after another)
//! machine-record <period> lost           a record did not fit the rig's buffer
//! machine-digest <period> <hex> <bytes>  the running digest after <period>, and the
//!                                        block's per-period tags (u16 little-endian)
//! ```

use std::collections::BTreeMap;

use anyhow::{anyhow, bail, Context, Result};
use controller_core::machine::messages::Request;
use controller_core::machine::record::{records, Digest, Record, BLOCK_PERIODS};
use controller_core::machine::{Channels, Down, Machine, MachineMemory};
use controller_core::motion::planner::SplitExecutor;
use controller_core::servo::snapshot::Snapshot;
use controller_core::servo::ServoState;

use crate::engine::split_memory::{PlanTask, SplitParts};
use crate::sim_gantry::{designed_settings, gantry_world};

/// The digest line at the end of a block of [`BLOCK_PERIODS`] periods.
#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    /// The block's last period.
    pub end: u32,
    pub digest: u64,
    pub tags: Vec<u16>,
}

/// A recorded session of the link rig.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Recording {
    /// Each period's records (periods without any are absent).
    pub records: BTreeMap<u32, Vec<Record>>,
    pub blocks: Vec<Block>,
    /// The first period whose records were lost.
    pub lost: Option<u32>,
}

/// `[1, 2, 0x3]` → bytes.
fn bytes(s: &str) -> Result<Vec<u8>> {
    let inner = s
        .trim()
        .strip_prefix('[')
        .and_then(|s| s.strip_suffix(']'))
        .ok_or_else(|| anyhow!("not a byte list: {s:.40}"))?;
    inner
        .split(',')
        .map(str::trim)
        .filter(|t| !t.is_empty())
        .map(|t| match t.strip_prefix("0x") {
            Some(h) => u8::from_str_radix(h, 16),
            None => t.parse(),
        })
        .collect::<Result<_, _>>()
        .map_err(|e| anyhow!("bad byte in list: {e}"))
}

/// The recording in a decoded log of the link rig (other lines are skipped; a last line
/// cut off by the emulator's end is ignored).
pub fn parse(text: &str) -> Result<Recording> {
    let mut rec = Recording::default();
    let lines: Vec<&str> = text.lines().collect();
    for (n, line) in lines.iter().enumerate() {
        let last = n + 1 == lines.len();
        let parsed = (|| -> Result<()> {
            if let Some(i) = line.find("machine-record ") {
                let rest = &line[i + "machine-record ".len()..];
                let (p, list) = rest.split_once(' ').context("no period")?;
                let p: u32 = p.parse().context("bad period")?;
                if list.trim() == "lost" {
                    rec.lost.get_or_insert(p);
                    return Ok(());
                }
                let b = bytes(list)?;
                let rs = records(&b)
                    .collect::<Result<Vec<_>, _>>()
                    .map_err(|e| anyhow!("period {p}: records do not decode: {e}"))?;
                rec.records.entry(p).or_default().extend(rs);
            } else if let Some(i) = line.find("machine-digest ") {
                let mut it = line[i + "machine-digest ".len()..].splitn(3, ' ');
                let end: u32 = it.next().context("no period")?.parse()?;
                let digest = u64::from_str_radix(it.next().context("no digest")?, 16)?;
                let b = bytes(it.next().context("no tags")?)?;
                if b.len() != 2 * BLOCK_PERIODS {
                    bail!("{} tag bytes", b.len());
                }
                let tags = b
                    .chunks(2)
                    .map(|c| u16::from_le_bytes([c[0], c[1]]))
                    .collect();
                rec.blocks.push(Block { end, digest, tags });
            }
            Ok(())
        })();
        match parsed {
            Err(_) if last => {}
            Err(e) => return Err(e.context(format!("log line {}", n + 1))),
            Ok(()) => {}
        }
    }
    Ok(rec)
}

/// What a replay that agreed covered.
#[derive(Clone, Debug, PartialEq)]
pub struct Agreement {
    /// Periods compared (every one, by its tag, and the running digest at each block end).
    pub periods: u32,
    pub blocks: usize,
    /// Link events the machine took, and program segments among them.
    pub events: usize,
    pub segments: usize,
    /// Periods the planning half did not run exactly once before.
    pub plan_irregular: usize,
    pub digest: u64,
    pub state: ServoState,
    pub pos_mm: [f32; 3],
}

impl Agreement {
    pub fn line(&self) -> String {
        format!(
            "{} periods ({} blocks), {} link events ({} segments), planning half not run \
             exactly once before {} periods; bit-exact, digest {:016x}, final state {:?} at \
             [{:.4}, {:.4}, {:.4}] mm",
            self.periods,
            self.blocks,
            self.events,
            self.segments,
            self.plan_irregular,
            self.digest,
            self.state,
            self.pos_mm[0],
            self.pos_mm[1],
            self.pos_mm[2]
        )
    }
}

type Exec = SplitExecutor<'static>;
type Task = PlanTask<'static>;
type SplitMachine = Machine<Box<MachineMemory<Exec>>, Exec>;

/// The link rig's machine: factory settings with the designed axis models, the planner
/// split as the firmware splits it (its parts leaked: they live as long as the replay's
/// caller), in the world of `gantry --sim`.
fn machine() -> Result<(SplitMachine, Task, controller_core::sim::world::World)> {
    let settings = designed_settings();
    let (world, rate_hz) = gantry_world(&settings, None, false)?;
    let parts: &'static mut SplitParts = Box::leak(Box::new(SplitParts::new()));
    let (memory, task) = parts.split();
    let m = Machine::new(
        &settings,
        rate_hz,
        world.counter_registers(),
        world.counts(),
        memory,
    )
    .map_err(|e| anyhow!("machine: {e:?}"))?;
    Ok((m, task, world))
}

/// Replay `rec` (see the module docs): `Ok(Ok(_))` bit-exact over every recorded block,
/// `Ok(Err(why))` naming the first period that differs (or why the recording cannot be
/// replayed), `Err` if host-sim's machine cannot be built.
pub fn replay(rec: &Recording) -> Result<std::result::Result<Agreement, String>> {
    let Some(last) = rec.blocks.last().map(|b| b.end) else {
        return Ok(Err("no digest in the log (did the link rig run?)".into()));
    };
    let mut blocks = rec.blocks.iter();
    run(rec, last, |p, digest, tags, s| {
        let Some(b) = blocks.next() else {
            return Some(format!("no digest line for the block ending at period {p}"));
        };
        if b.end != p || b.tags.len() != tags.len() {
            return Some(format!(
                "the rig's block ends at period {} ({} periods), here at {p} ({})",
                b.end,
                b.tags.len(),
                tags.len()
            ));
        }
        let start = p + 1 - tags.len() as u32;
        if let Some(i) = (0..tags.len()).find(|&i| tags[i] != b.tags[i]) {
            return Some(format!(
                "period {} differs (tag {:04x} here, {:04x} in the firmware; at the \
                 block's end, period {p}: state {:?}, pos [{}, {}, {}] mm here)",
                start + i as u32,
                tags[i],
                b.tags[i],
                s.state,
                s.pos[0],
                s.pos[1],
                s.pos[2]
            ));
        }
        (digest != b.digest).then(|| {
            format!(
                "the running digest differs at period {p} ({digest:016x} here, {:016x} in \
                 the firmware) with every period's tag equal",
                b.digest
            )
        })
    })
}

/// `rec`'s records run in host-sim for `periods` periods, with host-sim's digests as its
/// blocks (what the rig would log for the same inputs): a recording the comparator's
/// tests perturb.
pub fn record_on_host(rec: &Recording, periods: u32) -> Result<Recording> {
    let mut blocks = Vec::new();
    let r = run(rec, periods, |end, digest, tags, _| {
        blocks.push(Block {
            end,
            digest,
            tags: tags.to_vec(),
        });
        None
    })?;
    r.map_err(|e| anyhow!(e))?;
    Ok(Recording {
        records: rec.records.clone(),
        blocks,
        lost: None,
    })
}

/// The periods 1..=`last` with `rec`'s records; `block` sees each block's end, the
/// running digest, the block's tags and the snapshot, and says why it disagrees.
fn run(
    rec: &Recording,
    last: u32,
    mut block: impl FnMut(u32, u64, &[u16], &Snapshot) -> Option<String>,
) -> Result<std::result::Result<Agreement, String>> {
    if let Some(p) = rec.lost.filter(|&p| p <= last) {
        return Ok(Err(format!(
            "period {p}: the rig's records did not fit its buffer"
        )));
    }
    let (mut m, mut task, mut world) = machine()?;
    let mut channels = Box::new(Channels::new());
    let (mut ends, mut control) = channels.split();
    let mut digest = Digest::new();
    let mut tags = Vec::with_capacity(BLOCK_PERIODS);
    let (mut events, mut segments, mut plan_irregular, mut blocks) = (0, 0, 0, 0);
    for p in 1..=last {
        let rs = rec.records.get(&p).map(Vec::as_slice).unwrap_or(&[]);
        // the planning half's runs before this period (the firmware: after the last one)
        let mut runs = 1;
        for r in rs {
            if let Record::Plan { runs: n, busy } = *r {
                if busy {
                    return Ok(Err(format!(
                        "period {p} found the planning half still running (preempted \
                         mid-run): not replayable"
                    )));
                }
                runs = n;
                plan_irregular += 1;
            }
        }
        for _ in 0..runs {
            task.run();
        }
        for r in rs {
            match r {
                Record::Plan { .. } => {}
                Record::Estop(pressed) => world.set_estop(*pressed),
                Record::Down(d) => {
                    events += 1;
                    if matches!(d, Down::Request(Request::Segment(_))) {
                        segments += 1;
                    }
                    if !ends.replay_down(d.clone()) {
                        return Ok(Err(format!("period {p}: more events than the queue holds")));
                    }
                }
                Record::Settings(s) => {
                    if !ends.replay_settings(*s, m.rate_hz()) {
                        return Ok(Err(format!("period {p}: two settings trees at once")));
                    }
                }
            }
        }
        m.linked_period(&mut world, &mut control);
        world.advance();
        tags.push(digest.fold(m.servo().snapshot()));
        if tags.len() == BLOCK_PERIODS {
            if let Some(why) = block(p, digest.0, &tags, m.servo().snapshot()) {
                return Ok(Err(why));
            }
            blocks += 1;
            tags.clear();
        }
    }
    let s = m.servo().snapshot();
    Ok(Ok(Agreement {
        periods: last,
        blocks,
        events,
        segments,
        plan_irregular,
        digest: digest.0,
        state: s.state,
        pos_mm: s.pos,
    }))
}
