//! Checks of a machine description (`machine.*` of a scenario, usually included from
//! `host-sim/machines/*.toml`) before anything is built from it.
//!
//! Two kinds of value, one rule each:
//!
//! - **values a setting also holds** (encoder scale, amplifier full scale, the fault
//!   checks' limits, travel, homing, jog): checked by the settings themselves. The
//!   machine's values are written into the factory settings tree, axis by axis, and
//!   [`Settings::validate`] runs: the keys' ranges (`controller_core::settings::keys`) and
//!   every cross-field rule of the settings (following error at speed ≥ at rest, home
//!   inside the travel, planner speed ≤ overspeed limit, …). There is no second copy of
//!   those rules here, only the map between a machine-file field and its settings key.
//! - **values no setting holds** (the simulated plant, amplifier resolution, control rate,
//!   plant steps): the named physical ranges of [`PHYSICAL_RANGES`], each with its reason.
//!
//! The settings describe a physical machine (mm, mN·m): an axis with the paper's
//! normalised plant (`plant.paper`, unit-less lengths) is a study's, not a machine's, and
//! only its physical ranges apply.
//!
//! Parts a study leaves at their "off" default are not settings of a machine and are not
//! checked as such: the fault checks all off ([`AxisSafetyConfig::OFF`], the schema's
//! default), unlimited travel, no homing, an ideal amplifier (`full_scale = inf`,
//! `resolution_bits = 0`). A value written half-way (one limit infinite, the others not)
//! is checked and refused.

use crate::schema::{AxisSpec, MachineSpec};
use controller_core::servo::monitor::AxisSafetyConfig;
use controller_core::servo::travel::AxisTravel;
use controller_core::settings::{SetError, Settings, FACTORY};
use controller_core::sim::world::PlantConfig;

/// A physical range of a value no setting holds (bounds included).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhysicalRange {
    /// Field path under `machine.axes.<a>.` (or under `machine.` for machine-wide ones).
    pub field: &'static str,
    pub min: f64,
    pub max: f64,
    pub unit: &'static str,
    /// Why these bounds.
    pub reason: &'static str,
}

const fn range(
    field: &'static str,
    min: f64,
    max: f64,
    unit: &'static str,
    reason: &'static str,
) -> PhysicalRange {
    PhysicalRange {
        field,
        min,
        max,
        unit,
        reason,
    }
}

/// Every value of a machine file that has no setting, with its physical range: the one
/// place these bounds live.
pub const PHYSICAL_RANGES: &[PhysicalRange] = &[
    range("rate_hz", 1_000.0, 50_000.0, "Hz", "the control rates the firmware and the studies run (1-20 kHz; 50 kHz is the settings' highest tested rate)"),
    range("plant_substeps", 1.0, 64.0, "", "RK4 steps per period: 1 is the coarsest, more than 64 buys no accuracy and only time"),
    range("plant.physical.inertia", 1e-4, 100.0, "mN·m/(mm/s²)", "a 12 g slide to a 12 t gantry on a 5 mm lead (the gantry's: 0.041..0.18); below, the model's 1/J overflows the laws' f32"),
    range("plant.physical.viscous", 0.0, 100.0, "mN·m/(mm/s)", "from none to 400 times the gantry's Y axis (0.40)"),
    range("plant.physical.coulomb_pos_mnm", 0.0, 10_000.0, "mN·m", "forward friction opposes forward motion (>= 0), at most 10 N·m (ten times the gantry's motors' peak torque)"),
    range("plant.physical.coulomb_neg_mnm", -10_000.0, 0.0, "mN·m", "reverse friction opposes reverse motion (<= 0), at most 10 N·m"),
    range("plant.physical.stiction_ratio", 1.0, 5.0, "", "breakaway over Coulomb friction: 1 (no Stribeck peak) to 5 (far above the 1.3-2 of ball screws)"),
    range("plant.physical.v_stribeck_mm_s", 1e-3, 1_000.0, "mm/s", "the Stribeck velocity of lubricated contacts is µm/s to mm/s; above 1 m/s it is no peak"),
    range("plant.physical.v_reg_mm_s", 1e-6, 100.0, "mm/s", "regularisation of the friction sign: positive (a zero divides), far below any feed"),
    range("plant.physical.load_const_mnm", -100_000.0, 100_000.0, "mN·m", "a constant load within the largest effort of the machine class (100 N·m)"),
    range("plant.physical.load_step_mnm", -100_000.0, 100_000.0, "mN·m", "a load step within the largest effort of the machine class (100 N·m)"),
    range("plant.physical.torque_max_mnm", 1.0, 100_000.0, "mN·m", "a motor's peak torque, within the settings' effort range (1 mN·m..100 N·m)"),
    range("plant.physical.frame.mode_hz", 1.0, 2_000.0, "Hz", "a machine's structural modes: a slender beam's few Hz to a stiff spindle head's kHz (and the plant step must resolve it)"),
    range("plant.physical.frame.damping_ratio", 0.0, 1.0, "", "structures are lightly damped (0.01-0.1); 1 is critical"),
    range("plant.physical.frame.tool_inertia_ratio", 0.01, 0.99, "", "the tool side's share of the axis' inertia: both sides have mass"),
    range("plant.physical.frame.tool_friction_ratio", 0.0, 1.0, "", "the guides' share of the axis' friction: none to all"),
    range("plant.physical.frame.backlash_mm", 0.0, 1.0, "mm", "from none (preloaded nut) to 1 mm (a worn lead screw)"),
    range("plant.physical.frame.pitch_error.cumulative_um_per_m", -1_000.0, 1_000.0, "µm/m", "ISO 3408-3 tolerance classes span 6 to 210 µm per 300 mm; 1 mm/m is far beyond any screw"),
    range("plant.physical.frame.pitch_error.periodic_um", -1_000.0, 1_000.0, "µm", "the periodic lead variation, at most 1 mm"),
    range("plant.physical.frame.pitch_error.period_mm", 0.1, 10_000.0, "mm", "a lead (a few mm) to a whole screw's length"),
    range("plant.paper.a", -1e6, 1e6, "1/s", "the paper's normalised axis: any finite coefficient an f32 law can carry"),
    range("plant.paper.b", -1e6, 1e6, "1/s²", "the paper's normalised axis: any finite coefficient an f32 law can carry"),
    range("plant.paper.k", 1e-6, 1e6, "", "input gain: positive (the laws assume it), finite"),
    range("amplifier.resolution_bits", 8.0, 24.0, "bits", "0 is the ideal amplifier; a real one resolves at least 8 bits (a 1-bit one is a bang-bang switch) and at most 24 (no PWM timer or DAC resolves more)"),
    range("brake.holding_mnm", 0.0, 100_000.0, "mN·m", "the simulated brake's static torque: none (0) up to the largest effort of the machine class (100 N·m); positive when the brake is present"),
    range("initial.pos_mm", -10_000.0, 10_000.0, "mm", "any gantry's travel (the settings' length range, ±10 m)"),
    range("initial.vel_mm_s", -10_000.0, 10_000.0, "mm/s", "the settings' speed range (10 m/s)"),
];

