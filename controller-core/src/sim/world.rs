//! The simulated world: three axis plants behind the board's encoders (counts, counter
//! width) and amplifiers (range, resolution), with the safety inputs under the
//! simulation's control. It implements [`ServoIo`], so the servo step runs against it
//! exactly as it runs against the board; [`World::advance`] then integrates the plants
//! over one period with the output held (zero-order hold).
//!
//! The plants are integrated in `f64` with RK4 (soft float on the Cortex-M4 of the QEMU
//! rig: it is the simulated machine, not the controller).

use crate::axes::AXES;
use crate::config::{finite, ConfigError};
use crate::estimator::CounterWidth;
use crate::plant::frame::{Frame, MAX_MODE_OMEGA_STEP};
use crate::plant::paper::{DisturbedPaperAxis, PaperAxis};
use crate::plant::physical::{PhysicalAxis, PhysicalAxisConfig};
use crate::plant::state::{rk4_step, AxisDynamics, AxisState};
use crate::servo::brake::{BrakeConfig, DEFAULT_ENGAGE_S, DEFAULT_RELEASE_S};
use crate::servo::io::{Inputs, ServoIo};
use crate::servo::ServoConfig;
use crate::sim::frame_step::{self, FramedPush, FramedState, DRAG_V_REG};
use crate::sim::rng::SplitMix64;
use crate::Real;

/// Most plant RK4 steps per control period.
pub const MAX_PLANT_SUBSTEPS: u32 = 64;

/// One simulated axis plant.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(rename_all = "snake_case"))]
pub enum PlantConfig {
    /// The paper's normalised axis `θ'' = -a θ' - b θ + k u + d`, with an optional step
    /// `d = disturbance_accel` from `disturbance_t_s` on.
    Paper(PaperPlantConfig),
    /// The ball-screw axis with friction, load and torque limit (mm, s, mN·m).
    Physical(PhysicalAxisConfig),
}

/// The paper's axis `θ'' = -a θ' - b θ + k u + d` with its step disturbance.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct PaperPlantConfig {
    pub a: f32,
    pub b: f32,
    pub k: f32,
    /// Step added to θ'' (units/s²).
    #[cfg_attr(feature = "serde", serde(default))]
    pub disturbance_accel: f64,
    /// When the step starts, s (`inf`: never).
    #[cfg_attr(feature = "serde", serde(default = "never"))]
    pub disturbance_t_s: f64,
}

#[cfg(feature = "serde")]
fn never() -> f64 {
    f64::INFINITY
}

/// Initial state of one axis.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct InitialState {
    #[cfg_attr(feature = "serde", serde(default))]
    pub pos_mm: f64,
    #[cfg_attr(feature = "serde", serde(default))]
    pub vel_mm_s: f64,
}

/// One axis' limit switches and encoder index as the simulated machine has them.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields, default))]
pub struct SwitchConfig {
    /// The min switch is closed at or below this true position, mm (`-inf`: none).
    pub min_mm: f64,
    /// The max switch is closed at or above this true position, mm (`inf`: none).
    pub max_mm: f64,
    /// The encoder gives an index pulse every this many counts (one motor revolution;
    /// 0: no index), at the counts that are multiples of it.
    pub index_period_counts: u32,
}

impl Default for SwitchConfig {
    fn default() -> Self {
        Self::NONE
    }
}

impl SwitchConfig {
    pub const NONE: Self = Self {
        min_mm: f64::NEG_INFINITY,
        max_mm: f64::INFINITY,
        index_period_counts: 0,
    };

    /// The limit switches where `settings`' homing expects them, per axis: on the side
    /// the axis homes towards, at its `switch_pos_mm`; none where homing is off. The
    /// simulated machine of `gantry --sim` and of the firmware's QEMU link rig.
    pub fn for_homing(settings: &crate::settings::Settings) -> [Self; AXES] {
        settings.axis.map(|a| {
            let h = a.homing;
            if !h.enabled {
                Self::NONE
            } else if h.direction.switch() == 0 {
                Self {
                    min_mm: f64::from(h.switch_pos_mm),
                    ..Self::NONE
                }
            } else {
                Self {
                    max_mm: f64::from(h.switch_pos_mm),
                    ..Self::NONE
                }
            }
        })
    }
}

