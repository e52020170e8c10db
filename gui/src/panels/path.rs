//! The tool path tab: the loaded program's path in 2-D (XY, XZ or YZ, equal aspect, mm
//! on the axes) or 3-D (an orthographic view turned by dragging, with an X/Y/Z triad),
//! rapids dashed and light apart from the cuts, the segment being executed highlighted,
//! the tool's live position, and the executed path (the trail) coloured by contour error
//! against the program tolerance.
//!
//! Fast whatever the program's and the trail's length: the program's polyline (arcs
//! sampled once with the planner's own helix, [`Helix`]) is built once per loaded
//! program ([`ProgramPath`]); what is drawn is projected, decimated to the screen's pixels
//! and tessellated into a mesh only when the view changes, and the trail is meshed in
//! chunks that are kept once full, so a frame with nothing new re-sends cached meshes.

use crate::app::GantryApp;
use crate::live::TrailPoint;
use crate::session::LoadedProgram;
use egui::epaint::{Mesh, PathShape, TessellationOptions, Tessellator};
use egui::{Align2, Color32, FontId, Pos2, Rect, Sense, Shape, Stroke, Vec2};
use host_sim::gcode::measure::distance::Helix;
use host_sim::gcode::{Move, MoveKind};
use std::hash::{Hash, Hasher};
use std::sync::Arc;

/// The program tolerance when the machine's settings do not say (mm).
pub const DEFAULT_TOLERANCE_MM: f64 = 0.01;
/// The settings key of the program tolerance.
const TOLERANCE_KEY: &str = "planner.tolerance_mm";
/// Largest distance of an arc's chord from the arc in the drawn polyline (mm): below a
/// pixel at any zoom an operator uses, and a 50 mm radius takes ~0.8° steps.
pub const ARC_CHORD_ERROR_MM: f64 = 0.002;
/// Pieces of one arc at most (a 1 m radius full circle at the chord error above needs
/// ~2,200; a multi-turn helix more, then the chord error grows).
const ARC_MAX_PIECES: usize = 20_000;
/// Trail points per cached mesh chunk (the last, growing chunk is rebuilt each frame).
const TRAIL_CHUNK: usize = 8192;
/// A polyline keeps a point only this far (screen points) from the last one kept.
const MIN_STEP_PT: f32 = 0.7;
/// Zoom limits (screen points per mm).
const SCALE_RANGE: (f32, f32) = (1e-3, 1e5);

/// Which view of the path.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Projection {
    #[default]
    XY,
    XZ,
    YZ,
    /// Orthographic 3-D, turned by dragging.
    ThreeD,
}

impl Projection {
    const ALL: [Projection; 4] = [Self::XY, Self::XZ, Self::YZ, Self::ThreeD];
    fn label(self) -> &'static str {
        match self {
            Self::XY => "XY",
            Self::XZ => "XZ",
            Self::YZ => "YZ",
            Self::ThreeD => "3-D",
        }
    }
    /// Axis names of the screen's right and up directions (2-D views).
    fn axis_names(self) -> Option<(&'static str, &'static str)> {
        match self {
            Self::XY => Some(("X", "Y")),
            Self::XZ => Some(("X", "Z")),
            Self::YZ => Some(("Y", "Z")),
            Self::ThreeD => None,
        }
    }
}

/// The tab's state: the view, and the caches that keep it fast.
#[derive(Debug)]
pub struct PathView {
    /// Fit the view to the program at the next frame.
    pub fit: bool,
    pub projection: Projection,
    /// The view's centre in view coordinates (mm along the screen's right and up).
    pub center_mm: [f32; 2],
    /// Screen points per mm.
    pub scale_pt_per_mm: f32,
    /// 3-D: turn about Z and tilt (0: looking along +Y, π/2: from above), rad.
    pub yaw_rad: f32,
    pub pitch_rad: f32,
    pub show_rapids: bool,
    pub show_trail: bool,
    program: Option<ProgramPath>,
    program_mesh: Option<(MeshKey, Arc<Mesh>)>,
    trail_chunks: TrailChunks,
}

impl Default for PathView {
    fn default() -> Self {
        Self {
            fit: true,
            projection: Projection::XY,
            center_mm: [0.0; 2],
            scale_pt_per_mm: 2.0,
            yaw_rad: -0.6,
            pitch_rad: 0.9,
            show_rapids: true,
            show_trail: true,
            program: None,
            program_mesh: None,
            trail_chunks: TrailChunks::default(),
        }
    }
}

/// The program tolerance (mm) from the machine's settings, [`DEFAULT_TOLERANCE_MM`] when
/// absent or not a positive number.
pub fn tolerance_mm(settings: &[(String, String)]) -> f64 {
    settings
        .iter()
        .find(|(k, _)| k == TOLERANCE_KEY)
        .and_then(|(_, v)| v.trim().parse::<f64>().ok())
        .filter(|t| t.is_finite() && *t > 0.0)
        .unwrap_or(DEFAULT_TOLERANCE_MM)
}

/// The contour-error colour scale: green at 0, yellow half-way, red at the tolerance and
/// beyond (and for a NaN, which is not a good sign either).
pub fn contour_colour(contour_mm: f32, tolerance_mm: f32) -> Color32 {
    let f = contour_mm.abs() / tolerance_mm.max(f32::MIN_POSITIVE);
    let f = if f.is_nan() { 1.0 } else { f.clamp(0.0, 1.0) };
    scale_colour(f)
}

/// The scale at `f` in [0, 1].
fn scale_colour(f: f32) -> Color32 {
    let lerp = |a: u8, b: u8, t: f32| (f32::from(a) + (f32::from(b) - f32::from(a)) * t) as u8;
    let (g, y, r) = ([30u8, 170, 60], [230u8, 190, 0], [220u8, 30, 30]);
    let (a, b, t) = if f < 0.5 {
        (g, y, f * 2.0)
    } else {
        (y, r, (f - 0.5) * 2.0)
    };
    Color32::from_rgb(
        lerp(a[0], b[0], t),
        lerp(a[1], b[1], t),
        lerp(a[2], b[2], t),
    )
}

