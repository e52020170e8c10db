//! The planner's benchmark programs, generated (`cargo sim bench-programs --out DIR`).
//!
//! Each function returns the text of one program written the way CAM posts write them: a
//! `%` line, a comment naming the generator, a modal header (`G21`/`G20 G90 G17 G94 G54`
//! and the path-control mode), coordinates with 4 decimals (mm, or inches under G20),
//! modal `X… Y… Z…` lines after the first `G1`, `M30` at the end. Everything is
//! deterministic: the only pseudo-random program ([`zigzag`]) draws from a fixed seed, so
//! generating twice gives the same bytes (`tests/bench_programs.rs`).
//!
//! Every program stays inside the default machine's travel (±150 mm X/Y, ±50 mm Z around
//! the work origin, where the machine starts: [`DEFAULT_TRAVEL_MM`]) and starts from that
//! origin. Counts below are G-code moves as the parser reports them (zero-length moves are
//! skipped there; none of these programs has one); path lengths are the programmed path's,
//! as `cargo sim gcode` reports `path_length_mm`.
//!
//! | program | what it stands for |
//! | --- | --- |
//! | [`circle_chords`] | a circle posted as 10,000 tiny chords with a feed far above the machine: the naive-CAM case, the speed limited by the chords' number, not the feed |
//! | [`collinear_tiny`] | 3,000 collinear 0.0254 mm moves: junctions that must not slow down at all |
//! | [`surfacing_3d`] | a 3-D finishing raster in inches, `G64 P0.001`: the 3-D surfacing benchmark case |
//! | [`spiral_arcs`] | an Archimedean spiral of quarter-turn arcs in and out: arcs whose radius shrinks to 2 mm |
//! | [`zigzag`] | a zigzag pocket of 0.5-3 mm moves with 60-150° corners: corner blending at every move |
//! | [`dense_curve_3d`] | a 3-D space curve as 5,000 chords of 0.07-0.2 mm: look-ahead depth at a high feed |
//! | [`huge`] | a 170,000-line raster (42.9 m of path): the benchmark's "170,000-line program" |
//! | [`rest_to_rest`] | one `G61` line from rest to rest: the planner's time against the time-optimal move (`host-sim/bench/ruckig_lines.py`) |

use controller_core::sim::rng::SplitMix64;
use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::fmt::Write;

/// The default machine's travel around the work origin, `[[min, max]; 3]` mm
/// (`host-sim/scenarios/gcode.toml`): what every program here must stay within.
pub const DEFAULT_TRAVEL_MM: [[f64; 2]; 3] = [[-150.0, 150.0], [-150.0, 150.0], [-50.0, 50.0]];

/// Decimals of a coordinate in mm (a CAM post's usual format: 0.1 µm).
pub const MM_DECIMALS: usize = 4;
/// Decimals of a coordinate in inches (2.54 µm: the usual inch post format).
pub const INCH_DECIMALS: usize = 4;
/// Exact inch (mm).
const MM_PER_INCH: f64 = 25.4;
/// Clearance height of the programs that lift the tool between cuts (mm).
const CLEARANCE_Z_MM: f64 = 5.0;
/// Plunge feed down to the first cut (mm/min): slow, as posts write it.
const PLUNGE_FEED_MM_MIN: f64 = 1000.0;

// ---------------------------------------------------------------- circle_chords

/// Radius of [`circle_chords`]' circle (mm; 1 inch).
pub const CIRCLE_RADIUS_MM: f64 = 25.4;
/// G1 chords of [`circle_chords`] (0.016 mm each).
pub const CIRCLE_CHORDS: usize = 10_000;
/// Feed of [`circle_chords`] (mm/min = 1,667 mm/s, far above the axes' 250 mm/s).
pub const CIRCLE_FEED_MM_MIN: f64 = 100_000.0;

// ---------------------------------------------------------------- collinear_tiny

/// G1 moves of [`collinear_tiny`].
pub const COLLINEAR_MOVES: usize = 3_000;
/// Length of each move of [`collinear_tiny`] (mm; 0.001 in): 1e-4 mm units, exact in 4
/// decimals.
pub const COLLINEAR_STEP_MM: f64 = 0.0254;
/// Same step in units of the last decimal (1e-4 mm), so that the coordinates are
/// computed in integers and written exactly.
const COLLINEAR_STEP_E4: i64 = 254;
/// Feed of [`collinear_tiny`] (mm/min).
pub const COLLINEAR_FEED_MM_MIN: f64 = 6000.0;

// ---------------------------------------------------------------- surfacing_3d / huge

