//! What an operator reads: `gantry status` as one screen with units, and `gantry watch`'s
//! one-line digital read-out (state, position, feed, program place, faults), both from
//! the machine's [`Status`] (the link's reply to every real-time request).

use controller_core::machine::messages::{MachineState, ProgramEnd, Status};
use controller_core::machine::scope::ScopeState;

use super::{program_end_name, AXES};

/// The state in words: what the outputs do, and what the operator can do next.
pub fn state_words(s: &Status) -> String {
    match s.state {
        MachineState::Disabled => "Disabled (outputs off: `gantry arm` to hold position)".into(),
        MachineState::Idle => "Idle (armed, holding position)".into(),
        MachineState::Jog => "Jog (outputs on, jogging)".into(),
        MachineState::Homing => format!("Homing ({:.0} %)", 100.0 * s.progress.clamp(0.0, 1.0)),
        MachineState::Run { held: false } => "Run (running a program)".into(),
        MachineState::Run { held: true } => "Run, feed hold (`r` resumes)".into(),
        MachineState::Identify => format!("Identify ({:.0} %)", 100.0 * s.progress.clamp(0.0, 1.0)),
        MachineState::Stopping => "Stopping (decelerating, then outputs off)".into(),
        MachineState::EncoderCheck => {
            "EncoderCheck (checking the encoders before the reset)".into()
        }
        MachineState::Fault => "Fault (outputs off: `gantry reset` once the cause is gone)".into(),
    }
}

/// The axes whose bit is set in `mask`, as `x y`; `none` for none.
fn axes_of(mask: u8) -> String {
    let named: Vec<&str> = AXES
        .iter()
        .enumerate()
        .filter(|(i, _)| mask & (1 << i) != 0)
        .map(|(_, a)| *a)
        .collect();
    if named.is_empty() {
        "none".into()
    } else {
        named.join(" ")
    }
}

fn xyz(v: [f32; 3], decimals: usize) -> String {
    format!(
        "x {:>9.d$}  y {:>9.d$}  z {:>9.d$}",
        v[0],
        v[1],
        v[2],
        d = decimals
    )
}

/// The fault history kept across resets, oldest first: `estop`, `following_error on x`.
pub fn fault_history(s: &Status) -> Vec<String> {
    s.fault_history
        .iter()
        .map(|f| {
            let kind = f.kind().map_or("unknown", |k| k.name());
            match f.axis() {
                Some(a) => format!("{kind} on {}", a.name()),
                None => kind.to_string(),
            }
        })
        .collect()
}

/// The faults: the first of the latched ones (it names the cause), and the history kept
/// across resets, oldest first.
fn faults(s: &Status) -> (String, String) {
    let latched = match (&s.first_fault, s.state) {
        (Some(f), _) => f.to_string(),
        (None, MachineState::Fault) => "latched (kind unknown to this host)".into(),
        (None, _) => "none".into(),
    };
    let history = fault_history(s);
    let history = if history.is_empty() {
        "none".into()
    } else {
        history.join(", ")
    };
    (latched, history)
}

