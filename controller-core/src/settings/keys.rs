//! Dotted keys: every value of the settings tree by name (`axis.x.following_error_mm`,
//! `axis.y.model.inertia`, `coupling.lambda`, `link.watchdog_ms`, ...), with its unit,
//! allowed range, one-line doc and apply class, for the link's settings commands and the
//! `gantry settings` CLI.
//!
//! One table-driven registry: each key is one entry below, whose accessor is generated
//! from the field path, and whose name *is* that field path (so the key, the Rust field
//! and the serde name cannot drift apart). [`Settings::set`] checks the value's type and
//! range, applies it to a copy, validates the whole copy ([`Settings::servo_config`]) and
//! only then replaces the tree: nothing changes on an error.
//!
//! Ranges are plausibility bounds for a machine of this class (they catch typos and unit
//! slips, e.g. metres for millimetres); the relations between values (following error at
//! speed ≥ at rest, home inside the travel, estimator stable at the control rate, ...) are
//! the servo's own checks, run on every change.

use core::fmt;

use crate::axes::{Axis, AXES};
use crate::link::watchdog::{MAX_WATCHDOG_TIMEOUT_MS, MIN_WATCHDOG_TIMEOUT_MS};
use crate::motion::homing::HomeDirection;
use crate::motion::shaper::ShaperKind;

use super::offsets::{TOOL_COUNT, WORK_SYSTEMS};
use super::servo_config::{ServoConfigError, PLACEHOLDER_MODELS};
use super::tree::{AxisSettings, CouplingKind, FilterKind, LawKind, Settings};

/// A setting's value. Choices are the static names of [`Range::Choice`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Value {
    F32(f32),
    Bool(bool),
    U32(u32),
    /// One of a key's named choices (`"dsmc"`, `"contour"`, `"min"`).
    Choice(&'static str),
}

impl Value {
    /// Bit-identical (f32 compared by bits, so NaN equals itself and 0.0 differs from -0.0).
    pub fn same(&self, other: &Value) -> bool {
        match (self, other) {
            (Self::F32(a), Self::F32(b)) => a.to_bits() == b.to_bits(),
            (a, b) => a == b,
        }
    }
}

impl fmt::Display for Value {
    /// The text [`Range::parse`] reads back to the same value (f32: the shortest text that
    /// round-trips).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::F32(v) => write!(f, "{v}"),
            Self::Bool(v) => write!(f, "{v}"),
            Self::U32(v) => write!(f, "{v}"),
            Self::Choice(v) => f.write_str(v),
        }
    }
}

/// The values a key accepts (bounds included).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Range {
    F32 { min: f32, max: f32 },
    U32 { min: u32, max: u32 },
    Bool,
    Choice(&'static [&'static str]),
}

impl Range {
    /// `value` has this range's type and lies within it (NaN never does).
    pub fn admits(&self, value: &Value) -> bool {
        match (self, value) {
            (Self::F32 { min, max }, Value::F32(v)) => *v >= *min && *v <= *max,
            (Self::U32 { min, max }, Value::U32(v)) => *v >= *min && *v <= *max,
            (Self::Bool, Value::Bool(_)) => true,
            (Self::Choice(names), Value::Choice(v)) => names.contains(v),
            _ => false,
        }
    }

    /// `value` has this range's type (whether or not it lies within).
    pub fn fits_type(&self, value: &Value) -> bool {
        matches!(
            (self, value),
            (Self::F32 { .. }, Value::F32(_))
                | (Self::U32 { .. }, Value::U32(_))
                | (Self::Bool, Value::Bool(_))
                | (Self::Choice(_), Value::Choice(_))
        )
    }

    /// Parse the CLI's text (`"1.5"`, `"true"`, `"dsmc"`) as a value of this range's type;
    /// `None` when the text is not such a value (the range itself is checked by `set`).
    pub fn parse(&self, text: &str) -> Option<Value> {
        let t = text.trim();
        match self {
            Self::F32 { .. } => t.parse::<f32>().ok().map(Value::F32),
            Self::U32 { .. } => t.parse::<u32>().ok().map(Value::U32),
            Self::Bool => match t {
                "true" => Some(Value::Bool(true)),
                "false" => Some(Value::Bool(false)),
                _ => None,
            },
            Self::Choice(names) => names.iter().find(|n| **n == t).map(|n| Value::Choice(n)),
        }
    }
}

impl fmt::Display for Range {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::F32 { min, max } => write!(f, "[{min}, {max}]"),
            Self::U32 { min, max } => write!(f, "[{min}, {max}] (integer)"),
            Self::Bool => f.write_str("{true, false}"),
            Self::Choice(names) => {
                f.write_str("{")?;
                for (i, n) in names.iter().enumerate() {
                    if i > 0 {
                        f.write_str(", ")?;
                    }
                    f.write_str(n)?;
                }
                f.write_str("}")
            }
        }
    }
}

/// When a change may take effect.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Apply {
    /// Not a servo parameter (work offsets, tool table: the host's G-code interpreter
    /// reads them when it parses a program): taken at once, also while the machine moves.
    /// A program already parsed keeps the values it was parsed with.
    Anytime,
    /// May change while the outputs are on, at a period boundary: it cannot make the
    /// output jump (a limit, a jog speed, the link's timeout, identification's next run).
    Live,
    /// Only while the outputs are off (`Servo::reconfigure` refuses otherwise): new gains,
    /// a new model, scale or estimator could make the output jump.
    OutputsOff,
}

impl Apply {
    pub const fn name(self) -> &'static str {
        match self {
            Self::Anytime => "anytime",
            Self::Live => "live",
            Self::OutputsOff => "outputs_off",
        }
    }
}

/// Why a per-entry accessor refused (the value's type was checked before).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Put {
    WrongType,
    NoModel,
}

/// The conversion between a field's type and [`Value`].
trait Field: Sized {
    fn value(&self) -> Value;
    fn from_value(v: Value) -> Option<Self>;
}

impl Field for f32 {
    fn value(&self) -> Value {
        Value::F32(*self)
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::F32(x) => Some(x),
            _ => None,
        }
    }
}

impl Field for bool {
    fn value(&self) -> Value {
        Value::Bool(*self)
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Bool(x) => Some(x),
            _ => None,
        }
    }
}

impl Field for u32 {
    fn value(&self) -> Value {
        Value::U32(*self)
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::U32(x) => Some(x),
            _ => None,
        }
    }
}

impl Field for u8 {
    fn value(&self) -> Value {
        Value::U32(u32::from(*self))
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::U32(x) => u8::try_from(x).ok(),
            _ => None,
        }
    }
}

impl Field for LawKind {
    fn value(&self) -> Value {
        Value::Choice(self.name())
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Choice(n) => Self::from_name(n),
            _ => None,
        }
    }
}

impl Field for CouplingKind {
    fn value(&self) -> Value {
        Value::Choice(self.name())
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Choice(n) => Self::from_name(n),
            _ => None,
        }
    }
}

