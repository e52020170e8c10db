//! The physical 3-axis gantry (ball-screw axes with friction) and the law tunings derived
//! from its axis models, with the reasoning for each value (the patent, seed 002, and the
//! XY-table paper, seed 004, do not publish theirs). docs/seed-methods.md repeats the
//! derivations in a table.
//!
//! Units: mm, s, mN·m (see [`crate::physical_plant`]). The reflected inertia of an axis is
//! `J = J_motor_side · 2π/lead` with `J_motor_side` in kg·m² times 1000 (N·m → mN·m):
//! lead 5 mm gives 2π/lead = 1.2566 rad/mm, so 1e-4 kg·m² at the motor is
//! 0.1257 mN·m/(mm/s²) at the table.

use crate::coupling::variable_gain::{VariableGainConfig, VariableGainMode};
use crate::estimator::CounterWidth;
use crate::law::adaptive_smc::{AdaptiveSmcConfig, EstimateConfig};
use crate::law::dob_smc::DobSmcConfig;
use crate::law::pid::PidConfig;
use crate::law::smc::{ReachingConfig, SmcConfig, SurfaceConfig};
use crate::model::PlantParams;
use crate::servo::io::{AmplifierConfig, EncoderConfig};
use crate::servo::monitor::AxisSafetyConfig;
use crate::sim::physical::{PhysicalAxisConfig, DEFAULT_V_REG_MM_S, DEFAULT_V_STRIBECK_MM_S};
use crate::Exponent;

/// Control period of the firmware: 10 kHz (firmware/src/board.rs default).
pub const FIRMWARE_PERIOD_S: f32 = 1e-4;

/// Encoder resolution: 2000 lines × 4 (quadrature) per revolution of a 5 mm lead screw
/// (spec 1.3): 5 mm / 8000 = 0.625 µm per count.
pub const COUNT_MM: f32 = 5.0 / 8000.0;

/// Ratio of breakaway (static) to Coulomb friction: 1.3, a typical value for
/// preloaded ball screws on linear guides.
pub const STICTION_RATIO: f32 = 1.3;

/// X axis (carriage). Motor side: rotor 1.6e-5 kg·m² (100 W DC servo), Ø16 × 600 mm
/// steel screw 3.0e-5, 8 kg carriage 8·(5 mm/2π)² = 0.5e-5: total 5.1e-5 kg·m², i.e.
/// J = 0.064 mN·m/(mm/s²). Viscous 0.2 mN·m/(rad/s) at the motor = 0.25 mN·m/(mm/s).
/// Coulomb 40 / -32 mN·m (screw preload + guides, 20 % direction asymmetry as seed 004
/// reports asymmetric friction). Peak torque 1.0 N·m (about 3× rated for such a motor).
pub const GANTRY_X: PhysicalAxisConfig = PhysicalAxisConfig {
    inertia: 0.064,
    viscous: 0.25,
    coulomb_pos_mnm: 40.0,
    coulomb_neg_mnm: -32.0,
    stiction_ratio: STICTION_RATIO,
    v_stribeck_mm_s: DEFAULT_V_STRIBECK_MM_S,
    v_reg_mm_s: DEFAULT_V_REG_MM_S,
    load_const_mnm: 0.0,
    load_step_mnm: 0.0,
    load_step_t_s: f32::INFINITY,
    torque_max_mnm: 1000.0,
};

/// Y axis (carries the X beam, 25 kg). Rotor 3e-5, Ø20 × 800 mm screw 9.9e-5, 25 kg
/// reflected 1.6e-5: 1.45e-4 kg·m², J = 0.18. Viscous 0.40, Coulomb 60 / -50 mN·m, peak
/// torque 2.0 N·m. X and Y are deliberately mismatched (J ratio 2.8), the situation
/// cross-coupling is meant for.
pub const GANTRY_Y: PhysicalAxisConfig = PhysicalAxisConfig {
    inertia: 0.18,
    viscous: 0.40,
    coulomb_pos_mnm: 60.0,
    coulomb_neg_mnm: -50.0,
    torque_max_mnm: 2000.0,
    ..GANTRY_X
};

/// Z axis (vertical, 3 kg slide). Rotor 1.6e-5, Ø16 × 300 mm screw 1.5e-5, slide 0.2e-5:
/// 3.3e-5 kg·m², J = 0.041. Gravity 3 kg · 9.81 · 5 mm / 2π = 23 mN·m as a constant load.
pub const GANTRY_Z: PhysicalAxisConfig = PhysicalAxisConfig {
    inertia: 0.041,
    viscous: 0.20,
    coulomb_pos_mnm: 35.0,
    coulomb_neg_mnm: -30.0,
    load_const_mnm: 23.0,
    ..GANTRY_X
};

