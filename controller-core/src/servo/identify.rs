//! The servo's identification mode: one axis runs an identification procedure (its own
//! velocity loop and moves), the others hold their position with their laws when the
//! machine was armed, or stay unpowered when identification started from Disabled (a
//! machine whose laws have no model yet). Three procedures share the mode and its rules:
//! the model identification ([`crate::sysid::Identifier`], `Command::Identify`), the
//! frequency-response measurement ([`crate::sysid::frequency::ResponseMeasurement`],
//! `Command::MeasureResponse`) and the loop measurement
//! ([`crate::sysid::frequency::LoopMeasurement`], `Command::MeasureLoop`: the axis stays
//! on its laws, following the procedure's reference, the sine added to their effort;
//! from Idle only).
//!
//! The window is the axis' travel when homed, or the window the user confirmed; it is
//! never larger than the travel. The torque cap is the configured one, never above the
//! amplifier's full scale. The frequency response runs with the identification's
//! window, cap, velocity limit and inertia guess and the measurement's defaults
//! ([`ResponseConfig::from_identify`]); its points are read while it runs
//! ([`IdentifyRun::response_point`]: the servo keeps no array of them), how it ended
//! afterwards ([`ResponseOutcome`]).

use super::commands::CommandRefusal;
use super::travel::AxisTravel;
use crate::axes::Axis;
use crate::sysid::frequency::{
    LoopMeasurement, LoopReference, ResponseConfig, ResponseMeasurement, ResponseOutput,
    ResponsePoint,
};
use crate::sysid::{
    AxisSample, Identifier, IdentifyConfig, IdentifyOutput, IdentifyPhase, IdentifyResult,
    IdentifyStatus,
};

/// Identification as the servo keeps it: the configuration a run starts from, the run
/// under way and how the last one ended (either kind: one slot, the servo's size is
/// budgeted; a frequency response keeps its outcome there without a result).
pub(super) struct Identification {
    pub(super) cfg: IdentifyConfig,
    pub(super) run: Option<IdentifyRun>,
    pub(super) outcome: Option<IdentifyOutcome>,
    /// The kind of run `outcome` is from, and a frequency response's points measured.
    pub(super) outcome_kind: IdentifyKind,
    pub(super) response_points: u8,
    /// Identifications started (wrapping): tells a caller collecting a frequency
    /// response's points that a new run has begun.
    pub(super) runs: u8,
}

impl Identification {
    /// Keep how `run` ended.
    pub(super) fn keep_outcome(&mut self, run: &IdentifyRun) {
        self.outcome = Some(IdentifyOutcome {
            axis: run.axis_name(),
            status: run.last.status,
            result: match &run.procedure {
                Procedure::Model(id) => id.result().copied(),
                Procedure::Response(_) | Procedure::Loop(_) => None,
            },
        });
        self.outcome_kind = run.kind();
        self.response_points = match &run.procedure {
            Procedure::Response(m) => m.measured(),
            Procedure::Loop(m) => m.measured(),
            Procedure::Model(_) => 0,
        };
    }

    /// How the last model identification ended (`None` after a frequency response).
    pub(super) fn model_outcome(&self) -> Option<&IdentifyOutcome> {
        self.outcome
            .as_ref()
            .filter(|_| self.outcome_kind == IdentifyKind::Model)
    }

    /// How the last frequency response or loop measurement ended (`None` after a model
    /// identification).
    pub(super) fn response_outcome(&self) -> Option<ResponseOutcome> {
        let o = self.outcome.as_ref()?;
        (self.outcome_kind != IdentifyKind::Model).then_some(ResponseOutcome {
            axis: o.axis,
            status: o.status,
            points: self.response_points,
        })
    }
}

/// Which procedure an identification runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IdentifyKind {
    /// The rigid-body model (friction, inertia): `Command::Identify`.
    Model,
    /// The frequency response from effort to encoder: `Command::MeasureResponse`.
    Response,
    /// The open loop on the laws: `Command::MeasureLoop`.
    Loop,
}

/// The procedure of a run (in place: nothing allocates; the run is the model
/// identification's size either way).
#[derive(Clone, Debug, PartialEq)]
#[allow(clippy::large_enum_variant)]
enum Procedure {
    Model(Identifier),
    Response(ResponseMeasurement),
    Loop(LoopMeasurement),
}

/// An identification in progress.
pub struct IdentifyRun {
    pub axis: usize,
    /// The other axes hold with their laws (started from Idle).
    pub hold_others: bool,
    procedure: Procedure,
    last: IdentifyOutput,
}

/// How an identification ended (kept until the next one starts).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IdentifyOutcome {
    pub axis: Axis,
    pub status: IdentifyStatus,
    pub result: Option<IdentifyResult>,
}