/// Names of an input shaper's kind in keys: `none`, then Klipper's ([`ShaperKind::name`]).
const SHAPER_NAMES: &[&str] = &["none", "zv", "mzv", "zvd", "ei", "2hump_ei", "3hump_ei"];

impl Field for Option<ShaperKind> {
    fn value(&self) -> Value {
        Value::Choice(self.map_or("none", ShaperKind::name))
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Choice("none") => Some(None),
            Value::Choice(n) => ShaperKind::ALL
                .into_iter()
                .find(|k| k.name() == n)
                .map(Some),
            _ => None,
        }
    }
}

/// Names of a filter stage's kind in keys: `none`, then [`FilterKind::name`]'s.
const FILTER_NAMES: &[&str] = &["none", "notch", "low_pass"];

impl Field for Option<FilterKind> {
    fn value(&self) -> Value {
        Value::Choice(self.map_or("none", FilterKind::name))
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Choice("none") => Some(None),
            Value::Choice(n) => FilterKind::ALL
                .into_iter()
                .find(|k| k.name() == n)
                .map(Some),
            _ => None,
        }
    }
}

/// Names of [`HomeDirection`] in keys.
const DIRECTION_NAMES: &[&str] = &["min", "max"];

impl Field for HomeDirection {
    fn value(&self) -> Value {
        Value::Choice(match self {
            HomeDirection::Min => "min",
            HomeDirection::Max => "max",
        })
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Choice("min") => Some(HomeDirection::Min),
            Value::Choice("max") => Some(HomeDirection::Max),
            _ => None,
        }
    }
}

/// A per-axis registry entry: one for the three keys `axis.{x,y,z}.<path>`.
struct AxisDef {
    names: [&'static str; AXES],
    unit: &'static str,
    range: Range,
    apply: Apply,
    doc: &'static str,
    get: fn(&AxisSettings) -> Option<Value>,
    /// Writes the value (type-checked) into the axis of index `usize`.
    put: fn(&mut AxisSettings, usize, Value) -> Result<(), Put>,
}

/// A registry entry of a key outside `axis.*`.
struct GlobalDef {
    name: &'static str,
    unit: &'static str,
    range: Range,
    apply: Apply,
    doc: &'static str,
    get: fn(&Settings) -> Option<Value>,
    put: fn(&mut Settings, Value) -> Result<(), Put>,
}

/// A registry entry for one field of every row of a table: `work.<cs>.x_mm` for the nine
/// coordinate systems, `tool.<n>.length_mm` for the tools. Row `i` is key `names[i]`.
struct RowDef {
    names: &'static [&'static str],
    /// The key with the row written as a placeholder, for the doc table.
    pattern: &'static str,
    unit: &'static str,
    range: Range,
    apply: Apply,
    doc: &'static str,
    get: fn(&Settings, usize) -> Option<Value>,
    put: fn(&mut Settings, usize, Value) -> Result<(), Put>,
}

const fn f32_range(min: f32, max: f32) -> Range {
    Range::F32 { min, max }
}

/// The key suffix of a field path: `law.kind` → `"law.kind"`.
macro_rules! path_str {
    ($first:ident $(. $rest:ident)*) => {
        concat!(stringify!($first) $(, ".", stringify!($rest))*)
    };
}

/// A per-axis entry for the plain field `$path` of [`AxisSettings`].
macro_rules! axis_key {
    ($first:ident $(. $rest:ident)*, $unit:expr, $range:expr, $apply:ident, $doc:expr) => {
        AxisDef {
            names: [
                concat!("axis.x.", path_str!($first $(. $rest)*)),
                concat!("axis.y.", path_str!($first $(. $rest)*)),
                concat!("axis.z.", path_str!($first $(. $rest)*)),
            ],
            unit: $unit,
            range: $range,
            apply: Apply::$apply,
            doc: $doc,
            get: |a| Some(Field::value(&a.$first $(. $rest)*)),
            put: |a, _, v| {
                a.$first $(. $rest)* = Field::from_value(v).ok_or(Put::WrongType)?;
                Ok(())
            },
        }
    };
}

/// A per-axis entry for the model parameter `$field` (absent while the model is unknown).
macro_rules! model_key {
    ($field:ident, $unit:expr, $range:expr, $doc:expr) => {
        AxisDef {
            names: [
                concat!("axis.x.model.", stringify!($field)),
                concat!("axis.y.model.", stringify!($field)),
                concat!("axis.z.model.", stringify!($field)),
            ],
            unit: $unit,
            range: $range,
            apply: Apply::OutputsOff,
            doc: $doc,
            get: |a| a.model.map(|m| Value::F32(m.$field)),
            put: |a, _, v| {
                let m = a.model.as_mut().ok_or(Put::NoModel)?;
                m.$field = f32::from_value(v).ok_or(Put::WrongType)?;
                Ok(())
            },
        }
    };
}

/// An entry for the plain field `$path` of [`Settings`].
macro_rules! global_key {
    ($first:ident $(. $rest:ident)*, $unit:expr, $range:expr, $apply:ident, $doc:expr) => {
        GlobalDef {
            name: path_str!($first $(. $rest)*),
            unit: $unit,
            range: $range,
            apply: Apply::$apply,
            doc: $doc,
            get: |s| Some(Field::value(&s.$first $(. $rest)*)),
            put: |s, v| {
                s.$first $(. $rest)* = Field::from_value(v).ok_or(Put::WrongType)?;
                Ok(())
            },
        }
    };
}

/// The nine keys `work.<cs>.<field>` of one coordinate field, in G-code order (the
/// segments of [`super::offsets::WorkOffsets::NAMES`]).
macro_rules! work_names {
    ($field:ident) => {
        [
            concat!("work.g54.", stringify!($field)),
            concat!("work.g55.", stringify!($field)),
            concat!("work.g56.", stringify!($field)),
            concat!("work.g57.", stringify!($field)),
            concat!("work.g58.", stringify!($field)),
            concat!("work.g59.", stringify!($field)),
            concat!("work.g59_1.", stringify!($field)),
            concat!("work.g59_2.", stringify!($field)),
            concat!("work.g59_3.", stringify!($field)),
        ]
    };
}

/// The keys `tool.<n>.<field>` of one tool field, tools 1..=[`TOOL_COUNT`].
macro_rules! tool_names {
    ($field:ident) => {
        [
            concat!("tool.1.", stringify!($field)),
            concat!("tool.2.", stringify!($field)),
            concat!("tool.3.", stringify!($field)),
            concat!("tool.4.", stringify!($field)),
            concat!("tool.5.", stringify!($field)),
            concat!("tool.6.", stringify!($field)),
            concat!("tool.7.", stringify!($field)),
            concat!("tool.8.", stringify!($field)),
        ]
    };
}

// one key per coordinate system and per tool (fails to compile when a count changes
// without its list)
const _: [&str; WORK_SYSTEMS] = work_names!(x_mm);
const _: [&str; TOOL_COUNT] = tool_names!(length_mm);