/// The surface both rasters follow (mm): z = 2·sin(x/12)·cos(y/17) − 1, smooth (radius of
/// curvature ≥ 72 mm), between −3 and +1 mm.
pub fn surface_z_mm(x_mm: f64, y_mm: f64) -> f64 {
    SURFACE_AMPLITUDE_MM * (x_mm / SURFACE_X_SCALE_MM).sin() * (y_mm / SURFACE_Y_SCALE_MM).cos()
        - SURFACE_OFFSET_MM
}
/// Amplitude of [`surface_z_mm`] (mm).
const SURFACE_AMPLITUDE_MM: f64 = 2.0;
/// Length scales of [`surface_z_mm`] along X and Y (mm per radian).
const SURFACE_X_SCALE_MM: f64 = 12.0;
const SURFACE_Y_SCALE_MM: f64 = 17.0;
/// Depth of [`surface_z_mm`]'s mean below the work origin (mm).
const SURFACE_OFFSET_MM: f64 = 1.0;

/// Raster passes of [`surfacing_3d`] (along X, alternating direction).
pub const SURFACING_PASSES: usize = 23;
/// Length of each pass of [`surfacing_3d`] (mm, X from −40 to +40).
pub const SURFACING_PASS_MM: f64 = 80.0;
/// Distance between passes of [`surfacing_3d`] (mm; 23 passes cover Y from −29.7 to
/// +29.7).
///
/// 2.7 mm, not 1 mm: at 1 mm over 80 × 60 mm the raster would be 61 passes and
/// 5,000-7,000 moves, beyond the 1,900-2,500 of the surfacing benchmark case; the area (the surface's
/// whole shape) is kept and the stepover widened instead.
pub const SURFACING_STEPOVER_MM: f64 = 2.7;
/// Chord-height tolerance of [`surfacing_3d`]'s chords (mm): each chord is as long as this
/// sag allows on the pass's curvature, within [`SURFACING_CHORD_MM`].
pub const SURFACING_SAG_MM: f64 = 4e-4;
/// Shortest and longest chord of [`surfacing_3d`] (mm).
pub const SURFACING_CHORD_MM: [f64; 2] = [0.25, 1.0];
/// Feed of [`surfacing_3d`] (in/min: 50.8 mm/s).
pub const SURFACING_FEED_IN_MIN: f64 = 120.0;
/// Feed moves (G1) of [`surfacing_3d`]: the plunge, the chords and the links.
pub const SURFACING_FEED_MOVES: usize = 2_384;
/// Programmed path of [`surfacing_3d`] (mm, rapids included), to 0.1 %.
pub const SURFACING_PATH_MM: f64 = 1_972.0;

/// Raster passes of [`huge`].
pub const HUGE_PASSES: usize = 212;
/// Length of each pass of [`huge`] (mm, X from −100 to +100).
pub const HUGE_PASS_MM: f64 = 200.0;
/// Distance between passes of [`huge`] (mm; Y from −105.5 to +105.5).
pub const HUGE_STEPOVER_MM: f64 = 1.0;
/// Chord of [`huge`] along X (mm): 800 per pass, exact in 4 decimals.
pub const HUGE_CHORD_MM: f64 = 0.25;
/// Feed of [`huge`] (mm/min).
pub const HUGE_FEED_MM_MIN: f64 = 6000.0;
/// Lines of [`huge`]'s text.
pub const HUGE_LINES: usize = 169_822;
/// Feed moves (G1) of [`huge`]: the plunge, 212 × 800 chords, 211 links.
pub const HUGE_FEED_MOVES: usize = 1 + HUGE_PASSES * 800 + (HUGE_PASSES - 1);
/// Programmed path of [`huge`] (mm, rapids included), to 0.1 %.
pub const HUGE_PATH_MM: f64 = 42_916.0;

// ---------------------------------------------------------------- spiral_arcs

/// Radius where [`spiral_arcs`] starts and ends (mm).
pub const SPIRAL_OUTER_MM: f64 = 40.0;
/// Radius at the spiral's centre (mm).
pub const SPIRAL_INNER_MM: f64 = 2.0;
/// Radius lost per quarter turn (mm: 2 mm per turn, a pocketing stepover).
pub const SPIRAL_STEP_MM: f64 = 0.5;
/// Quarter-turn arcs of each of the two spirals (in with G3 at Z−1, out with G2 at Z−2).
pub const SPIRAL_ARCS_PER_SPIRAL: usize = 76;
/// Feed of [`spiral_arcs`] (mm/min).
pub const SPIRAL_FEED_MM_MIN: f64 = 3000.0;
/// Largest difference of an arc's end radius from its start radius (mm): both ends and
/// the centre are rounded to 4 decimals, so the ends agree to ~1.5e-4 mm.
pub const SPIRAL_RADIUS_MISMATCH_MAX_MM: f64 = 0.002;
/// Programmed path of [`spiral_arcs`] (mm, rapids included), to 0.1 %.
pub const SPIRAL_PATH_MM: f64 = 5_074.0;

// ---------------------------------------------------------------- zigzag