/// The three physical axes.
pub const GANTRY_AXES: [PhysicalAxisConfig; 3] = [GANTRY_X, GANTRY_Y, GANTRY_Z];

/// Maximum axis speed: 250 mm/s, a 3000 rpm servo motor on the 5 mm lead.
pub const GANTRY_VEL_MAX_MM_S: f32 = 250.0;

/// Counts per mm of the gantry's encoders (2000 lines × 4 per 5 mm lead).
pub const GANTRY_COUNTS_PER_MM: f32 = 1600.0;

/// Command resolution of the amplifiers as the simulator models it: 12 bits over the ±
/// range, coarser than the board's TIM1 duty (8400 steps per direction at 20 kHz from
/// 168 MHz, about 14 bits), so the simulated quantisation is on the safe side.
pub const GANTRY_AMPLIFIER_BITS: u8 = 12;

/// The gantry's encoders: X and Y on 32-bit timers (TIM2, TIM5), Z on a 16-bit one
/// (TIM3).
pub const GANTRY_ENCODERS: [EncoderConfig; 3] = [
    EncoderConfig {
        counts_per_mm: GANTRY_COUNTS_PER_MM,
        counter: CounterWidth::Bits32,
    },
    EncoderConfig {
        counts_per_mm: GANTRY_COUNTS_PER_MM,
        counter: CounterWidth::Bits32,
    },
    EncoderConfig {
        counts_per_mm: GANTRY_COUNTS_PER_MM,
        counter: CounterWidth::Bits16,
    },
];

/// Torque-mode amplifiers whose full command is the motor's peak torque.
pub const GANTRY_AMPLIFIERS: [AmplifierConfig; 3] = [
    amplifier(&GANTRY_X),
    amplifier(&GANTRY_Y),
    amplifier(&GANTRY_Z),
];

const fn amplifier(a: &PhysicalAxisConfig) -> AmplifierConfig {
    AmplifierConfig {
        full_scale: a.torque_max_mnm,
        resolution_bits: GANTRY_AMPLIFIER_BITS,
    }
}

/// Fault thresholds of one gantry axis (docs/safety.md):
/// - speed limit [`GANTRY_VEL_MAX_MM_S`];
/// - physical acceleration bound twice peak torque (plus gravity) over inertia, room for
///   external loads;
/// - following error 0.1 mm at rest growing to 1 mm at full speed (the loaded contouring
///   runs stay below 40 µm);
/// - stuck-encoder effort change: twice the breakaway friction (1.3 × the larger Coulomb
///   level) plus 20 mN·m, rounded up to 5 mN·m;
/// - controlled-stop deceleration `stop_decel` (well below the axis' capability).
pub const fn gantry_safety(a: &PhysicalAxisConfig, stop_decel_mm_s2: f32) -> AxisSafetyConfig {
    let coulomb = if a.coulomb_pos_mnm > -a.coulomb_neg_mnm {
        a.coulomb_pos_mnm
    } else {
        -a.coulomb_neg_mnm
    };
    let change = 2.0 * a.stiction_ratio * coulomb + 20.0;
    AxisSafetyConfig {
        vel_max_mm_s: GANTRY_VEL_MAX_MM_S,
        accel_max_mm_s2: 2.0 * (a.torque_max_mnm + a.load_const_mnm) / a.inertia,
        min_ferror_mm: 0.1,
        ferror_mm: 1.0,
        stuck_effort_change: 5.0 * ((change / 5.0) as u32 + 1) as f32,
        stop_decel_mm_s2,
    }
}

/// The three axes' fault thresholds: controlled stops at 2000 mm/s² (1500 on the heavy Y).
pub const GANTRY_SAFETY: [AxisSafetyConfig; 3] = [
    gantry_safety(&GANTRY_X, 2000.0),
    gantry_safety(&GANTRY_Y, 1500.0),
    gantry_safety(&GANTRY_Z, 2000.0),
];

/// Load step of the contouring scenarios: a 200 N cutting force on the X table,
/// 200 N · 5 mm / 2π = 159 mN·m, rounded to 150 mN·m.
pub const CUTTING_LOAD_MNM: f32 = 150.0;

/// Closed-loop bandwidth of the position loops, rad/s: 2π·25 Hz. Limited by the velocity
/// observer (100 Hz, [`crate::estimator`]) whose phase lag must stay small at the
/// loop's crossover, and by the encoder: at 157 rad/s one count of error asks for
/// J ω² · 0.625 µm, a few mN·m, below the friction level (no count-level limit cycling).
pub const LOOP_OMEGA: f32 = 157.0;