/// An entry for the coordinate `$field` (`x_mm`, ...) of every work coordinate system.
macro_rules! work_key {
    ($field:ident, $doc:expr) => {
        RowDef {
            names: &work_names!($field),
            pattern: concat!("work.<cs>.", stringify!($field)),
            unit: unit::MM,
            range: WORK_OFFSET,
            apply: Apply::Anytime,
            doc: $doc,
            get: |s, i| s.work.get(i).map(|w| Value::F32(w.$field)),
            put: |s, i, v| {
                let w = s.work.get_mut(i).ok_or(Put::WrongType)?;
                w.$field = f32::from_value(v).ok_or(Put::WrongType)?;
                Ok(())
            },
        }
    };
}

/// An entry for the field `$field` of every tool.
macro_rules! tool_key {
    ($field:ident, $range:expr, $doc:expr) => {
        RowDef {
            names: &tool_names!($field),
            pattern: concat!("tool.<n>.", stringify!($field)),
            unit: unit::MM,
            range: $range,
            apply: Apply::Anytime,
            doc: $doc,
            // row i is tool i + 1
            get: |s, i| s.tool.get(i + 1).map(|t| Value::F32(t.$field)),
            put: |s, i, v| {
                let t = s.tool.get_mut(i + 1).ok_or(Put::WrongType)?;
                t.$field = f32::from_value(v).ok_or(Put::WrongType)?;
                Ok(())
            },
        }
    };
}

/// Units, written as the rest of the docs write them (UTF-8).
mod unit {
    pub const MM: &str = "mm";
    pub const MM_S: &str = "mm/s";
    pub const MM_S2: &str = "mm/s²";
    pub const MNM: &str = "mN·m";
    pub const RAD_S: &str = "rad/s";
    pub const S: &str = "s";
    pub const HZ: &str = "Hz";
    pub const NONE: &str = "";
}

/// Plausible bounds of this machine class, with their reasoning:
/// - lengths ±10 m: any gantry's travel, far beyond this one's (±150 mm);
/// - efforts 1 mN·m..100 N·m: the smallest effort a law could resolve to the largest motor
///   such an amplifier drives (the gantry's: 1–2 N·m peak);
/// - following errors 1 µm..100 mm: about one count to a third of the X travel;
/// - speeds up to 10 m/s, accelerations up to 10⁷ mm/s² (≈ 1000 g: bounds what the
///   encoder check tolerates, above any physical axis).
const LEN: Range = f32_range(-10_000.0, 10_000.0);
const EFFORT: Range = f32_range(1.0, 100_000.0);
const FERROR: Range = f32_range(0.001, 100.0);
/// A work origin anywhere a length may be (±10 m): G10 may put one beyond the travel (a
/// fixture on an extension table), the program's moves are what the travel check sees.
const WORK_OFFSET: Range = LEN;
/// Tool length offsets within ±1 m: a router's tools are well under 300 mm; negative for a
/// tool shorter than the reference one (LinuxCNC measures lengths from a master tool).
const TOOL_LENGTH: Range = f32_range(-1_000.0, 1_000.0);
/// Cutter diameters 0..1 m (0: not measured).
const TOOL_DIAMETER: Range = f32_range(0.0, 1_000.0);
/// Brake engage and release times 0..=1 s: the servo's own bound
/// ([`crate::servo::brake::MAX_BRAKE_TIME_S`], checked again by the servo).
const BRAKE_TIME: Range = f32_range(0.0, crate::servo::brake::MAX_BRAKE_TIME_S);
/// Shaped modes 1..200 Hz: a frame's modes are tens of Hz; the shaper's own bound
/// (1/100 of the control rate, its history's length) is checked with the whole tree.
const SHAPER_FREQ: Range = f32_range(1.0, 200.0);

/// Filter frequencies 0.1 Hz..25 kHz; the filters' own bounds (1/10⁴ to 0.45 of the
/// control rate) are checked with the whole tree.
const FILTER_FREQ: Range = f32_range(0.1, 25_000.0);
/// Notch depths up to the design's [`crate::filter::design::MAX_DEPTH_DB`].
const FILTER_DEPTH: Range = f32_range(0.1, crate::filter::design::MAX_DEPTH_DB);
/// Low-pass qualities up to the design's [`crate::filter::design::MAX_LOW_PASS_Q`].
const FILTER_Q: Range = f32_range(0.1, crate::filter::design::MAX_LOW_PASS_Q);