/// A run of moves of one kind drawn as one polyline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Run {
    /// Points `start..end` of [`ProgramPath::points_mm`].
    pub start: usize,
    pub end: usize,
    pub rapid: bool,
}

/// A program's polyline, built once per load.
#[derive(Debug)]
pub struct ProgramPath {
    key: u64,
    pub points_mm: Vec<[f32; 3]>,
    pub runs: Vec<Run>,
    /// Per program move, its points `start..end` (empty for dwell, pause, blend).
    pub move_points: Vec<(usize, usize)>,
    /// Extent of the points `[[min, max]; 3]` (None: no point).
    pub bounds_mm: Option<[[f32; 2]; 3]>,
}

/// A fingerprint of a program: the file, its size, and a sample of its moves (hashing
/// all 10,000 moves every frame would cost more than the rest of the tab).
fn program_key(p: &LoadedProgram) -> u64 {
    let mut h = std::collections::hash_map::DefaultHasher::new();
    p.path.hash(&mut h);
    p.lines.hash(&mut h);
    p.moves.len().hash(&mut h);
    let stride = (p.moves.len() / 64).max(1);
    for m in p.moves.iter().step_by(stride).chain(p.moves.last()) {
        m.line.hash(&mut h);
        for v in m.from.iter().chain(m.to().iter()) {
            v.to_bits().hash(&mut h);
        }
    }
    h.finish()
}

fn finite3(p: [f64; 3]) -> Option<[f32; 3]> {
    p.iter().all(|v| v.is_finite()).then(|| p.map(|v| v as f32))
}

/// Points of an arc after its start, its end last (exactly `to`).
pub fn arc_points(m: &Move, chord_error_mm: f64) -> Vec<[f64; 3]> {
    let Some(h) = Helix::of(m) else {
        return vec![m.to()];
    };
    let r_mm = h.r0_mm.max(h.radius_mm(h.sweep_rad)).abs();
    // the angle whose chord stays within the error of the circle: 2·acos(1 − e/r)
    let step_rad = if r_mm > chord_error_mm {
        2.0 * (1.0 - chord_error_mm / r_mm).acos()
    } else {
        std::f64::consts::FRAC_PI_2
    };
    let pieces = (h.sweep_rad / step_rad).ceil();
    let pieces = if pieces.is_finite() {
        (pieces as usize).clamp(1, ARC_MAX_PIECES)
    } else {
        1
    };
    let mut out: Vec<[f64; 3]> = (1..pieces)
        .map(|i| h.point(h.sweep_rad * i as f64 / pieces as f64))
        .collect();
    out.push(m.to());
    out
}

impl ProgramPath {
    /// The polyline of `program`'s moves: runs of cuts and of rapids, arcs sampled within
    /// `chord_error_mm`; non-finite points break a run and are left out.
    pub fn build(program: &LoadedProgram, chord_error_mm: f64) -> Self {
        let mut points_mm: Vec<[f32; 3]> = Vec::with_capacity(program.moves.len() + 1);
        let mut runs: Vec<Run> = Vec::new();
        let mut move_points = Vec::with_capacity(program.moves.len());
        let mut open: Option<Run> = None;
        for m in &program.moves {
            let (rapid, tail): (bool, Vec<[f64; 3]>) = match m.kind {
                MoveKind::Rapid { to } => (true, vec![to]),
                MoveKind::Line { to, .. } => (false, vec![to]),
                MoveKind::Arc { .. } => (false, arc_points(m, chord_error_mm)),
                _ => {
                    let at = points_mm.len();
                    move_points.push((at, at));
                    continue;
                }
            };
            let Some(from) = finite3(m.from) else {
                if let Some(r) = open.take() {
                    runs.push(r);
                }
                let at = points_mm.len();
                move_points.push((at, at));
                continue;
            };
            // continue the open run when this move is of its kind and starts at its end
            let continues = open
                .as_ref()
                .is_some_and(|r| r.rapid == rapid && points_mm.last() == Some(&from));
            if !continues {
                if let Some(r) = open.take() {
                    runs.push(r);
                }
                open = Some(Run {
                    start: points_mm.len(),
                    end: points_mm.len(),
                    rapid,
                });
                points_mm.push(from);
            }
            let first = points_mm.len() - 1;
            for p in tail {
                match finite3(p) {
                    Some(q) => points_mm.push(q),
                    None => break,
                }
            }
            if let Some(r) = open.as_mut() {
                r.end = points_mm.len();
            }
            move_points.push((first, points_mm.len()));
        }
        if let Some(r) = open.take() {
            runs.push(r);
        }
        runs.retain(|r| r.end > r.start + 1);
        let bounds_mm = bounds_of(points_mm.iter().copied());
        Self {
            key: program_key(program),
            points_mm,
            runs,
            move_points,
            bounds_mm,
        }
    }
}

fn bounds_of(points: impl Iterator<Item = [f32; 3]>) -> Option<[[f32; 2]; 3]> {
    let mut b: Option<[[f32; 2]; 3]> = None;
    for p in points.filter(|p| p.iter().all(|v| v.is_finite())) {
        let e = b.get_or_insert([[p[0], p[0]], [p[1], p[1]], [p[2], p[2]]]);
        for a in 0..3 {
            e[a][0] = e[a][0].min(p[a]);
            e[a][1] = e[a][1].max(p[a]);
        }
    }
    b
}

/// The view: machine mm to screen points (orthographic).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Camera {
    /// Unit vectors of the screen's right and up directions in machine coordinates.
    right: [f32; 3],
    up: [f32; 3],
    center_mm: [f32; 2],
    scale_pt_per_mm: f32,
    /// Screen point of `center_mm`.
    origin: Pos2,
}

