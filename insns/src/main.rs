//! `cargo insns`: the measured cost of one control step on the Cortex-M4, and the
//! host-versus-target bit-exactness check.
//!
//! ```text
//! cargo insns              build the kernels for thumbv7em-none-eabihf (release profile),
//!                          count each one in the unicorn emulator, print
//!                          `<name> instructions=<N> cycles_est=<M>`
//! cargo insns bitexact     replay a recorded closed-loop input sequence through the
//!                          controller on the host and in the emulator; fail unless the
//!                          outputs are bit-identical
//! cargo insns profile K    exclusive instructions per function of kernel K
//! cargo insns parts        `servo_period` per part of the period (exact attribution)
//! ```
//!
//! The emulator side is `insns/count.py` (Python: `unicorn`, `capstone`, `pyelftools`);
//! set `INSNS_PYTHON` to choose the interpreter (default `python3`). See `insns/README.md`.

use anyhow::{bail, Context, Result};
use controller_core::controller::{Controller3, Measured};
use controller_core::motion::trajectory::Trajectory;
use controller_core::num::fixed::{FxQ16, FxQ32};
use controller_core::plant::paper::{DisturbedPaperAxis, PaperAxis};
use controller_core::plant::state::{rk4_step, AxisState};
use controller_core::presets::paper::PAPER_PLANT;
use controller_core::{LibmF32, Vec3};
use insns_kernels::{paper_dsmc_config, replay, RawBits, KERNEL_PERIOD_S, REPLAY_IN, REPLAY_OUT};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

/// Steps of the recorded sequence: 0.1 s of the helix at 20 kHz, long enough for the
/// integrators, the sign changes of every sliding variable and the trig range reduction.
const REPLAY_STEPS: usize = 2000;

/// Encoder quantum of the recorded positions (plant units), as in the discrete scenario.
const REPLAY_QUANTUM: f64 = 1e-4;

/// Start time of the recording (s): past the first quadrant, so `sin`/`cos` reduce.
const REPLAY_T0_S: f64 = 3.0;

/// The Cortex-M4F target (the board) and the FPU-less Cortex-M3 one (STM32F1 class):
/// every kernel is built for the first, the `_m3` kernels for the second.
const M4: &str = "thumbv7em-none-eabihf";
const M3: &str = "thumbv7m-none-eabi";

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let command = args.first().map(String::as_str);
    let elf = build_kernels(M4)?;
    // `profile` and `parts` look at one kernel of the board's ELF only
    let elf_m3 = match command {
        None | Some("count") | Some("bitexact") => Some(build_kernels(M3)?),
        _ => None,
    };
    match command {
        None | Some("count") => count(&[elf].into_iter().chain(elf_m3).collect::<Vec<_>>()),
        Some("bitexact") => bitexact(&[elf].into_iter().chain(elf_m3).collect::<Vec<_>>()),
        Some("profile") => match args.get(1) {
            Some(kernel) => profile(&elf, kernel),
            None => bail!("usage: cargo insns profile <kernel>"),
        },
        Some("parts") => parts(&elf),
        Some(other) => {
            bail!(
                "unknown command `{other}` (expected `count`, `bitexact`, `parts` or \
                 `profile <kernel>`)"
            )
        }
    }
}

fn manifest_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Build the thumb ELF for `target` with the workspace's release profile (the
/// firmware's) and return its path, taken from cargo's own build report. The workspace's
/// `.cargo/config.toml` gives cortex-m-rt's linker script to the board's target only;
/// the Cortex-M3 build gets it here.
fn build_kernels(target: &str) -> Result<PathBuf> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let link_script = format!("target.{target}.rustflags=[\"-C\", \"link-arg=-Tlink.x\"]");
    let mut cmd = Command::new(cargo);
    cmd.current_dir(manifest_dir().join(".."));
    cmd.args([
        "build",
        "-p",
        "insns-kernels",
        "--release",
        "--target",
        target,
        "--features",
        "target",
        "--bin",
        "insns-kernels",
        "--message-format=json-render-diagnostics",
    ]);
    if target != M4 {
        cmd.args(["--config", &link_script]);
    }
    let out = cmd
        .stderr(Stdio::inherit())
        .output()
        .context("running cargo to build the thumb kernels")?;
    if !out.status.success() {
        bail!(
            "building the kernels for {target} failed \
             (is the target installed? `rustup target add {target}`)"
        );
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    for line in stdout.lines() {
        let Ok(msg) = serde_json::from_str::<serde_json::Value>(line) else {
            continue;
        };
        if msg["reason"] == "compiler-artifact" && msg["target"]["name"] == "insns-kernels" {
            if let Some(exe) = msg["executable"].as_str() {
                return Ok(PathBuf::from(exe));
            }
        }
    }
    bail!("cargo did not report the insns-kernels executable")
}