/// The per-axis keys, in the tree's field order.
static AXIS_KEYS: &[AxisDef] = &[
    axis_key!(
        law.kind,
        unit::NONE,
        Range::Choice(LawKind::NAMES),
        OutputsOff,
        "Control law of the axis; the model-based ones (all but pid) need a known model to arm"
    ),
    axis_key!(
        law.bandwidth_rad_s,
        unit::RAD_S,
        f32_range(1.0, 1_000.0),
        OutputsOff,
        "Closed-loop bandwidth the law's gains are tuned for (sysid::tuning); keep it below the velocity estimator's"
    ),
    AxisDef {
        names: ["axis.x.model.known", "axis.y.model.known", "axis.z.model.known"],
        unit: unit::NONE,
        range: Range::Bool,
        apply: Apply::OutputsOff,
        doc: "The axis' model is known (identified or entered); false forgets it, true starts from the designed gantry's model",
        get: |a| Some(Value::Bool(a.model.is_some())),
        put: |a, i, v| {
            let known = bool::from_value(v).ok_or(Put::WrongType)?;
            if !known {
                a.model = None;
            } else if a.model.is_none() {
                a.model = PLACEHOLDER_MODELS.get(i).copied();
            }
            Ok(())
        },
    },
    model_key!(
        inertia,
        "mN·m/(mm/s²)",
        f32_range(1e-4, 100.0),
        "Inertia reflected to the table (the gantry's: 0.041..0.18)"
    ),
    model_key!(
        viscous,
        "mN·m/(mm/s)",
        f32_range(0.0, 100.0),
        "Viscous friction coefficient"
    ),
    model_key!(
        coulomb_pos_mnm,
        unit::MNM,
        f32_range(-10_000.0, 10_000.0),
        "Torque to keep moving forward beyond the viscous part (Coulomb f+ plus any constant load)"
    ),
    model_key!(
        coulomb_neg_mnm,
        unit::MNM,
        f32_range(-10_000.0, 10_000.0),
        "Torque to keep moving backward beyond the viscous part (Coulomb f-, < 0 without load); at most coulomb_pos_mnm"
    ),
    axis_key!(
        encoder.counts_per_mm,
        "counts/mm",
        f32_range(1.0, 100_000.0),
        OutputsOff,
        "Quadrature counts per mm (lines x 4 / screw lead)"
    ),
    axis_key!(
        encoder.invert,
        unit::NONE,
        Range::Bool,
        OutputsOff,
        "The encoder counts down when the axis moves forward (A/B swapped): count it the other way (homes again)"
    ),
    axis_key!(
        motor.invert,
        unit::NONE,
        Range::Bool,
        OutputsOff,
        "A positive command turns the motor backwards: drive it negated (homes again)"
    ),
    axis_key!(
        amplifier.full_scale,
        unit::MNM,
        EFFORT,
        OutputsOff,
        "Effort at full command: every law's saturation and the tuning's torque limit"
    ),
    axis_key!(
        min_ferror_mm,
        unit::MM,
        FERROR,
        Live,
        "Following error allowed at rest"
    ),
    axis_key!(
        following_error_mm,
        unit::MM,
        FERROR,
        Live,
        "Following error allowed at vel_max_mm_s (at least min_ferror_mm; linear in between)"
    ),
    axis_key!(
        vel_max_mm_s,
        unit::MM_S,
        f32_range(0.1, 10_000.0),
        OutputsOff,
        "Largest speed of the axis (overspeed trips 10 % above)"
    ),
    axis_key!(
        accel_max_mm_s2,
        unit::MM_S2,
        f32_range(1.0, 1e7),
        OutputsOff,
        "Largest acceleration the axis can physically make (bounds the encoder-jump check)"
    ),
    axis_key!(
        stop_decel_mm_s2,
        unit::MM_S2,
        f32_range(1.0, 1e6),
        OutputsOff,
        "Deceleration of a controlled stop"
    ),
    axis_key!(
        stuck_effort_change,
        unit::MNM,
        f32_range(0.1, 100_000.0),
        OutputsOff,
        "Effort change that must move a resting axis (stuck-encoder and runaway threshold)"
    ),
    axis_key!(
        travel.min_mm,
        unit::MM,
        LEN,
        OutputsOff,
        "Soft limit at the low end, machine coordinates (below travel.max_mm)"
    ),
    axis_key!(
        travel.max_mm,
        unit::MM,
        LEN,
        OutputsOff,
        "Soft limit at the high end, machine coordinates"
    ),
    axis_key!(
        homing.enabled,
        unit::NONE,
        Range::Bool,
        OutputsOff,
        "The axis homes on its switch (false: counts as homed where it is armed)"
    ),
    axis_key!(
        homing.order,
        unit::NONE,
        Range::U32 { min: 0, max: 2 },
        OutputsOff,
        "Axes home in increasing order (ties: x, y, z)"
    ),
    axis_key!(
        homing.direction,
        unit::NONE,
        Range::Choice(DIRECTION_NAMES),
        OutputsOff,
        "End of the axis the home switch is at"
    ),
    axis_key!(
        homing.seek_mm_s,
        unit::MM_S,
        f32_range(0.1, 1_000.0),
        OutputsOff,
        "Search speed toward the switch"
    ),
    axis_key!(
        homing.locate_mm_s,
        unit::MM_S,
        f32_range(0.01, 1_000.0),
        OutputsOff,
        "Slow speed of the release and locate passes (at most seek_mm_s)"
    ),
    axis_key!(
        homing.accel_mm_s2,
        unit::MM_S2,
        f32_range(1.0, 100_000.0),
        OutputsOff,
        "Acceleration of every homing move"
    ),
    axis_key!(
        homing.backoff_mm,
        unit::MM,
        f32_range(0.01, 100.0),
        OutputsOff,
        "Distance moved past the switch's release before locating"
    ),
    axis_key!(
        homing.pulloff_mm,
        unit::MM,
        f32_range(0.01, 100.0),
        OutputsOff,
        "Final distance from the switch (the home position must lie inside the travel)"
    ),
    axis_key!(
        homing.switch_pos_mm,
        unit::MM,
        LEN,
        OutputsOff,
        "Machine coordinate of the switch's trigger point"
    ),
    axis_key!(
        homing.max_seek_mm,
        unit::MM,
        f32_range(1.0, 20_000.0),
        OutputsOff,
        "The seek fails after this distance without the switch"
    ),
    axis_key!(
        homing.use_index,
        unit::NONE,
        Range::Bool,
        OutputsOff,
        "Latch the encoder's index pulse after the switch"
    ),
    axis_key!(
        homing.index_search_mm,
        unit::MM,
        f32_range(0.1, 100.0),
        OutputsOff,
        "Distance within which the index must follow the switch (one screw lead)"
    ),
    axis_key!(
        jog.speed_max_mm_s,
        unit::MM_S,
        f32_range(0.1, 10_000.0),
        Live,
        "Largest jog speed (commands beyond it are clamped)"
    ),
    axis_key!(
        jog.accel_mm_s2,
        unit::MM_S2,
        f32_range(1.0, 100_000.0),
        Live,
        "Acceleration and deceleration of a jog"
    ),
    axis_key!(
        planner.vel_max_mm_s,
        unit::MM_S,
        f32_range(0.1, 10_000.0),
        OutputsOff,
        "Largest speed the motion planner commands (also the rapid speed); at most vel_max_mm_s"
    ),
    axis_key!(
        planner.acc_max_mm_s2,
        unit::MM_S2,
        f32_range(1.0, 1e6),
        OutputsOff,
        "Largest acceleration the motion planner commands"
    ),
    axis_key!(
        planner.jerk_max_mm_s3,
        "mm/s³",
        f32_range(10.0, 1e9),
        OutputsOff,
        "Largest jerk the motion planner commands"
    ),
    axis_key!(
        brake.present,
        unit::NONE,
        Range::Bool,
        OutputsOff,
        "The axis has a holding brake on its brake output (gripping when de-energised; the servo releases it only while it drives the axis)"
    ),
    axis_key!(
        brake.engage_s,
        unit::S,
        BRAKE_TIME,
        OutputsOff,
        "Time the brake needs to grip after its coil is switched off: a controlled stop holds the axis this long before the outputs go off"
    ),
    axis_key!(
        brake.release_s,
        unit::S,
        BRAKE_TIME,
        OutputsOff,
        "Time the brake needs to open after its coil is switched on: motion after arming waits this long"
    ),    axis_key!(
        feedforward.coulomb_pos_mnm,
        unit::MNM,
        f32_range(0.0, 100_000.0),
        OutputsOff,
        "Coulomb torque added while the reference moves forward (the model's coulomb_pos_mnm; 0: none): removes the quadrant spike at reversals"
    ),
    axis_key!(
        feedforward.coulomb_neg_mnm,
        unit::MNM,
        f32_range(-100_000.0, 0.0),
        OutputsOff,
        "Coulomb torque added while the reference moves backward (the model's coulomb_neg_mnm, <= 0; 0: none)"
    ),
    axis_key!(
        feedforward.compliance_s2,
        "s²",
        f32_range(0.0, crate::motion::feedforward::MAX_COMPLIANCE_S2),
        OutputsOff,
        "Frame compliance as a lag per acceleration, 1/ω_a² of the axis' anti-resonance (cargo sim freqresp measures it; 0: a rigid axis): the motor is sent ahead by compliance_s2 · a"
    ),
    axis_key!(
        feedforward.lag_s,
        unit::S,
        f32_range(0.0, crate::motion::feedforward::MAX_LAG_S),
        OutputsOff,
        "Frame deflection under the tool side's viscous friction as a lag, B_tool/k (0: none): the motor is sent ahead by lag_s · v"
    ),
    axis_key!(
        feedforward.deflection_pos_mm,
        unit::MM,
        f32_range(0.0, crate::motion::feedforward::MAX_DEFLECTION_MM),
        OutputsOff,
        "Frame deflection under the tool side's friction while moving forward (cargo sim compensation measures it; 0: none)"
    ),
    axis_key!(
        feedforward.deflection_neg_mm,
        unit::MM,
        f32_range(-crate::motion::feedforward::MAX_DEFLECTION_MM, 0.0),
        OutputsOff,
        "The same while moving backward (<= 0; 0: none)"
    ),
    axis_key!(
        feedforward.reversal_band_mm_s,
        unit::MM_S,
        f32_range(0.001, 100.0),
        OutputsOff,
        "Reference speed over which the friction terms change sign (default 0.5: the guides' pre-sliding range at a circle's reversal)"
    ),
    axis_key!(
        feedforward.stiction_ratio,
        unit::NONE,
        f32_range(1.0, crate::motion::feedforward::MAX_STICTION_RATIO),
        OutputsOff,
        "Friction at rest over friction in motion (the Stribeck peak; 1: none): the friction terms grow by it near rest"
    ),
    axis_key!(
        feedforward.v_stribeck_mm_s,
        unit::MM_S,
        f32_range(0.001, 1_000.0),
        OutputsOff,
        "Speed over which the Stribeck peak decays"
    ),
    axis_key!(
        filter.stage1.kind,
        unit::NONE,
        Range::Choice(FILTER_NAMES),
        OutputsOff,
        "Filter stage 1 on the axis' control output (none: off; stages run in order, cargo sim filters places them from the measured response)"
    ),
    axis_key!(
        filter.stage1.freq_hz,
        unit::HZ,
        FILTER_FREQ,
        OutputsOff,
        "Stage 1's notch centre or low-pass cutoff (below 0.45 of the control rate)"
    ),
    axis_key!(
        filter.stage1.width_hz,
        unit::HZ,
        FILTER_FREQ,
        OutputsOff,
        "Stage 1's notch width, between the frequencies attenuated by half its depth in dB"
    ),
    axis_key!(
        filter.stage1.depth_db,
        "dB",
        FILTER_DEPTH,
        OutputsOff,
        "Stage 1's notch attenuation at its centre"
    ),
    axis_key!(
        filter.stage1.q,
        unit::NONE,
        FILTER_Q,
        OutputsOff,
        "Stage 1's low-pass quality (0.707: Butterworth; the gain at the cutoff)"
    ),
    axis_key!(
        filter.stage2.kind,
        unit::NONE,
        Range::Choice(FILTER_NAMES),
        OutputsOff,
        "Filter stage 2 on the axis' control output (none: off; stages run in order, cargo sim filters places them from the measured response)"
    ),
    axis_key!(
        filter.stage2.freq_hz,
        unit::HZ,
        FILTER_FREQ,
        OutputsOff,
        "Stage 2's notch centre or low-pass cutoff (below 0.45 of the control rate)"
    ),
    axis_key!(
        filter.stage2.width_hz,
        unit::HZ,
        FILTER_FREQ,
        OutputsOff,
        "Stage 2's notch width, between the frequencies attenuated by half its depth in dB"
    ),
    axis_key!(
        filter.stage2.depth_db,
        "dB",
        FILTER_DEPTH,
        OutputsOff,
        "Stage 2's notch attenuation at its centre"
    ),
    axis_key!(
        filter.stage2.q,
        unit::NONE,
        FILTER_Q,
        OutputsOff,
        "Stage 2's low-pass quality (0.707: Butterworth; the gain at the cutoff)"
    ),
    axis_key!(
        filter.stage3.kind,
        unit::NONE,
        Range::Choice(FILTER_NAMES),
        OutputsOff,
        "Filter stage 3 on the axis' control output (none: off; stages run in order, cargo sim filters places them from the measured response)"
    ),
    axis_key!(
        filter.stage3.freq_hz,
        unit::HZ,
        FILTER_FREQ,
        OutputsOff,
        "Stage 3's notch centre or low-pass cutoff (below 0.45 of the control rate)"
    ),
    axis_key!(
        filter.stage3.width_hz,
        unit::HZ,
        FILTER_FREQ,
        OutputsOff,
        "Stage 3's notch width, between the frequencies attenuated by half its depth in dB"
    ),
    axis_key!(
        filter.stage3.depth_db,
        "dB",
        FILTER_DEPTH,
        OutputsOff,
        "Stage 3's notch attenuation at its centre"
    ),
    axis_key!(
        filter.stage3.q,
        unit::NONE,
        FILTER_Q,
        OutputsOff,
        "Stage 3's low-pass quality (0.707: Butterworth; the gain at the cutoff)"
    ),
    axis_key!(
        filter.stage4.kind,
        unit::NONE,
        Range::Choice(FILTER_NAMES),
        OutputsOff,
        "Filter stage 4 on the axis' control output (none: off; stages run in order, cargo sim filters places them from the measured response)"
    ),
    axis_key!(
        filter.stage4.freq_hz,
        unit::HZ,
        FILTER_FREQ,
        OutputsOff,
        "Stage 4's notch centre or low-pass cutoff (below 0.45 of the control rate)"
    ),
    axis_key!(
        filter.stage4.width_hz,
        unit::HZ,
        FILTER_FREQ,
        OutputsOff,
        "Stage 4's notch width, between the frequencies attenuated by half its depth in dB"
    ),
    axis_key!(
        filter.stage4.depth_db,
        "dB",
        FILTER_DEPTH,
        OutputsOff,
        "Stage 4's notch attenuation at its centre"
    ),
    axis_key!(
        filter.stage4.q,
        unit::NONE,
        FILTER_Q,
        OutputsOff,
        "Stage 4's low-pass quality (0.707: Butterworth; the gain at the cutoff)"
    ),
];