impl Camera {
    fn view_mm(&self, p: [f32; 3]) -> [f32; 2] {
        let d = |a: [f32; 3]| a[0] * p[0] + a[1] * p[1] + a[2] * p[2];
        [d(self.right), d(self.up)]
    }
    fn screen_of(&self, p: [f32; 3]) -> Pos2 {
        let [u, v] = self.view_mm(p);
        Pos2::new(
            self.origin.x + (u - self.center_mm[0]) * self.scale_pt_per_mm,
            self.origin.y - (v - self.center_mm[1]) * self.scale_pt_per_mm,
        )
    }
    /// View coordinates (mm) of a screen point.
    fn view_of_screen(&self, s: Pos2) -> [f32; 2] {
        [
            self.center_mm[0] + (s.x - self.origin.x) / self.scale_pt_per_mm,
            self.center_mm[1] - (s.y - self.origin.y) / self.scale_pt_per_mm,
        ]
    }
}

impl PathView {
    fn camera(&self, rect: Rect) -> Camera {
        let (right, up) = match self.projection {
            Projection::XY => ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
            Projection::XZ => ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
            Projection::YZ => ([0.0, 1.0, 0.0], [0.0, 0.0, 1.0]),
            Projection::ThreeD => {
                let (sy, cy) = self.yaw_rad.sin_cos();
                let (sp, cp) = self.pitch_rad.sin_cos();
                ([cy, sy, 0.0], [-sy * sp, cy * sp, cp])
            }
        };
        Camera {
            right,
            up,
            center_mm: self.center_mm,
            scale_pt_per_mm: self.scale_pt_per_mm,
            origin: rect.center(),
        }
    }

    /// Centre and zoom on `bounds` (the program, else the trail).
    fn fit_to(&mut self, bounds: Option<[[f32; 2]; 3]>, rect: Rect) {
        let Some(b) = bounds else {
            self.center_mm = [0.0; 2];
            self.scale_pt_per_mm = 2.0;
            return;
        };
        let cam = self.camera(rect);
        let mut lo = [f32::INFINITY; 2];
        let mut hi = [f32::NEG_INFINITY; 2];
        for i in 0..8 {
            let corner = [b[0][i & 1], b[1][(i >> 1) & 1], b[2][(i >> 2) & 1]];
            let v = cam.view_mm(corner);
            for a in 0..2 {
                lo[a] = lo[a].min(v[a]);
                hi[a] = hi[a].max(v[a]);
            }
        }
        self.center_mm = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
        let span = [(hi[0] - lo[0]).max(1e-3), (hi[1] - lo[1]).max(1e-3)];
        let s = (0.9 * rect.width() / span[0]).min(0.9 * rect.height() / span[1]);
        if s.is_finite() && s > 0.0 {
            self.scale_pt_per_mm = s.clamp(SCALE_RANGE.0, SCALE_RANGE.1);
        }
        if !self.center_mm.iter().all(|c| c.is_finite()) {
            self.center_mm = [0.0; 2];
        }
    }
}

/// What a cached mesh was drawn for.
#[derive(Clone, Copy, Debug, PartialEq)]
struct MeshKey {
    camera: Camera,
    clip: Rect,
    pixels_per_point: f32,
    program: u64,
    rapids: bool,
    dark: bool,
    tolerance_mm: f32,
}

/// Screen polylines of `points` through `cam`: a point is kept only `MIN_STEP_PT` from
/// the last one kept (so a polyline has about as many points as the pixels it covers),
/// and the polyline is cut where it leaves `clip` (so zooming in costs nothing for what
/// is off the screen). Each polyline is handed to `out` (≥ 2 points).
fn screen_polylines(
    points: impl Iterator<Item = [f32; 3]>,
    cam: &Camera,
    clip: Rect,
    mut out: impl FnMut(&[Pos2]),
) {
    let clip = clip.expand(4.0);
    let mut line: Vec<Pos2> = Vec::new();
    // the last point seen but not kept (the polyline's end when it is the last)
    let mut pending: Option<Pos2> = None;
    let mut prev: Option<Pos2> = None;
    let flush = |line: &mut Vec<Pos2>, pending: &mut Option<Pos2>, out: &mut dyn FnMut(&[Pos2])| {
        if let Some(p) = pending.take() {
            line.push(p);
        }
        if line.len() >= 2 {
            out(line);
        }
        line.clear();
    };
    for p in points {
        let s = cam.screen_of(p);
        if !(s.x.is_finite() && s.y.is_finite()) {
            flush(&mut line, &mut pending, &mut out);
            prev = None;
            continue;
        }
        if let Some(q) = prev {
            let seg = Rect::from_two_pos(q, s);
            if !seg.intersects(clip) {
                // the segment is off the screen: end the polyline here, start anew at s
                flush(&mut line, &mut pending, &mut out);
                line.push(s);
                prev = Some(s);
                continue;
            }
        } else {
            line.push(s);
            prev = Some(s);
            continue;
        }
        prev = Some(s);
        match line.last() {
            Some(l) if l.distance(s) < MIN_STEP_PT => pending = Some(s),
            _ => {
                line.push(s);
                pending = None;
            }
        }
    }
    flush(&mut line, &mut pending, &mut out);
}

fn tessellator(pixels_per_point: f32, clip: Rect) -> Tessellator {
    let mut t = Tessellator::new(
        pixels_per_point,
        TessellationOptions::default(),
        [1, 1],
        Vec::new(),
    );
    t.set_clip_rect(clip);
    t
}

/// The program's mesh: cuts solid, rapids dashed and light.
fn program_mesh(path: &ProgramPath, key: &MeshKey) -> Mesh {
    let dark = key.dark;
    let mut tess = tessellator(key.pixels_per_point, key.clip);
    let mut mesh = Mesh::default();
    let cut = Stroke::new(
        1.2,
        if dark {
            Color32::from_rgb(150, 170, 200)
        } else {
            Color32::from_rgb(40, 70, 140)
        },
    );
    let rapid = Stroke::new(1.0, Color32::from_gray(if dark { 110 } else { 160 }));
    for r in &path.runs {
        if r.rapid && !key.rapids {
            continue;
        }
        let pts = path.points_mm[r.start..r.end].iter().copied();
        screen_polylines(pts, &key.camera, key.clip, |line| {
            if r.rapid {
                for s in Shape::dashed_line(line, rapid, 6.0, 4.0) {
                    tess.tessellate_shape(s, &mut mesh);
                }
            } else {
                tess.tessellate_path(&PathShape::line(line.to_vec(), cut), &mut mesh);
            }
        });
    }
    mesh
}

