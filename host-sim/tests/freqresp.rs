//! `host-sim freqresp` on the simulated gantries: each axis' frequency response measured
//! through the servo step (MeasureResponse from Disabled, ±50 mm window, the study's
//! imperfections: ±1 count of encoder noise, one period of command delay) and its modes.
//!
//! - The flexible gantry (host-sim/machines/gantry_flexible.toml): one resonance per axis
//!   within 3 % of the machine file's `frame.mode_hz`, its damping within 30 % of the
//!   damping that mode has on that machine: the linear two-mass model's exact pole, the
//!   frame's `damping_ratio` plus what the guides' share of the viscous friction adds
//!   (32-84 % more on this machine: `studies::freqresp::model_mode`); the anti-resonance
//!   within 3 % of `√(k/J_t)`.
//! - The same machine with the guides' friction on the motor side and no backlash: the
//!   mode is the frame's alone, and its damping within 30 % of `frame.damping_ratio`.
//! - The rigid gantry (host-sim/machines/gantry.toml): no resonance, no anti-resonance.
//! - Every run: the axis never leaves its window, the effort never exceeds the cap.
//!
//! Release-mode: `cargo test -p host-sim --release --test sim_tests freqresp::` (about 10 s).

use host_sim::studies::freqresp::{run, AxisResponse, FreqRespReport, WINDOW_HALF_MM};
use std::path::{Path, PathBuf};

fn machine(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("machines")
        .join(name)
}

/// Every axis ended by itself, inside its window and under its cap.
fn check_bounds(r: &FreqRespReport) {
    for (name, a) in &r.axes {
        assert_eq!(a.status, "done", "axis {name}");
        let b = a.bounds.expect("the study sees every period");
        assert!(
            b.travel_max_mm <= f64::from(WINDOW_HALF_MM),
            "axis {name}: {} mm from the start, window ±{WINDOW_HALF_MM}",
            b.travel_max_mm
        );
        assert!(
            b.effort_max_mnm <= b.torque_cap_mnm,
            "axis {name}: {} mN·m, cap {}",
            b.effort_max_mnm,
            b.torque_cap_mnm
        );
        // the lowest frequencies still show the rigid body: a few per cent of the inertia
        assert!(
            a.points.len() == 64,
            "axis {name}: {} points",
            a.points.len()
        );
    }
}

fn show(r: &FreqRespReport) {
    println!("{}", host_sim::studies::freqresp::table(r));
}

/// The one resonance of `a` near the machine's mode.
fn resonance<'a>(name: &str, a: &'a AxisResponse) -> &'a host_sim::studies::freqresp::ModeJson {
    assert_eq!(a.resonances.len(), 1, "axis {name}: {:?}", a.resonances);
    &a.resonances[0]
}

#[test]
fn the_flexible_gantrys_modes_are_measured_within_3_percent_and_their_damping_within_30() {
    let r = run(Some(&machine("gantry_flexible.toml"))).unwrap();
    show(&r);
    check_bounds(&r);
    for (name, a) in &r.axes {
        let m = a.machine.expect("a frame");
        let res = resonance(name, a);
        let f_err = (res.freq_hz / m.mode_hz - 1.0).abs();
        assert!(
            f_err < 0.03,
            "axis {name}: {} Hz vs {} Hz",
            res.freq_hz,
            m.mode_hz
        );
        let z_err = (res.damping_ratio / m.model_damping_ratio - 1.0).abs();
        assert!(
            z_err < 0.30,
            "axis {name}: ζ {} vs {} (frame {})",
            res.damping_ratio,
            m.model_damping_ratio,
            m.damping_ratio
        );
        // the guides' viscous friction damps the mode beyond the frame's own damping
        assert!(res.damping_ratio > m.damping_ratio, "axis {name}");
        assert!(res.peak_db > 0.5, "axis {name}: {res:?}");
        assert_eq!(
            a.anti_resonances.len(),
            1,
            "axis {name}: {:?}",
            a.anti_resonances
        );
        let anti = &a.anti_resonances[0];
        let a_err = (anti.freq_hz / m.anti_resonance_hz - 1.0).abs();
        assert!(
            a_err < 0.03,
            "axis {name}: {anti:?} vs {} Hz",
            m.anti_resonance_hz
        );
        assert!(anti.freq_hz < res.freq_hz, "axis {name}");
        // the loop's one period of delay, seen in the phase
        assert!(
            (a.delay_s / 1e-4 - 1.0).abs() < 0.3,
            "axis {name}: {} s",
            a.delay_s
        );
    }
}

#[test]
fn without_the_guides_friction_and_backlash_the_frames_own_damping_is_measured() {
    let text = std::fs::read_to_string(machine("gantry_flexible.toml")).unwrap();
    // the guides' friction moved to the motor side (a nut without play needs no preload)
    let text = text
        .replace(
            "tool_inertia_ratio =",
            "tool_friction_ratio = 0.0, tool_inertia_ratio =",
        )
        .replace("backlash_mm = 0.02", "backlash_mm = 0.0");
    assert_eq!(text.matches("tool_friction_ratio = 0.0").count(), 3);
    let path =
        std::env::temp_dir().join(format!("freqresp_frame_only_{}.toml", std::process::id()));
    std::fs::write(&path, text).unwrap();
    let r = run(Some(&path));
    let _ = std::fs::remove_file(&path);
    let r = r.unwrap();
    show(&r);
    check_bounds(&r);
    for (name, a) in &r.axes {
        let m = a.machine.expect("a frame");
        let res = resonance(name, a);
        assert!(
            (res.freq_hz / m.mode_hz - 1.0).abs() < 0.03,
            "axis {name}: {res:?}"
        );
        let z_err = (res.damping_ratio / m.damping_ratio - 1.0).abs();
        assert!(
            z_err < 0.30,
            "axis {name}: ζ {} vs the frame's {}",
            res.damping_ratio,
            m.damping_ratio
        );
    }
}

#[test]
fn the_rigid_gantry_shows_no_resonance() {
    let r = run(Some(&machine("gantry.toml"))).unwrap();
    show(&r);
    check_bounds(&r);
    for (name, a) in &r.axes {
        assert!(a.machine.is_none(), "axis {name}");
        assert!(a.resonances.is_empty(), "axis {name}: {:?}", a.resonances);
        assert!(
            a.anti_resonances.is_empty(),
            "axis {name}: {:?}",
            a.anti_resonances
        );
        // the rigid-body line: the machine file's inertia within 2 %
        let j = match name.as_str() {
            "x" => 0.064,
            "y" => 0.18,
            _ => 0.041,
        };
        assert!(
            (a.inertia / j - 1.0).abs() < 0.02,
            "axis {name}: J {}",
            a.inertia
        );
    }
}