/// Imperfections of the simulated sensors and actuators beyond quantisation.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields, default))]
pub struct ImperfectionConfig {
    /// Jitter of the encoder's edges: each reading quantises the true position shifted
    /// by a uniform draw within ±n/2 counts, so a reading is off by up to n/2 rounded
    /// counts and consecutive readings of a resting axis dither between neighbours, as a
    /// quadrature encoder sitting near an edge does (0: exact).
    pub noise_counts: u8,
    /// Seed of the noise (SplitMix64).
    pub seed: u64,
    /// The amplifiers apply a command this many periods after it was written (0 or 1: the
    /// PWM update at the next period boundary).
    pub command_delay_periods: u8,
}

/// One axis' holding brake as the simulated machine has it: a static friction torque
/// while it grips, with the delays of a real brake between its command and its effect.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields, default))]
pub struct BrakePlantConfig {
    /// Holding torque while the brake grips, mN·m on a physical axis (units/s² on the
    /// paper's); 0: no brake. It acts as static friction: the axis does not move while the
    /// sum of the other torques on it stays within it, and decelerates with it otherwise.
    pub holding_mnm: f32,
    /// The brake grips this long after its coil is de-energised, s.
    pub engage_s: f32,
    /// The brake opens this long after its coil is energised, s.
    pub release_s: f32,
}

impl BrakePlantConfig {
    /// No brake.
    pub const NONE: Self = Self {
        holding_mnm: 0.0,
        engage_s: DEFAULT_ENGAGE_S,
        release_s: DEFAULT_RELEASE_S,
    };
}

impl Default for BrakePlantConfig {
    fn default() -> Self {
        Self::NONE
    }
}

/// The simulated machine.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(deny_unknown_fields))]
pub struct WorldConfig {
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub plants: [PlantConfig; AXES],
    /// RK4 steps of the plants per control period.
    pub plant_substeps: u32,
    #[cfg_attr(feature = "serde", serde(with = "crate::axes::per_axis"))]
    pub initial: [InitialState; AXES],
    /// Limit switches and index pulses (default: none).
    #[cfg_attr(feature = "serde", serde(default, with = "crate::axes::per_axis"))]
    pub switches: [SwitchConfig; AXES],
    #[cfg_attr(feature = "serde", serde(default))]
    pub imperfections: ImperfectionConfig,
    /// Holding brakes (default: none).
    #[cfg_attr(feature = "serde", serde(default, with = "crate::axes::per_axis"))]
    pub brakes: [BrakePlantConfig; AXES],
}

/// A validated plant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Plant {
    Paper(DisturbedPaperAxis<f64>),
    Physical(PhysicalAxis<f64>),
}

impl Plant {
    pub fn new(cfg: &PlantConfig) -> Result<Self, ConfigError> {
        Ok(match cfg {
            PlantConfig::Paper(p) => {
                let f = |v: f32, n| finite(v, n).map(f64::from);
                if p.disturbance_t_s.is_nan() || !p.disturbance_accel.is_finite() {
                    return Err(ConfigError::NotFinite("plant.paper.disturbance"));
                }
                Self::Paper(DisturbedPaperAxis {
                    axis: PaperAxis {
                        a: f(p.a, "plant.paper.a")?,
                        b: f(p.b, "plant.paper.b")?,
                        k: f(p.k, "plant.paper.k")?,
                    },
                    d_step: p.disturbance_accel,
                    t_dist: p.disturbance_t_s,
                })
            }
            PlantConfig::Physical(c) => Self::Physical(PhysicalAxis::new(c)?),
        })
    }
}

impl AxisDynamics<f64> for Plant {
    fn accel(&self, s: AxisState<f64>, u: f64, t: f64) -> f64 {
        match self {
            Self::Paper(p) => p.accel(s, u, t),
            Self::Physical(p) => p.accel(s, u, t),
        }
    }
}

