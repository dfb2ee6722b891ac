//! Watching a run: the events it reports and the [`Observer`] that receives them and may
//! stop it. Nothing here draws; a command line or a notebook implements the observer.

use std::ops::ControlFlow;

/// What a run reports while it works.
#[derive(Debug, Clone, Copy)]
pub enum Event<'a> {
    /// A generation of a search finished. Searches of parallel repetitions report from
    /// their own threads, so generations of different repetitions interleave.
    Generation {
        /// Its number within its search (1-based).
        generation: u64,
        /// The best cost found so far by its search.
        best_so_far: f64,
        /// The search's step size.
        sigma: f64,
    },
    /// The run entered a stage (`demonstrations 3/20`, `scaled (1/2)`).
    Stage(&'a str),
    /// Work that is not a counted generation (a timing measurement) made a step; the
    /// observer may stop it like a generation.
    Working,
}

/// Watches a run: progress and cancellation. Called from the run's worker threads.
pub trait Observer: Sync {
    /// The run starts; `generations` is the number it will report (0 when it reports
    /// stages instead).
    fn started(&self, generations: u64) {
        let _ = generations;
    }

    /// Something happened; return `ControlFlow::Break(())` to stop the run early (its
    /// finished part is still returned, marked incomplete).
    fn event(&self, event: Event<'_>) -> ControlFlow<()> {
        let _ = event;
        ControlFlow::Continue(())
    }

    /// The computing is over (before the outcome is assembled).
    fn finished(&self) {}
}

/// Watches nothing and never stops a run.
impl Observer for () {}