/// How a frequency-response measurement ended (kept until the next one starts).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResponseOutcome {
    pub axis: Axis,
    pub status: IdentifyStatus,
    /// Frequencies measured.
    pub points: u8,
}

impl IdentifyRun {
    /// Prepare identification of `axis` from rest at `pos_mm`; `window_mm` is the user's
    /// window (`None`: the travel, which must then be limited... or, on an unlimited
    /// simulated axis, the template's window around the start). `count_mm` is the axis'
    /// count length (the frequency response's travel speed is chosen from it).
    #[allow(clippy::too_many_arguments)]
    pub fn start(
        template: &IdentifyConfig,
        kind: IdentifyKind,
        axis: Axis,
        pos_mm: f32,
        travel: &AxisTravel,
        window_mm: Option<[f32; 2]>,
        full_scale: f32,
        period_s: f32,
        count_mm: f32,
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
        let rejected = CommandRefusal::IdentifyRejected { axis };
        let (procedure, phase) = match kind {
            IdentifyKind::Loop if hold_others => (
                Procedure::Loop(
                    LoopMeasurement::new(&ResponseConfig::loop_from_identify(&cfg), pos_mm)
                        .map_err(|_| rejected)?,
                ),
                IdentifyPhase::FrequencyResponse,
            ),
            // (the laws hold the axis: never from Disabled)
            IdentifyKind::Loop => return Err(CommandRefusal::WrongState),
            IdentifyKind::Model => (
                Procedure::Model(Identifier::new(&cfg, pos_mm).map_err(|_| rejected)?),
                IdentifyPhase::FrictionPasses,
            ),
            IdentifyKind::Response => (
                Procedure::Response(
                    ResponseMeasurement::new(
                        &ResponseConfig::from_identify(&cfg),
                        pos_mm,
                        count_mm,
                    )
                    .map_err(|_| rejected)?,
                ),
                IdentifyPhase::FrequencyResponse,
            ),
        };
        Ok(Self {
            axis: axis.index(),
            hold_others,
            procedure,
            last: IdentifyOutput {
                effort_mnm: 0.0,
                phase,
                progress: 0.0,
                status: IdentifyStatus::Running,
            },
        })
    }

    /// One period: the measurement and the laws' effort on the axis (`law_mnm`, the
    /// loop measurement's) in, this period's effort out.
    pub fn step(&mut self, sample: &AxisSample, law_mnm: f32) -> IdentifyOutput {
        self.last = match &mut self.procedure {
            Procedure::Model(id) => id.step(sample),
            Procedure::Response(m) => stepped_sine_output(m.step(sample)),
            Procedure::Loop(m) => stepped_sine_output(m.step(sample, law_mnm)),
        };
        self.last
    }

    pub fn last(&self) -> &IdentifyOutput {
        &self.last
    }

    pub fn kind(&self) -> IdentifyKind {
        match self.procedure {
            Procedure::Model(_) => IdentifyKind::Model,
            Procedure::Response(_) => IdentifyKind::Response,
            Procedure::Loop(_) => IdentifyKind::Loop,
        }
    }

    /// The loop measurement's reference for the axis (`None`: the other procedures
    /// drive the axis themselves, without a reference).
    pub fn reference(&self) -> Option<LoopReference> {
        match &self.procedure {
            Procedure::Loop(m) => Some(m.reference()),
            Procedure::Model(_) | Procedure::Response(_) => None,
        }
    }

    /// Finished (done or aborted, at rest).
    pub fn finished(&self) -> bool {
        matches!(
            self.last.status,
            IdentifyStatus::Done | IdentifyStatus::Aborted(_)
        )
    }

    /// The frequency response's (or the loop's) latest point and its index in the grid.
    pub fn response_point(&self) -> Option<(u8, ResponsePoint)> {
        match &self.procedure {
            Procedure::Response(m) => m.last_point(),
            Procedure::Loop(m) => m.last_point(),
            Procedure::Model(_) => None,
        }
    }

    fn axis_name(&self) -> Axis {
        Axis::ALL[self.axis.min(2)]
    }
}

/// A stepped sine's period (frequency response or loop) as an identification's.
fn stepped_sine_output(o: ResponseOutput) -> IdentifyOutput {
    IdentifyOutput {
        effort_mnm: o.effort_mnm,
        phase: match o.status {
            IdentifyStatus::Running => IdentifyPhase::FrequencyResponse,
            IdentifyStatus::Stopping(_) => IdentifyPhase::Stopping,
            IdentifyStatus::Done => IdentifyPhase::Done,
            IdentifyStatus::Aborted(_) => IdentifyPhase::Aborted,
        },
        progress: o.progress,
        status: o.status,
    }
}