/// Zigzag moves of [`zigzag`] (after the plunge; row links included).
pub const ZIGZAG_MOVES: usize = 1_000;
/// X range of the pocket (mm).
pub const ZIGZAG_X_MM: [f64; 2] = [-20.0, 20.0];
/// Top of the first row (mm).
const ZIGZAG_TOP_MM: f64 = 15.0;
/// Height of a row's band, drawn per row (mm): each move goes from the band's top to its
/// bottom or back, so its length is the band height over the sine of its angle.
const ZIGZAG_BAND_MM: [f64; 2] = [0.5, 1.5];
/// Angle of a move to the row's direction, drawn per move (rad: 30-75°): the corner
/// between two moves of a row is the sum of their angles, 60-150°.
const ZIGZAG_ANGLE_RAD: [f64; 2] = [PI / 6.0, 5.0 * PI / 12.0];
/// Gap between one row's band and the next (mm): the row link is 0.5-2 mm in −Y.
const ZIGZAG_GAP_MM: f64 = 0.5;
/// Depth of the pocket (mm).
const ZIGZAG_Z_MM: f64 = -1.0;
/// Feed of [`zigzag`] (mm/min).
pub const ZIGZAG_FEED_MM_MIN: f64 = 4000.0;
/// Seed of [`zigzag`]'s pseudo-random draws (fixed: the program is the same every time).
pub const ZIGZAG_SEED: u64 = 0x6A61_6E74_7279_0001;
/// Programmed path of [`zigzag`] (mm, rapids included), to 0.1 %.
pub const ZIGZAG_PATH_MM: f64 = 1_172.0;

// ---------------------------------------------------------------- dense_curve_3d

/// G1 chords of [`dense_curve_3d`].
pub const DENSE_CURVE_CHORDS: usize = 5_000;
/// Angle swept around Z by the curve (rad: 8.8 turns); equal steps in angle, so the chords
/// are as long as the radius makes them: 0.07-0.2 mm.
pub const DENSE_CURVE_SWEEP_RAD: f64 = 55.5;
/// Radius of the curve: 12 + 6·sin(0.3·θ) mm (6-18 mm).
const DENSE_CURVE_RADIUS_MM: [f64; 2] = [12.0, 6.0];
const DENSE_CURVE_RADIUS_RATE: f64 = 0.3;
/// Pitch of the curve: 1 + 0.5·cos(θ/2) mm per turn (0.5-1.5), descending.
const DENSE_CURVE_PITCH_MM: [f64; 2] = [1.0, 0.5];
const DENSE_CURVE_PITCH_RATE: f64 = 0.5;
/// Feed of [`dense_curve_3d`] (mm/min = 150 mm/s).
pub const DENSE_CURVE_FEED_MM_MIN: f64 = 9000.0;
/// Programmed path of [`dense_curve_3d`] (mm, rapids included), to 0.1 %.
pub const DENSE_CURVE_PATH_MM: f64 = 738.0;

// ---------------------------------------------------------------- rest_to_rest

/// Lengths of the rest-to-rest lines (mm).
pub const REST_TO_REST_LENGTHS_MM: [f64; 8] = [0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 300.0];
/// Feed of the rest-to-rest lines (mm/min = 250 mm/s along the path): the axis' own limit
/// along X; at 45° and along the diagonal it binds before the axes (177 and 144 mm/s per
/// axis of their 250), so a time-optimal comparison takes it as a path speed limit.
pub const REST_TO_REST_FEED_MM_MIN: f64 = 15_000.0;

/// Direction of a rest-to-rest line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Direction {
    /// Along +X.
    X,
    /// At 45° in XY: (1, 1, 0)/√2.
    Xy,
    /// Along the space diagonal (1, −1, 1)/√3.
    Xyz,
}

impl Direction {
    /// Every direction, in the order of the tables.
    pub const ALL: [Direction; 3] = [Direction::X, Direction::Xy, Direction::Xyz];

    /// The unit vector.
    pub fn unit(self) -> [f64; 3] {
        match self {
            Direction::X => [1.0, 0.0, 0.0],
            Direction::Xy => [1.0, 1.0, 0.0].map(|c| c / 2f64.sqrt()),
            Direction::Xyz => [1.0, -1.0, 1.0].map(|c| c / 3f64.sqrt()),
        }
    }

    /// What it is, for a program's comment (no parentheses: it goes inside one).
    pub fn describe(self) -> &'static str {
        match self {
            Direction::X => "along X",
            Direction::Xy => "at 45 degrees in XY",
            Direction::Xyz => "along the space diagonal X+ Y- Z+",
        }
    }

    /// Its name in file names (`r2r_<name>_<len>.nc`).
    pub fn name(self) -> &'static str {
        match self {
            Direction::X => "x",
            Direction::Xy => "xy",
            Direction::Xyz => "xyz",
        }
    }
}

// ---------------------------------------------------------------- writing