/// The simulated machine's state.
#[derive(Clone, Copy, Debug)]
pub struct World {
    plants: [Plant; AXES],
    /// The motor side: what the encoders, switches and brakes see (the whole axis when it
    /// has no frame).
    state: [AxisState<f64>; AXES],
    /// A framed axis' frame ([`crate::plant::frame`]); `None`: rigid.
    frames: [Option<Frame>; AXES],
    /// The tool side: where the tool is (the motor side's state on a rigid axis).
    tool: [AxisState<f64>; AXES],
    /// A framed axis' deflection under its constant load at rest, mm: what a tool
    /// set-up takes out ([`World::tool_pos`]).
    tool_set_mm: [f64; AXES],
    substeps: u32,
    period_s: f64,
    count_len: [f64; AXES],
    counter_mask: [u32; AXES],
    full_scale: [f64; AXES],
    /// Amplifier command step (0: ideal).
    effort_step: [f64; AXES],
    /// Effort commanded for the current period (after the amplifier's range).
    effort: [f64; AXES],
    outputs_on: bool,
    periods: u64,
    /// Safety inputs as the servo will read them (the simulation may set them).
    pub inputs: Inputs,
    /// Injected sensor and plant faults.
    faults: WorldFaults,
    switches: [SwitchConfig; AXES],
    imperfect: ImperfectionConfig,
    rng: SplitMix64,
    /// Edge jitter of the current reading, counts.
    noise: [f64; AXES],
    /// Command written last period, applied this period (one period of delay).
    pending: [f64; AXES],
    /// A torque added at each axis' motor, laws' units ([`World::set_effort_offset`]).
    effort_offset: [f64; AXES],
    /// Counts at the previous reading (index crossings).
    last_counts: [i64; AXES],
    /// The index pulse of the last period: the count the encoder reported as it passed
    /// (before the counter's width, [`World::index_counts`]).
    index: [Option<i64>; AXES],
    brakes: WorldBrakes,
}

/// The simulated brakes' state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct WorldBrakes {
    /// Holding torque as an acceleration, units/s² (0: no brake).
    hold_accel: [f64; AXES],
    engage_s: [f64; AXES],
    release_s: [f64; AXES],
    /// The coil is energised (the servo's last command).
    released: [bool; AXES],
    /// When that command was given, s (`-inf`: at boot, engaged long since).
    since_s: [f64; AXES],
    /// The axis is held at rest by the gripping brake (stuck, in the static-friction
    /// sense).
    stuck: [bool; AXES],
}

/// Slack of the brake's timing comparisons, s: far below a period, above the rounding of
/// `periods × period_s`.
const BRAKE_TIME_SLACK_S: f64 = 1e-9;

/// An axis whose brake grips: the brake's friction `-hold · sign` added to the plant's
/// acceleration, or, while stuck, no motion at all.
struct Braked<'a> {
    pushed: Pushed<'a>,
    /// Acceleration of the brake's friction over this substep (signed), units/s².
    friction: f64,
    stuck: bool,
}

impl AxisDynamics<f64> for Braked<'_> {
    fn accel(&self, s: AxisState<f64>, u: f64, t: f64) -> f64 {
        if self.stuck {
            0.0
        } else {
            self.pushed.accel(s, u, t) + self.friction
        }
    }
}

/// Faults injected into the simulated machine (fault matrix, tests).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct WorldFaults {
    /// The counter reads this count from now on.
    frozen: [Option<i64>; AXES],
    /// Added to the count.
    offset: [i64; AXES],
    /// The counter counts backwards from this count on.
    reversed: [Option<i64>; AXES],
    /// External acceleration on the plant (a collision, a falling load), units/s².
    ext_accel: [f64; AXES],
    /// ... until this time, s.
    ext_until_s: [f64; AXES],
    /// Extra Coulomb friction, as an acceleration magnitude, units/s².
    drag: [f64; AXES],
    /// The motor turns backwards for a positive command (its wiring reversed).
    motor_reversed: [bool; AXES],
}

/// A fault the simulated machine can be given.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(
    feature = "serde",
    serde(rename_all = "snake_case", deny_unknown_fields)
)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Injection {
    /// The e-stop input becomes active.
    Estop,
    /// A limit switch becomes active.
    Limit { axis: crate::axes::Axis, high: bool },
    /// An amplifier reports a fault.
    AmplifierFault { axis: crate::axes::Axis },
    /// The encoder stops counting (the counter keeps its value).
    EncoderStuck { axis: crate::axes::Axis },
    /// The count jumps by `counts` (noise, a lost connection that comes back).
    EncoderJump {
        axis: crate::axes::Axis,
        counts: i32,
    },
    /// The encoder counts backwards from here on (swapped A/B).
    EncoderReversed { axis: crate::axes::Axis },
    /// The motor turns backwards for a positive command from here on (its phases or the
    /// amplifier's direction input wired the other way: what `axis.<a>.motor.invert`
    /// undoes at bring-up).
    MotorReversed { axis: crate::axes::Axis },
    /// An external acceleration acts on the axis (units/s²) for `for_s` seconds (`inf`:
    /// from here on): an obstruction, an impact, a falling load.
    ExternalAccel {
        axis: crate::axes::Axis,
        accel_mm_s2: f32,
        for_s: f32,
    },
    /// Extra Coulomb friction on the axis from here on (mN·m on a physical axis, units/s²
    /// on the paper's): something dragging, or blocking, the axis.
    ExtraFriction { axis: crate::axes::Axis, mnm: f32 },
    /// Every control period overruns its deadline from here on.
    Overrun,
    /// The controller's state on the axis is corrupted (the servo's injection hook).
    CorruptState { axis: crate::axes::Axis },
}