/// The trail's mesh of `points`: decimated to the screen as the program's polylines are
/// (a kept point takes the largest contour error of the points it stands for, so a
/// one-sample excursion still shows red), each segment a quad shaded from its ends'
/// colours. Not the tessellator's paths: with the colour changing at nearly every point
/// (noise across a bin's edge) they would be one path per segment, ~8× the vertices.
fn trail_mesh(points: &[TrailPoint], key: &MeshKey) -> Mesh {
    let clip = key.clip.expand(4.0);
    let tol = key.tolerance_mm;
    let mut mesh = Mesh::default();
    let feather = 1.0 / key.pixels_per_point.max(0.1);
    // the last point kept and its error; the newest point not kept, with the largest
    // error since the last kept one
    let mut kept: Option<(Pos2, f32)> = None;
    let mut pending: Option<(Pos2, f32)> = None;
    let err_of = |p: &TrailPoint| {
        let e = p.contour_mm.abs();
        if e.is_nan() {
            f32::INFINITY
        } else {
            e
        }
    };
    for p in points {
        let s = key.camera.screen_of(p.pos_mm);
        let e = err_of(p);
        if !(s.x.is_finite() && s.y.is_finite()) {
            if let (Some(a), Some(b)) = (kept, pending) {
                segment_quad(&mut mesh, a, b, tol, feather, clip);
            }
            kept = None;
            pending = None;
            continue;
        }
        let Some(a) = kept else {
            kept = Some((s, e));
            continue;
        };
        let e = pending.map_or(e, |(_, pe)| pe.max(e));
        if a.0.distance(s) < MIN_STEP_PT {
            pending = Some((s, e));
            continue;
        }
        segment_quad(&mut mesh, a, (s, e), tol, feather, clip);
        kept = Some((s, e));
        pending = None;
    }
    if let (Some(a), Some(b)) = (kept, pending) {
        segment_quad(&mut mesh, a, b, tol, feather, clip);
    }
    mesh
}

/// Half the trail's width, screen points.
const TRAIL_HALF_WIDTH_PT: f32 = 1.0;

/// One trail segment `a → b` (screen point, contour error mm) as a quad 2 points wide
/// with a feathered edge (anti-aliasing), colours from each end's error; off `clip`, none.
fn segment_quad(
    mesh: &mut Mesh,
    a: (Pos2, f32),
    b: (Pos2, f32),
    tol_mm: f32,
    feather: f32,
    clip: Rect,
) {
    if !Rect::from_two_pos(a.0, b.0).intersects(clip) {
        return;
    }
    let d = b.0 - a.0;
    let len = d.length();
    if len.is_nan() || len <= 0.0 {
        return;
    }
    let n = Vec2::new(-d.y, d.x) / len;
    let (w, f) = (TRAIL_HALF_WIDTH_PT, TRAIL_HALF_WIDTH_PT + feather);
    let i = mesh.vertices.len() as u32;
    for (p, e) in [a, b] {
        let c = contour_colour(e, tol_mm);
        mesh.colored_vertex(p + n * f, Color32::TRANSPARENT);
        mesh.colored_vertex(p + n * w, c);
        mesh.colored_vertex(p - n * w, c);
        mesh.colored_vertex(p - n * f, Color32::TRANSPARENT);
    }
    // three strips (feather, core, feather) between the ends' vertices i..i+4, i+4..i+8
    for k in 0..3 {
        let (p0, p1, q0, q1) = (i + k, i + k + 1, i + 4 + k, i + 4 + k + 1);
        mesh.add_triangle(p0, p1, q0);
        mesh.add_triangle(p1, q1, q0);
    }
}