/// PID from the pole placement `(s + ω)³` on `J s²`: `kp = 3Jω²`, `kd = 3Jω`,
/// `ki = Jω³`; output limited to the peak torque and the integral to what the integral
/// term can use.
pub const fn pid_for(axis: &PhysicalAxisConfig) -> PidConfig {
    let j = axis.inertia;
    let w = LOOP_OMEGA;
    let ki = j * w * w * w;
    PidConfig {
        kp: 3.0 * j * w * w,
        ki,
        kd: 3.0 * j * w,
        kv_ff: 0.0,
        ka_ff: 0.0,
        integral_limit: axis.torque_max_mnm / ki,
        u_max: axis.torque_max_mnm,
    }
}

/// The paper's DSMC (spec 2.3) rescaled for a physical axis in mm: the equivalent control
/// cancels the known `B/J` (plant a = B/J, b = 0, k = 1/J); friction and load are left to
/// the reaching law and the integral. Surface α = ω (same bandwidth as the PID),
/// β = 10 mm^(4/9)/s so the terminal term matters below ~0.1 mm, singular floor one
/// encoder count (errors below it are not measurable). Reaching: the paper's k1 = k2 = 20,
/// k3 = 200 (Table 2) are kept. Tried on this axis at 10 kHz with the 100 Hz velocity
/// observer: k1 = 200 or k3 = 2000 drive the control into full-scale chattering (the
/// effective gain k3 |e|^(1/3) on `s` exceeds the observer's bandwidth), and k2 = 300
/// lowers the loaded contour error by only ~15 % for 3× the chattering. Friction and
/// load are therefore rejected by the integral, k4 = ω³ (the PID's `ki/J`).
pub const fn dsmc_for(axis: &PhysicalAxisConfig) -> SmcConfig {
    let j = axis.inertia;
    SmcConfig {
        plant: PlantParams {
            a: axis.viscous / j,
            b: 0.0,
            k: 1.0 / j,
        },
        surface: SurfaceConfig::Terminal {
            alpha: LOOP_OMEGA,
            beta: 10.0,
            p: 9,
            q: 5,
            singular_floor: COUNT_MM,
        },
        reaching: ReachingConfig::DoublePower {
            k1: 20.0,
            k2: 20.0,
            k3: 200.0,
            beta2: Exponent { num: 1, den: 3 },
            beta3: Exponent { num: 1, den: 3 },
        },
        k4: LOOP_OMEGA * LOOP_OMEGA * LOOP_OMEGA,
        integral_limit: axis.torque_max_mnm / j / (LOOP_OMEGA * LOOP_OMEGA * LOOP_OMEGA),
        u_max: axis.torque_max_mnm,
    }
}

/// DOB-SMC (spec 2.4): model a = B/J, b = 1/J (nominal = identified values). Surface
/// c = ω. Reaching k = 100 1/s, η = 200 mm/s² with boundary layer φ = 5 mm/s (η/φ = 40
/// 1/s more inside the layer); η covers the observer's residual on a friction reversal,
/// about 20 % of the 1100 mm/s² jump on X. Tried at 10 kHz with the 100 Hz velocity
/// observer: k = 2ω, φ = 2 mm/s chatter at full scale once cross-coupling is added;
/// k = 0 (the patent's pure η term) doubles the loaded contour error. Observer ω_o = 2π·40 Hz = 250 rad/s, critically
/// damped (k1 = 2ω_o, k2 = ω_o²): below the velocity observer's 100 Hz so its noise
/// is filtered, above the loop's 25 Hz so the estimate leads the loop. `|d̂|` limited to
/// the peak acceleration.
pub const fn dob_smc_for(axis: &PhysicalAxisConfig) -> DobSmcConfig {
    let j = axis.inertia;
    let wo = 250.0;
    DobSmcConfig {
        a: axis.viscous / j,
        b: 1.0 / j,
        c: LOOP_OMEGA,
        k: 100.0,
        eta: 200.0,
        boundary_layer: 5.0,
        k1: 2.0 * wo,
        k2: wo * wo,
        d_hat_limit: axis.torque_max_mnm / j,
        u_max: axis.torque_max_mnm,
    }
}

pub const DOB_SMC_X: DobSmcConfig = dob_smc_for(&GANTRY_X);