/// The keys outside `axis.*`, in the tree's field order.
static GLOBAL_KEYS: &[GlobalDef] = &[
    global_key!(
        jog.timeout_s,
        "s",
        f32_range(0.05, 10.0),
        Live,
        "A jog decelerates to rest when no jog command came for this long"
    ),
    global_key!(
        coupling.kind,
        unit::NONE,
        Range::Choice(CouplingKind::NAMES),
        OutputsOff,
        "Coupling between the axes"
    ),
    global_key!(
        coupling.lambda,
        unit::NONE,
        f32_range(0.0, 100.0),
        OutputsOff,
        "Contour coupling gain (mm units; the board's 1, the paper's 0.01 in its units)"
    ),
    global_key!(
        estimator.pll_bandwidth_rad_s,
        unit::RAD_S,
        f32_range(10.0, 20_000.0),
        OutputsOff,
        "Velocity PLL natural frequency (stable below about 0.83 x the control rate in Hz)"
    ),
    global_key!(
        estimator.pll_damping,
        unit::NONE,
        f32_range(0.1, 10.0),
        OutputsOff,
        "Velocity PLL damping (1: critically damped)"
    ),
    global_key!(
        link.watchdog_ms,
        "ms",
        Range::U32 {
            min: MIN_WATCHDOG_TIMEOUT_MS,
            max: MAX_WATCHDOG_TIMEOUT_MS
        },
        Live,
        "Link silence after which the machine stops (controlled stop, LinkLost)"
    ),
    global_key!(
        identify.torque_cap_mnm,
        unit::MNM,
        EFFORT,
        Live,
        "Hard limit on identification's effort (never above the axis' full scale); read when a run starts"
    ),
    global_key!(
        identify.edge_margin_mm,
        unit::MM,
        f32_range(0.0, 100.0),
        Live,
        "Distance identification's motion keeps from each end of its window; read when a run starts"
    ),
    global_key!(
        planner.tolerance_mm,
        unit::MM,
        f32_range(0.0, 10.0),
        OutputsOff,
        "Path tolerance of G64 without P: blended corners stay this close to the programmed path"
    ),
    global_key!(
        planner.tangential_share,
        unit::NONE,
        f32_range(0.05, 0.95),
        OutputsOff,
        "Share of each axis' acceleration and jerk kept along curves (the rest bounds the centripetal terms)"
    ),
    global_key!(
        planner.servo_reserve,
        unit::NONE,
        f32_range(0.0, 0.95),
        OutputsOff,
        "Share of each axis' jerk the planner leaves to the servo along the path (0: the full limits)"
    ),
    global_key!(
        safety.arm_encoder_check,
        unit::NONE,
        Range::Bool,
        OutputsOff,
        "Arming checks every encoder first: each axis' hold point moves 16 counts out and back both ways, and a reading that goes the wrong way (swapped A/B) or not at all faults"
    ),
    global_key!(
        shaper.x.kind,
        unit::NONE,
        Range::Choice(SHAPER_NAMES),
        OutputsOff,
        "Input shaper of the planner's X reference (Klipper's kinds; none: not shaped); its contour deviation is counted inside planner.tolerance_mm"
    ),
    global_key!(
        shaper.x.freq_hz,
        unit::HZ,
        SHAPER_FREQ,
        OutputsOff,
        "Frequency of the X mode the shaper cancels (cargo sim freqresp measures it); at most 1/100 of the control rate"
    ),
    global_key!(
        shaper.x.damping_ratio,
        unit::NONE,
        f32_range(0.0, 0.99),
        OutputsOff,
        "Damping ratio of the X mode (Klipper's default 0.1; ei 0.4, 2hump_ei 0.3, 3hump_ei 0.2 at most)"
    ),
    global_key!(
        shaper.y.kind,
        unit::NONE,
        Range::Choice(SHAPER_NAMES),
        OutputsOff,
        "Input shaper of the planner's Y reference (Klipper's kinds; none: not shaped); its contour deviation is counted inside planner.tolerance_mm"
    ),
    global_key!(
        shaper.y.freq_hz,
        unit::HZ,
        SHAPER_FREQ,
        OutputsOff,
        "Frequency of the Y mode the shaper cancels (cargo sim freqresp measures it); at most 1/100 of the control rate"
    ),
    global_key!(
        shaper.y.damping_ratio,
        unit::NONE,
        f32_range(0.0, 0.99),
        OutputsOff,
        "Damping ratio of the Y mode (Klipper's default 0.1; ei 0.4, 2hump_ei 0.3, 3hump_ei 0.2 at most)"
    ),
    global_key!(
        shaper.z.kind,
        unit::NONE,
        Range::Choice(SHAPER_NAMES),
        OutputsOff,
        "Input shaper of the planner's Z reference (Klipper's kinds; none: not shaped); its contour deviation is counted inside planner.tolerance_mm"
    ),
    global_key!(
        shaper.z.freq_hz,
        unit::HZ,
        SHAPER_FREQ,
        OutputsOff,
        "Frequency of the Z mode the shaper cancels (cargo sim freqresp measures it); at most 1/100 of the control rate"
    ),
    global_key!(
        shaper.z.damping_ratio,
        unit::NONE,
        f32_range(0.0, 0.99),
        OutputsOff,
        "Damping ratio of the Z mode (Klipper's default 0.1; ei 0.4, 2hump_ei 0.3, 3hump_ei 0.2 at most)"
    ),
];