fn python() -> Command {
    let py = std::env::var("INSNS_PYTHON").unwrap_or_else(|_| "python3".into());
    let mut c = Command::new(py);
    c.arg(manifest_dir().join("count.py"));
    c
}

/// Count every kernel of every ELF; print the lines of all of them sorted by name.
fn count(elfs: &[PathBuf]) -> Result<()> {
    let mut lines = Vec::new();
    let mut failed = false;
    for elf in elfs {
        let out = python()
            .arg(elf)
            .arg("count")
            .stderr(Stdio::inherit())
            .output()
            .context("running insns/count.py (python3 with unicorn, capstone, pyelftools)")?;
        failed |= !out.status.success();
        lines.extend(
            String::from_utf8_lossy(&out.stdout)
                .lines()
                .map(str::to_owned),
        );
    }
    // the kernels' lines sorted by name; any note a kernel line carries stays below it
    let mut records: Vec<(String, Vec<String>)> = Vec::new();
    for l in lines {
        match records.last_mut() {
            Some((_, notes)) if l.starts_with(' ') => notes.push(l),
            _ => records.push((l, Vec::new())),
        }
    }
    records.sort_by(|a, b| a.0.cmp(&b.0));
    for (l, notes) in records {
        println!("{l}");
        for n in notes {
            println!("{n}");
        }
    }
    if failed {
        bail!("insns/count.py failed");
    }
    Ok(())
}

/// Exclusive instructions per function of one kernel step (inlined code counts in its
/// caller): where a kernel spends its instructions.
fn profile(elf: &Path, kernel: &str) -> Result<()> {
    let status = python()
        .arg(elf)
        .arg("profile")
        .arg(kernel)
        .status()
        .context("running insns/count.py")?;
    if !status.success() {
        bail!("insns/count.py profile failed ({status})");
    }
    Ok(())
}

/// Instructions of one `servo_period` per part of the period (estimators, reference,
/// checks, coupling, laws, the servo's own body), attributed from the DWARF inline tree of
/// the real optimised `Servo::period`: the parts add up to the `servo_period` count.
fn parts(elf: &Path) -> Result<()> {
    let status = python()
        .arg(elf)
        .arg("parts")
        .arg("servo_period")
        .status()
        .context("running insns/count.py")?;
    if !status.success() {
        bail!("insns/count.py parts failed ({status})");
    }
    Ok(())
}

/// A closed-loop recording: the f64 paper plant driven by the f32 controller from
/// `REPLAY_T0_S` on, with quantised positions and backward-difference velocities, as
/// the discrete scenario measures them. Returns `REPLAY_IN` f32 per step.
fn record_inputs() -> Result<Vec<f32>> {
    let mut g = Controller3::<f32>::new(&paper_dsmc_config())
        .map_err(|e| anyhow::anyhow!("paper DSMC configuration rejected: {e}"))?;
    let traj = Trajectory::<f64>::paper_helix();
    let traj32 = traj.cast::<f32>();
    let axis = DisturbedPaperAxis {
        axis: PaperAxis::<f64>::from_params(PAPER_PLANT),
        d_step: 0.0,
        t_dist: f64::INFINITY,
    };
    let plants = [axis; 3];
    let dt = KERNEL_PERIOD_S as f64;
    // start on the path, slightly off, so every error is non-zero from the first step
    let r0 = traj.sample(REPLAY_T0_S);
    let mut plant: [AxisState<f64>; 3] = core::array::from_fn(|i| AxisState {
        pos: r0.pos[i] - 3e-3 * (i as f64 + 1.0),
        vel: r0.vel[i],
    });
    let q = |v: f64| (v / REPLAY_QUANTUM).round() * REPLAY_QUANTUM;
    let mut prev: Option<Vec3<f64>> = None;
    let mut rec = Vec::with_capacity(REPLAY_STEPS * REPLAY_IN);
    for k in 0..REPLAY_STEPS {
        let t = REPLAY_T0_S + k as f64 * dt;
        let pos = Vec3::new(q(plant[0].pos), q(plant[1].pos), q(plant[2].pos));
        let vel = match prev {
            Some(p) => (pos - p).scale(1.0 / dt),
            None => Vec3::new(plant[0].vel, plant[1].vel, plant[2].vel),
        };
        prev = Some(pos);
        let inp = [
            t as f32,
            pos.x as f32,
            pos.y as f32,
            pos.z as f32,
            vel.x as f32,
            vel.y as f32,
            vel.z as f32,
        ];
        rec.extend_from_slice(&inp);
        let meas = Measured {
            pos: Vec3::new(inp[1], inp[2], inp[3]),
            vel: Vec3::new(inp[4], inp[5], inp[6]),
        };
        let out = g.step(&traj32.sample(inp[0]), &meas, KERNEL_PERIOD_S);
        let u = [out.u.x as f64, out.u.y as f64, out.u.z as f64];
        rk4_step(&plants, &mut plant, t, dt, |_, _| u);
    }
    Ok(rec)
}