fn same_bits(a: &TrailPoint, b: &TrailPoint) -> bool {
    a.contour_mm.to_bits() == b.contour_mm.to_bits()
        && a.pos_mm
            .iter()
            .zip(b.pos_mm)
            .all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The trail's meshes: full chunks of [`TRAIL_CHUNK`] points kept while the view and the
/// trail's start stay, the growing last chunk rebuilt every frame.
#[derive(Debug, Default)]
struct TrailChunks {
    key: Option<MeshKey>,
    /// Per chunk: the index after its last point, that point, its mesh.
    chunks: Vec<(usize, TrailPoint, Arc<Mesh>)>,
}

impl TrailChunks {
    fn meshes(&mut self, trail: &[TrailPoint], key: &MeshKey) -> Vec<Arc<Mesh>> {
        // a new view, or a trail that was cleared or thinned (the live trail halves its
        // density when full): what was cached no longer matches
        let stale = self.key.as_ref() != Some(key)
            || self.chunks.iter().any(|(end, last, _)| {
                // (bitwise: a NaN point must not make its chunk stale every frame)
                trail
                    .get(end.wrapping_sub(1))
                    .is_none_or(|p| !same_bits(p, last))
            });
        if stale {
            self.chunks.clear();
            self.key = Some(*key);
        }
        let mut done = self.chunks.last().map_or(0, |c| c.0);
        while trail.len() > done + TRAIL_CHUNK {
            // each chunk starts at the previous one's last point, so the trail is unbroken
            let start = done.saturating_sub(1);
            let end = done + TRAIL_CHUNK;
            let mesh = Arc::new(trail_mesh(&trail[start..end], key));
            self.chunks.push((end, trail[end - 1], mesh));
            done = end;
        }
        let mut out: Vec<Arc<Mesh>> = self.chunks.iter().map(|c| c.2.clone()).collect();
        let tail = &trail[done.saturating_sub(1).min(trail.len())..];
        if tail.len() >= 2 {
            out.push(Arc::new(trail_mesh(tail, key)));
        }
        out
    }
}

/// The tab.
pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    let tolerance_mm = tolerance_mm(&app.settings.values) as f32;
    let view = &mut app.path_view;
    // the program's polyline, once per program
    match &app.program {
        Some(p) => {
            let key = program_key(p);
            if view.program.as_ref().is_none_or(|c| c.key != key) {
                view.program = Some(ProgramPath::build(p, ARC_CHORD_ERROR_MM));
                view.program_mesh = None;
                view.fit = true;
            }
        }
        None => {
            view.program = None;
            view.program_mesh = None;
        }
    }

    ui.horizontal(|ui| {
        for p in Projection::ALL {
            if ui
                .selectable_value(&mut view.projection, p, p.label())
                .clicked()
            {
                view.fit = true;
            }
        }
        ui.separator();
        if ui
            .button("Fit")
            .on_hover_text("fit the view to the program (or double-click)")
            .clicked()
        {
            view.fit = true;
        }
        ui.checkbox(&mut view.show_rapids, "Rapids (G0)");
        ui.checkbox(&mut view.show_trail, "Executed path");
        ui.separator();
        match &view.program {
            Some(p) => ui.label(format!(
                "{} moves, {} path points",
                p.move_points.len(),
                p.points_mm.len()
            )),
            None => ui.label("no program loaded"),
        };
        ui.label(format!("trail {} points", app.live.trail.len()));
        if view.projection == Projection::ThreeD {
            ui.weak("drag: turn · right-drag: pan · wheel: zoom");
        } else {
            ui.weak("drag: pan · wheel: zoom");
        }
    });

    let (rect, response) = ui.allocate_exact_size(ui.available_size(), Sense::click_and_drag());
    if !(rect.width() >= 1.0 && rect.height() >= 1.0) {
        return;
    }
    let painter = ui.painter_at(rect);
    let dark = ui.visuals().dark_mode;
    painter.rect_filled(rect, 0.0, ui.visuals().extreme_bg_color);

    // interaction: turn, pan, zoom about the pointer, fit
    if response.double_clicked() {
        view.fit = true;
    }
    let delta = response.drag_delta();
    if delta != Vec2::ZERO {
        let turning = view.projection == Projection::ThreeD
            && response.dragged_by(egui::PointerButton::Primary);
        if turning {
            view.yaw_rad -= delta.x * 0.01;
            view.pitch_rad = (view.pitch_rad + delta.y * 0.01)
                .clamp(-std::f32::consts::FRAC_PI_2, std::f32::consts::FRAC_PI_2);
        } else {
            let s = view.scale_pt_per_mm;
            view.center_mm[0] -= delta.x / s;
            view.center_mm[1] += delta.y / s;
        }
    }
    if response.hovered() {
        let (scroll, zoom) = ui.input(|i| (i.smooth_scroll_delta.y, i.zoom_delta()));
        let factor = (scroll * 0.003).exp() * zoom;
        if factor.is_finite() && factor > 0.0 && factor != 1.0 {
            let before = view.camera(rect);
            let at = response.hover_pos().unwrap_or(rect.center());
            let fixed = before.view_of_screen(at);
            view.scale_pt_per_mm =
                (view.scale_pt_per_mm * factor).clamp(SCALE_RANGE.0, SCALE_RANGE.1);
            let s = view.scale_pt_per_mm;
            view.center_mm = [
                fixed[0] - (at.x - rect.center().x) / s,
                fixed[1] + (at.y - rect.center().y) / s,
            ];
        }
    }
    if view.fit {
        view.fit = false;
        let bounds = view
            .program
            .as_ref()
            .and_then(|p| p.bounds_mm)
            .or_else(|| bounds_of(app.live.trail.iter().map(|t| t.pos_mm)));
        // fit beside the legend (top right) when there is room
        let fit_rect = if rect.width() > 3.0 * LEGEND_WIDTH_PT {
            Rect::from_min_max(
                rect.min,
                Pos2::new(rect.right() - LEGEND_WIDTH_PT, rect.bottom()),
            )
        } else {
            rect
        };
        view.fit_to(bounds, fit_rect);
        // (the camera's origin is the whole rect's centre)
        view.center_mm[0] += (rect.center().x - fit_rect.center().x) / view.scale_pt_per_mm;
    }

    let cam = view.camera(rect);
    let key = MeshKey {
        camera: cam,
        clip: rect,
        pixels_per_point: ui.ctx().pixels_per_point(),
        program: view.program.as_ref().map_or(0, |p| p.key),
        rapids: view.show_rapids,
        dark,
        tolerance_mm,
    };

    if let Some(names) = view.projection.axis_names() {
        draw_grid(&painter, &cam, rect, names, dark);
    }

    // the program (cached mesh)
    if let Some(path) = &view.program {
        let mesh = match &view.program_mesh {
            Some((k, m)) if *k == key => m.clone(),
            _ => {
                let m = Arc::new(program_mesh(path, &key));
                view.program_mesh = Some((key, m.clone()));
                m
            }
        };
        painter.add(Shape::Mesh(mesh));
    }

    // the executed path
    if view.show_trail {
        for m in view.trail_chunks.meshes(&app.live.trail, &key) {
            painter.add(Shape::Mesh(m));
        }
    }

    // the segment being executed
    let running = app.live.latest.as_ref().filter(|t| {
        matches!(
            t.state,
            controller_core::machine::messages::MachineState::Run { .. }
        )
    });
    if let (Some(t), Some(path)) = (running, &view.program) {
        if let Some(&(a, b)) = path.move_points.get(t.tag as usize) {
            let hl = Stroke::new(4.0, Color32::from_rgba_unmultiplied(255, 140, 0, 200));
            if let Some(pts) = path.points_mm.get(a..b) {
                screen_polylines(pts.iter().copied(), &cam, rect, |line| {
                    painter.add(Shape::line(line.to_vec(), hl));
                });
            }
        }
    }

    // the tool
    if let Some(p) = app.live.pos_mm() {
        let s = cam.screen_of(p);
        if rect.expand(8.0).contains(s) {
            let c = if dark { Color32::WHITE } else { Color32::BLACK };
            painter.circle_stroke(s, 6.0, Stroke::new(2.0, c));
            painter.line_segment(
                [s - Vec2::X * 10.0, s + Vec2::X * 10.0],
                Stroke::new(1.0, c),
            );
            painter.line_segment(
                [s - Vec2::Y * 10.0, s + Vec2::Y * 10.0],
                Stroke::new(1.0, c),
            );
        }
    }

    if view.projection == Projection::ThreeD {
        draw_triad(&painter, &cam, rect, dark);
        draw_scale_bar(&painter, &cam, rect, dark);
    }
    draw_legend(&painter, rect, tolerance_mm, dark);
}

