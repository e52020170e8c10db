//! The physical 3-axis gantry (ball-screw axes with friction) and the law tunings derived
//! from its axis models, with the reasoning for each value (the patent, seed 002, and the
//! XY-table paper, seed 004, do not publish theirs). docs/seed-methods.md repeats the
//! derivations in a table.
//!
//! Units: mm, s, mN·m (see [`crate::plant::physical`]). The reflected inertia of an axis is
//! `J = J_motor_side · 2π/lead` with `J_motor_side` in kg·m² times 1000 (N·m → mN·m):
//! lead 5 mm gives 2π/lead = 1.2566 rad/mm, so 1e-4 kg·m² at the motor is
//! 0.1257 mN·m/(mm/s²) at the table.

use crate::coupling::variable_gain::{VariableGainConfig, VariableGainMode};
use crate::estimator::CounterWidth;
use crate::law::adaptive_smc::{AdaptiveSmcConfig, EstimateConfig};
use crate::law::dob_smc::DobSmcConfig;
use crate::law::pid::PidConfig;
use crate::law::smc::SmcConfig;
use crate::motion::homing::{AxisHomingConfig, HomeDirection, HomingConfig};
use crate::plant::physical::{PhysicalAxisConfig, DEFAULT_V_REG_MM_S, DEFAULT_V_STRIBECK_MM_S};
use crate::plant::AxisModel;
use crate::servo::brake::BrakeConfig;
use crate::servo::io::{AmplifierConfig, EncoderConfig};
use crate::servo::monitor::AxisSafetyConfig;
use crate::servo::travel::{AxisTravel, TravelConfig};
use crate::sysid::tuning::{self, TuningConfig};

// The rules' constants moved to the tuning module with the rules; kept here under their
// old paths.
pub use crate::sysid::tuning::{ADAPTIVE_DEAD_ZONE_MM_S, ADAPT_GAIN_B, ADAPT_GAIN_F, ADAPT_GAIN_J};

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
    frame: None,
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

/// The holding brakes: Z, the vertical axis that falls when its amplifier goes off, has
/// one (the Z motor's built-in spring-applied brake, default timings of
/// [`crate::servo::brake`]: 30 ms to grip, 70 ms to open); X and Y, horizontal, have none.
pub const GANTRY_BRAKES: [BrakeConfig; 3] =
    [BrakeConfig::NONE, BrakeConfig::NONE, BrakeConfig::FITTED];

/// Holding torque of the Z brake as the simulated machine models it, mN·m: 320, the
/// static torque catalogues list for the holding brake of a 100 W servo motor (0.32 N·m,
/// the motor's rated torque: the brake holds what the motor can hold continuously), 14
/// times Z's 23 mN·m of gravity.
pub const GANTRY_Z_BRAKE_HOLDING_MNM: f32 = 320.0;

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

/// The gantry's encoders give an index pulse once per revolution: 2000 lines read × 4.
pub const GANTRY_INDEX_PERIOD_COUNTS: u32 = 8000;