/// The table keys: the work coordinate systems, then the tool table, each row by row.
static ROW_KEYS: &[RowDef] = &[
    work_key!(
        x_mm,
        "X of the coordinate system's origin in machine coordinates (G10 L2; G54 is the one a program starts in)"
    ),
    work_key!(y_mm, "Y of the coordinate system's origin in machine coordinates"),
    work_key!(z_mm, "Z of the coordinate system's origin in machine coordinates"),
    tool_key!(
        length_mm,
        TOOL_LENGTH,
        "Tool length offset (G43 H<n>): machine Z = programmed Z + length (LinuxCNC's sign)"
    ),
    tool_key!(
        diameter_mm,
        TOOL_DIAMETER,
        "Cutter diameter (G10 L1 R sets it as 2 R; kept for the table, no cutter compensation)"
    ),
];

/// How a key reaches its value.
#[derive(Clone, Copy)]
enum Access {
    Axis { axis: usize, def: &'static AxisDef },
    Global(&'static GlobalDef),
    Row { row: usize, def: &'static RowDef },
}

/// One key of the registry.
#[derive(Clone, Copy)]
pub struct Key {
    /// Dotted name (`axis.x.following_error_mm`).
    pub name: &'static str,
    /// Unit of the value (empty for booleans, counts and choices).
    pub unit: &'static str,
    pub range: Range,
    pub apply: Apply,
    /// One line: what it is.
    pub doc: &'static str,
    access: Access,
}

impl fmt::Debug for Key {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Key")
            .field("name", &self.name)
            .field("unit", &self.unit)
            .field("range", &self.range)
            .field("apply", &self.apply)
            .finish()
    }
}

impl PartialEq for Key {
    fn eq(&self, other: &Self) -> bool {
        self.name == other.name
    }
}

impl Key {
    /// The axis of a per-axis key.
    pub fn axis(&self) -> Option<Axis> {
        match self.access {
            Access::Axis { axis, .. } => Axis::from_index(axis),
            Access::Global(_) | Access::Row { .. } => None,
        }
    }

    /// The key's value in `s` (`None`: a model parameter of an axis without a model).
    pub fn get(&self, s: &Settings) -> Option<Value> {
        match self.access {
            Access::Axis { axis, def } => s.axis.get(axis).and_then(def.get),
            Access::Global(def) => (def.get)(s),
            Access::Row { row, def } => (def.get)(s, row),
        }
    }

    fn put(&self, s: &mut Settings, v: Value) -> Result<(), Put> {
        match self.access {
            Access::Axis { axis, def } => match s.axis.get_mut(axis) {
                Some(a) => (def.put)(a, axis, v),
                None => Err(Put::WrongType),
            },
            Access::Global(def) => (def.put)(s, v),
            Access::Row { row, def } => (def.put)(s, row, v),
        }
    }

    /// Parse the CLI's text as this key's value (type only; `set` checks the range).
    pub fn parse(&self, text: &str) -> Result<Value, SetError> {
        self.range.parse(text).ok_or(SetError::WrongType {
            key: self.name,
            range: self.range,
        })
    }
}

/// Every key: `axis.x.*`, `axis.y.*`, `axis.z.*` (each in the tree's field order), then the
/// others, then the tables (`work.g54.*` .. `work.g59_3.*`, `tool.1.*` .. `tool.8.*`, row
/// by row). Static: the values come from [`Settings::list`] or [`Key::get`].
pub fn keys() -> impl Iterator<Item = Key> + Clone {
    let axis_keys = (0..AXES).flat_map(|axis| {
        AXIS_KEYS.iter().filter_map(move |def| {
            Some(Key {
                name: def.names.get(axis).copied()?,
                unit: def.unit,
                range: def.range,
                apply: def.apply,
                doc: def.doc,
                access: Access::Axis { axis, def },
            })
        })
    });
    let global_keys = GLOBAL_KEYS.iter().map(|def| Key {
        name: def.name,
        unit: def.unit,
        range: def.range,
        apply: def.apply,
        doc: def.doc,
        access: Access::Global(def),
    });
    // the tables row by row, so that one system's (or tool's) keys stay together
    let work_rows = (0..WORK_SYSTEMS).flat_map(|row| {
        ROW_KEYS
            .iter()
            .filter(|d| d.pattern.starts_with("work."))
            .map(move |def| (row, def))
    });
    let tool_rows = (0..TOOL_COUNT).flat_map(|row| {
        ROW_KEYS
            .iter()
            .filter(|d| d.pattern.starts_with("tool."))
            .map(move |def| (row, def))
    });
    let row_keys = work_rows.chain(tool_rows).filter_map(|(row, def)| {
        Some(Key {
            name: def.names.get(row).copied()?,
            unit: def.unit,
            range: def.range,
            apply: def.apply,
            doc: def.doc,
            access: Access::Row { row, def },
        })
    });
    axis_keys.chain(global_keys).chain(row_keys)
}

/// The key named `name`.
pub fn find(name: &str) -> Result<Key, KeyError> {
    keys()
        .find(|k| k.name == name)
        .ok_or_else(|| KeyError::Unknown(KeyText::new(name)))
}

/// Longest key text an error repeats back (longer names are cut, with `…`).
pub const KEY_TEXT_MAX: usize = 48;

/// A copy of a key as the user gave it (for "unknown key" errors).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct KeyText(heapless::String<KEY_TEXT_MAX>);

impl KeyText {
    fn new(text: &str) -> Self {
        let mut s = heapless::String::new();
        for c in text.chars() {
            // leave room for the ellipsis (3 bytes)
            if s.len() + c.len_utf8() > KEY_TEXT_MAX - 3 {
                let _ = s.push('…');
                break;
            }
            let _ = s.push(c);
        }
        Self(s)
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

/// Why [`Settings::get`] failed.
#[derive(Clone, Debug, PartialEq)]
pub enum KeyError {
    /// No such key.
    Unknown(KeyText),
    /// A model parameter of an axis whose model is unknown.
    NoModel { key: &'static str },
}

impl fmt::Display for KeyError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Unknown(k) => write!(f, "unknown key `{}`", k.as_str()),
            Self::NoModel { key } => write!(
                f,
                "{key}: the axis has no model (identify it, or set axis.<a>.model.known true to enter one)"
            ),
        }
    }
}

/// Why [`Settings::set`] refused; every variant names the key. Nothing was changed.
#[derive(Clone, Debug, PartialEq)]
pub enum SetError {
    /// No such key.
    Unknown(KeyText),
    /// The value (or text) is not of the key's type.
    WrongType { key: &'static str, range: Range },
    /// The value is outside the key's range.
    OutOfRange {
        key: &'static str,
        value: Value,
        range: Range,
        unit: &'static str,
    },
    /// A model parameter of an axis whose model is unknown.
    NoModel { key: &'static str },
    /// The value is valid alone but the tree with it is not (the servo's reason).
    Rejected {
        key: &'static str,
        value: Value,
        error: ServoConfigError,
    },
    /// A whole tree from outside (store, import) gives no servo configuration.
    Tree(ServoConfigError),
}

impl fmt::Display for SetError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Unknown(k) => write!(f, "unknown key `{}`", k.as_str()),
            Self::WrongType { key, range } => write!(f, "{key}: expected {range}"),
            Self::OutOfRange {
                key,
                value,
                range,
                unit,
            } => {
                write!(f, "{key}: {value} is outside the allowed range {range}")?;
                if !unit.is_empty() {
                    write!(f, " {unit}")?;
                }
                Ok(())
            }
            Self::NoModel { key } => write!(
                f,
                "{key}: the axis has no model (identify it, or set axis.<a>.model.known true to enter one)"
            ),
            Self::Rejected { key, value, error } => {
                write!(f, "{key} = {value} rejected: {error}")
            }
            Self::Tree(error) => write!(f, "settings rejected: {error}"),
        }
    }
}

impl From<KeyError> for SetError {
    fn from(e: KeyError) -> Self {
        match e {
            KeyError::Unknown(k) => Self::Unknown(k),
            KeyError::NoModel { key } => Self::NoModel { key },
        }
    }
}

impl Settings {
    /// Every key with its value here (`None`: model parameters of an axis without a model).
    pub fn list(&self) -> impl Iterator<Item = (Key, Option<Value>)> + '_ {
        keys().map(move |k| (k, k.get(self)))
    }

