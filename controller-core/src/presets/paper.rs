//! The reference paper's plant and Table 2 gains (seed 000: Wang, Chen, Wang 2021,
//! "Compensation Sliding Cross Coupling Control Research of Cartesian Coordinate Robot").

use crate::law::pid::PidConfig;
use crate::law::smc::{ReachingConfig, SmcConfig, SurfaceConfig, DEFAULT_SINGULAR_FLOOR};
use crate::plant::PlantParams;
use crate::Exponent;

/// Paper section 3: a = 10, b = 1, k = 1 for each of the three axes.
pub const PAPER_PLANT: PlantParams = PlantParams {
    a: 10.0,
    b: 1.0,
    k: 1.0,
};

/// Paper Table 2: P = 600, I = 1, D = 10, no feed-forward, no limits.
pub const PAPER_PID: PidConfig = PidConfig {
    kp: 600.0,
    ki: 1.0,
    kd: 10.0,
    kv_ff: 0.0,
    ka_ff: 0.0,
    integral_limit: f32::INFINITY,
    u_max: f32::INFINITY,
};

/// Paper Table 2 surface: α = 10, β = 1, p = 9, q = 5.
pub const PAPER_SURFACE: SurfaceConfig = SurfaceConfig::Terminal {
    alpha: 10.0,
    beta: 1.0,
    p: 9,
    q: 5,
    singular_floor: DEFAULT_SINGULAR_FLOOR,
};

/// Paper Table 2 "SMC": terminal surface + exponential law, k = 200, ε = 33.
pub const PAPER_SMC: SmcConfig = SmcConfig {
    plant: PAPER_PLANT,
    surface: PAPER_SURFACE,
    reaching: ReachingConfig::Exponential {
        k: 200.0,
        epsilon: 33.0,
        boundary_layer: 0.0,
    },
    k4: 0.0,
    integral_limit: f32::INFINITY,
    u_max: f32::INFINITY,
};

/// Paper Table 2 "DSMC": k1 = k2 = k4 = 20, k3 = 200, β1 = 5/3, β2 = 1/3, β3 = 1/3.
pub const PAPER_DSMC: SmcConfig = SmcConfig {
    plant: PAPER_PLANT,
    surface: PAPER_SURFACE,
    reaching: ReachingConfig::DoublePower {
        k1: 20.0,
        k2: 20.0,
        k3: 200.0,
        beta2: Exponent { num: 1, den: 3 },
        beta3: Exponent { num: 1, den: 3 },
    },
    k4: 20.0,
    integral_limit: f32::INFINITY,
    u_max: f32::INFINITY,
};

/// Paper cross-coupling gain λ = 0.01 (section 4.2).
pub const PAPER_LAMBDA: f32 = 0.01;