/// A plant with an external acceleration and an extra drag (Coulomb friction, as an
/// acceleration, regularised like the plant's own at [`DRAG_V_REG`]).
struct Pushed<'a> {
    plant: &'a Plant,
    ext: f64,
    drag: f64,
}

impl AxisDynamics<f64> for Pushed<'_> {
    fn accel(&self, s: AxisState<f64>, u: f64, t: f64) -> f64 {
        let sgn = s.vel / libm::sqrt(s.vel * s.vel + DRAG_V_REG * DRAG_V_REG);
        self.plant.accel(s, u, t) + self.ext - self.drag * sgn
    }
}

impl World {
    /// The world of `cfg` behind the sensors and actuators of `servo`.
    pub fn new(cfg: &WorldConfig, servo: &ServoConfig) -> Result<Self, ConfigError> {
        if cfg.plant_substeps == 0 || cfg.plant_substeps > MAX_PLANT_SUBSTEPS {
            return Err(ConfigError::OutOfRange("plant_substeps (1..=64)"));
        }
        if servo.rate_hz == 0 {
            return Err(ConfigError::NotPositive("rate_hz"));
        }
        let mut w = Self {
            plants: [
                Plant::new(&cfg.plants[0])?,
                Plant::new(&cfg.plants[1])?,
                Plant::new(&cfg.plants[2])?,
            ],
            state: [AxisState::default(); AXES],
            frames: [None; AXES],
            tool: [AxisState::default(); AXES],
            tool_set_mm: [0.0; AXES],
            substeps: cfg.plant_substeps,
            period_s: 1.0 / f64::from(servo.rate_hz),
            count_len: [0.0; AXES],
            counter_mask: [0; AXES],
            full_scale: [0.0; AXES],
            effort_step: [0.0; AXES],
            effort: [0.0; AXES],
            outputs_on: false,
            periods: 0,
            inputs: Inputs::default(),
            faults: WorldFaults::default(),
            switches: cfg.switches,
            imperfect: cfg.imperfections,
            rng: SplitMix64::new(cfg.imperfections.seed),
            noise: [0.0; AXES],
            pending: [0.0; AXES],
            effort_offset: [0.0; AXES],
            last_counts: [0; AXES],
            index: [None; AXES],
            brakes: WorldBrakes {
                since_s: [f64::NEG_INFINITY; AXES],
                ..WorldBrakes::default()
            },
        };
        if cfg.imperfections.command_delay_periods > 1 {
            return Err(ConfigError::OutOfRange(
                "imperfections.command_delay_periods (0 or 1)",
            ));
        }
        for sw in &cfg.switches {
            if sw.min_mm.is_nan() || sw.max_mm.is_nan() || !(sw.min_mm < sw.max_mm) {
                return Err(ConfigError::OutOfRange("switches (min_mm < max_mm)"));
            }
        }
        for i in 0..AXES {
            let init = &cfg.initial[i];
            if !(init.pos_mm.is_finite() && init.vel_mm_s.is_finite()) {
                return Err(ConfigError::NotFinite("initial"));
            }
            w.state[i] = AxisState {
                pos: init.pos_mm,
                vel: init.vel_mm_s,
            };
            w.tool[i] = w.state[i];
            if let PlantConfig::Physical(PhysicalAxisConfig {
                frame: Some(fc),
                inertia,
                load_const_mnm,
                ..
            }) = &cfg.plants[i]
            {
                let frame = Frame::new(fc, *inertia)?;
                let h = w.period_s / f64::from(w.substeps);
                if frame.omega() * h > MAX_MODE_OMEGA_STEP {
                    return Err(ConfigError::OutOfRange(
                        "frame.mode_hz (2π · mode_hz · plant step ≤ 0.5: more plant_substeps)",
                    ));
                }
                let load = f64::from(*load_const_mnm);
                w.tool[i].pos = frame.tool_at_rest(init.pos_mm, load);
                w.tool_set_mm[i] = frame.load_deflection_mm(load);
                w.frames[i] = Some(frame);
            }
            w.count_len[i] = servo.encoders[i].count_len()?;
            w.counter_mask[i] = match servo.encoders[i].counter {
                CounterWidth::Bits16 => 0xFFFF,
                CounterWidth::Bits32 => u32::MAX,
            };
            let b = &cfg.brakes[i];
            // the timings are checked by the servo's own rule (one implementation)
            BrakeConfig {
                present: true,
                engage_s: b.engage_s,
                release_s: b.release_s,
            }
            .validate(i)?;
            if !(b.holding_mnm >= 0.0 && b.holding_mnm.is_finite()) {
                return Err(ConfigError::OutOfRange("brakes.holding_mnm (finite, >= 0)"));
            }
            let scale = match &w.plants[i] {
                Plant::Physical(p) => p.inv_inertia(),
                Plant::Paper(_) => 1.0,
            };
            w.brakes.hold_accel[i] = f64::from(b.holding_mnm) * scale;
            w.brakes.engage_s[i] = f64::from(b.engage_s);
            w.brakes.release_s[i] = f64::from(b.release_s);
            let amp = &servo.amplifiers[i];
            w.full_scale[i] = f64::from(amp.checked_full_scale()?);
            if amp.resolution_bits > 0 {
                w.effort_step[i] = 2.0 * w.full_scale[i] / (1u64 << amp.resolution_bits) as f64;
            }
        }
        w.last_counts = w.counts();
        Ok(w)
    }