    /// The value of `key`.
    pub fn get(&self, key: &str) -> Result<Value, KeyError> {
        let k = find(key)?;
        k.get(self).ok_or(KeyError::NoModel { key: k.name })
    }

    /// Set `key` to `value`: the value must have the key's type and lie in its range, and
    /// the whole tree with it must give a servo configuration at `rate_hz` (the control
    /// rate of the machine). On any error nothing changes.
    pub fn set(&mut self, key: &str, value: Value, rate_hz: u32) -> Result<(), SetError> {
        self.set_all(&[(key, value)], rate_hz)
    }

    /// Set several keys at once, validated together: for changes that are only valid
    /// together (a home switch moved to the other end with its direction, a travel moved
    /// beyond its old other end). Each value is checked like [`Self::set`]; the tree is
    /// validated once, after all of them. On any error nothing changes; a whole-tree
    /// rejection names the last key.
    pub fn set_all(&mut self, changes: &[(&str, Value)], rate_hz: u32) -> Result<(), SetError> {
        let mut next = *self;
        let mut last = None;
        for (key, value) in changes {
            let k = find(key)?;
            next.put_checked(&k, *value)?;
            last = Some((k.name, *value));
        }
        if let Some((key, value)) = last {
            next.servo_config(rate_hz)
                .map_err(|error| SetError::Rejected { key, value, error })?;
        }
        *self = next;
        Ok(())
    }

