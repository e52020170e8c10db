//! Checked numbers of the `gantry` command line: finite and within a stated range, so that
//! no flag starts an endless wait (`--seconds inf`), a hold that never comes (`--hold-at-s
//! nan`) or a jog that silently does nothing (`jog x nan`). Each parser is a clap value
//! parser: a bad value is an error naming the flag and the range, before anything is sent.

/// Longest stretch of machine time a flag may ask for, s (an hour: far beyond any jog,
/// log or capture, short enough that a typo cannot hold a session for days).
pub const MAX_SECONDS: f32 = 3600.0;

fn number(s: &str) -> Result<f32, String> {
    let x: f32 = s
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a number"))?;
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("`{s}` is not finite"))
    }
}

/// A finite number (a speed in mm/s, a coordinate in mm): the machine's own limits and
/// travel check the rest.
pub fn finite(s: &str) -> Result<f32, String> {
    number(s)
}

/// A duration of machine time, s: more than 0, at most [`MAX_SECONDS`].
pub fn duration_s(s: &str) -> Result<f32, String> {
    let x = number(s)?;
    if x > 0.0 && x <= MAX_SECONDS {
        Ok(x)
    } else {
        Err(format!("{x} s is outside (0, {MAX_SECONDS}] s"))
    }
}

/// A moment of machine time from the start, s: 0 to [`MAX_SECONDS`].
pub fn instant_s(s: &str) -> Result<f32, String> {
    let x = number(s)?;
    if (0.0..=MAX_SECONDS).contains(&x) {
        Ok(x)
    } else {
        Err(format!("{x} s is outside [0, {MAX_SECONDS}] s"))
    }
}

/// Read-outs per second of `gantry watch`: 0.5 to 50.
pub fn watch_hz(s: &str) -> Result<f32, String> {
    let x = number(s)?;
    if (0.5..=50.0).contains(&x) {
        Ok(x)
    } else {
        Err(format!("{x} Hz is outside [0.5, 50] Hz"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn non_finite_and_out_of_range_values_are_refused() {
        for bad in ["nan", "NaN", "inf", "-inf", "1e39", "x", ""] {
            assert!(finite(bad).is_err(), "{bad}");
            assert!(duration_s(bad).is_err(), "{bad}");
            assert!(instant_s(bad).is_err(), "{bad}");
        }
        assert!(duration_s("0").is_err() && duration_s("-1").is_err());
        assert!(duration_s("3600.5").is_err() && instant_s("-0.1").is_err());
        assert_eq!(duration_s("0.5"), Ok(0.5));
        assert_eq!(instant_s("0"), Ok(0.0));
        assert_eq!(finite("-12.5"), Ok(-12.5));
        assert!(duration_s("inf").unwrap_err().contains("not finite"));
        assert!(watch_hz("0").is_err() && watch_hz("51").is_err() && watch_hz("nan").is_err());
        assert_eq!(watch_hz("10"), Ok(10.0));
    }
}
