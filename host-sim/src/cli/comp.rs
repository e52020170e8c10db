//! `gantry comp`: an axis' backlash and lead-screw compensation entered on the machine
//! over the link (controller-core `machine::CompEntry`): a LinuxCNC `COMP_FILE` read and
//! checked here first (errors name `FILE:LINE`), sent in parts of
//! [`COMP_CHUNK`] points, put in use with the outputs off, then read back and compared
//! bit for bit with what was sent; read back alone (`show`); cleared (`clear`).
//!
//! The machine keeps its tables in RAM until its next boot: load them each session, as
//! LinuxCNC reads its `COMP_FILE`s at start (`gantry status` lists the axes that carry
//! one).

use anyhow::{bail, Result};
use controller_core::machine::messages::{CompChunk, Outcome, Request, COMP_CHUNK};
use controller_core::motion::compensation::{AxisCompensation, CompPoint};

use super::client::Client;
use super::transport::Transport;
use super::AXES;

/// An axis' compensation as the machine holds it.
#[derive(Clone, Debug, PartialEq)]
pub struct MachineComp {
    pub backlash_mm: f32,
    pub rate_mm_s: f32,
    pub accel_mm_s2: f32,
    /// The points, trims as stored (rounded to 0.1 µm).
    pub points: Vec<CompPoint>,
}

impl MachineComp {
    /// The table `t` (as the machine stores it).
    pub fn of(t: &AxisCompensation) -> Self {
        Self {
            backlash_mm: t.backlash_mm(),
            rate_mm_s: t.rate_mm_s(),
            accel_mm_s2: t.accel_mm_s2(),
            points: (0..t.len()).filter_map(|i| t.point(i)).collect(),
        }
    }
}

fn axis_name(axis: usize) -> &'static str {
    AXES.get(axis).copied().unwrap_or("?")
}

/// Execute `r` on the machine; an error naming `what` when refused.
fn exec_done<T: Transport>(c: &mut Client<T>, r: Request, what: &str) -> Result<()> {
    match c.exec(r)? {
        Outcome::Refused(why) => bail!(
            "{what} refused: {}",
            why.strip_prefix("comp: ").unwrap_or(why.as_str())
        ),
        _ => Ok(()),
    }
}

/// Enter `table` as `axis`' compensation on the machine (outputs off), and check that it
/// reads back as sent. A refusal names the points it was about.
pub fn load<T: Transport>(c: &mut Client<T>, axis: usize, table: &AxisCompensation) -> Result<()> {
    let sent = MachineComp::of(table);
    let name = axis_name(axis);
    exec_done(
        c,
        Request::CompBegin {
            axis: axis as u8,
            points: sent.points.len() as u16,
            backlash_mm: sent.backlash_mm,
            rate_mm_s: sent.rate_mm_s,
            accel_mm_s2: sent.accel_mm_s2,
        },
        &format!("comp {name}: the table's start"),
    )?;
    for (k, part) in sent.points.chunks(COMP_CHUNK).enumerate() {
        let first = k * COMP_CHUNK;
        let points = heapless::Vec::from_slice(part)
            .map_err(|_| anyhow::anyhow!("a part of more than {COMP_CHUNK} points"))?;
        exec_done(
            c,
            Request::CompPoints {
                first: first as u16,
                points,
            },
            &format!("comp {name}: points {}-{}", first + 1, first + part.len()),
        )?;
    }
    exec_done(c, Request::CompCommit, &format!("comp {name}"))?;
    let back = read(c, axis)?;
    if back != sent {
        bail!(
            "comp {name}: the table read back differs from the one sent ({} points sent, {} read)",
            sent.points.len(),
            back.points.len()
        );
    }
    Ok(())
}

