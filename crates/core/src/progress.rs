//! Progress reporting that the pure stage cores can call without knowing about terminals.

/// Receives progress from a stage. Implementations must be cheap and thread-safe: stages call
/// [`Progress::advance`] from rayon workers.
pub trait Progress: Sync {
    /// A new phase of `total` steps starts.
    fn begin(&self, phase: &str, total: u64);
    /// `steps` more steps are done.
    fn advance(&self, steps: u64);
}

/// No progress reporting (tests, benchmarks, `--quiet`).
impl Progress for () {
    fn begin(&self, _phase: &str, _total: u64) {}
    fn advance(&self, _steps: u64) {}
}