/// A coordinate with `decimals` decimals, never `-0.0000`.
fn coord(v: f64, decimals: usize) -> String {
    let s = format!("{v:.decimals$}");
    if s.trim_start_matches('-')
        .bytes()
        .all(|b| b == b'0' || b == b'.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

/// The program's opening: `%`, the comment naming it and its generator (a function of
/// this module), the modal header with `units` (`G21` or `G20`) and the path-control
/// line `blend` (`G64 P0.01`, `G61`, …). `what` is inside a comment: no parentheses.
fn header(name: &str, generator: &str, what: &str, units: &str, blend: &str) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "%");
    let _ = writeln!(
        s,
        "({name}: {what}; generated by host_sim::bench_programs::{generator}, do not edit)"
    );
    let _ = writeln!(s, "{units} G90 G17 G94 G54");
    let _ = writeln!(s, "{blend}");
    s
}

/// The program's end: `M30` and `%`.
fn footer(s: &mut String) {
    let _ = writeln!(s, "M30");
    let _ = writeln!(s, "%");
}

/// A feed in the program's units per minute, as posts write it.
fn feed(f: f64) -> String {
    let s = format!("{f:.1}");
    s.strip_suffix(".0").map_or(s.clone(), str::to_string)
}

// ---------------------------------------------------------------- the programs

/// A 25.4 mm-radius circle in XY around the origin as [`CIRCLE_CHORDS`] G1 chords at
/// F100000 (`G64` without P: the machine's default tolerance), after a G0 to its start
/// point (25.4, 0, 0). 1 rapid + 10,000 feed moves, 185.0 mm of path: the rapid's 25.4
/// and the circle's 2π·25.4 = 159.59 (the 4-decimal rounding changes it by < 0.01 %).
pub fn circle_chords() -> String {
    let mut s = header(
        "circle_chords",
        "circle_chords",
        "R25.4 mm circle as 10,000 G1 chords at F100000",
        "G21",
        "G64",
    );
    let point = |i: usize| {
        let a = TAU * (i % CIRCLE_CHORDS) as f64 / CIRCLE_CHORDS as f64;
        [CIRCLE_RADIUS_MM * a.cos(), CIRCLE_RADIUS_MM * a.sin()].map(|v| coord(v, MM_DECIMALS))
    };
    let [x0, y0] = point(0);
    let _ = writeln!(s, "G0 X{x0} Y{y0}");
    for i in 1..=CIRCLE_CHORDS {
        let [x, y] = point(i);
        if i == 1 {
            let _ = writeln!(s, "G1 X{x} Y{y} F{}", feed(CIRCLE_FEED_MM_MIN));
        } else {
            let _ = writeln!(s, "X{x} Y{y}");
        }
    }
    footer(&mut s);
    s
}

/// [`COLLINEAR_MOVES`] G1 moves of 0.0254 mm along +X at F6000 (`G64`), from X−38.1 to
/// X+38.1 after a G0 to the first: 1 rapid + 3,000 feed moves, 114.3 mm of path (38.1 of
/// it the rapid).
pub fn collinear_tiny() -> String {
    let mut s = header(
        "collinear_tiny",
        "collinear_tiny",
        "3,000 collinear 0.0254 mm G1 moves along X at F6000",
        "G21",
        "G64",
    );
    // in units of 1e-4 mm: every coordinate exact
    let n = i64::try_from(COLLINEAR_MOVES).unwrap_or(i64::MAX);
    let x0 = -n * COLLINEAR_STEP_E4 / 2;
    let x_text = |e4: i64| coord(e4 as f64 / 1e4, MM_DECIMALS);
    let _ = writeln!(s, "G0 X{} Y0.0000", x_text(x0));
    for i in 1..=n {
        let x = x_text(x0 + i * COLLINEAR_STEP_E4);
        if i == 1 {
            let _ = writeln!(s, "G1 X{x} F{}", feed(COLLINEAR_FEED_MM_MIN));
        } else {
            let _ = writeln!(s, "X{x}");
        }
    }
    footer(&mut s);
    s
}

/// Units a program is written in.
#[derive(Clone, Copy)]
enum Units {
    /// `G21`, [`MM_DECIMALS`].
    Mm,
    /// `G20`, [`INCH_DECIMALS`].
    Inch,
}

impl Units {
    /// A length in mm as the program writes it.
    fn text(self, mm: f64) -> String {
        match self {
            Units::Mm => coord(mm, MM_DECIMALS),
            Units::Inch => coord(mm / MM_PER_INCH, INCH_DECIMALS),
        }
    }

    /// A point in mm as `X… Y… Z…`.
    fn xyz(self, p: [f64; 3]) -> String {
        let [x, y, z] = p.map(|v| self.text(v));
        format!("X{x} Y{y} Z{z}")
    }

    /// A feed in mm/min as the program writes it (mm/min or in/min).
    fn feed(self, mm_min: f64) -> String {
        match self {
            Units::Mm => feed(mm_min),
            Units::Inch => feed(mm_min / MM_PER_INCH),
        }
    }
}

