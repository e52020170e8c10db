//! The live plots tab: the last 1, 2, 5 or 10 s of telemetry at its full rate, on a
//! shared time axis (seconds of machine time): tracking error per axis and contour error
//! (µm), the planner's velocity per axis (mm/s), the effort per axis (when the telemetry
//! carries `effort.x` etc.) and every chosen telemetry signal, each with its unit. A
//! freeze button keeps what is shown (then zoom and pan, linked across the plots), and a
//! chooser sends the machine the up-to-four signals to carry.
//!
//! Each series is decimated to the plot's width before it is drawn, keeping each pixel
//! column's minimum and maximum (so a one-sample spike stays visible): a frame costs a
//! pass over the window's samples and ~2 points per pixel per series, whatever the rate.

use crate::app::GantryApp;
use crate::session::Command;
use controller_core::machine::messages::{Telemetry, TELEMETRY_SIGNALS};
use egui::{Color32, Id};
use egui_plot::{Corner, Legend, Line, Plot, PlotPoints};

/// Windows offered, s.
pub const WINDOWS_S: [f64; 4] = [1.0, 2.0, 5.0, 10.0];
/// Axis colours (X, Y, Z) and a fourth for a fourth signal.
const COLOURS: [Color32; 4] = [
    Color32::from_rgb(220, 60, 60),
    Color32::from_rgb(40, 160, 70),
    Color32::from_rgb(60, 110, 230),
    Color32::from_rgb(200, 140, 0),
];
const AXES: [&str; 3] = ["x", "y", "z"];

/// The tab's state.
#[derive(Debug)]
pub struct Plots {
    /// Seconds shown.
    pub window_s: f64,
    /// The samples shown while frozen (the window at the time of freezing).
    pub frozen: Option<Vec<Telemetry>>,
    /// The signal chooser's choice (empty: none), before it is sent.
    pub choice: [String; TELEMETRY_SIGNALS],
    /// The chooser was set from the machine's signals.
    choice_from: Vec<String>,
}

impl Default for Plots {
    fn default() -> Self {
        Self {
            window_s: 5.0,
            frozen: None,
            choice: Default::default(),
            choice_from: Vec::new(),
        }
    }
}

/// A decimation column: its index, its minimum and its maximum `(t, v)`.
type Column = (usize, (f64, f64), (f64, f64));

/// `(t, v)` decimated to `buckets` columns of `[t0, t1]`: each column keeps its minimum
/// and its maximum, in time order (one point when they are the same sample). Samples
/// outside `[t0, t1]` and non-finite values are left out. At most `2 × buckets` points.
pub fn min_max_decimate(
    samples: impl Iterator<Item = (f64, f64)>,
    t0: f64,
    t1: f64,
    buckets: usize,
) -> Vec<[f64; 2]> {
    let buckets = buckets.max(1);
    let span = t1 - t0;
    let mut out = Vec::with_capacity(2 * buckets);
    if !(span.is_finite() && span > 0.0) {
        return out;
    }
    let per_s = buckets as f64 / span;
    // the current column: its index, its minimum and maximum (t, v)
    let mut col: Option<Column> = None;
    let flush = |out: &mut Vec<[f64; 2]>, lo: (f64, f64), hi: (f64, f64)| {
        let (a, b) = if lo.0 <= hi.0 { (lo, hi) } else { (hi, lo) };
        out.push([a.0, a.1]);
        if a != b {
            out.push([b.0, b.1]);
        }
    };
    for (t, v) in samples {
        if !(t >= t0 && t <= t1 && v.is_finite()) {
            continue;
        }
        let k = (((t - t0) * per_s) as usize).min(buckets - 1);
        match &mut col {
            Some((c, lo, hi)) if *c == k => {
                if v < lo.1 {
                    *lo = (t, v);
                }
                if v > hi.1 {
                    *hi = (t, v);
                }
            }
            _ => {
                if let Some((_, lo, hi)) = col.take() {
                    flush(&mut out, lo, hi);
                }
                col = Some((k, (t, v), (t, v)));
            }
        }
    }
    if let Some((_, lo, hi)) = col {
        flush(&mut out, lo, hi);
    }
    out
}

pub use super::scope::{signal_names, signal_unit};

/// One series: its name, colour and value of a sample.
struct Series<'a> {
    name: String,
    colour: Color32,
    value: Box<dyn Fn(&Telemetry) -> f64 + 'a>,
}

/// One plot: its title (with the unit) and series.
struct Panel<'a> {
    id: &'static str,
    unit: String,
    series: Vec<Series<'a>>,
}

