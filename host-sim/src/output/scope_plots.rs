//! The figure of `gantry scope` (PNG and SVG beside the CSV): one panel per recorded
//! signal against time from the trigger.

use crate::cli::scope::Capture;
use crate::output::plots::{both, register_font, Panel, Series};
use anyhow::Result;
use plotters::style::RGBColor;
use std::path::Path;

const LINE: RGBColor = RGBColor(31, 119, 180);
const TRIGGER: RGBColor = RGBColor(214, 39, 40);

/// The unit of a scope signal by its name (`pos.x`, `vel.y`, `contour`, …), as
/// `controller_core::machine::scope::Signal` documents them; effort is the gantry's mN·m.
pub fn signal_unit(name: &str) -> &'static str {
    match name.split('.').next().unwrap_or(name) {
        "pos" | "ref" | "tracking" | "contour" => "mm",
        "vel" | "ref_vel" | "sliding" => "mm/s",
        "effort" => "mN·m",
        _ => "",
    }
}

/// `<stem>.png` and `<stem>.svg` in `dir`; the number of files written.
pub fn figure(dir: &Path, stem: &str, cap: &Capture) -> Result<usize> {
    register_font()?;
    let n = cap.names.len().max(1);
    let height = (220 * n as u32).clamp(300, 1200);
    both(dir, stem, (1000, height), &|add| {
        for (i, name) in cap.names.iter().enumerate() {
            let points: Vec<(f64, f64)> = cap
                .rows
                .iter()
                .map(|(t, v)| (*t, f64::from(v[i])))
                .collect();
            let (lo, hi) = points
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| {
                    (l.min(p.1), h.max(p.1))
                });
            add(Panel::lines(
                format!("{name} (trigger at t = 0)"),
                "time from the trigger (s)",
                (name, signal_unit(name)),
                vec![
                    Series::new(name.clone(), LINE, points),
                    Series::new(
                        "trigger",
                        TRIGGER,
                        if lo.is_finite() {
                            vec![(0.0, lo), (0.0, hi)]
                        } else {
                            vec![]
                        },
                    )
                    .dashed(),
                ],
            ))?;
        }
        Ok(())
    })
}