/// The shape of a raster over [`surface_z_mm`].
struct Raster<'a> {
    /// Passes along X, alternating direction, from Y = −(passes − 1)·stepover/2 up.
    passes: usize,
    /// X where the passes start and end (mm).
    x_mm: [f64; 2],
    /// Distance between passes (mm): the length of the links along the passes' ends.
    stepover_mm: f64,
    /// Length of the chord from (x, y) on (mm).
    chord_mm: &'a dyn Fn(f64, f64) -> f64,
    /// Feed on the surface (mm/min).
    feed_mm_min: f64,
    units: Units,
}

/// Write `r`: up to the clearance, across to the first pass's start, the plunge onto the
/// surface, the passes with their links (straight lines on the surface), up again.
fn raster(s: &mut String, r: &Raster) {
    let u = r.units;
    let y0 = -((r.passes.max(1) - 1) as f64) * r.stepover_mm / 2.0;
    let at = |x: f64, y: f64| [x, y, surface_z_mm(x, y)];
    let clearance = format!("G0 Z{}", u.text(CLEARANCE_Z_MM));
    let _ = writeln!(s, "{clearance}");
    let _ = writeln!(s, "G0 X{} Y{}", u.text(r.x_mm[0]), u.text(y0));
    let _ = writeln!(
        s,
        "G1 {} F{}",
        u.xyz(at(r.x_mm[0], y0)),
        u.feed(PLUNGE_FEED_MM_MIN)
    );
    let _ = writeln!(s, "F{}", u.feed(r.feed_mm_min));
    for pass in 0..r.passes {
        let y = y0 + pass as f64 * r.stepover_mm;
        let (from, to) = if pass % 2 == 0 {
            (r.x_mm[0], r.x_mm[1])
        } else {
            (r.x_mm[1], r.x_mm[0])
        };
        if pass > 0 {
            let _ = writeln!(s, "{}", u.xyz(at(from, y)));
        }
        let dir = (to - from).signum();
        let mut x = from;
        while (to - x) * dir > 0.0 {
            let step = (r.chord_mm)(x, y);
            // the last chord ends on the pass's end; a remainder under half a chord is
            // merged into it rather than written as a sliver
            let next = if (to - (x + dir * step)) * dir < 0.5 * step {
                to
            } else {
                x + dir * step
            };
            let _ = writeln!(s, "{}", u.xyz(at(next, y)));
            x = next;
        }
    }
    let _ = writeln!(s, "{clearance}");
}

/// Radius of curvature of [`surface_z_mm`] along X at (x, y) (mm; infinite where flat).
fn surface_radius_x_mm(x: f64, y: f64) -> f64 {
    let k = SURFACE_AMPLITUDE_MM / SURFACE_X_SCALE_MM;
    let slope = k * (x / SURFACE_X_SCALE_MM).cos() * (y / SURFACE_Y_SCALE_MM).cos();
    let curv =
        (k / SURFACE_X_SCALE_MM * (x / SURFACE_X_SCALE_MM).sin() * (y / SURFACE_Y_SCALE_MM).cos())
            .abs();
    if curv > 0.0 {
        (1.0 + slope * slope).powf(1.5) / curv
    } else {
        f64::INFINITY
    }
}

/// A 3-D finishing raster in inches (`G20`, `G64 P0.001`, F120 in/min) over
/// [`surface_z_mm`] on 80 × 60 mm (X ±40, Y ±29.7): [`SURFACING_PASSES`] = 23 passes
/// along X, [`SURFACING_STEPOVER_MM`] = 2.7 mm apart, of chords as long as a CAM's chord
/// tolerance ([`SURFACING_SAG_MM`]) allows on the surface's curvature within its limits
/// of 0.25-1 mm (0.48-1 mm of X here; each pass's last chord, to its end, 0.5-1.5 mm),
/// joined by 2.7 mm links on the surface; coordinates in inches with 4 decimals. 2
/// rapids up, 1 across, [`SURFACING_FEED_MOVES`] = 2,384 feed moves (the plunge, 2,361
/// chords, 22 links), 1,972 mm of path, 39 s at the feed.
pub fn surfacing_3d() -> String {
    let mut s = header(
        "surfacing_3d",
        "surfacing_3d",
        "3-D finishing raster over z = 2 sin x/12 cos y/17 - 1 mm, in inches",
        "G20",
        "G64 P0.001",
    );
    let chord = |x: f64, y: f64| {
        let [lo, hi] = SURFACING_CHORD_MM;
        // sag of a chord c on radius r: c²/(8 r)
        (8.0 * SURFACING_SAG_MM * surface_radius_x_mm(x, y))
            .sqrt()
            .clamp(lo, hi)
    };
    let half = SURFACING_PASS_MM / 2.0;
    raster(
        &mut s,
        &Raster {
            passes: SURFACING_PASSES,
            x_mm: [-half, half],
            stepover_mm: SURFACING_STEPOVER_MM,
            chord_mm: &chord,
            feed_mm_min: SURFACING_FEED_IN_MIN * MM_PER_INCH,
            units: Units::Inch,
        },
    );
    footer(&mut s);
    s
}

