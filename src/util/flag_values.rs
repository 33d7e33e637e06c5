//! Values of command-line flags, checked as clap parses them: one rule per
//! kind of value, shared by every command that takes such a flag, so that a
//! nonsense value is refused naming the flag and the value before anything
//! runs (exit status 2), e.g.
//! `invalid value '-1' for '--fps <FPS>': must be a number greater than 0`.
//!
//! A flag using these also takes `allow_negative_numbers = true`, so that
//! `--radius-mm -3` reaches the check instead of being read as a flag.

/// A number greater than 0 (a frame rate, a length, a scale, a density):
/// 0, negative numbers, NaN and infinity are refused.
pub fn positive(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err("must be a number greater than 0".into()),
    }
}

/// A finite number (a row, which may lie above the picture): NaN and
/// infinity are refused.
pub fn finite(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err("must be a finite number".into()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn positive_takes_numbers_above_zero_only() {
        for ok in ["1", "0.04", "1e4", "+3", "10000.0"] {
            assert!(positive(ok).is_ok(), "{ok}");
        }
        for bad in [
            "0", "-0", "-1", "-3", "NaN", "inf", "-inf", "1e400", "", "abc", "3mm",
        ] {
            assert_eq!(
                positive(bad).unwrap_err(),
                "must be a number greater than 0",
                "{bad}"
            );
        }
    }
}