    fn next_random(&mut self) -> u64 {
        self.rng.next_u64()
    }

    /// The safety inputs now: the injected ones, the switches at the true positions and
    /// the index pulses passed since the last reading.
    fn sample_inputs(&mut self) -> Inputs {
        let mut inp = self.inputs;
        let counts = self.counts();
        #[allow(clippy::needless_range_loop)] // five per-axis arrays
        for i in 0..AXES {
            let sw = &self.switches[i];
            let p = self.state[i].pos;
            inp.limits[i][0] |= p <= sw.min_mm;
            inp.limits[i][1] |= p >= sw.max_mm;
            let period = i64::from(sw.index_period_counts);
            if period > 0 {
                let (a, b) = (self.last_counts[i], counts[i]);
                // the multiple of the period crossed (the last one, moving either way)
                let crossed = if b > a {
                    let m = b.div_euclid(period) * period;
                    (m > a).then_some(m)
                } else if b < a {
                    let m = (b + period - 1).div_euclid(period) * period;
                    (m < a).then_some(m)
                } else {
                    None
                };
                // the counter captures what it holds as the index passes: the true
                // count there with the jitter and whatever counts the faults lost
                self.index[i] = crossed.map(|m| self.report(i, m as f64));
            }
        }
        self.last_counts = counts;
        inp
    }

    /// True plant states: the motor side of a framed axis (what its encoder reads).
    pub fn state(&self) -> &[AxisState<f64>; AXES] {
        &self.state
    }

    /// True tool positions, mm: where the contour is judged (a framed axis' tool side,
    /// a rigid axis' position). As a tool set-up (touch-off at rest) measures them: the
    /// static deflection under the axis' constant load (gravity on Z) is taken out, as it
    /// is on a machine; what moves with the motion (the mode, backlash at reversals, the
    /// lead error along the travel) stays.
    pub fn tool_pos(&self) -> [f64; AXES] {
        [0, 1, 2].map(|i| match self.frames[i] {
            Some(_) => self.tool[i].pos + self.tool_set_mm[i],
            None => self.tool[i].pos,
        })
    }

    /// The axes with a frame (a compliant mode, backlash, lead error).
    pub fn framed(&self) -> [bool; AXES] {
        self.frames.map(|f| f.is_some())
    }

    /// The effort commanded for the current period (what the amplifiers were told, within
    /// their range; 0 while the outputs are off).
    pub fn effort(&self) -> [f64; AXES] {
        self.effort
    }

    /// Whether the servo drives the outputs this period.
    pub fn outputs_on(&self) -> bool {
        self.outputs_on
    }

    /// Per axis: the brake coil is energised (the servo's last brake command).
    pub fn brakes_released(&self) -> [bool; AXES] {
        self.brakes.released
    }