/// The big finishing program: [`HUGE_PASSES`] passes of 200 mm along X over
/// [`surface_z_mm`] (X ±100, Y ±105.5, 1 mm apart), chords of 0.25 mm along X, links of
/// 1 mm, `G64 P0.01`, F6000, 4 decimals in mm: [`HUGE_LINES`] = 169,822 lines,
/// [`HUGE_FEED_MOVES`] = 169,812 feed moves (the plunge, 169,600 chords, 211 links),
/// 3 rapids, 42.9 m of path (7.2 minutes at the feed).
pub fn huge() -> String {
    let mut s = header(
        "huge",
        "huge",
        "170,000-line 3-D finishing raster, 0.25 mm chords",
        "G21",
        "G64 P0.01",
    );
    let half = HUGE_PASS_MM / 2.0;
    raster(
        &mut s,
        &Raster {
            passes: HUGE_PASSES,
            x_mm: [-half, half],
            stepover_mm: HUGE_STEPOVER_MM,
            chord_mm: &|_, _| HUGE_CHORD_MM,
            feed_mm_min: HUGE_FEED_MM_MIN,
            units: Units::Mm,
        },
    );
    footer(&mut s);
    s
}

/// The centre of the arc from `a` to `b` nearest to the origin (the spiral's axis): the
/// origin projected on the chord's perpendicular bisector, so both ends are on its circle.
fn centre_towards_origin(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    let m = [(a[0] + b[0]) / 2.0, (a[1] + b[1]) / 2.0];
    let d = [b[0] - a[0], b[1] - a[1]];
    let len = d[0].hypot(d[1]);
    if len == 0.0 {
        return m;
    }
    let n = [-d[1] / len, d[0] / len];
    let t = -(m[0] * n[0] + m[1] * n[1]);
    [m[0] + t * n[0], m[1] + t * n[1]]
}

/// Parse back a coordinate just written (so the centre is computed from the rounded
/// ends the parser will see).
fn rounded(v: f64) -> f64 {
    coord(v, MM_DECIMALS).parse().unwrap_or(v)
}

/// An Archimedean spiral of quarter-turn arcs (`G64 P0.01`, F3000): in from r = 40 mm to
/// r = 2 mm counter-clockwise (G3) at Z−1, 0.5 mm of radius per quarter turn, then down to
/// Z−2 and out again clockwise (G2) to r = 40 mm; [`SPIRAL_ARCS_PER_SPIRAL`] = 76 arcs each.
/// Each arc's centre (I, J) is the point of its chord's bisector nearest the spiral's
/// axis, computed from the rounded ends and rounded itself: its ends agree with I/J within
/// 2e-4 mm ([`SPIRAL_RADIUS_MISMATCH_MAX_MM`]). 3 rapids, 2 feed lines (plunges), 152
/// arcs, 5,074 mm of path.
pub fn spiral_arcs() -> String {
    let mut s = header(
        "spiral_arcs",
        "spiral_arcs",
        "Archimedean spiral of quarter-turn G2/G3 arcs, r 40 -> 2 -> 40 mm",
        "G21",
        "G64 P0.01",
    );
    let n = SPIRAL_ARCS_PER_SPIRAL;
    // point k of a spiral: radius from `r0` by `dr` per quarter, angle `sign`·k·90°
    let pt = |r0: f64, dr: f64, sign: f64, k: usize| {
        let r = r0 + dr * k as f64;
        let a = sign * FRAC_PI_2 * k as f64;
        [rounded(r * a.cos()), rounded(r * a.sin())]
    };
    let arcs = |s: &mut String, code: &str, r0: f64, dr: f64, sign: f64| {
        for k in 0..n {
            let a = pt(r0, dr, sign, k);
            let b = pt(r0, dr, sign, k + 1);
            let c = centre_towards_origin(a, b).map(rounded);
            let (i, j) = (
                coord(c[0] - a[0], MM_DECIMALS),
                coord(c[1] - a[1], MM_DECIMALS),
            );
            let (x, y) = (coord(b[0], MM_DECIMALS), coord(b[1], MM_DECIMALS));
            if k == 0 {
                let _ = writeln!(
                    s,
                    "{code} X{x} Y{y} I{i} J{j} F{}",
                    feed(SPIRAL_FEED_MM_MIN)
                );
            } else {
                let _ = writeln!(s, "{code} X{x} Y{y} I{i} J{j}");
            }
        }
    };
    let start = pt(SPIRAL_OUTER_MM, 0.0, 1.0, 0);
    let _ = writeln!(s, "G0 Z{}", coord(CLEARANCE_Z_MM, MM_DECIMALS));
    let _ = writeln!(
        s,
        "G0 X{} Y{}",
        coord(start[0], MM_DECIMALS),
        coord(start[1], MM_DECIMALS)
    );
    let _ = writeln!(s, "G1 Z-1.0000 F{}", feed(PLUNGE_FEED_MM_MIN));
    arcs(&mut s, "G3", SPIRAL_OUTER_MM, -SPIRAL_STEP_MM, 1.0);
    let _ = writeln!(s, "G1 Z-2.0000 F{}", feed(PLUNGE_FEED_MM_MIN));
    // out again clockwise from where the inward spiral ended: r = 2 mm at 76 × 90° = 0°
    arcs(&mut s, "G2", SPIRAL_INNER_MM, SPIRAL_STEP_MM, -1.0);
    let _ = writeln!(s, "G0 Z{}", coord(CLEARANCE_Z_MM, MM_DECIMALS));
    footer(&mut s);
    s
}

