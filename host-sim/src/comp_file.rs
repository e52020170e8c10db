//! LinuxCNC's screw-compensation file (`[JOINT_n] COMP_FILE`, `COMP_FILE_TYPE`), read into
//! one axis' table (controller-core `motion::compensation`) and written back.
//!
//! One point per line, three numbers separated by blanks, nominal positions increasing
//! (LinuxCNC `usrmotLoadComp`, at most 256 points):
//! - type 0: `nominal forward-actual reverse-actual`: where the axis really is, measured at
//!   the tool (a laser, a gauge), when it comes to `nominal` moving forward and in reverse;
//!   the trim added to the command is `nominal − actual`;
//! - type 1: `nominal forward-trim reverse-trim`: the trims themselves.
//!
//! Blank lines and lines starting with `#` or `;` are skipped (LinuxCNC stops at the first
//! line that is not a triplet; here such a line is an error naming `FILE:LINE`). Units are
//! the machine's: mm.

use anyhow::{bail, Context, Result};
use controller_core::filter::AxisFilterConfig;
use controller_core::motion::compensation::{AxisCompensation, CompPoint, MAX_COMP_POINTS};
use controller_core::motion::feedforward::FeedForwardConfig;
use std::fmt::Write as _;
use std::path::Path;

/// The two layouts of a compensation file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompFileType {
    /// `nominal forward-actual reverse-actual`.
    Actual,
    /// `nominal forward-trim reverse-trim`.
    Trim,
}

impl CompFileType {
    /// LinuxCNC's `COMP_FILE_TYPE` number.
    pub fn from_number(n: u32) -> Result<Self> {
        match n {
            0 => Ok(Self::Actual),
            1 => Ok(Self::Trim),
            _ => bail!("COMP_FILE_TYPE must be 0 (actual positions) or 1 (trims), got {n}"),
        }
    }
}

/// Parse the text of a compensation file named `name` (for the errors).
pub fn parse(name: &str, text: &str, kind: CompFileType) -> Result<Vec<CompPoint>> {
    let mut pts: Vec<CompPoint> = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with(';') {
            continue;
        }
        let at = || format!("{name}:{}", i + 1);
        let v: Vec<f64> = line
            .split_whitespace()
            .map(|w| w.parse::<f64>())
            .collect::<Result<_, _>>()
            .with_context(|| format!("{}: not three numbers: `{line}`", at()))?;
        let [nom, fwd, rev] = v[..] else {
            bail!(
                "{}: expected three numbers (nominal, forward, reverse), got {}",
                at(),
                v.len()
            );
        };
        if !(nom.is_finite() && fwd.is_finite() && rev.is_finite()) {
            bail!("{}: a value is not finite", at());
        }
        if let Some(prev) = pts.last() {
            if nom <= f64::from(prev.nominal_mm) {
                bail!(
                    "{}: nominal {nom} does not increase (previous {})",
                    at(),
                    prev.nominal_mm
                );
            }
        }
        if pts.len() == MAX_COMP_POINTS {
            bail!("{}: more than {MAX_COMP_POINTS} points", at());
        }
        let (f, r) = match kind {
            CompFileType::Actual => (nom - fwd, nom - rev),
            CompFileType::Trim => (fwd, rev),
        };
        pts.push(CompPoint {
            nominal_mm: nom as f32,
            fwd_trim_mm: f as f32,
            rev_trim_mm: r as f32,
        });
    }
    Ok(pts)
}

/// Read the compensation file at `path`.
/// Largest compensation file read (256 points of three numbers are a few KiB).
pub const COMP_FILE_MAX_BYTES: u64 = 1 << 20;

pub fn read(path: &Path, kind: CompFileType) -> Result<Vec<CompPoint>> {
    // (a regular file only: a pipe or a device is refused before it is opened)
    let text = gantry_scenario::file::read_regular(path, COMP_FILE_MAX_BYTES)
        .map_err(anyhow::Error::msg)
        .with_context(|| format!("reading compensation file {}", path.display()))?;
    parse(&path.display().to_string(), &text, kind)
}