/// The gantry's encoders: X and Y on 32-bit timers (TIM2, TIM5), Z on a 16-bit one
/// (TIM3).
pub const GANTRY_ENCODERS: [EncoderConfig; 3] = [
    EncoderConfig {
        counts_per_mm: GANTRY_COUNTS_PER_MM,
        counter: CounterWidth::Bits32,
        index_period_counts: GANTRY_INDEX_PERIOD_COUNTS,
        invert: false,
    },
    EncoderConfig {
        counts_per_mm: GANTRY_COUNTS_PER_MM,
        counter: CounterWidth::Bits32,
        index_period_counts: GANTRY_INDEX_PERIOD_COUNTS,
        invert: false,
    },
    EncoderConfig {
        counts_per_mm: GANTRY_COUNTS_PER_MM,
        counter: CounterWidth::Bits16,
        index_period_counts: GANTRY_INDEX_PERIOD_COUNTS,
        invert: false,
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
        invert: false,
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

/// Tuning of the seed laws for a preset axis: bandwidth [`LOOP_OMEGA`], the axis' peak
/// torque, one encoder count [`COUNT_MM`].
pub const fn tuning_for(axis: &PhysicalAxisConfig) -> TuningConfig {
    TuningConfig {
        bandwidth_rad_s: LOOP_OMEGA,
        torque_max_mnm: axis.torque_max_mnm,
        count_mm: COUNT_MM,
    }
}

/// PID of [`tuning::pid`] for a preset axis (pole placement `(s + ω)³` on `J s²`).
pub const fn pid_for(axis: &PhysicalAxisConfig) -> PidConfig {
    tuning::pid(&AxisModel::from_physical(axis), &tuning_for(axis))
}

/// DSMC of [`tuning::dsmc`] for a preset axis (the paper's DSMC rescaled to mm; the
/// reasoning for each gain is there).
pub const fn dsmc_for(axis: &PhysicalAxisConfig) -> SmcConfig {
    tuning::dsmc(&AxisModel::from_physical(axis), &tuning_for(axis))
}

/// DOB-SMC of [`tuning::dob_smc`] for a preset axis (nominal model = the preset).
pub const fn dob_smc_for(axis: &PhysicalAxisConfig) -> DobSmcConfig {
    tuning::dob_smc(&AxisModel::from_physical(axis), &tuning_for(axis))
}

pub const DOB_SMC_X: DobSmcConfig = dob_smc_for(&GANTRY_X);

/// Adaptive SMC of [`tuning::adaptive_smc`] for the friction-identification scenario: the
/// gains of the model-based rule, but the initial estimates are a deliberately poor
/// guess (J 25 % low, B and friction unknown = 0) with bounds spanning 0.3×..3× the truth,
/// so the scenario shows the adaptation converging.
pub const fn adaptive_for(axis: &PhysicalAxisConfig) -> AdaptiveSmcConfig {
    let j = axis.inertia;
    let mut c = tuning::adaptive_smc(&AxisModel::from_physical(axis), &tuning_for(axis));
    c.inertia = EstimateConfig {
        initial: 0.75 * j,
        min: 0.3 * j,
        max: 3.0 * j,
        gamma: j * ADAPT_GAIN_J,
    };
    c.viscous = EstimateConfig {
        initial: 0.0,
        min: 0.0,
        max: 3.0 * axis.viscous,
        gamma: j * ADAPT_GAIN_B,
    };
    c.coulomb_pos = EstimateConfig {
        initial: 0.0,
        min: 0.0,
        max: 3.0 * axis.coulomb_pos_mnm,
        gamma: j * ADAPT_GAIN_F,
    };
    c.coulomb_neg = EstimateConfig {
        initial: 0.0,
        min: 3.0 * axis.coulomb_neg_mnm,
        max: 0.0,
        gamma: j * ADAPT_GAIN_F,
    };
    c
}

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

/// The gantry's travel around the work origin: ±150 mm on X and Y, ±50 mm on Z (the
/// 600/800 mm screws leave room for the carriages and the switches beyond).
pub const GANTRY_TRAVEL: TravelConfig = TravelConfig {
    axes: [
        AxisTravel {
            min_mm: -150.0,
            max_mm: 150.0,
        },
        AxisTravel {
            min_mm: -150.0,
            max_mm: 150.0,
        },
        AxisTravel {
            min_mm: -50.0,
            max_mm: 50.0,
        },
    ],
    tolerance_mm: TravelConfig::DEFAULT_TOLERANCE_MM,
};

/// One axis' homing on the gantry: seek at 20 mm/s (stops within 0.4 mm at the 500 mm/s²
/// homing acceleration, inside the 2 mm between switch and hard stop), locate at 1 mm/s
/// (a 1 ms switch response is 1 µm), 2 mm back-off, 2 mm pull-off. The switch triggers
/// 1 mm beyond the soft limit.
const fn gantry_homing_axis(
    order: u8,
    direction: HomeDirection,
    switch_pos_mm: f32,
) -> AxisHomingConfig {
    AxisHomingConfig {
        enabled: true,
        order,
        direction,
        seek_mm_s: 20.0,
        locate_mm_s: 1.0,
        accel_mm_s2: 500.0,
        backoff_mm: 2.0,
        pulloff_mm: 2.0,
        switch_pos_mm,
        // the whole 300 mm travel plus the 2 mm beyond each end
        max_seek_mm: 320.0,
        use_index: false,
        index_search_mm: AxisHomingConfig::INDEX_SEARCH_MM,
    }
}

/// Homing of the gantry: Z up first (clears the work), then X and Y to their minimum
/// ends.
pub const GANTRY_HOMING: HomingConfig = HomingConfig {
    axes: [
        gantry_homing_axis(1, HomeDirection::Min, -151.0),
        gantry_homing_axis(1, HomeDirection::Min, -151.0),
        gantry_homing_axis(0, HomeDirection::Max, 51.0),
    ],
};