/// A zigzag pocket (`G64 P0.02`, F4000) at Z−1 over X ±20 from Y+15 down: rows in
/// alternating X direction, each in a band 0.5-1.5 mm high, every move from the band's
/// top to its bottom or back at 30-75° to the row (moves of 0.5-3 mm, corners of 60-150°
/// between them), rows joined by a 0.5-2 mm link in −Y (15-165° corners there); draws
/// from [`ZIGZAG_SEED`]. 3 rapids, the plunge and [`ZIGZAG_MOVES`] = 1,000 zigzag moves
/// in 19 rows (Y from +15 down to −10), 1,172 mm of path.
pub fn zigzag() -> String {
    let mut s = header(
        "zigzag",
        "zigzag",
        "zigzag pocket, 1,000 moves of 0.5-3 mm with 60-150 degree corners",
        "G21",
        "G64 P0.02",
    );
    let mut rng = SplitMix64::new(ZIGZAG_SEED);
    let [x_lo, x_hi] = ZIGZAG_X_MM;
    let (mut x, mut y) = (x_lo, ZIGZAG_TOP_MM);
    let _ = writeln!(s, "G0 Z{}", coord(CLEARANCE_Z_MM, MM_DECIMALS));
    let _ = writeln!(
        s,
        "G0 X{} Y{}",
        coord(x, MM_DECIMALS),
        coord(y, MM_DECIMALS)
    );
    let _ = writeln!(
        s,
        "G1 Z{} F{}",
        coord(ZIGZAG_Z_MM, MM_DECIMALS),
        feed(PLUNGE_FEED_MM_MIN)
    );
    let _ = writeln!(s, "F{}", feed(ZIGZAG_FEED_MM_MIN));
    let mut moves = 0usize;
    let mut top = ZIGZAG_TOP_MM;
    let mut dir = 1.0f64;
    // the shortest advance a move may make: at the largest angle
    let min_advance = |h: f64| h / ZIGZAG_ANGLE_RAD[1].tan();
    let line = |s: &mut String, x: f64, y: f64| {
        let _ = writeln!(s, "X{} Y{}", coord(x, MM_DECIMALS), coord(y, MM_DECIMALS));
    };
    'rows: while moves < ZIGZAG_MOVES {
        let h = rng.uniform(ZIGZAG_BAND_MM[0], ZIGZAG_BAND_MM[1]);
        let bottom = top - h;
        let wall = if dir > 0.0 { x_hi } else { x_lo };
        loop {
            let room = (wall - x) * dir;
            if room < min_advance(h) {
                break;
            }
            let angle = rng.uniform(ZIGZAG_ANGLE_RAD[0], ZIGZAG_ANGLE_RAD[1]);
            let advance = (h / angle.tan()).min(room);
            x += dir * advance;
            y = if y > bottom + h / 2.0 { bottom } else { top };
            line(&mut s, x, y);
            moves += 1;
            if moves == ZIGZAG_MOVES {
                break 'rows;
            }
        }
        // the link down to the next row's band, which runs the other way
        top = bottom - ZIGZAG_GAP_MM;
        y = top;
        line(&mut s, x, y);
        moves += 1;
        dir = -dir;
    }
    let _ = writeln!(s, "G0 Z{}", coord(CLEARANCE_Z_MM, MM_DECIMALS));
    footer(&mut s);
    s
}

/// The point of [`dense_curve_3d`]'s curve at angle `theta` (mm): radius 12 + 6 sin 0.3θ,
/// descending by 1 + 0.5 cos(θ/2) mm per turn from Z0.
pub fn dense_curve_point_mm(theta: f64) -> [f64; 3] {
    let r = DENSE_CURVE_RADIUS_MM[0]
        + DENSE_CURVE_RADIUS_MM[1] * (DENSE_CURVE_RADIUS_RATE * theta).sin();
    // z = −∫ pitch(θ)/2π dθ
    let z = -(DENSE_CURVE_PITCH_MM[0] * theta
        + DENSE_CURVE_PITCH_MM[1] / DENSE_CURVE_PITCH_RATE
            * (DENSE_CURVE_PITCH_RATE * theta).sin())
        / TAU;
    [r * theta.cos(), r * theta.sin(), z]
}