/// The tables of a folder of type-0 files `comp_x.txt`, `comp_y.txt`, `comp_z.txt` (an
/// absent file: no compensation on that axis).
pub fn read_dir(dir: &Path) -> Result<[AxisCompensation; 3]> {
    let mut out = [AxisCompensation::NONE; 3];
    if !dir.is_dir() {
        bail!("compensation folder {} not found", dir.display());
    }
    for (i, letter) in ['x', 'y', 'z'].into_iter().enumerate() {
        let path = dir.join(format!("comp_{letter}.txt"));
        if path.exists() {
            let pts = read(&path, CompFileType::Actual)?;
            out[i] = AxisCompensation::new(&pts, 0.0)
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        }
    }
    Ok(out)
}

/// The name of the feed-forward file in a compensation folder.
pub const FEEDFORWARD_FILE: &str = "feedforward.toml";

/// The name of the output filters' file in a compensation folder.
pub const FILTERS_FILE: &str = "filters.toml";

/// A per-axis file of a compensation folder (`feedforward.toml`, `filters.toml`): a key
/// per axis (`x`, `y`, `z`, each optional) holding that axis' configuration.
#[derive(Debug, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields)]
pub struct PerAxisFile<T> {
    #[serde(default = "none", skip_serializing_if = "Option::is_none")]
    pub x: Option<T>,
    #[serde(default = "none", skip_serializing_if = "Option::is_none")]
    pub y: Option<T>,
    #[serde(default = "none", skip_serializing_if = "Option::is_none")]
    pub z: Option<T>,
}

fn none<T>() -> Option<T> {
    None
}

impl<T: Copy + Default> PerAxisFile<T> {
    /// The three axes' configurations (an absent one: the default, none).
    pub fn axes(&self) -> [T; 3] {
        [self.x, self.y, self.z].map(Option::unwrap_or_default)
    }

    /// The file holding `axes` (an axis equal to the default is left out).
    pub fn of(axes: [T; 3]) -> Self
    where
        T: PartialEq,
    {
        let [x, y, z] = axes.map(|a| (a != T::default()).then_some(a));
        Self { x, y, z }
    }
}

/// The feed-forward file: `[x]`, `[y]`, `[z]` tables with the keys of controller-core's
/// `FeedForwardConfig`.
pub type FeedForwardFile = PerAxisFile<FeedForwardConfig>;

/// The filters' file: `x`, `y`, `z` lists of stages as controller-core's
/// `AxisFilterConfig` reads them (`y = [{ notch = { freq_hz = 35.0, ... } }]`).
pub type FiltersFile = PerAxisFile<AxisFilterConfig>;

/// The file `name` of the folder `dir`, if it has one, each axis checked by `validate`;
/// errors name the file and the axis.
fn read_per_axis<T, E: std::fmt::Display>(
    dir: &Path,
    name: &str,
    what: &str,
    validate: impl Fn(&T) -> Result<(), E>,
) -> Result<Option<[T; 3]>>
where
    T: Copy + Default + serde::de::DeserializeOwned,
{
    let path = dir.join(name);
    if !path.exists() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path)
        .with_context(|| format!("reading {what} file {}", path.display()))?;
    let file: PerAxisFile<T> =
        toml::from_str(&text).with_context(|| format!("{what} file {}", path.display()))?;
    let axes = file.axes();
    for (c, letter) in axes.iter().zip(['x', 'y', 'z']) {
        validate(c).map_err(|e| anyhow::anyhow!("{}: [{letter}]: {e}", path.display()))?;
    }
    Ok(Some(axes))
}

/// The feed-forward of the folder `dir` (its `feedforward.toml`), if it has one; each
/// axis validated, errors naming the file and the axis.
pub fn read_feedforward(dir: &Path) -> Result<Option<[FeedForwardConfig; 3]>> {
    read_per_axis(
        dir,
        FEEDFORWARD_FILE,
        "feed-forward",
        FeedForwardConfig::validate,
    )
}

