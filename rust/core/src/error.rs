//! Errors of the core's public functions. Every entry point checks the lengths and ranges of its
//! arguments before touching them, so a wrong call from Rust is an `Err`, never a panic or an
//! out-of-bounds index; the Python bindings turn these into `ValueError`.

use std::fmt;

/// What was wrong with the arguments of a core call.
#[derive(Debug, Clone, PartialEq)]
pub enum CoreError {
    /// An argument has the wrong number of elements.
    Length { name: &'static str, got: usize, expected: String },
    /// An argument's value is out of range (not finite, not positive, not increasing, ...).
    Value { name: &'static str, reason: String },
}

impl CoreError {
    pub(crate) fn length(name: &'static str, got: usize, expected: impl Into<String>) -> Self {
        CoreError::Length { name, got, expected: expected.into() }
    }

    pub(crate) fn value(name: &'static str, reason: impl Into<String>) -> Self {
        CoreError::Value { name, reason: reason.into() }
    }

    /// The argument the error is about.
    pub fn name(&self) -> &'static str {
        match self {
            CoreError::Length { name, .. } | CoreError::Value { name, .. } => name,
        }
    }
}

impl fmt::Display for CoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CoreError::Length { name, got, expected } => write!(f, "{name} has {got} elements, expected {expected}"),
            CoreError::Value { name, reason } => write!(f, "{name} {reason}"),
        }
    }
}

impl std::error::Error for CoreError {}

/// Check that `a` has exactly `want` elements.
pub(crate) fn expect_len<T>(name: &'static str, a: &[T], want: usize) -> Result<(), CoreError> {
    if a.len() != want {
        return Err(CoreError::length(name, a.len(), want.to_string()));
    }
    Ok(())
}

/// Check that `a` has `one` elements (broadcast) or `all` elements (one row per point).
pub(crate) fn expect_len_or_broadcast<T>(name: &'static str, a: &[T], one: usize, all: usize) -> Result<(), CoreError> {
    if a.len() != one && a.len() != all {
        return Err(CoreError::length(name, a.len(), format!("{one} (broadcast) or {all}")));
    }
    Ok(())
}

/// `n1 * n2 * ...` without overflow.
pub(crate) fn product(name: &'static str, dims: &[usize]) -> Result<usize, CoreError> {
    dims.iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| CoreError::value(name, format!("size {dims:?} overflows")))
}