/// A 3-D space curve (a helix whose radius and pitch vary, [`dense_curve_point_mm`]) as
/// [`DENSE_CURVE_CHORDS`] = 5,000 G1 chords of 0.07-0.2 mm in equal steps of angle,
/// 4 decimals, `G64 P0.01`, F9000: 3 rapids, the plunge and 5,000 chords (about 700 mm,
/// 8.8 turns down to Z−8.9), 738 mm of path.
pub fn dense_curve_3d() -> String {
    let mut s = header(
        "dense_curve_3d",
        "dense_curve_3d",
        "3-D helix of varying radius and pitch as 5,000 G1 chords of 0.07-0.2 mm",
        "G21",
        "G64 P0.01",
    );
    let p0 = dense_curve_point_mm(0.0);
    let _ = writeln!(s, "G0 Z{}", coord(CLEARANCE_Z_MM, MM_DECIMALS));
    let _ = writeln!(
        s,
        "G0 X{} Y{}",
        coord(p0[0], MM_DECIMALS),
        coord(p0[1], MM_DECIMALS)
    );
    let _ = writeln!(s, "G1 {} F{}", Units::Mm.xyz(p0), feed(PLUNGE_FEED_MM_MIN));
    let _ = writeln!(s, "F{}", feed(DENSE_CURVE_FEED_MM_MIN));
    for i in 1..=DENSE_CURVE_CHORDS {
        let theta = DENSE_CURVE_SWEEP_RAD * i as f64 / DENSE_CURVE_CHORDS as f64;
        let _ = writeln!(s, "{}", Units::Mm.xyz(dense_curve_point_mm(theta)));
    }
    let _ = writeln!(s, "G0 Z{}", coord(CLEARANCE_Z_MM, MM_DECIMALS));
    footer(&mut s);
    s
}

/// One line from rest at the origin (where the machine starts) to rest at `len_mm` along
/// `dir`, under `G61` at F15000: the only move, so `cargo sim gcode`'s `duration_s` is the
/// line's time. The end point is rounded to 4 decimals (the length with it: 0.1 mm along
/// the diagonal is 0.09994 mm; `ruckig_lines.py` reads the end point back from the file).
/// A `len_mm` that is not finite gives a program the parser rejects.
pub fn rest_to_rest(len_mm: f64, dir: Direction) -> String {
    let mut s = header(
        &rest_to_rest_name(len_mm, dir),
        "rest_to_rest",
        &format!("rest-to-rest line of {len_mm} mm {}", dir.describe()),
        "G21",
        "G61",
    );
    let u = dir.unit();
    let _ = writeln!(
        s,
        "G1 {} F{}",
        Units::Mm.xyz(u.map(|c| c * len_mm)),
        feed(REST_TO_REST_FEED_MM_MIN)
    );
    footer(&mut s);
    s
}

/// Whether the line of [`rest_to_rest`]`(len_mm, dir)` from the origin stays within
/// [`DEFAULT_TRAVEL_MM`].
pub fn rest_to_rest_fits(len_mm: f64, dir: Direction) -> bool {
    let u = dir.unit();
    (0..3).all(|a| {
        let end = u[a] * len_mm;
        let [lo, hi] = DEFAULT_TRAVEL_MM[a];
        end >= lo && end <= hi
    })
}

/// File stem of a rest-to-rest case: `r2r_<dir>_<len>` (`r2r_xyz_0.3`).
pub fn rest_to_rest_name(len_mm: f64, dir: Direction) -> String {
    format!("r2r_{}_{}", dir.name(), len_mm)
}

/// The rest-to-rest cases of the set: every length of [`REST_TO_REST_LENGTHS_MM`] in every
/// [`Direction`] whose line from the origin stays within the default machine's travel, as
/// `(name, len_mm, dir)`. Left out: 300 mm along X (X would reach 300 of 150), 300 mm at
/// 45° (212 of 150), 100 and 300 mm along the diagonal (Z 57.7 and 173 of 50).
pub fn rest_to_rest_cases() -> Vec<(String, f64, Direction)> {
    Direction::ALL
        .iter()
        .flat_map(|&d| {
            REST_TO_REST_LENGTHS_MM
                .iter()
                .filter(move |&&l| rest_to_rest_fits(l, d))
                .map(move |&l| (rest_to_rest_name(l, d), l, d))
        })
        .collect()
}

/// The set except [`huge`] and the rest-to-rest lines, as `(name, text)`, in the order of
/// the table above.
pub fn all() -> Vec<(&'static str, String)> {
    vec![
        ("circle_chords", circle_chords()),
        ("collinear_tiny", collinear_tiny()),
        ("surfacing_3d", surfacing_3d()),
        ("spiral_arcs", spiral_arcs()),
        ("zigzag", zigzag()),
        ("dense_curve_3d", dense_curve_3d()),
    ]
}