/// A "nice" grid step (1, 2 or 5 × 10ⁿ mm) for about `target` lines over `span_mm`.
pub fn nice_step_mm(span_mm: f32, target: f32) -> f32 {
    let raw = (span_mm / target.max(1.0)).abs();
    if !(raw.is_finite() && raw > 0.0) {
        return 1.0;
    }
    let mag = 10f32.powf(raw.log10().floor());
    let f = raw / mag;
    let m = if f < 1.5 {
        1.0
    } else if f < 3.5 {
        2.0
    } else if f < 7.5 {
        5.0
    } else {
        10.0
    };
    m * mag
}

fn text_colour(dark: bool) -> Color32 {
    if dark {
        Color32::from_gray(200)
    } else {
        Color32::from_gray(40)
    }
}

/// A 2-D view's grid and its axes in mm.
fn draw_grid(painter: &egui::Painter, cam: &Camera, rect: Rect, names: (&str, &str), dark: bool) {
    let lo = cam.view_of_screen(rect.left_bottom());
    let hi = cam.view_of_screen(rect.right_top());
    let grid = Stroke::new(
        1.0,
        if dark {
            Color32::from_gray(45)
        } else {
            Color32::from_gray(225)
        },
    );
    let font = FontId::proportional(11.0);
    let tc = text_colour(dark);
    for axis in 0..2 {
        let span = if axis == 0 {
            rect.width()
        } else {
            rect.height()
        };
        let step = nice_step_mm(hi[axis] - lo[axis], span / 90.0);
        let first = (lo[axis] / step).ceil();
        let count = ((hi[axis] - lo[axis]) / step).floor();
        if !(first.is_finite() && count.is_finite()) || count > 200.0 {
            continue;
        }
        let decimals = (-step.log10().floor()).max(0.0) as usize;
        for i in 0..=(count as i64) {
            let v = (first + i as f32) * step;
            let label = format!("{v:.decimals$}");
            if axis == 0 {
                let x = cam.origin.x + (v - cam.center_mm[0]) * cam.scale_pt_per_mm;
                painter.line_segment(
                    [Pos2::new(x, rect.top()), Pos2::new(x, rect.bottom())],
                    grid,
                );
                painter.text(
                    Pos2::new(x + 2.0, rect.bottom() - 2.0),
                    Align2::LEFT_BOTTOM,
                    label,
                    font.clone(),
                    tc,
                );
            } else {
                let y = cam.origin.y - (v - cam.center_mm[1]) * cam.scale_pt_per_mm;
                painter.line_segment(
                    [Pos2::new(rect.left(), y), Pos2::new(rect.right(), y)],
                    grid,
                );
                painter.text(
                    Pos2::new(rect.left() + 2.0, y - 1.0),
                    Align2::LEFT_BOTTOM,
                    label,
                    font.clone(),
                    tc,
                );
            }
        }
    }
    let bold = FontId::proportional(13.0);
    painter.text(
        rect.right_bottom() + Vec2::new(-6.0, -16.0),
        Align2::RIGHT_BOTTOM,
        format!("{} (mm)", names.0),
        bold.clone(),
        tc,
    );
    painter.text(
        rect.left_top() + Vec2::new(6.0, 6.0),
        Align2::LEFT_TOP,
        format!("{} (mm)", names.1),
        bold,
        tc,
    );
}

/// The X/Y/Z triad of the 3-D view (bottom left).
fn draw_triad(painter: &egui::Painter, cam: &Camera, rect: Rect, dark: bool) {
    let o = rect.left_bottom() + Vec2::new(50.0, -50.0);
    let axes = [
        ("X", [1.0, 0.0, 0.0], Color32::from_rgb(220, 60, 60)),
        ("Y", [0.0, 1.0, 0.0], Color32::from_rgb(40, 170, 70)),
        ("Z", [0.0, 0.0, 1.0], Color32::from_rgb(60, 110, 230)),
    ];
    for (name, a, c) in axes {
        let r = cam.right[0] * a[0] + cam.right[1] * a[1] + cam.right[2] * a[2];
        let u = cam.up[0] * a[0] + cam.up[1] * a[1] + cam.up[2] * a[2];
        let tip = o + Vec2::new(r, -u) * 36.0;
        painter.line_segment([o, tip], Stroke::new(2.0, c));
        painter.text(
            o + Vec2::new(r, -u) * 46.0,
            Align2::CENTER_CENTER,
            name,
            FontId::proportional(14.0),
            if dark { c } else { c.gamma_multiply(0.9) },
        );
    }
}

/// A scale bar in mm (the 3-D view has no axes to read lengths from).
fn draw_scale_bar(painter: &egui::Painter, cam: &Camera, rect: Rect, dark: bool) {
    let mm = nice_step_mm(120.0 / cam.scale_pt_per_mm, 1.0);
    let len = mm * cam.scale_pt_per_mm;
    if !(len.is_finite() && len > 1.0) {
        return;
    }
    let tc = text_colour(dark);
    let y = rect.bottom() - 14.0;
    let x0 = rect.left() + 110.0;
    painter.line_segment(
        [Pos2::new(x0, y), Pos2::new(x0 + len, y)],
        Stroke::new(2.0, tc),
    );
    for x in [x0, x0 + len] {
        painter.line_segment(
            [Pos2::new(x, y - 4.0), Pos2::new(x, y + 4.0)],
            Stroke::new(1.0, tc),
        );
    }
    painter.text(
        Pos2::new(x0 + 0.5 * len, y - 5.0),
        Align2::CENTER_BOTTOM,
        format!("{mm} mm"),
        FontId::proportional(11.0),
        tc,
    );
}

/// The legend's width, screen points.
const LEGEND_WIDTH_PT: f32 = 180.0;