    /// Per axis: the brake grips now (engaged for its `engage_s`, or still closed while
    /// it opens); false on an axis without a brake.
    pub fn brake_gripping(&self) -> [bool; AXES] {
        let t = self.time_s();
        core::array::from_fn(|i| self.gripping_at(i, t))
    }

    fn gripping_at(&self, i: usize, t: f64) -> bool {
        let b = &self.brakes;
        if !(b.hold_accel[i] > 0.0) {
            return false;
        }
        let since = t - b.since_s[i];
        if b.released[i] {
            since < b.release_s[i] - BRAKE_TIME_SLACK_S
        } else {
            since >= b.engage_s[i] - BRAKE_TIME_SLACK_S
        }
    }

    /// Per axis the amplifier's effort at full command (100 % duty), the laws' units.
    pub fn full_scale(&self) -> [f64; AXES] {
        self.full_scale
    }

    /// Simulated time at the start of the current period, s.
    pub fn time_s(&self) -> f64 {
        self.periods as f64 * self.period_s
    }

    /// Control periods simulated so far.
    pub fn periods(&self) -> u64 {
        self.periods
    }

    /// Whole counts of the true positions (nearest count).
    pub fn counts(&self) -> [i64; AXES] {
        let mut c = [0; AXES];
        for (n, (s, len)) in c.iter_mut().zip(self.state.iter().zip(self.count_len)) {
            *n = libm::round(s.pos / len) as i64;
        }
        c
    }

    /// The counts the encoders report (the true counts with the edge jitter, unless a
    /// fault was injected).
    pub fn reported_counts(&self) -> [i64; AXES] {
        let mut c = [0; AXES];
        for (i, n) in c.iter_mut().enumerate() {
            *n = self.report(i, self.state[i].pos / self.count_len[i]);
        }
        c
    }

    /// What axis `i`'s counter holds when its true position is `counts` (fractional): the
    /// edge jitter, then the injected faults.
    fn report(&self, i: usize, counts: f64) -> i64 {
        let mut n = libm::round(counts + self.noise[i]) as i64;
        let f = &self.faults;
        if let Some(pivot) = f.reversed[i] {
            n = pivot.saturating_mul(2).saturating_sub(n);
        }
        n = n.saturating_add(f.offset[i]);
        if let Some(frozen) = f.frozen[i] {
            n = frozen;
        }
        n
    }

    /// Per axis the index pulse passed in the period up to the last reading of the inputs
    /// (`ServoIo::read_inputs`), as the encoder's count there ([`Self::reported_counts`]'s
    /// frame, not truncated to the counter's width: `read_index` gives it truncated); `None`
    /// where no index passed. The board twin puts it into its encoder timers, whose counts
    /// carry the firmware's own offset.
    pub fn index_counts(&self) -> [Option<i64>; AXES] {
        self.index
    }

    /// The counter registers as the board's timers would read them.
    pub fn counter_registers(&self) -> [u32; AXES] {
        let mut raw = self.reported_counts().map(|n| n as u32);
        for (r, mask) in raw.iter_mut().zip(self.counter_mask) {
            // two's-complement truncation to the register width, as the timer counts
            *r &= mask;
        }
        raw
    }

    /// The operator's e-stop button, pressed or released: the servo reads it from its next
    /// step on. [`Injection::Estop`] presses the same input; this is also how it is let go
    /// (host-sim's `SimMachine` and the QEMU link rig's operator panel both come here).
    pub fn set_estop(&mut self, pressed: bool) {
        self.inputs.estop = pressed;
    }

    /// A torque at each axis' motor from this period on, in the laws' units (mN·m on a
    /// physical axis), added to whatever the amplifier gives: the injected signal of a
    /// loop-response measurement (the servo's effort against the sum it meets at the
    /// plant is the open loop, host-sim's `filters` study). Non-finite values count as 0.
    pub fn set_effort_offset(&mut self, offset: [f64; AXES]) {
        self.effort_offset = offset.map(|d| if d.is_finite() { d } else { 0.0 });
    }

