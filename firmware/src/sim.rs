//! The in-firmware simulated gantry of the QEMU build.
//!
//! [`SimGantry`] implements [`GantryIo`] with controller-core's paper plant
//! (`θ'' = -a θ' - b θ + k u + d`, RK4 with the output held over the period) in place of
//! the encoder reads and PWM writes. Safety inputs still come from the real input pins.
//! The plant position is quantised to whole encoder counts and handed to the control loop
//! as *raw timer registers* of the board's widths (32, 32, 16 bits), so the QEMU run also
//! exercises the wrap extension: in the paper scenario Z travels 75 units, i.e. 750 000
//! counts of 1e-4, and its 16-bit counter wraps eleven times.
//!
//! The plant is integrated in `f64` (soft float on the Cortex-M4; it is the simulated
//! machine, not the controller), exactly like host-sim's discrete mode. The simulation
//! also records the *true* tracking and contour figures with host-sim's definitions
//! ([`TruthSpec`]), which the QEMU verdict compares with host-sim's bounds; the control
//! loop itself only ever sees counts.

use controller_core::metrics::{distance_to_path, Itse, MaxRms, TotalVariation};
use controller_core::plant::{rk4_step, AxisState, DisturbedPaperAxis};
use controller_core::trajectory::Trajectory;
use controller_core::Vec3;

use crate::io::{GantryIo, SafetyInputSource};
use crate::safety::{Request, SafetyInputs};
use crate::telemetry::Figures;
use crate::AXES;

/// How the true figures are taken (host-sim's `MetricSpec`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TruthSpec {
    /// The reference the figures are taken against.
    pub reference: Trajectory<f64>,
    /// Contour error (true distance to the path) is sampled from this time on...
    pub contour_from_s: f64,
    /// ...every this many control periods.
    pub contour_every_periods: u32,
    /// Half-width of the path-parameter window searched for the nearest point, s.
    pub contour_window_s: f32,
}

/// Plant, disturbance and sensor description of a simulated run.
#[derive(Clone, Copy, Debug)]
pub struct SimConfig {
    /// Per-axis plant (controller-core's disturbed paper axis).
    pub axes: [DisturbedPaperAxis<f64>; AXES],
    /// Initial plant state.
    pub initial: [AxisState<f64>; AXES],
    /// Length of one encoder count.
    pub length_per_count: f64,
    /// Control period, seconds.
    pub period_s: f64,
    /// RK4 steps of the plant per control period.
    pub plant_substeps: u32,
    /// Figures of the true plant state.
    pub truth: TruthSpec,
    /// Periods recorded into the true figures (the run's horizon / period).
    pub record_periods: u32,
}

/// Counter register widths of the board's encoder timers (TIM2, TIM5, TIM3).
const COUNTER_MASK: [u32; AXES] = [u32::MAX, u32::MAX, 0xFFFF];

/// True-state figures, accumulated with controller-core's metrics.
#[derive(Clone, Copy, Debug, Default)]
struct Truth {
    itse: [Itse<f64>; AXES],
    tracking: [MaxRms<f64>; AXES],
    contour: MaxRms<f32>,
    variation: [TotalVariation<f64>; AXES],
}

/// The simulated machine.
pub struct SimGantry<P> {
    cfg: SimConfig,
    reference_f32: Trajectory<f32>,
    inputs: P,
    state: [AxisState<f64>; AXES],
    effort: [f64; AXES],
    periods: u32,
    arm_pending: bool,
    truth: Truth,
}

impl<P: SafetyInputSource> SimGantry<P> {
    /// A machine at `cfg.initial` whose operator asks to arm once, in the first period.
    pub fn new(cfg: SimConfig, inputs: P) -> Self {
        Self {
            state: cfg.initial,
            reference_f32: cfg.truth.reference.cast(),
            cfg,
            inputs,
            effort: [0.0; AXES],
            periods: 0,
            arm_pending: true,
            truth: Truth::default(),
        }
    }

    /// True plant state.
    pub fn plant_state(&self) -> &[AxisState<f64>; AXES] {
        &self.state
    }

    /// Whole counts of the current plant positions (nearest count, as host-sim
    /// quantises).
    pub fn counts(&self) -> [i64; AXES] {
        let mut c = [0; AXES];
        for (n, s) in c.iter_mut().zip(self.state.iter()) {
            *n = libm::round(s.pos / self.cfg.length_per_count) as i64;
        }
        c
    }

    /// Figures of the true plant state so far.
    pub fn truth_figures(&self) -> Figures {
        let t = &self.truth;
        let mut f = Figures {
            samples: t.tracking[0].count(),
            contour_max: t.contour.max,
            contour_rms: t.contour.rms(),
            ..Figures::default()
        };
        for i in 0..AXES {
            f.itse[i] = t.itse[i].value as f32;
            f.tracking_max[i] = t.tracking[i].max as f32;
            f.tracking_rms[i] = t.tracking[i].rms() as f32;
            f.effort_variation[i] = t.variation[i].value as f32;
        }
        f
    }

    /// Records the true figures at the start of the period (state and held output of this
    /// period), like host-sim's recorder.
    fn record(&mut self, t_s: f64) {
        let spec = self.cfg.truth;
        let r = spec.reference.sample(t_s);
        for i in 0..AXES {
            let e = r.pos[i] - self.state[i].pos;
            self.truth.itse[i].add(t_s, e, self.cfg.period_s);
            self.truth.tracking[i].add(e);
            self.truth.variation[i].add(self.effort[i]);
        }
        if t_s + 0.5 * self.cfg.period_s >= spec.contour_from_s
            && self.periods % spec.contour_every_periods.max(1) == 0
        {
            let p = Vec3::new(self.state[0].pos, self.state[1].pos, self.state[2].pos);
            let d = distance_to_path(
                &self.reference_f32,
                p.cast(),
                t_s as f32,
                spec.contour_window_s,
            );
            self.truth.contour.add(d);
        }
    }
}

impl<P: SafetyInputSource> GantryIo for SimGantry<P> {
    fn read_safety_inputs(&mut self) -> SafetyInputs {
        self.inputs.read_safety_inputs()
    }

    fn read_request(&mut self) -> Request {
        if core::mem::take(&mut self.arm_pending) {
            Request::ArmOrReset
        } else {
            Request::None
        }
    }

    fn read_encoder_raw(&mut self) -> [u32; AXES] {
        let counts = self.counts();
        let mut raw = [0; AXES];
        for i in 0..AXES {
            // Two's-complement truncation to the register width, as the timer counts.
            raw[i] = (counts[i] as u32) & COUNTER_MASK[i];
        }
        raw
    }

    fn drive(&mut self, effort: &[f32; AXES]) {
        for (e, u) in self.effort.iter_mut().zip(effort) {
            *e = f64::from(*u);
        }
    }

    fn disable_outputs(&mut self) {
        self.effort = [0.0; AXES];
    }

    fn period_end(&mut self) {
        let t_s = f64::from(self.periods) * self.cfg.period_s;
        if self.periods < self.cfg.record_periods {
            self.record(t_s);
        }
        let u = self.effort;
        let substeps = self.cfg.plant_substeps.max(1);
        let h = self.cfg.period_s / f64::from(substeps);
        for j in 0..substeps {
            rk4_step(
                &self.cfg.axes,
                &mut self.state,
                t_s + f64::from(j) * h,
                h,
                |_, _| u,
            );
        }
        self.periods = self.periods.wrapping_add(1);
    }
}