/// The output filters of the folder `dir` (its `filters.toml`), if it has one; each
/// axis validated at the control rate `rate_hz`, errors naming the file and the axis.
pub fn read_filters(dir: &Path, rate_hz: u32) -> Result<Option<[AxisFilterConfig; 3]>> {
    let period_s = 1.0 / rate_hz.max(1) as f32;
    read_per_axis(dir, FILTERS_FILE, "filters", |c: &AxisFilterConfig| {
        c.validate(period_s)
    })
}

/// A type-0 file (`nominal forward-actual reverse-actual`, µm resolution kept to 0.1 µm)
/// of measured points `(nominal, forward actual, reverse actual)`, with a header comment.
pub fn write_actual(header: &str, pts: &[(f64, f64, f64)]) -> String {
    let mut s = String::new();
    for h in header.lines() {
        let _ = writeln!(s, "# {h}");
    }
    for (n, f, r) in pts {
        let _ = writeln!(s, "{n:.4} {f:.5} {r:.5}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn type_0_gives_nominal_minus_actual_and_type_1_the_trims() {
        let text = "# measured\n0.0 0.0 -0.001\n\n10.0 10.002 9.995\n";
        let p = parse("c.txt", text, CompFileType::Actual).unwrap();
        assert_eq!(p.len(), 2);
        assert!((p[0].rev_trim_mm - 0.001).abs() < 1e-7);
        assert!((p[1].fwd_trim_mm + 0.002).abs() < 1e-6);
        assert!((p[1].rev_trim_mm - 0.005).abs() < 1e-6);
        let p = parse("c.txt", "5 0.01 -0.01\n", CompFileType::Trim).unwrap();
        assert_eq!(p[0].fwd_trim_mm, 0.01);
    }

    #[test]
    fn bad_lines_are_errors_naming_file_and_line() {
        let e = |t: &str| {
            parse("comp.txt", t, CompFileType::Actual)
                .unwrap_err()
                .to_string()
        };
        assert!(
            e("0 0 0\n1 1\n").starts_with("comp.txt:2: expected three numbers"),
            "{}",
            e("0 0 0\n1 1\n")
        );
        assert!(e("0 0 0\n0 0 0\n").starts_with("comp.txt:2: nominal 0 does not increase"));
        assert!(e("0 x 0\n").starts_with("comp.txt:1: not three numbers"));
        assert!(e("0 inf 0\n").starts_with("comp.txt:1: a value is not finite"));
        let many: String = (0..=MAX_COMP_POINTS)
            .map(|i| format!("{i} {i} {i}\n"))
            .collect();
        assert!(e(&many).starts_with("comp.txt:257: more than 256 points"));
        assert!(CompFileType::from_number(2).is_err());
    }

    #[test]
    fn a_missing_folder_or_a_bad_file_in_it_is_an_error_naming_it() {
        let e = read_dir(Path::new("/nonexistent/comp"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/comp not found"), "{e}");
        let dir = std::env::temp_dir().join(format!("gantry-comp-dir-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("comp_y.txt"), "0 0 0\n1 1\n").unwrap();
        let e = read_dir(&dir).unwrap_err().to_string();
        assert!(e.contains("comp_y.txt:2: expected three numbers"), "{e}");
        std::fs::write(dir.join("comp_y.txt"), "0 0.001 -0.001\n").unwrap();
        let t = read_dir(&dir).unwrap();
        assert!(t[0].is_none() && !t[1].is_none() && t[2].is_none());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_written_file_reads_back() {
        let s = write_actual("test", &[(0.0, 0.001, -0.002), (7.0, 7.0, 6.99)]);
        let p = parse("w", &s, CompFileType::Actual).unwrap();
        assert!((p[0].fwd_trim_mm + 0.001).abs() < 1e-7);
        assert!((p[1].rev_trim_mm - 0.01).abs() < 1e-6);
    }
}
