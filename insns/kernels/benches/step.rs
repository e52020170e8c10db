//! Host benchmark of the kernels `cargo insns` counts on the Cortex-M4: one 3-axis
//! control step (paper helix sample + contour error + cross-coupling + DSMC on three
//! axes) in each number type, on the same worst-case inputs.
//!
//! `cargo bench -p insns-kernels` (criterion; reports in target/criterion).

use controller_core::num::fixed::{FxQ16, FxQ32};
use controller_core::{LibmF32, Real};
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use insns_kernels::Dsmc3;

fn bench_one<R: Real>(c: &mut Criterion, name: &str) {
    let Some(mut k) = Dsmc3::<R>::setup() else {
        panic!("{name}: the paper DSMC configuration was rejected");
    };
    c.bench_function(name, |b| b.iter(|| black_box(k.step())));
}

fn steps(c: &mut Criterion) {
    bench_one::<f32>(c, "dsmc3_f32");
    bench_one::<LibmF32>(c, "dsmc3_f32_libm");
    bench_one::<FxQ32>(c, "dsmc3_fixed");
    bench_one::<FxQ16>(c, "dsmc3_fixed_q16");
    bench_one::<f64>(c, "dsmc3_f64");
}

criterion_group!(benches, steps);
criterion_main!(benches);
