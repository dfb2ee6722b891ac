//! The terminal's view of a run: a progress bar (or a spinner for kinds that report
//! stages) fed by the library's observer events, and Ctrl-C turned into cancellation.

use std::io::IsTerminal;
use std::ops::ControlFlow;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use cps_experiment::{Event, Observer};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// A progress bar on stderr (hidden with `--quiet` or without a terminal); stops the run
/// when `interrupted` is set.
pub struct Terminal<'a> {
    bar: ProgressBar,
    show: bool,
    interrupted: &'a AtomicBool,
    best: AtomicU64,
    stage: Mutex<String>,
}

impl<'a> Terminal<'a> {
    /// A terminal view; `show` false draws nothing.
    pub fn new(show: bool, interrupted: &'a AtomicBool) -> Self {
        Self {
            bar: ProgressBar::hidden(),
            show: show && std::io::stderr().is_terminal(),
            interrupted,
            best: AtomicU64::new(f64::INFINITY.to_bits()),
            stage: Mutex::new(String::new()),
        }
    }

    /// Removes the bar from the terminal.
    pub fn clear(&self) {
        self.bar.finish_and_clear();
    }

    fn verdict(&self) -> ControlFlow<()> {
        if self.interrupted.load(Ordering::Relaxed) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }
}

impl Observer for Terminal<'_> {
    fn started(&self, total: u64) {
        if !self.show {
            return;
        }
        let target = ProgressDrawTarget::stderr_with_hz(10);
        self.bar.set_draw_target(target);
        if total > 0 {
            self.bar.set_length(total);
        } else {
            self.bar.unset_length();
        }
        self.bar.set_style(
            ProgressStyle::with_template(if total == 0 {
                "{spinner} {msg}  {elapsed}"
            } else {
                "{bar:20} {pos}/{len} gen  {msg}  {elapsed}"
            })
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
    }

    fn event(&self, event: Event<'_>) -> ControlFlow<()> {
        match event {
            Event::Generation {
                generation,
                best_so_far,
                sigma,
            } => {
                self.bar.inc(1);
                let prev = f64::from_bits(self.best.load(Ordering::Relaxed));
                if best_so_far < prev {
                    self.best.store(best_so_far.to_bits(), Ordering::Relaxed);
                }
                if generation.is_multiple_of(25) {
                    let stage = self.stage.lock().unwrap_or_else(|p| p.into_inner());
                    let best = f64::from_bits(self.best.load(Ordering::Relaxed));
                    self.bar
                        .set_message(format!("{stage}best {best:.3e}  σ {sigma:.1e}"));
                }
            }
            Event::Working => self.bar.tick(),
            Event::Stage(s) => {
                *self.stage.lock().unwrap_or_else(|p| p.into_inner()) = format!("{s}  ");
                // A new stage starts its own best cost.
                self.best.store(f64::INFINITY.to_bits(), Ordering::Relaxed);
                self.bar.set_message(s.to_string());
                self.bar.tick();
            }
        }
        self.verdict()
    }

    fn finished(&self) {
        self.bar.finish_and_clear();
    }
}