fn panels(signals: &[String]) -> Vec<Panel<'static>> {
    let axis_series = |what: &str, f: fn(&Telemetry, usize) -> f64| -> Vec<Series<'static>> {
        (0..3)
            .map(|a| Series {
                name: format!("{what} {}", AXES[a].to_uppercase()),
                colour: COLOURS[a],
                value: Box::new(move |t: &Telemetry| f(t, a)),
            })
            .collect()
    };
    let mut out = vec![
        Panel {
            id: "tracking",
            unit: "tracking (pos − ref), µm".into(),
            series: axis_series("tracking", |t, a| {
                1000.0 * (f64::from(t.pos_mm[a]) - f64::from(t.reference_mm[a]))
            }),
        },
        Panel {
            id: "contour",
            unit: "contour, µm".into(),
            series: vec![Series {
                name: "contour".into(),
                colour: COLOURS[3],
                value: Box::new(|t: &Telemetry| 1000.0 * f64::from(t.contour_mm)),
            }],
        },
        Panel {
            id: "velocity",
            unit: "ref. velocity, mm/s".into(),
            series: axis_series("velocity", |t, a| f64::from(t.ref_vel_mm_s[a])),
        },
    ];
    let effort: Vec<Series<'static>> = (0..3)
        .filter_map(|a| {
            let i = signals
                .iter()
                .position(|s| *s == format!("effort.{}", AXES[a]))?;
            Some(Series {
                name: format!("effort {}", AXES[a].to_uppercase()),
                colour: COLOURS[a],
                value: Box::new(move |t: &Telemetry| signal_value(t, i)),
            })
        })
        .collect();
    if !effort.is_empty() {
        out.push(Panel {
            id: "effort",
            unit: "effort, mN·m".into(),
            series: effort,
        });
    }
    // the chosen signals not already plotted above (the efforts)
    let others: Vec<(usize, &String)> = signals
        .iter()
        .enumerate()
        .filter(|(_, s)| !(s.starts_with("effort.") && AXES.iter().any(|a| s.ends_with(a))))
        .collect();
    if !others.is_empty() {
        let units: Vec<&str> = others.iter().map(|(_, s)| signal_unit(s)).collect();
        let unit = if units.windows(2).all(|w| w[0] == w[1]) {
            format!("signals, {}", units[0])
        } else {
            "signals (units in the legend)".into()
        };
        out.push(Panel {
            id: "signals",
            unit,
            series: others
                .into_iter()
                .map(|(i, s)| Series {
                    name: format!("{s} ({})", signal_unit(s)),
                    colour: COLOURS[i % COLOURS.len()],
                    value: Box::new(move |t: &Telemetry| signal_value(t, i)),
                })
                .collect(),
        });
    }
    out
}

/// Signal `i` of a sample (NaN when the sample does not carry it: samples taken before
/// the signals changed).
fn signal_value(t: &Telemetry, i: usize) -> f64 {
    t.signals.get(i).map_or(f64::NAN, |v| f64::from(*v))
}

