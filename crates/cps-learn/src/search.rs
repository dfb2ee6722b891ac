//! What every search shares: its record ([`SearchStats`], [`GenerationRecord`]) and the
//! pool of evaluation buffers its workers reuse. CMA-ES (`viapoint.rs`) and
//! Levenberg–Marquardt (`lsq.rs`) both build on it.

use serde::{Deserialize, Serialize};

/// One generation of a repetition's history.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GenerationRecord {
    /// Generation number (1-based).
    pub generation: u64,
    /// Best cost of the generation.
    pub best: f64,
    /// Median cost of the generation.
    pub median: f64,
    /// Best cost so far.
    pub best_so_far: f64,
    /// Step size after the generation.
    pub sigma: f64,
}

/// How a search went: the budget spent, why it ended, and the history.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SearchStats {
    /// Generations run (0 for an exact solve).
    pub generations: u64,
    /// Cost evaluations.
    pub evaluations: u64,
    /// Evaluations whose cost was NaN or infinite.
    pub non_finite_evaluations: u64,
    /// Why the search ended (`max_generations`, `tolfun`, `exact`, `interrupted`, …).
    pub termination: String,
    /// Per-generation history (empty for an exact solve).
    pub history: Vec<GenerationRecord>,
}

impl SearchStats {
    /// True if the search was stopped by its caller (Ctrl-C).
    pub fn interrupted(&self) -> bool {
        self.termination == "interrupted"
    }

    /// The statistics of an exact solve (no search): one evaluation.
    pub(crate) fn exact() -> Self {
        Self {
            generations: 0,
            evaluations: 1,
            non_finite_evaluations: 0,
            termination: "exact".into(),
            history: Vec::new(),
        }
    }
}

/// Buffers kept between uses: a job takes one (or makes one), uses it and puts it back,
/// so large buffers are allocated once per worker and run, not per job. (Fresh buffers
/// cost page faults, which serialise the threads: measured 4× slower populations.)
#[derive(Debug)]
pub(crate) struct BufferPool<T>(std::sync::Mutex<Vec<T>>);

impl<T> Default for BufferPool<T> {
    fn default() -> Self {
        Self(std::sync::Mutex::new(Vec::new()))
    }
}

impl<T> BufferPool<T> {
    /// Runs `f` on a pooled buffer (made by `make` if none is free).
    pub(crate) fn with<R>(&self, make: impl FnOnce() -> T, f: impl FnOnce(&mut T) -> R) -> R {
        let taken = self.0.lock().ok().and_then(|mut free| free.pop());
        let mut buffer = taken.unwrap_or_else(make);
        let r = f(&mut buffer);
        if let Ok(mut free) = self.0.lock() {
            free.push(buffer);
        }
        r
    }
}
