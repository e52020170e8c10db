//! The window without a screen (egui_kittest, through its accessibility tree) on the
//! simulated gantry served in real time: the operator's path through it, clicked as a
//! person would: the program loads and its path shows, Home homes, Run runs the program
//! to its end with the trail and the report, and what the read-out says.

use controller_core::machine::messages::MachineState;
use egui_kittest::kittest::Queryable;
use egui_kittest::Harness;
use gantry_gui::app::{GantryApp, Script};
use gantry_gui::served::Served;
use host_sim::cli::machine::MachineArgs;
use std::time::{Duration, Instant};

/// Frames until `done` holds (real time passes: the machine is served in real time).
fn until(
    h: &mut Harness<'_, GantryApp>,
    what: &str,
    limit: Duration,
    done: impl Fn(&GantryApp) -> bool,
) {
    let t0 = Instant::now();
    while !done(h.state()) {
        assert!(
            t0.elapsed() < limit,
            "{what}: not within {limit:?}; busy {:?}, status {:?}, log: {:?}",
            h.state().busy,
            h.state().live.status.as_ref().map(|s| (
                s.state,
                s.homed,
                s.progress,
                s.first_fault.clone()
            )),
            h.state().log
        );
        assert!(
            h.state().lost.is_none(),
            "session lost: {:?}",
            h.state().lost
        );
        h.step();
        std::thread::sleep(Duration::from_millis(15));
    }
}

#[test]
fn the_operator_homes_and_runs_a_program_by_clicking() {
    let dir = std::env::temp_dir().join(format!("gantry-gui-headless-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    // a circle of 10 mm radius about the origin and a rapid back: 3-4 s of machine time
    let program = dir.join("circle.nc");
    std::fs::write(
        &program,
        "G21 G90\nG0 X10 Y0\nG2 X10 Y0 I-10 J0 F1200\nG0 X0 Y0\nM2\n",
    )
    .expect("write the program");

    let sim = MachineArgs {
        sim: true,
        telemetry_hz: 1000,
        ..MachineArgs::default()
    };
    let (_served, args) = Served::start(&sim).expect("serve the simulated gantry");
    let app = GantryApp::new(
        args,
        Script {
            program: Some(program.clone()),
            ..Script::default()
        },
        || {},
    );
    let mut h = Harness::builder()
        .with_size(egui::vec2(1400.0, 900.0))
        .build_ui_state(|ui, app: &mut GantryApp| app.frame(ui), app);

    until(
        &mut h,
        "connected, program loaded",
        Duration::from_secs(20),
        |a| a.connected && a.program.is_some() && a.live.status.is_some() && a.busy.is_none(),
    );
    let p = h.state().program.as_ref().expect("loaded");
    assert_eq!(p.moves.len(), 3, "{:?}", p.moves);
    // the machine starts disarmed: Arm is offered, Reset is not (no fault latched)
    assert_eq!(
        h.state().live.status.as_ref().map(|s| s.state),
        Some(MachineState::Disabled)
    );
    h.get_by_label("Home").click();
    h.step();
    until(&mut h, "homed", Duration::from_secs(120), |a| {
        a.busy.is_none() && a.live.status.as_ref().is_some_and(|s| s.homed == 0b111)
    });
    assert!(
        h.state().log.iter().any(|l| l.starts_with("homed: X")),
        "{:?}",
        h.state().log
    );

    h.get_by_label("Run").click();
    h.step();
    until(&mut h, "program run", Duration::from_secs(60), |a| {
        a.report.is_some() && a.busy.is_none()
    });
    let app = h.state();
    let r = app.report.as_ref().expect("report");
    assert_eq!(r.status, "completed", "{:?}", app.log);
    // the simulated gantry follows a 10 mm circle at 20 mm/s within 10 µm
    assert!(
        r.contour_max_mm < 0.010,
        "contour max {} mm",
        r.contour_max_mm
    );
    // the trail: every sample of the run at 1 kHz (the run lasts > 3 s)
    assert!(
        app.live.trail.len() > 3_000,
        "{} trail points",
        app.live.trail.len()
    );
    // the circle in it: 62.8 mm at 20 mm/s, 3.1 s of samples on the 10 mm radius
    let on_circle = app
        .live
        .trail
        .iter()
        .filter(|t| (t.pos_mm[0].hypot(t.pos_mm[1]) - 10.0).abs() < 0.01)
        .count();
    assert!(on_circle > 2_800, "{on_circle} trail points on the circle");
    assert_eq!(gantry_gui::panels::controls::progress(app), Some(1.0));
    // back at the origin, armed, no fault: the read-out says so
    let s = app.live.status.as_ref().expect("status");
    assert_eq!(s.state, MachineState::Idle);
    assert!(s.first_fault.is_none());
    h.get_by_label("IDLE");
    assert!(h.query_all_by_label_contains("contour max").count() >= 1);
}