/// The legend: what the lines are, and the contour-error colour bar in µm.
fn draw_legend(painter: &egui::Painter, rect: Rect, tolerance_mm: f32, dark: bool) {
    let tc = text_colour(dark);
    let font = FontId::proportional(11.0);
    let w = LEGEND_WIDTH_PT - 10.0;
    let x0 = rect.right() - w;
    let top = rect.top() + 8.0;
    if x0 < rect.left() + 40.0 || rect.height() < 200.0 {
        return;
    }
    let bg = if dark {
        Color32::from_black_alpha(160)
    } else {
        Color32::from_white_alpha(200)
    };
    painter.rect_filled(
        Rect::from_min_size(Pos2::new(x0 - 6.0, top - 4.0), Vec2::new(w, 196.0)),
        4.0,
        bg,
    );
    let entries: [(&str, Shape); 3] = [
        (
            "cut (G1/G2/G3)",
            Shape::line_segment(
                [Pos2::new(x0, top + 7.0), Pos2::new(x0 + 22.0, top + 7.0)],
                Stroke::new(1.5, Color32::from_rgb(90, 120, 180)),
            ),
        ),
        (
            "rapid (G0)",
            Shape::Vec(Shape::dashed_line(
                &[Pos2::new(x0, top + 25.0), Pos2::new(x0 + 22.0, top + 25.0)],
                Stroke::new(1.0, Color32::from_gray(140)),
                6.0,
                4.0,
            )),
        ),
        (
            "executing segment",
            Shape::line_segment(
                [Pos2::new(x0, top + 43.0), Pos2::new(x0 + 22.0, top + 43.0)],
                Stroke::new(4.0, Color32::from_rgb(255, 140, 0)),
            ),
        ),
    ];
    for (k, (text, swatch)) in entries.into_iter().enumerate() {
        painter.add(swatch);
        painter.text(
            Pos2::new(x0 + 28.0, top + 7.0 + 18.0 * k as f32),
            Align2::LEFT_CENTER,
            text,
            font.clone(),
            tc,
        );
    }
    let y0 = top + 62.0;
    painter.text(
        Pos2::new(x0, y0),
        Align2::LEFT_TOP,
        "executed path: contour error",
        font.clone(),
        tc,
    );
    // the bar: 0 at the bottom, the tolerance at the top
    let bar = Rect::from_min_size(Pos2::new(x0, y0 + 18.0), Vec2::new(14.0, 100.0));
    let mut mesh = Mesh::default();
    let n = 20;
    for i in 0..n {
        let f0 = i as f32 / n as f32;
        let f1 = (i + 1) as f32 / n as f32;
        let r = Rect::from_x_y_ranges(
            bar.x_range(),
            (bar.bottom() - f1 * bar.height())..=(bar.bottom() - f0 * bar.height()),
        );
        mesh.add_colored_rect(r, scale_colour(0.5 * (f0 + f1)));
    }
    painter.add(Shape::mesh(mesh));
    let tol_um = tolerance_mm * 1000.0;
    for (f, text) in [
        (1.0, format!("≥ {tol_um:.1} µm (tolerance)")),
        (0.5, format!("{:.1} µm", 0.5 * tol_um)),
        (0.0, "0 µm".to_string()),
    ] {
        painter.text(
            Pos2::new(bar.right() + 6.0, bar.bottom() - f * bar.height()),
            Align2::LEFT_CENTER,
            text,
            font.clone(),
            tc,
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::PathBuf;

    fn load(text: &str) -> LoadedProgram {
        let p = host_sim::gcode::parse_str("t.nc", text).expect("parses");
        LoadedProgram {
            path: PathBuf::from("t.nc"),
            moves: p.moves,
            bounds_mm: p.bounds_mm,
            lines: text.lines().count(),
        }
    }

    /// A full circle G2 of radius 10 about (10, 0): every point on the circle, every
    /// chord within the chord error of it.
    #[test]
    fn an_arcs_polyline_lies_on_its_circle() {
        let prog = load("G21 G90 G17\nG0 X0 Y0 Z0\nG2 X0 Y0 I10 J0 F600\n");
        let path = ProgramPath::build(&prog, ARC_CHORD_ERROR_MM);
        let arc = path.runs.iter().find(|r| !r.rapid).expect("a cut run");
        let pts = &path.points_mm[arc.start..arc.end];
        assert!(pts.len() > 100, "{} points", pts.len());
        let (cx, cy, r) = (10.0f64, 0.0f64, 10.0f64);
        for p in pts {
            let d = (f64::from(p[0]) - cx).hypot(f64::from(p[1]) - cy);
            assert!((d - r).abs() < 1e-5, "point {p:?} at radius {d}");
        }
        for w in pts.windows(2) {
            let mx = 0.5 * (f64::from(w[0][0]) + f64::from(w[1][0]));
            let my = 0.5 * (f64::from(w[0][1]) + f64::from(w[1][1]));
            let sag = r - (mx - cx).hypot(my - cy);
            assert!(sag <= ARC_CHORD_ERROR_MM + 1e-5, "sagitta {sag}");
        }
        // clockwise seen from +Z from the circle's leftmost point: upwards first (y > 0)
        assert!(pts[1][1] > 0.0);
    }

    #[test]
    fn rapids_and_cuts_are_separate_runs() {
        let prog = load("G0 X0 Y0 Z5\nG1 Z0 F100\nG1 X10\nG1 Y10\nG0 Z5\nG0 X0 Y0\n");
        let path = ProgramPath::build(&prog, ARC_CHORD_ERROR_MM);
        let kinds: Vec<bool> = path.runs.iter().map(|r| r.rapid).collect();
        assert_eq!(kinds, vec![true, false, true]);
        assert_eq!(path.move_points.len(), prog.moves.len());
        let b = path.bounds_mm.expect("bounds");
        assert_eq!(b[0], [0.0, 10.0]);
    }

    #[test]
    fn an_empty_program_draws_nothing() {
        let prog = load("G21\n");
        let path = ProgramPath::build(&prog, ARC_CHORD_ERROR_MM);
        assert!(path.runs.is_empty());
        assert!(path.bounds_mm.is_none());
    }

    #[test]
    fn the_colour_scale_spans_zero_to_the_tolerance() {
        let tol = 0.01;
        assert_eq!(contour_colour(0.0, tol), Color32::from_rgb(30, 170, 60));
        assert_eq!(contour_colour(tol, tol), Color32::from_rgb(220, 30, 30));
        assert_eq!(contour_colour(5.0 * tol, tol), contour_colour(tol, tol));
        assert_eq!(contour_colour(f32::NAN, tol), contour_colour(tol, tol));
        assert_eq!(contour_colour(0.0, 0.0), contour_colour(0.0, tol));
    }

    #[test]
    fn the_tolerance_comes_from_the_settings_or_the_default() {
        assert_eq!(tolerance_mm(&[]), DEFAULT_TOLERANCE_MM);
        let s = vec![("planner.tolerance_mm".to_string(), " 0.025 ".to_string())];
        assert_eq!(tolerance_mm(&s), 0.025);
        let bad = vec![("planner.tolerance_mm".to_string(), "nan".to_string())];
        assert_eq!(tolerance_mm(&bad), DEFAULT_TOLERANCE_MM);
    }

    /// 100,000 points along 100 pt of screen: the polyline keeps about one per 0.7 pt,
    /// its ends exact; points off the screen are dropped; NaN breaks the line.
    #[test]
    fn polylines_are_decimated_to_the_screen() {
        let cam = Camera {
            right: [1.0, 0.0, 0.0],
            up: [0.0, 1.0, 0.0],
            center_mm: [0.0, 0.0],
            scale_pt_per_mm: 1.0,
            origin: Pos2::new(100.0, 100.0),
        };
        let clip = Rect::from_min_size(Pos2::ZERO, Vec2::splat(200.0));
        let n = 100_000;
        let pts = (0..=n).map(|i| [-50.0 + 100.0 * i as f32 / n as f32, 0.0, 0.0]);
        let mut lines = Vec::new();
        screen_polylines(pts, &cam, clip, |l| lines.push(l.to_vec()));
        assert_eq!(lines.len(), 1);
        let l = &lines[0];
        assert!(l.len() <= 150 && l.len() >= 100, "{} points", l.len());
        assert_eq!(l[0], Pos2::new(50.0, 100.0));
        assert_eq!(*l.last().expect("points"), Pos2::new(150.0, 100.0));

        let far = [[1000.0, 0.0, 0.0], [2000.0, 0.0, 0.0], [3000.0, 1.0, 0.0]];
        let mut count = 0;
        screen_polylines(far.into_iter(), &cam, clip, |_| count += 1);
        assert_eq!(count, 0);

        let broken = [
            [0.0, 0.0, 0.0],
            [10.0, 0.0, 0.0],
            [f32::NAN, 0.0, 0.0],
            [20.0, 0.0, 0.0],
        ];
        let mut lines = Vec::new();
        screen_polylines(broken.into_iter(), &cam, clip, |l| lines.push(l.len()));
        assert_eq!(lines, vec![2]);
    }

    /// The XY view of a 200-point square at 1 point per mm, tolerance 10 µm.
    fn xy_key() -> MeshKey {
        MeshKey {
            camera: Camera {
                right: [1.0, 0.0, 0.0],
                up: [0.0, 1.0, 0.0],
                center_mm: [0.0, 0.0],
                scale_pt_per_mm: 1.0,
                origin: Pos2::new(100.0, 100.0),
            },
            clip: Rect::from_min_size(Pos2::ZERO, Vec2::splat(200.0)),
            pixels_per_point: 1.0,
            program: 0,
            rapids: true,
            dark: false,
            tolerance_mm: 0.01,
        }
    }

    /// 1,000 trail points within half a screen point, one of them 1 mm off: the mesh is
    /// one segment, and it shows red.
    #[test]
    fn a_trail_spike_stays_red_when_decimated() {
        let key = xy_key();
        let pts: Vec<TrailPoint> = (0..1000)
            .map(|i| TrailPoint {
                pos_mm: [i as f32 * 0.0005, 0.0, 0.0],
                contour_mm: if i == 500 { 1.0 } else { 0.0 },
            })
            .collect();
        let mesh = trail_mesh(&pts, &key);
        assert_eq!(mesh.vertices.len(), 8);
        let red = contour_colour(1.0, 0.01);
        assert!(mesh.vertices.iter().any(|v| v.color == red));
        assert!(mesh.is_valid());
        let nan = [TrailPoint {
            pos_mm: [f32::NAN; 3],
            contour_mm: f32::NAN,
        }; 3];
        assert!(trail_mesh(&nan, &key).vertices.is_empty());
    }

    /// Full chunks are kept while the trail grows, dropped when it is thinned or cleared.
    #[test]
    fn trail_chunks_are_kept_until_the_trail_changes() {
        let key = xy_key();
        let point = |i: usize| TrailPoint {
            pos_mm: [
                (i as f32 * 0.01).sin() * 50.0,
                (i as f32 * 0.01).cos() * 50.0,
                0.0,
            ],
            contour_mm: 0.001,
        };
        let mut trail: Vec<TrailPoint> = (0..3 * TRAIL_CHUNK).map(point).collect();
        let mut chunks = TrailChunks::default();
        let first = chunks.meshes(&trail, &key);
        assert_eq!(chunks.chunks.len(), 2);
        assert_eq!(first.len(), 3);
        trail.extend((3 * TRAIL_CHUNK..3 * TRAIL_CHUNK + 10).map(point));
        let again = chunks.meshes(&trail, &key);
        assert!(Arc::ptr_eq(&first[0], &again[0]) && Arc::ptr_eq(&first[1], &again[1]));
        // thinned (every other point), as the live trail does when full
        let thinned: Vec<TrailPoint> = trail.iter().step_by(2).copied().collect();
        let after = chunks.meshes(&thinned, &key);
        assert!(!Arc::ptr_eq(&first[0], &after[0]));
        assert!(chunks.meshes(&[], &key).is_empty());
    }

    #[test]
    fn nice_steps() {
        assert_eq!(nice_step_mm(100.0, 10.0), 10.0);
        assert_eq!(nice_step_mm(30.0, 10.0), 2.0);
        assert_eq!(nice_step_mm(0.0, 10.0), 1.0);
        assert_eq!(nice_step_mm(f32::NAN, 10.0), 1.0);
    }
}
