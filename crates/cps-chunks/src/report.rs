//! A chunk run judged in numbers: the commands' acceleration and jerk peaks per joint, at
//! the chunk boundaries and overall (against the limits they kept), the inference delay
//! and its jitter, how closely the robot tracked its commands, and how often a chunk was
//! taken, refused, or had targets skipped.

use crate::feed::{ChunkLog, ChunkVerdict};
use crate::run::Followed;

/// Milliseconds either side of a chunk's arrival counted as its boundary.
pub const BOUNDARY_MS: f64 = 20.0;

/// A few numbers of a series: mean, standard deviation (the jitter, for times), least and
/// largest. All NaN for no value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    /// Mean.
    pub mean: f64,
    /// Standard deviation.
    pub std: f64,
    /// Least.
    pub min: f64,
    /// Largest.
    pub max: f64,
}

impl Spread {
    /// Of `x`.
    pub fn of(x: &[f64]) -> Spread {
        if x.is_empty() {
            return Spread {
                mean: f64::NAN,
                std: f64::NAN,
                min: f64::NAN,
                max: f64::NAN,
            };
        }
        let n = x.len() as f64;
        let mean = x.iter().sum::<f64>() / n;
        let var = x.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n;
        Spread {
            mean,
            std: var.sqrt(),
            min: x.iter().copied().fold(f64::INFINITY, f64::min),
            max: x.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        }
    }
}

/// Peaks of the commands' backward differences per joint (absolute values).
#[derive(Debug, Clone, PartialEq)]
pub struct Peaks {
    /// Velocity (rad/s).
    pub velocity: Vec<f64>,
    /// Acceleration (rad/s²).
    pub acceleration: Vec<f64>,
    /// Jerk (rad/s³).
    pub jerk: Vec<f64>,
}

/// A chunk run's report (see the module's text).
#[derive(Debug, Clone, PartialEq)]
pub struct FollowReport {
    /// Peaks over the whole run.
    pub overall: Peaks,
    /// Peaks within [`BOUNDARY_MS`] of a taken chunk's arrival.
    pub boundaries: Peaks,
    /// The largest share of its limit any joint's velocity, acceleration and jerk reached
    /// (1 = at the limit the commands kept).
    pub usage: [f64; 3],
    /// Inference delay of the chunks that came: arrival − observation (s).
    pub delay: Spread,
    /// Time between arrivals (s).
    pub interval: Spread,
    /// Largest |measured − commanded| per joint (rad), the measured one period later.
    pub tracking_max: Vec<f64>,
    /// Root mean square of it per joint (rad).
    pub tracking_rms: Vec<f64>,
    /// Chunks that came, taken, refused (with the first few reasons), targets skipped.
    pub chunks: usize,
    /// Taken.
    pub taken: usize,
    /// Refused.
    pub refused: usize,
    /// The reasons of the first refusals (at most five), with the chunk's index.
    pub refusals: Vec<(usize, String)>,
    /// Targets skipped as already past.
    pub skipped: usize,
    /// When each stall began (s): the arm braked to rest for want of chunks.
    pub stalls: Vec<f64>,
    /// Log entries lost on their way back from the loop.
    pub lost: usize,
    /// Chunks that never reached the executor: the run had ended before they came (a
    /// pause in the stream longer than the idle end), with the pause (s) before the first.
    pub unplayed: Option<(usize, f64)>,
}

/// Backward differences of `x` (from rest before its first value) divided by `dt`.
fn rates(x: &[f64], first: f64, dt: f64) -> Vec<f64> {
    let mut prev = first;
    x.iter()
        .map(|&v| {
            let d = (v - prev) / dt;
            prev = v;
            d
        })
        .collect()
}

