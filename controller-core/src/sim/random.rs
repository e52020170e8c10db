//! Random machines for the identification studies: physical axes drawn from the
//! documented range of docs/identification.md with the crate's [`SplitMix64`], so that a
//! seed names one machine on every platform.

use crate::plant::physical::PhysicalAxisConfig;
use crate::sim::rng::SplitMix64;

/// One random axis from the documented range (docs/identification.md): J 0.02–0.4
/// mN·m/(mm/s²) and B 0.05–1.0 mN·m/(mm/s) log-uniform, f+ 10–80 and f- −8..−80 mN·m
/// uniform and independent (asymmetric), Stribeck ratio 1.0–1.5 at 1–3 mm/s, peak torque
/// 1–3 N·m; `loaded` adds a constant load of ±(5–30) mN·m (gravity on a vertical axis).
pub fn random_axis(
    rng: &mut SplitMix64,
    loaded: bool,
    base: &PhysicalAxisConfig,
) -> PhysicalAxisConfig {
    let load = if loaded {
        let l = rng.uniform(5.0, 30.0);
        if rng.unit() < 0.5 {
            l
        } else {
            -l
        }
    } else {
        0.0
    };
    PhysicalAxisConfig {
        inertia: rng.log_uniform(0.02, 0.4) as f32,
        viscous: rng.log_uniform(0.05, 1.0) as f32,
        coulomb_pos_mnm: rng.uniform(10.0, 80.0) as f32,
        coulomb_neg_mnm: -rng.uniform(8.0, 80.0) as f32,
        stiction_ratio: rng.uniform(1.0, 1.5) as f32,
        v_stribeck_mm_s: rng.uniform(1.0, 3.0) as f32,
        load_const_mnm: load as f32,
        torque_max_mnm: rng.uniform(1000.0, 3000.0) as f32,
        ..*base
    }
}