/// The feed: the speed along the path, mm/min (as G-code's F), from the axes' velocities.
pub fn feed_mm_min(s: &Status) -> f32 {
    let v = s.vel_mm_s;
    60.0 * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn program(s: &Status) -> String {
    match s.program.end {
        ProgramEnd::None => "none since power-on".into(),
        ProgramEnd::Running => format!(
            "running, segment {} ({} queued, {} planner slots free)",
            s.program.tag, s.queued, s.planner_free
        ),
        end => format!(
            "{} (last segment {})",
            program_end_name(end).replace('_', " "),
            s.program.tag
        ),
    }
}

/// `gantry status`: one screen, every value with its unit.
pub fn status_text(s: &Status, rate_hz: u32) -> String {
    let (latched, history) = faults(s);
    let mut out = String::new();
    let mut line = |k: &str, v: String| out.push_str(&format!("{k:<11}{v}\n"));
    line("state", state_words(s));
    line(
        "position",
        format!("{} mm (machine coordinates)", xyz(s.pos_mm, 3)),
    );
    line("velocity", format!("{} mm/s", xyz(s.vel_mm_s, 3)));
    line("feed", format!("{:.0} mm/min", feed_mm_min(s)));
    line(
        "homed",
        format!(
            "{}{}",
            axes_of(s.homed),
            if s.homed == 0b111 {
                ""
            } else {
                "  (`gantry home` homes the rest)"
            }
        ),
    );
    if s.model_missing != 0 {
        line(
            "no model",
            format!(
                "{}  (nothing can arm: `gantry identify --axis {} --window-mm 10 --accept`)",
                axes_of(s.model_missing),
                AXES[s.model_missing.trailing_zeros().min(2) as usize]
            ),
        );
    }
    if s.comp != 0 {
        line(
            "comp",
            format!(
                "{}  (backlash / lead-screw tables in use: `gantry comp show AXIS`)",
                axes_of(s.comp)
            ),
        );
    }
    line("fault", latched);
    line("history", format!("{history} (kept across resets)"));
    line("program", program(s));
    if let Some(id) = &s.identify {
        line(
            "identified",
            format!(
                "axis {}: {} (NRMSE {:.4}, R² {:.4}, {:.2} s)",
                AXES.get(usize::from(id.axis)).copied().unwrap_or("?"),
                if id.done && id.model.is_some() {
                    "model found"
                } else {
                    "no model"
                },
                id.nrmse,
                id.r2,
                id.time_s
            ),
        );
    }
    let scope = match s.scope {
        ScopeState::Off => "off",
        ScopeState::Waiting => "waiting for its trigger",
        ScopeState::Triggered => "triggered, recording",
        ScopeState::Done => "capture ready",
    };
    line("scope", scope.into());
    line(
        "clock",
        format!(
            "period {} ({:.3} s of machine time at {} Hz)",
            s.period,
            f64::from(s.period) / f64::from(rate_hz.max(1)),
            rate_hz
        ),
    );
    out
}

/// `gantry watch`: one line, about 100 characters.
pub fn dro_line(s: &Status) -> String {
    let state = match s.state {
        MachineState::Run { held: true } => "Hold".to_string(),
        MachineState::Run { held: false } => "Run".to_string(),
        other => format!("{other:?}"),
    };
    let (latched, _) = faults(s);
    let place = match s.program.end {
        ProgramEnd::Running => format!("seg {}", s.program.tag),
        _ => "-".into(),
    };
    format!(
        "{state:<12} X {:>9.3} Y {:>9.3} Z {:>9.3} mm  F {:>6.0} mm/min  {place:<10} fault {latched}",
        s.pos_mm[0],
        s.pos_mm[1],
        s.pos_mm[2],
        feed_mm_min(s),
    )
}

/// A fault's name (`following_error`, as the link and `first_fault` spell it; `… on x`
/// allowed) in plain words with what to do about it; the name itself for one this host
/// does not know.
pub fn fault_words(name: &str) -> String {
    let (kind, axis) = match name.split_once(" on ") {
        Some((k, a)) => (k, Some(a)),
        None => (name, None),
    };
    let what = match kind {
        "estop" => "emergency stop pressed (or its wire broken): release it, then reset",
        "limit_min" | "limit_max" => {
            "a limit switch is pressed: reset, then jog off the switch (docs/bring-up.md)"
        }
        "amplifier_fault" => "the servo amplifier reports a fault: check it and its supply",
        "encoder_stuck" => "the encoder stopped counting while the axis had to move: check its cable",
        "encoder_jump" => {
            "the encoder count jumped further than the axis can move: noise or a reversed encoder (axis.<a>.encoder.invert)"
        }
        "encoder_runaway" => {
            "the axis sped up against its effort: motor or encoder reversed (axis.<a>.motor.invert)"
        }
        "non_finite" => "the control law's output was not a number: check the axis model and gains",
        "following_error" => {
            "the axis fell behind its reference beyond the following-error limit: load, friction or gains"
        }
        "overspeed" => "the axis moved faster than its maximum speed",
        "deadline_overrun" => "the control interrupt missed its deadline too often",
        "link_lost" => "the host link went silent (no heartbeat)",
        "config_invalid" => "the settings were rejected at boot: outputs stay off",
        "clock_fault" => "the board's crystal failed: its timing is not trustworthy",
        "soft_limit" => "a reference left the axis' travel",
        "homing_failed" => "homing did not find (or could not leave) the switch or the index",
        "settings_corrupt" => "the settings store was unreadable at boot: factory settings are in use",
        "encoder_index" => "the count at an index pulse was off: counts lost (coupling slip, bad disk)",
        "board_config" => "the board's peripherals are not configured as expected",
        other => return other.to_string(),
    };
    match axis {
        Some(a) => format!("{a}: {what}"),
        None => what.to_string(),
    }
}