impl FollowReport {
    /// The report of `run` with its chunks' `log`.
    pub fn new(run: &Followed, log: &ChunkLog) -> FollowReport {
        let dof = run.limits.len();
        let dt = run.dt;
        let n = run.commands.len();
        let arrivals: Vec<f64> = log
            .entries
            .iter()
            .filter(|(_, v)| matches!(v, Some(ChunkVerdict::Taken { .. })))
            .map(|(c, _)| c.arrived_s)
            .collect();
        // Command k is for the period ending at (k + 1) dt.
        let near = |k: usize| {
            let t = (k + 1) as f64 * dt;
            let i = arrivals.partition_point(|a| *a < t - BOUNDARY_MS * 1e-3);
            arrivals
                .get(i)
                .is_some_and(|a| *a <= t + BOUNDARY_MS * 1e-3)
        };
        let start = run.run.q.first();
        let mut overall = Peaks {
            velocity: vec![0.0; dof],
            acceleration: vec![0.0; dof],
            jerk: vec![0.0; dof],
        };
        let mut boundaries = overall.clone();
        let mut usage = [0.0_f64; 3];
        for j in 0..dof {
            let q: Vec<f64> = run.commands.iter().map(|c| c[j]).collect();
            let q0 = start.map_or(q.first().copied().unwrap_or(0.0), |s| s[j]);
            let v = rates(&q, q0, dt);
            let a = rates(&v, 0.0, dt);
            let jk = rates(&a, 0.0, dt);
            for (k, ((v, a), jk)) in v.iter().zip(&a).zip(&jk).enumerate() {
                let peaks = [
                    (&mut overall.velocity[j], v),
                    (&mut overall.acceleration[j], a),
                    (&mut overall.jerk[j], jk),
                ];
                for (p, x) in peaks {
                    *p = p.max(x.abs());
                }
                if near(k) {
                    boundaries.velocity[j] = boundaries.velocity[j].max(v.abs());
                    boundaries.acceleration[j] = boundaries.acceleration[j].max(a.abs());
                    boundaries.jerk[j] = boundaries.jerk[j].max(jk.abs());
                }
            }
            let l = run.limits[j];
            usage[0] = usage[0].max(overall.velocity[j] / l.velocity);
            usage[1] = usage[1].max(overall.acceleration[j] / l.acceleration);
            usage[2] = usage[2].max(overall.jerk[j] / l.jerk);
        }
        let (mut tracking_max, mut sq) = (vec![0.0_f64; dof], vec![0.0; dof]);
        let pairs = n.min(run.run.q.len().saturating_sub(1));
        for k in 0..pairs {
            for j in 0..dof {
                let e = (run.run.q[k + 1][j] - run.commands[k][j]).abs();
                tracking_max[j] = tracking_max[j].max(e);
                sq[j] += e * e;
            }
        }
        let tracking_rms = sq
            .iter()
            .map(|s| (s / pairs.max(1) as f64).sqrt())
            .collect();
        let came: Vec<f64> = log.entries.iter().map(|(c, _)| c.arrived_s).collect();
        let delays: Vec<f64> = log.entries.iter().map(|(c, _)| c.delay()).collect();
        let intervals: Vec<f64> = came.windows(2).map(|w| w[1] - w[0]).collect();
        let mut refusals = Vec::new();
        let (mut taken, mut refused, mut skipped) = (0, 0, 0);
        let first_unplayed = log.entries.iter().position(|(_, v)| v.is_none());
        let unplayed = first_unplayed.map(|i| {
            let pause = i.checked_sub(1).map_or(0.0, |p| {
                log.entries[i].0.arrived_s - log.entries[p].0.arrived_s
            });
            (log.entries.len() - i, pause)
        });
        for (i, (_, v)) in log.entries.iter().enumerate() {
            match v {
                Some(ChunkVerdict::Taken { skipped: s }) => {
                    taken += 1;
                    skipped += s;
                }
                Some(ChunkVerdict::Refused(why)) => {
                    refused += 1;
                    if refusals.len() < 5 {
                        refusals.push((i, why.to_string()));
                    }
                }
                None => {}
            }
        }
        FollowReport {
            overall,
            boundaries,
            usage,
            delay: Spread::of(&delays),
            interval: Spread::of(&intervals),
            tracking_max,
            tracking_rms,
            chunks: log.entries.len(),
            taken,
            refused,
            refusals,
            skipped,
            stalls: run.stalls.clone(),
            lost: log.lost,
            unplayed,
        }
    }

    /// The report in a few lines for a terminal.
    pub fn lines(&self) -> Vec<String> {
        let peak = |x: &[f64]| x.iter().copied().fold(0.0, f64::max);
        let ms = |x: f64| x * 1e3;
        let mut out = vec![
            format!(
                "chunks: {} came, {} taken, {} refused; {} targets skipped as already past",
                self.chunks, self.taken, self.refused, self.skipped
            ),
            // Statistics of no value are NaN: a run without chunks (or with one) says so.
            match (self.delay.mean.is_finite(), self.interval.mean.is_finite()) {
                (false, _) => "no chunk came: no inference delay to measure".into(),
                (true, false) => {
                    format!("inference delay {:.1} ms (one chunk)", ms(self.delay.mean))
                }
                (true, true) => format!(
                    "inference delay {:.1} ms mean (jitter {:.1} ms, {:.1}–{:.1} ms); a chunk every {:.1} ms (jitter {:.1} ms)",
                    ms(self.delay.mean),
                    ms(self.delay.std),
                    ms(self.delay.min),
                    ms(self.delay.max),
                    ms(self.interval.mean),
                    ms(self.interval.std)
                ),
            },
            format!(
                "commands: peak acceleration {:.2} rad/s² ({:.2} at boundaries), jerk {:.0} rad/s³ ({:.0} at boundaries); {:.0} % / {:.0} % / {:.0} % of the velocity, acceleration and jerk limits",
                peak(&self.overall.acceleration),
                peak(&self.boundaries.acceleration),
                peak(&self.overall.jerk),
                peak(&self.boundaries.jerk),
                100.0 * self.usage[0],
                100.0 * self.usage[1],
                100.0 * self.usage[2]
            ),
            format!(
                "tracking: the robot within {:.2} mrad of its commands (rms {:.2} mrad, worst joint)",
                1e3 * peak(&self.tracking_max),
                1e3 * peak(&self.tracking_rms)
            ),
        ];
        for (i, why) in &self.refusals {
            out.push(format!("chunk {i} refused: {why}"));
        }
        if !self.stalls.is_empty() {
            out.push(format!(
                "stalled {} time(s) (first at {:.3} s): no chunk for the stall timeout, the arm braked to rest",
                self.stalls.len(),
                self.stalls[0]
            ));
        }
        if self.lost > 0 {
            out.push(format!(
                "{} log entries were lost on their way back from the loop",
                self.lost
            ));
        }
        if let Some((n, pause)) = self.unplayed {
            out.push(format!(
                "{n} chunk(s) never reached the arm: the stream paused {} s before them, longer than the idle end (the run ends once the arm has stood that long without a fresh chunk), and the run had ended",
                cps_files::number(pause, 4)
            ));
        }
        out
    }
}