/// A table measured at the tool holds the guides' friction deflection in its reversal
/// (docs/precision.md §6); the feed-forward's deflection terms take it up too. Both on
/// one axis compensate a reversal twice: on the flexible gantry's Y two steps at once
/// that ring its 35 Hz mode, which the cross-coupling carries into X (a false
/// `encoder_stuck` on X in arcs.nc, docs/precision.md §7). `None` when `axis` has no
/// deflection term.
pub fn deflection_warning<T: Transport>(c: &mut Client<T>, axis: usize) -> Result<Option<String>> {
    let name = axis_name(axis);
    let mut terms = Vec::new();
    for side in ["pos", "neg"] {
        let key = format!("axis.{name}.feedforward.deflection_{side}_mm");
        let v: f64 = super::get(c, &key)?.parse().unwrap_or(0.0);
        if v != 0.0 {
            terms.push(format!("{key} = {v}"));
        }
    }
    Ok((!terms.is_empty()).then(|| {
        format!(
            "axis {name}'s feed-forward has a friction deflection term ({}): a table measured \
             at the tool already holds that deflection in its reversal, so the reversal is \
             compensated twice; measure the table with the feed-forward on, or set those terms \
             to 0 (docs/precision.md §6)",
            terms.join(", ")
        )
    }))
}

/// `axis`' compensation in use on the machine.
pub fn read<T: Transport>(c: &mut Client<T>, axis: usize) -> Result<MachineComp> {
    let name = axis_name(axis);
    let mut out: Option<MachineComp> = None;
    loop {
        let first = out.as_ref().map_or(0, |m| m.points.len());
        let chunk = match c.exec(Request::CompRead {
            axis: axis as u8,
            first: first as u16,
        })? {
            Outcome::Comp(chunk) => chunk,
            Outcome::Refused(why) => bail!("comp {name} read refused: {why}"),
            other => bail!("comp {name} read: unexpected answer {other:?}"),
        };
        let CompChunk {
            total,
            first: at,
            backlash_mm,
            rate_mm_s,
            accel_mm_s2,
            points,
            ..
        } = chunk;
        if usize::from(at) != first {
            bail!("comp {name} read: the part at point {at} is not the one asked for");
        }
        let m = out.get_or_insert(MachineComp {
            backlash_mm,
            rate_mm_s,
            accel_mm_s2,
            points: Vec::new(),
        });
        m.points.extend(points.iter().copied());
        if m.points.len() >= usize::from(total) || points.is_empty() {
            break;
        }
    }
    out.ok_or_else(|| anyhow::anyhow!("comp {name} read: no answer"))
}

/// Remove `axis`' compensation (outputs off).
pub fn clear<T: Transport>(c: &mut Client<T>, axis: usize) -> Result<()> {
    let none = AxisCompensation::new(&[], 0.0).map_err(|e| anyhow::anyhow!("{e}"))?;
    load(c, axis, &none)
}

/// `gantry comp show` as text: the limits, then one line per point.
pub fn text(axis: usize, m: &MachineComp) -> String {
    let mut s = format!(
        "axis {}: {} points, backlash {:.4} mm, offset rate {} mm/s, acceleration {} mm/s²\n",
        axis_name(axis),
        m.points.len(),
        m.backlash_mm,
        m.rate_mm_s,
        m.accel_mm_s2
    );
    if !m.points.is_empty() {
        s.push_str("# nominal_mm forward_trim_mm reverse_trim_mm (COMP_FILE_TYPE 1)\n");
    }
    for p in &m.points {
        s.push_str(&format!(
            "{} {:.4} {:.4}\n",
            p.nominal_mm, p.fwd_trim_mm, p.rev_trim_mm
        ));
    }
    s
}

/// `gantry comp show --json`.
pub fn json(axis: usize, m: &MachineComp) -> serde_json::Value {
    serde_json::json!({
        "axis": axis_name(axis),
        "backlash_mm": decimal(m.backlash_mm),
        "rate_mm_s": decimal(m.rate_mm_s),
        "accel_mm_s2": decimal(m.accel_mm_s2),
        "points": m
            .points
            .iter()
            .map(|p| [decimal(p.nominal_mm), decimal(p.fwd_trim_mm), decimal(p.rev_trim_mm)])
            .collect::<Vec<_>>(),
    })
}

/// `v` as the shortest decimal that reads back as the same `f32` (0.02, not the
/// 0.019999999552965164 of its exact value as an `f64`).
fn decimal(v: f32) -> f64 {
    v.to_string().parse().unwrap_or(f64::from(v))
}