fn physical(field: &str) -> Option<&'static PhysicalRange> {
    PHYSICAL_RANGES.iter().find(|r| r.field == field)
}

/// `value` of `field` (an axis' when `axis` is given) within its physical range.
fn check_physical(axis: Option<&str>, field: &str, value: f64) -> Result<(), String> {
    let Some(r) = physical(field) else {
        return Ok(());
    };
    // (written so that NaN fails)
    if value >= r.min && value <= r.max {
        return Ok(());
    }
    let path = match axis {
        Some(a) => format!("machine.axes.{a}.{field}"),
        None => format!("machine.{field}"),
    };
    Err(format!(
        "`{path}` = {value} is outside its physical range [{}, {}]{}{} ({})",
        r.min,
        r.max,
        if r.unit.is_empty() { "" } else { " " },
        r.unit,
        r.reason
    ))
}

/// The machine-file field (under `machine.axes.<a>.`) of a per-axis settings key suffix
/// (under `axis.<a>.`), for the keys a machine file gives.
fn field_of_key(suffix: &str) -> String {
    match suffix {
        "min_ferror_mm"
        | "vel_max_mm_s"
        | "accel_max_mm_s2"
        | "stop_decel_mm_s2"
        | "stuck_effort_change" => format!("safety.{suffix}"),
        "following_error_mm" => "safety.ferror_mm".into(),
        // capped at the axis' own limit, as the planner is on such a machine
        "planner.vel_max_mm_s" => "safety.vel_max_mm_s".into(),
        other => other.into(),
    }
}

/// A settings error in the machine file's terms: the field path, the value and the
/// allowed range, or the rule the axis' values break together.
fn describe(axis: &str, e: &SetError) -> String {
    match e {
        SetError::OutOfRange {
            key,
            value,
            range,
            unit,
        } => {
            let (path, via) = match key.strip_prefix(&format!("axis.{axis}.")[..]) {
                Some(suffix) => (
                    format!("machine.axes.{axis}.{}", field_of_key(suffix)),
                    *key,
                ),
                None if *key == "jog.timeout_s" => ("machine.jog_timeout_s".into(), *key),
                None => (format!("machine ({key})"), *key),
            };
            format!(
                "`{path}` = {value} is outside the allowed range {range}{}{} (the range of \
                 the setting {via})",
                if unit.is_empty() { "" } else { " " },
                unit
            )
        }
        SetError::Tree(t) => format!(
            "`machine.axes.{axis}`: its values are each in range but not valid together \
             (the settings' rule): {t}"
        ),
        other => format!("`machine.axes.{axis}`: {other}"),
    }
}