    /// Type and range check of `value` for `k`, then write it (no whole-tree check).
    fn put_checked(&mut self, k: &Key, value: Value) -> Result<(), SetError> {
        if !k.range.fits_type(&value) {
            return Err(SetError::WrongType {
                key: k.name,
                range: k.range,
            });
        }
        if !k.range.admits(&value) {
            return Err(SetError::OutOfRange {
                key: k.name,
                value,
                range: k.range,
                unit: k.unit,
            });
        }
        k.put(self, value).map_err(|e| match e {
            Put::NoModel => SetError::NoModel { key: k.name },
            Put::WrongType => SetError::WrongType {
                key: k.name,
                range: k.range,
            },
        })
    }

    /// Set `key` from the CLI's text, type- and range-checked but without the whole-tree
    /// check: one change of a transaction, whose tree is validated whole at its commit
    /// ([`Self::validate_change`]). On an error nothing changes.
    pub fn stage_text(&mut self, key: &str, text: &str) -> Result<(), SetError> {
        let k = find(key)?;
        let value = k.parse(text)?;
        self.put_checked(&k, value)
    }

    /// Whole validation of `self`, a change of `base` (a transaction's tree), at
    /// `rate_hz`. A whole-tree rejection names a key, the first changed one (in key order)
    /// that is found to be a cause: first one whose old value alone makes the tree valid
    /// again; else one whose new value alone makes `base` invalid (when several changes
    /// break rules, or one key was changed twice); else the last changed key.
    pub fn validate_change(&self, base: &Settings, rate_hz: u32) -> Result<(), SetError> {
        if let Some(e) = self.out_of_range() {
            return Err(e);
        }
        let Err(error) = self.servo_config(rate_hz) else {
            return Ok(());
        };
        let changed = || {
            keys().filter_map(|k| match (k.get(self), k.get(base)) {
                (Some(now), old) if old.is_none_or(|o| !o.same(&now)) => Some((k, now, old)),
                _ => None,
            })
        };
        for (k, value, old) in changed() {
            let Some(old) = old else { continue };
            let mut t = *self;
            if t.put_checked(&k, old).is_ok() && t.servo_config(rate_hz).is_ok() {
                return Err(SetError::Rejected {
                    key: k.name,
                    value,
                    error,
                });
            }
        }
        for (k, value, _) in changed() {
            let mut t = *base;
            if t.put_checked(&k, value).is_ok() && t.servo_config(rate_hz).is_err() {
                return Err(SetError::Rejected {
                    key: k.name,
                    value,
                    error,
                });
            }
        }
        Err(match changed().last() {
            Some((k, value, _)) => SetError::Rejected {
                key: k.name,
                value,
                error,
            },
            None => SetError::Tree(error),
        })
    }

    /// [`Self::set`] from the CLI's text (`"1.5"`, `"true"`, `"dsmc"`).
    pub fn set_text(&mut self, key: &str, text: &str, rate_hz: u32) -> Result<(), SetError> {
        let value = find(key)?.parse(text)?;
        self.set(key, value, rate_hz)
    }

    /// The first key whose value lies outside its range (a tree that did not come through
    /// [`Self::set`]: a stored record, an imported file).
    pub fn out_of_range(&self) -> Option<SetError> {
        self.list().find_map(|(k, v)| {
            let v = v?;
            (!k.range.admits(&v)).then_some(SetError::OutOfRange {
                key: k.name,
                value: v,
                range: k.range,
                unit: k.unit,
            })
        })
    }

    /// Whole validation of a tree from outside (store, import): every key in range and a
    /// servo configuration at `rate_hz`.
    pub fn validate(&self, rate_hz: u32) -> Result<(), SetError> {
        if let Some(e) = self.out_of_range() {
            return Err(e);
        }
        self.servo_config(rate_hz)
            .map(|_| ())
            .map_err(SetError::Tree)
    }

    /// What changing from `self` to `next` needs from the servo: `None` if no servo
    /// parameter differs (identical, or only [`Apply::Anytime`] keys: taken at once, also
    /// while moving), `Live` if only live keys differ, else `OutputsOff`.
    pub fn change_class(&self, next: &Settings) -> Option<Apply> {
        keys()
            .filter(|k| k.apply != Apply::Anytime)
            .filter(|k| match (k.get(self), k.get(next)) {
                (Some(a), Some(b)) => !a.same(&b),
                (a, b) => a.is_some() != b.is_some(),
            })
            .map(|k| k.apply)
            .max()
    }
}

/// The key table of docs/settings.md (Markdown), from the registry and the factory values
/// of `s`: per-axis keys once as `axis.<a>.…` with the x / y / z values, then the others,
/// then the tables once per field (`work.<cs>.x_mm`, `tool.<n>.length_mm`) with the value
/// of every row when they agree.
pub fn write_markdown_table(w: &mut impl fmt::Write, s: &Settings) -> fmt::Result {
    writeln!(
        w,
        "| key | unit | range | factory (x / y / z) | apply | meaning |"
    )?;
    writeln!(w, "| --- | --- | --- | --- | --- | --- |")?;
    let cell = |v: Option<Value>| v.map_or(Cell::Unset, Cell::Value);
    for def in AXIS_KEYS {
        let suffix = def.names[0].strip_prefix("axis.x.").unwrap_or(def.names[0]);
        let vals = [0, 1, 2].map(|i| cell(s.axis.get(i).and_then(def.get)));
        let factory = if vals[0] == vals[1] && vals[1] == vals[2] {
            Factory::One(vals[0])
        } else {
            Factory::Three(vals)
        };
        writeln!(
            w,
            "| `axis.<a>.{suffix}` | {} | {} | {factory} | {} | {} |",
            def.unit,
            def.range,
            def.apply.name(),
            def.doc
        )?;
    }
    for def in GLOBAL_KEYS {
        writeln!(
            w,
            "| `{}` | {} | {} | {} | {} | {} |",
            def.name,
            def.unit,
            def.range,
            Factory::One(cell((def.get)(s))),
            def.apply.name(),
            def.doc
        )?;
    }
    for def in ROW_KEYS {
        let row = |i| cell((def.get)(s, i));
        let first = row(0);
        let factory = if (0..def.names.len()).all(|i| row(i) == first) {
            Factory::One(first)
        } else {
            Factory::Rows
        };
        writeln!(
            w,
            "| `{}` | {} | {} | {factory} | {} | {} |",
            def.pattern,
            def.unit,
            def.range,
            def.apply.name(),
            def.doc
        )?;
    }
    Ok(())
}

#[derive(Clone, Copy, PartialEq)]
enum Cell {
    Value(Value),
    Unset,
}

impl fmt::Display for Cell {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Value(v) => write!(f, "{v}"),
            Self::Unset => f.write_str("(none)"),
        }
    }
}

enum Factory {
    One(Cell),
    Three([Cell; AXES]),
    /// A table whose rows differ (see the keys themselves).
    Rows,
}

impl fmt::Display for Factory {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::One(c) => write!(f, "{c}"),
            Self::Three([x, y, z]) => write!(f, "{x} / {y} / {z}"),
            Self::Rows => f.write_str("(per row)"),
        }
    }
}

#[cfg(test)]
mod tests;