    /// Give the machine a fault (the servo-side ones, `CorruptState`, are the run's).
    pub fn inject(&mut self, inj: &Injection) {
        let reported = self.reported_counts();
        let counts = self.counts();
        match *inj {
            Injection::Estop => self.set_estop(true),
            Injection::Limit { axis, high } => {
                self.inputs.limits[axis.index()][usize::from(high)] = true
            }
            Injection::AmplifierFault { axis } => self.inputs.amp_fault[axis.index()] = true,
            Injection::EncoderStuck { axis } => {
                self.faults.frozen[axis.index()] = Some(reported[axis.index()])
            }
            Injection::EncoderJump { axis, counts } => {
                let o = &mut self.faults.offset[axis.index()];
                *o = o.saturating_add(i64::from(counts));
            }
            Injection::EncoderReversed { axis } => {
                self.faults.reversed[axis.index()] = Some(counts[axis.index()])
            }
            Injection::MotorReversed { axis } => self.faults.motor_reversed[axis.index()] = true,
            Injection::ExternalAccel {
                axis,
                accel_mm_s2,
                for_s,
            } => {
                self.faults.ext_accel[axis.index()] = f64::from(accel_mm_s2);
                self.faults.ext_until_s[axis.index()] = self.time_s() + f64::from(for_s);
            }
            Injection::ExtraFriction { axis, mnm } => {
                let i = axis.index();
                self.faults.drag[i] = match &self.plants[i] {
                    Plant::Physical(p) => f64::from(mnm) * p.inv_inertia(),
                    Plant::Paper(_) => f64::from(mnm),
                };
            }
            Injection::Overrun => self.inputs.overrun = true,
            Injection::CorruptState { .. } => {}
        }
    }

    /// Integrate the plants over one period with the commanded effort held, quantised to
    /// the amplifiers' resolution.
    pub fn advance(&mut self) {
        let t = self.time_s();
        let mut u = if self.imperfect.command_delay_periods == 1 {
            core::mem::replace(&mut self.pending, self.effort)
        } else {
            self.effort
        };
        for (u, step) in u.iter_mut().zip(self.effort_step) {
            if step > 0.0 {
                *u = libm::round(*u / step) * step;
            }
        }
        for (u, d) in u.iter_mut().zip(self.effort_offset) {
            if d != 0.0 {
                // (only then: a -0.0 effort stays bit for bit what it was)
                *u += d;
            }
        }
        let h = self.period_s / f64::from(self.substeps);
        for (a, until) in self
            .faults
            .ext_accel
            .iter_mut()
            .zip(self.faults.ext_until_s)
        {
            if !(t < until) {
                *a = 0.0;
            }
        }
        let gripping = [0, 1, 2].map(|i| self.gripping_at(i, t));
        let before = self.state;
        if gripping.iter().any(|g| *g) {
            self.advance_braked(t, h, u, gripping);
        } else if self.faults.ext_accel == [0.0; AXES] && self.faults.drag == [0.0; AXES] {
            self.brakes.stuck = [false; AXES];
            for j in 0..self.substeps {
                rk4_step(
                    &self.plants,
                    &mut self.state,
                    t + f64::from(j) * h,
                    h,
                    |_, _| u,
                );
            }
        } else {
            self.brakes.stuck = [false; AXES];
            let f = &self.faults;
            let axes = [0, 1, 2].map(|i| Pushed {
                plant: &self.plants[i],
                ext: f.ext_accel[i],
                drag: f.drag[i],
            });
            for j in 0..self.substeps {
                rk4_step(&axes, &mut self.state, t + f64::from(j) * h, h, |_, _| u);
            }
        }
        self.advance_frames(before, t, h, u, gripping);
        self.periods += 1;
        let n = f64::from(self.imperfect.noise_counts);
        if n > 0.0 {
            for i in 0..AXES {
                let unit = (self.next_random() >> 11) as f64 / (1u64 << 53) as f64;
                self.noise[i] = n * (unit - 0.5);
            }
        }
    }
}

impl World {
    /// The framed axes over the period (their motor and tool sides together, from the
    /// motor side's state `before` it), in place of the rigid step taken for every axis;
    /// a rigid axis' tool is where its motor side is.
    fn advance_frames(
        &mut self,
        before: [AxisState<f64>; AXES],
        t: f64,
        h: f64,
        u: [f64; AXES],
        gripping: [bool; AXES],
    ) {
        for i in 0..AXES {
            let (Some(frame), Plant::Physical(plant)) = (&self.frames[i], &self.plants[i]) else {
                self.tool[i] = self.state[i];
                continue;
            };
            let push = FramedPush {
                ext_mm_s2: self.faults.ext_accel[i],
                drag_mm_s2: self.faults.drag[i],
                gripping: gripping[i],
            };
            let s = FramedState {
                motor: before[i],
                tool: self.tool[i],
            };
            let s = frame_step::advance(plant, frame, &push, s, t, h, self.substeps, u[i]);
            self.state[i] = s.motor;
            self.tool[i] = s.tool;
        }
    }