/// Write the parts of `a` that a setting holds into the settings' axis `i`.
fn write_axis(s: &mut Settings, i: usize, a: &AxisSpec) {
    let Some(t) = s.axis.get_mut(i) else { return };
    t.encoder.counts_per_mm = a.encoder.counts_per_mm;
    // an ideal amplifier (a study's) has no full scale to check
    if !(a.amplifier.resolution_bits == 0 && a.amplifier.full_scale == f32::INFINITY) {
        t.amplifier.full_scale = a.amplifier.full_scale;
    }
    if a.safety != AxisSafetyConfig::OFF {
        let f = &a.safety;
        t.vel_max_mm_s = f.vel_max_mm_s;
        t.accel_max_mm_s2 = f.accel_max_mm_s2;
        t.min_ferror_mm = f.min_ferror_mm;
        t.following_error_mm = f.ferror_mm;
        t.stuck_effort_change = f.stuck_effort_change;
        t.stop_decel_mm_s2 = f.stop_decel_mm_s2;
        // the planner never commands more than the axis' limit on this machine
        // (host-sim's `machine_and_planner` caps it the same way)
        if f.vel_max_mm_s < t.planner.vel_max_mm_s {
            t.planner.vel_max_mm_s = f.vel_max_mm_s;
        }
    }
    if a.travel != AxisTravel::UNLIMITED {
        t.travel = a.travel;
    }
    if a.homing.enabled {
        t.homing = a.homing;
    } else {
        t.homing.enabled = false;
    }
    t.jog = a.jog;
    // the brake's timings are settings (`axis.<a>.brake.*`): their ranges and the servo's
    // own check apply
    t.brake = a.brake.servo();
}

/// Check machine `m` (see the module docs); the error names the field, its value and the
/// allowed range. Changes nothing.
pub fn check(m: &MachineSpec) -> Result<(), String> {
    check_physical(None, "rate_hz", f64::from(m.rate_hz))?;
    check_physical(None, "plant_substeps", f64::from(m.plant_substeps))?;
    let names = ["x", "y", "z"];
    for (a, name) in m.axes.iter().zip(names) {
        let n = Some(name);
        match &a.plant {
            PlantConfig::Physical(p) => {
                for (field, v) in [
                    ("inertia", p.inertia),
                    ("viscous", p.viscous),
                    ("coulomb_pos_mnm", p.coulomb_pos_mnm),
                    ("coulomb_neg_mnm", p.coulomb_neg_mnm),
                    ("stiction_ratio", p.stiction_ratio),
                    ("v_stribeck_mm_s", p.v_stribeck_mm_s),
                    ("v_reg_mm_s", p.v_reg_mm_s),
                    ("load_const_mnm", p.load_const_mnm),
                    ("load_step_mnm", p.load_step_mnm),
                    ("torque_max_mnm", p.torque_max_mnm),
                ] {
                    check_physical(n, &format!("plant.physical.{field}"), f64::from(v))?;
                }
                if let Some(f) = &p.frame {
                    let e = &f.pitch_error;
                    for (field, v) in [
                        ("mode_hz", f.mode_hz),
                        ("damping_ratio", f.damping_ratio),
                        ("tool_inertia_ratio", f.tool_inertia_ratio),
                        ("tool_friction_ratio", f.tool_friction_ratio),
                        ("backlash_mm", f.backlash_mm),
                        ("pitch_error.cumulative_um_per_m", e.cumulative_um_per_m),
                        ("pitch_error.periodic_um", e.periodic_um),
                        ("pitch_error.period_mm", e.period_mm),
                    ] {
                        let key = format!("plant.physical.frame.{field}");
                        check_physical(n, &key, f64::from(v))?;
                    }
                }
            }
            PlantConfig::Paper(p) => {
                for (field, v) in [("a", p.a), ("b", p.b), ("k", p.k)] {
                    check_physical(n, &format!("plant.paper.{field}"), f64::from(v))?;
                }
            }
        }
        if a.amplifier.resolution_bits != 0 {
            check_physical(
                n,
                "amplifier.resolution_bits",
                f64::from(a.amplifier.resolution_bits),
            )?;
        }
        check_physical(n, "brake.holding_mnm", f64::from(a.brake.holding_mnm))?;
        if a.brake.present && !(a.brake.holding_mnm > 0.0) {
            return Err(format!(
                "`machine.axes.{name}.brake.holding_mnm` = {} must be positive when \
                 `brake.present = true` (the simulated brake must hold something)",
                a.brake.holding_mnm
            ));
        }
        check_physical(n, "initial.pos_mm", a.initial.pos_mm)?;
        check_physical(n, "initial.vel_mm_s", a.initial.vel_mm_s)?;
        a.feedforward
            .validate()
            .map_err(|e| format!("`machine.axes.{name}.feedforward`: {e}"))?;
        a.filters
            .validate(1.0 / m.rate_hz.max(1) as f32)
            .map_err(|e| {
                format!(
                    "`machine.axes.{name}.filters`: {e} (at rate_hz = {})",
                    m.rate_hz
                )
            })?;
    }
    // the settings' values, axis by axis, so that a rule broken together names its axis
    let mut s = FACTORY;
    s.jog.timeout_s = m.jog_timeout_s;
    if let Err(e) = s.validate(m.rate_hz) {
        return Err(describe("x", &e));
    }
    for (i, (a, name)) in m.axes.iter().zip(names).enumerate() {
        if !matches!(a.plant, PlantConfig::Physical(_)) {
            continue;
        }
        write_axis(&mut s, i, a);
        s.validate(m.rate_hz).map_err(|e| describe(name, &e))?;
    }
    Ok(())
}