/// The tab.
pub fn show(app: &mut GantryApp, ui: &mut egui::Ui) {
    let live = &app.live;
    // the chooser follows the machine's signals until edited
    if app.plots.choice_from != live.signals {
        app.plots.choice_from = live.signals.clone();
        for (k, c) in app.plots.choice.iter_mut().enumerate() {
            *c = live.signals.get(k).cloned().unwrap_or_default();
        }
    }
    let mut send: Option<Vec<String>> = None;
    ui.horizontal(|ui| {
        ui.label("window");
        for w in WINDOWS_S {
            ui.selectable_value(&mut app.plots.window_s, w, format!("{w} s"));
        }
        ui.separator();
        let frozen = app.plots.frozen.is_some();
        if ui
            .selectable_label(frozen, if frozen { "Resume" } else { "Freeze" })
            .on_hover_text("freeze the plots (then drag and scroll to zoom, double-click to reset)")
            .clicked()
        {
            app.plots.frozen = if frozen {
                None
            } else {
                Some(live.history.iter().cloned().collect())
            };
        }
        ui.separator();
        ui.label("signals");
        let names = signal_names();
        for (k, c) in app.plots.choice.iter_mut().enumerate() {
            egui::ComboBox::from_id_salt(("signal", k))
                .width(90.0)
                .selected_text(if c.is_empty() { "—" } else { c.as_str() })
                .show_ui(ui, |ui| {
                    ui.selectable_value(c, String::new(), "—");
                    for n in &names {
                        ui.selectable_value(c, n.clone(), n);
                    }
                });
        }
        let chosen: Vec<String> = app
            .plots
            .choice
            .iter()
            .filter(|c| !c.is_empty())
            .cloned()
            .collect();
        if ui
            .add_enabled(chosen != live.signals, egui::Button::new("Apply"))
            .on_hover_text("ask the machine for these telemetry signals")
            .clicked()
        {
            send = Some(chosen);
        }
    });
    if let Some(names) = send {
        app.send(Command::Signals(names));
    }

    let live = &app.live;
    // the samples shown: the frozen copy, or the history (a ring: two slices)
    let (older, newer): (&[Telemetry], &[Telemetry]) = match &app.plots.frozen {
        Some(f) => (f, &[]),
        None => live.history.as_slices(),
    };
    let samples = || older.iter().chain(newer);
    let last = match &app.plots.frozen {
        Some(f) => f.last(),
        None => live.history.back(),
    };
    let Some(last) = last else {
        ui.label("no telemetry yet");
        return;
    };
    let t1 = live.time_s(last);
    let t0 = t1 - app.plots.window_s;
    let frozen = app.plots.frozen.is_some();
    let panels = panels(&live.signals);
    let n = panels.len().max(1) as f32;
    let spacing = ui.spacing().item_spacing.y;
    let height = ((ui.available_height() - spacing * (n - 1.0)) / n).max(60.0);
    let buckets = (ui.available_width() * ui.ctx().pixels_per_point()).clamp(16.0, 4096.0) as usize;
    let link = Id::unique("live_plots_time");
    egui::ScrollArea::vertical().show(ui, |ui| {
        for (k, p) in panels.iter().enumerate() {
            let last_plot = k + 1 == panels.len();
            let lines: Vec<(String, Color32, Vec<[f64; 2]>)> = p
                .series
                .iter()
                .map(|s| {
                    let pts = min_max_decimate(
                        samples().map(|t| (live.time_s(t), (s.value)(t))),
                        t0,
                        t1,
                        buckets,
                    );
                    (s.name.clone(), s.colour, pts)
                })
                .collect();
            let mut plot = Plot::new(p.id)
                .height(height)
                .legend(Legend::default().position(Corner::LeftTop))
                .link_axis(link, [true, false])
                .link_cursor(link, [true, false])
                .y_axis_label(p.unit.clone())
                .y_axis_min_width(48.0)
                .allow_drag(frozen)
                .allow_zoom(frozen)
                .allow_scroll(frozen)
                .allow_boxed_zoom(frozen)
                .show_x(true)
                .show_y(true);
            if last_plot {
                plot = plot.x_axis_label("machine time, s");
            }
            plot.show(ui, |pu| {
                if !frozen {
                    pu.set_auto_bounds([false, true]);
                    pu.set_plot_bounds_x(t0..=t1);
                }
                for (name, colour, pts) in lines {
                    pu.line(Line::new(name, PlotPoints::from(pts)).color(colour));
                }
            });
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_one_sample_spike_survives_decimation() {
        let n = 10_000;
        let spike = 4321;
        let s = (0..n).map(|i| (i as f64 * 1e-3, if i == spike { 5.0 } else { 0.0 }));
        let out = min_max_decimate(s, 0.0, 10.0, 100);
        assert!(out.len() <= 200, "{} points", out.len());
        assert!(out
            .iter()
            .any(|p| p[1] == 5.0 && (p[0] - 4.321).abs() < 1e-9));
        // in time order
        assert!(out.windows(2).all(|w| w[0][0] <= w[1][0]));
    }

    #[test]
    fn a_negative_spike_and_the_ends_survive() {
        let s = (0..1000).map(|i| (f64::from(i), if i == 500 { -3.0 } else { f64::from(i % 2) }));
        let out = min_max_decimate(s, 0.0, 999.0, 10);
        assert!(out.iter().any(|p| p[1] == -3.0));
        assert!(out.iter().any(|p| p[1] == 1.0));
        assert!(out.len() <= 20);
    }

    #[test]
    fn decimation_tolerates_bad_data() {
        assert!(min_max_decimate([(0.0, 1.0)].into_iter(), 1.0, 1.0, 10).is_empty());
        assert!(min_max_decimate([(0.0, 1.0)].into_iter(), 0.0, f64::NAN, 10).is_empty());
        let s = [(0.1, f64::NAN), (0.2, 2.0), (f64::NAN, 3.0), (5.0, 4.0)];
        assert_eq!(
            min_max_decimate(s.into_iter(), 0.0, 1.0, 0),
            vec![[0.2, 2.0]]
        );
    }

    #[test]
    fn signal_names_and_units() {
        let names = signal_names();
        assert!(names.contains(&"effort.x".to_string()));
        assert!(names.contains(&"contour".to_string()));
        for n in &names {
            assert!(
                controller_core::machine::scope::Signal::from_name(n).is_some(),
                "{n}"
            );
            // (the feed ratio is a pure number)
            assert!(
                n == "feed_ratio" || !signal_unit(n).is_empty(),
                "{n} has no unit"
            );
        }
    }
}
