//! The servo's identification mode: one axis runs [`crate::sysid::Identifier`] (its own
//! velocity loop and moves), the others hold their position with their laws when the
//! machine was armed, or stay unpowered when identification started from Disabled (a
//! machine whose laws have no model yet).
//!
//! The window is the axis' travel when homed, or the window the user confirmed; it is
//! never larger than the travel. The torque cap is the configured one, never above the
//! amplifier's full scale.

use super::commands::CommandRefusal;
use super::travel::AxisTravel;
use crate::axes::Axis;
use crate::sysid::{
    AxisSample, Identifier, IdentifyConfig, IdentifyOutput, IdentifyResult, IdentifyStatus,
};

/// Identification as the servo keeps it: the configuration a run starts from, the run
/// under way and how the last one ended.
pub(super) struct Identification {
    pub(super) cfg: IdentifyConfig,
    pub(super) run: Option<IdentifyRun>,
    pub(super) outcome: Option<IdentifyOutcome>,
}

/// An identification in progress.
pub struct IdentifyRun {
    pub axis: usize,
    /// The other axes hold with their laws (started from Idle).
    pub hold_others: bool,
    identifier: Identifier,
    last: IdentifyOutput,
}

/// How an identification ended (kept until the next one starts).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifyOutcome {
    pub axis: Axis,
    pub status: IdentifyStatus,
    pub result: Option<IdentifyResult>,
}

impl IdentifyRun {
    /// Prepare identification of `axis` from rest at `pos_mm`; `window_mm` is the user's
    /// window (`None`: the travel, which must then be limited... or, on an unlimited
    /// simulated axis, the template's window around the start).
    #[allow(clippy::too_many_arguments)]
    pub fn start(
        template: &IdentifyConfig,
        axis: Axis,
        pos_mm: f32,
        travel: &AxisTravel,
        window_mm: Option<[f32; 2]>,
        full_scale: f32,
        period_s: f32,
        hold_others: bool,
    ) -> Result<Self, CommandRefusal> {
        let bad = CommandRefusal::BadWindow { axis };
        let (lo, hi) = match window_mm {
            Some([lo, hi]) => {
                if !(lo < hi && travel.contains(lo) && travel.contains(hi)) {
                    return Err(bad);
                }
                (lo, hi)
            }
            None if travel.is_limited() => (travel.min_mm, travel.max_mm),
            None => (
                pos_mm + template.window_min_mm,
                pos_mm + template.window_max_mm,
            ),
        };
        if !(lo..=hi).contains(&pos_mm) {
            return Err(bad);
        }
        let cfg = IdentifyConfig {
            period_s,
            window_min_mm: lo,
            window_max_mm: hi,
            torque_cap_mnm: template.torque_cap_mnm.min(full_scale),
            ..*template
        };
        let identifier =
            Identifier::new(&cfg, pos_mm).map_err(|_| CommandRefusal::IdentifyRejected { axis })?;
        Ok(Self {
            axis: axis.index(),
            hold_others,
            identifier,
            last: IdentifyOutput {
                effort_mnm: 0.0,
                phase: crate::sysid::IdentifyPhase::FrictionPasses,
                progress: 0.0,
                status: IdentifyStatus::Running,
            },
        })
    }

    /// One period: the measurement in, this period's effort out.
    pub fn step(&mut self, sample: &AxisSample) -> IdentifyOutput {
        self.last = self.identifier.step(sample);
        self.last
    }

    pub fn last(&self) -> &IdentifyOutput {
        &self.last
    }

    /// Finished (done or aborted, at rest).
    pub fn finished(&self) -> bool {
        matches!(
            self.last.status,
            IdentifyStatus::Done | IdentifyStatus::Aborted(_)
        )
    }

    pub fn outcome(&self) -> IdentifyOutcome {
        IdentifyOutcome {
            axis: Axis::ALL[self.axis.min(2)],
            status: self.last.status,
            result: self.identifier.result().copied(),
        }
    }
}