fn host_outputs<R: RawBits>(inputs: &[f32]) -> Vec<u64> {
    let mut out = vec![0u64; REPLAY_STEPS * REPLAY_OUT];
    let n = replay::<R>(inputs, &mut out);
    out.truncate(n * REPLAY_OUT);
    out
}

/// Replay the recorded sequence on the host and on every ELF (the Cortex-M4F, then the
/// Cortex-M3 with soft float); fail on the first differing bit.
fn bitexact(elfs: &[PathBuf]) -> Result<()> {
    let inputs = record_inputs()?;
    let dir = std::env::temp_dir().join(format!("insns-bitexact-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let in_path = dir.join("inputs.bin");
    let bytes: Vec<u8> = inputs.iter().flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(&in_path, bytes)?;
    let cases: [(&str, Vec<u64>); 4] = [
        ("fixed", host_outputs::<FxQ32>(&inputs)),
        ("fixed_q16", host_outputs::<FxQ16>(&inputs)),
        ("f32", host_outputs::<f32>(&inputs)),
        ("f32_libm", host_outputs::<LibmF32>(&inputs)),
    ];
    let mut failed = 0;
    let runs = elfs.iter().enumerate().flat_map(|(k, elf)| {
        // kernel-name suffix and core of each ELF (the board's first)
        let (suffix, core) = if k == 0 {
            ("", "cortex-m4")
        } else {
            ("_m3", "cortex-m3")
        };
        cases
            .iter()
            .map(move |(name, host)| (elf, suffix, core, *name, host))
    });
    for (elf, suffix, core, name, host) in runs {
        if host.len() != REPLAY_STEPS * REPLAY_OUT {
            bail!("host replay of {name} ran {} values", host.len());
        }
        let out_path = dir.join(format!("{name}{suffix}.out"));
        let status = python()
            .arg(elf)
            .args(["replay", name])
            .arg(&in_path)
            .arg(REPLAY_STEPS.to_string())
            .arg(&out_path)
            .status()
            .context("running insns/count.py replay")?;
        if !status.success() {
            bail!("emulated replay of {name} failed ({status})");
        }
        let raw = std::fs::read(&out_path)?;
        let target: Vec<u64> = raw
            .chunks_exact(8)
            .map(|c| u64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
            .collect();
        let first_diff = host.iter().zip(&target).position(|(a, b)| a != b);
        match (target.len() == host.len(), first_diff) {
            (true, None) => println!(
                "bitexact dsmc3_{name}{suffix}: {REPLAY_STEPS} steps x {REPLAY_OUT} outputs identical (host == {core})"
            ),
            (_, d) => {
                failed += 1;
                let i = d.unwrap_or(host.len().min(target.len()));
                println!(
                    "bitexact dsmc3_{name}{suffix}: MISMATCH at step {} output {} (host {:#x}, target {:#x})",
                    i / REPLAY_OUT,
                    i % REPLAY_OUT,
                    host.get(i).copied().unwrap_or(0),
                    target.get(i).copied().unwrap_or(0)
                );
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    if failed > 0 {
        bail!("{failed} kernel(s) differ between host and target");
    }
    // a replay that exercised nothing would prove nothing
    let sample = host_outputs::<FxQ32>(&inputs);
    let nonzero_u = sample
        .chunks_exact(REPLAY_OUT)
        .filter(|r| r[0] != 0 && r[3] != 0)
        .count();
    if nonzero_u < REPLAY_STEPS / 2 {
        bail!("the recorded sequence did not exercise the law ({nonzero_u} active steps)");
    }
    Ok(())
}