/// Adaptive SMC (spec 2.5). λ = ω; k_d = 2Jω so the s-loop is twice as fast as the
/// surface; k = 10 mN·m covers the unmodelled Stribeck excess (0.3 · 40 mN·m at the
/// lowest speeds) with T_load = 0 in the friction scenario. Switching boundary layer
/// Φ = 0.3 mm/s, adaptation dead zone δ = [`ADAPTIVE_DEAD_ZONE_MM_S`].
/// Initial estimates are a deliberately poor guess (J 25 % low, B and friction unknown =
/// 0); bounds span 0.3×..3× the truth. Adaptation gains are per unit of the axis'
/// inertia, `γ = J g`: the parameter errors decay at a rate ∝ γ φ²/J (the s-loop's
/// inertia divides the torque error), so scaling γ with J gives every axis the same
/// convergence time on the same motion. The per-unit gains g were raised until each
/// estimate settles within ~2 s on the 5 mm / 2 Hz sine of the friction scenario
/// (regressor sizes there: x_d'' ~ 800 mm/s², x' ~ 60 mm/s, μ ~ 1; g scales as
/// 1/regressor²), and kept below the point where the adaptation couples with the
/// 2 ms s-loop.
pub const fn adaptive_for(axis: &PhysicalAxisConfig) -> AdaptiveSmcConfig {
    let j = axis.inertia;
    AdaptiveSmcConfig {
        lambda: LOOP_OMEGA,
        boundary_layer: 0.3,
        dead_zone: ADAPTIVE_DEAD_ZONE_MM_S,
        kd: 2.0 * j * LOOP_OMEGA,
        k: 10.0,
        inertia: EstimateConfig {
            initial: 0.75 * j,
            min: 0.3 * j,
            max: 3.0 * j,
            gamma: j * ADAPT_GAIN_J,
        },
        viscous: EstimateConfig {
            initial: 0.0,
            min: 0.0,
            max: 3.0 * axis.viscous,
            gamma: j * ADAPT_GAIN_B,
        },
        coulomb_pos: EstimateConfig {
            initial: 0.0,
            min: 0.0,
            max: 3.0 * axis.coulomb_pos_mnm,
            gamma: j * ADAPT_GAIN_F,
        },
        coulomb_neg: EstimateConfig {
            initial: 0.0,
            min: 3.0 * axis.coulomb_neg_mnm,
            max: 0.0,
            gamma: j * ADAPT_GAIN_F,
        },
        u_max: axis.torque_max_mnm,
    }
}

/// Adaptation dead zone δ = 0.05 mm/s. The estimates stop once the feedback absorbs the
/// remaining parameter error inside `|s| < δ`, i.e. a torque error of about
/// `δ (k_d + k/Φ)` = 0.05 · (20 + 33) ≈ 2.7 mN·m on X (5 mN·m on Y): below 10 % of each
/// term on the friction scenario (viscous 16 mN·m at 63 mm/s, Coulomb 32..60 mN·m,
/// inertial 50 mN·m). The former δ = Φ = 0.3 mm/s left ~16 mN·m unidentified (B̂ ended
/// 20 % off even with the exact velocity). δ is not meant to be above the velocity
/// noise: zero-mean estimator noise is averaged by the adaptation integrators; δ only
/// stops biased unmodelled torques below that 2.7 mN·m from drifting the estimates.
/// Measured with the exact velocity on the 5 mm / 2 Hz sine: δ = 0.3 / 0.1 / 0.03 mm/s
/// gives B̂ −20 / +3 / +1 % on X.
pub const ADAPTIVE_DEAD_ZONE_MM_S: f32 = 0.05;

/// Per-unit adaptation gain of Ĵ (γ_J = J · g): 6e-4 on the X axis (J = 0.064).
pub const ADAPT_GAIN_J: f32 = 6e-4 / 0.064;
/// Per-unit adaptation gain of B̂: 0.06 on the X axis.
pub const ADAPT_GAIN_B: f32 = 0.06 / 0.064;
/// Per-unit adaptation gain of f̂±: 600 on the X axis.
pub const ADAPT_GAIN_F: f32 = 600.0 / 0.064;

pub const ADAPTIVE_SMC_X: AdaptiveSmcConfig = adaptive_for(&GANTRY_X);

/// Patent cross-coupling for the XY pair: the contour PID is the lighter (X) axis' PID,
/// scaled by `VARIABLE_GAIN_SCALE`. Its correction acts on both axes along the normal, so
/// it may not exceed what the X loop tolerates with the 100 Hz velocity observer.
/// Scale of the contour PID relative to the X axis' PID.
pub const VARIABLE_GAIN_SCALE: f32 = 0.5;

pub const VARIABLE_GAIN_XY: VariableGainConfig = VariableGainConfig {
    mode: VariableGainMode::Planar,
    kp: VARIABLE_GAIN_SCALE * 3.0 * GANTRY_X.inertia * LOOP_OMEGA * LOOP_OMEGA,
    ki: VARIABLE_GAIN_SCALE * GANTRY_X.inertia * LOOP_OMEGA * LOOP_OMEGA * LOOP_OMEGA,
    kd: VARIABLE_GAIN_SCALE * 3.0 * GANTRY_X.inertia * LOOP_OMEGA,
    integral_limit: 1.0,
    u_max: 1000.0,
    min_direction_norm_sq: 1e-6,
};