    /// One period's substeps with at least one brake gripping. A gripping brake is static
    /// friction of `hold` (as an acceleration): a stuck axis stays stuck while the other
    /// accelerations at rest sum to at most `hold`; otherwise the brake's friction opposes
    /// the motion (or, breaking away, the net push) over the substep, and a velocity that
    /// crosses zero sticks the axis there. Stick and slip resolve at the substep (25 µs at
    /// 10 kHz × 4).
    fn advance_braked(&mut self, t: f64, h: f64, u: [f64; AXES], gripping: [bool; AXES]) {
        for (s, g) in self.brakes.stuck.iter_mut().zip(gripping) {
            // a released brake lets go at once
            *s &= g;
        }
        for j in 0..self.substeps {
            let tj = t + f64::from(j) * h;
            let f = &self.faults;
            let pushed = |i: usize| Pushed {
                plant: &self.plants[i],
                ext: f.ext_accel[i],
                drag: f.drag[i],
            };
            let mut friction = [0.0; AXES];
            let mut stuck = self.brakes.stuck;
            for i in 0..AXES {
                if !gripping[i] {
                    continue;
                }
                let hold = self.brakes.hold_accel[i];
                let v = self.state[i].vel;
                if stuck[i] || v == 0.0 {
                    // at rest: does the rest of the push overcome the brake?
                    let rest = AxisState {
                        pos: self.state[i].pos,
                        vel: 0.0,
                    };
                    let a = pushed(i).accel(rest, u[i], tj);
                    if libm::fabs(a) <= hold {
                        stuck[i] = true;
                    } else {
                        stuck[i] = false;
                        friction[i] = -libm::copysign(hold, a);
                    }
                } else {
                    friction[i] = -libm::copysign(hold, v);
                }
            }
            let axes = [0, 1, 2].map(|i| Braked {
                pushed: pushed(i),
                friction: friction[i],
                stuck: stuck[i],
            });
            let before = self.state;
            rk4_step(&axes, &mut self.state, tj, h, |_, _| u);
            for i in 0..AXES {
                if stuck[i] {
                    self.state[i] = AxisState {
                        pos: before[i].pos,
                        vel: 0.0,
                    };
                } else if gripping[i]
                    && before[i].vel * self.state[i].vel <= 0.0
                    && before[i].vel != 0.0
                {
                    // the brake's friction stops a moving axis, never reverses it: it sticks
                    // where its velocity crosses zero (breaking away, it moves the push's way)
                    self.state[i].vel = 0.0;
                    stuck[i] = true;
                }
            }
            self.brakes.stuck = stuck;
        }
    }
}

impl<R: Real> ServoIo<R> for World {
    fn read_inputs(&mut self) -> Inputs {
        self.sample_inputs()
    }

    fn read_counters(&mut self) -> [u32; AXES] {
        self.counter_registers()
    }

    fn read_index(&mut self) -> [Option<u32>; AXES] {
        let mut raw = [None; AXES];
        for ((r, n), mask) in raw.iter_mut().zip(self.index).zip(self.counter_mask) {
            // two's-complement truncation to the register width, as the timer counts
            *r = n.map(|n| n as u32 & mask);
        }
        raw
    }

    fn write_outputs(&mut self, effort: &[R; AXES]) {
        for (((e, u), lim), back) in self
            .effort
            .iter_mut()
            .zip(effort)
            .zip(self.full_scale)
            .zip(self.faults.motor_reversed)
        {
            let u = if back { -u.to_f64() } else { u.to_f64() };
            *e = u.max(-lim).min(lim);
        }
        self.outputs_on = true;
    }

    fn disable_outputs(&mut self) {
        self.effort = [0.0; AXES];
        // the enable line cuts the amplifier at once, whatever it was about to apply
        self.pending = [0.0; AXES];
        self.outputs_on = false;
    }

    fn write_brakes(&mut self, released: [bool; AXES]) {
        let t = self.time_s();
        let b = &mut self.brakes;
        for ((now, was), since) in released.iter().zip(&mut b.released).zip(&mut b.since_s) {
            if now != was {
                *was = *now;
                *since = t;
            }
        }
    }

    fn true_velocity(&self) -> Option<[f64; AXES]> {
        Some([self.state[0].vel, self.state[1].vel, self.state[2].vel])
    }
}
