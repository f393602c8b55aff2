//! The field checks every settings struct's `validate` is made of: each names the field's
//! dotted path (`optimize.tolerance`), the value found and what was expected, so the pipeline
//! file can turn a refusal into an error at the line of the setting.

use std::fmt;

/// A setting that parses but is not allowed.
#[derive(Debug, Clone, PartialEq)]
pub struct Invalid {
    /// The dotted path of the field, as `PipelineFile::place_of` takes it: `match.max_speed`.
    pub field: String,
    /// What is wrong: the value found and what was expected (`is NaN; expected ...`).
    pub message: String,
}

impl fmt::Display for Invalid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "`{}` {}", self.field, self.message)
    }
}

impl std::error::Error for Invalid {}

/// What a `validate` returns.
pub type Check = Result<(), Invalid>;

/// Refuses `field` with `message`.
pub fn invalid(field: &str, message: impl Into<String>) -> Invalid {
    Invalid {
        field: field.to_string(),
        message: message.into(),
    }
}

/// `ok`, or `field` refused as "is {value}; expected {expected}".
pub fn require(ok: bool, field: &str, value: impl fmt::Display, expected: &str) -> Check {
    if ok {
        Ok(())
    } else {
        Err(invalid(field, format!("is {value}; expected {expected}")))
    }
}

/// A finite number above zero (NaN and infinity are refused).
pub fn positive(field: &str, value: f64, expected: &str) -> Check {
    require(
        value.is_finite() && value > 0.0,
        field,
        Num(value),
        expected,
    )
}

/// A finite number of zero or more.
pub fn not_negative(field: &str, value: f64, expected: &str) -> Check {
    require(
        value.is_finite() && value >= 0.0,
        field,
        Num(value),
        expected,
    )
}

/// A number in (0, 1]: a share (NaN is refused, as it compares with nothing).
pub fn share(field: &str, value: f64, expected: &str) -> Check {
    require(value > 0.0 && value <= 1.0, field, Num(value), expected)
}

/// A number as a person writes it: `20`, `0.3`, `1e300` (not three hundred digits), `1e-9`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Num(pub f64);

impl fmt::Display for Num {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let v = self.0;
        if v != 0.0 && v.is_finite() && !(1e-4..1e9).contains(&v.abs()) {
            write!(f, "{v:e}")
        } else {
            write!(f, "{v}")
        }
    }
}

/// A count from 1 to `most`: an iteration limit, whose largest value bounds the work it
/// allows.
pub fn count_up_to(field: &str, value: u32, most: u32, expected: &str) -> Check {
    require((1..=most).contains(&value), field, value, expected)
}
