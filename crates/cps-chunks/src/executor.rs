//! The chunk executor's logic, robot-free: chunks pushed as they arrive, one command out
//! per control period. The newest chunk is the reference — its targets joined by a cubic
//! through them (Hermite: the policy's velocities where it gives them, else Catmull–Rom's;
//! continuous in position and velocity), evaluated at the current time, so the targets already in the past are skipped by construction — and a
//! [`Follower`] moves the command toward it within the velocity, acceleration and jerk
//! limits: a new chunk that starts elsewhere than the old one ended is blended into, never
//! jumped to. After the last target the reference holds it. When no chunk has arrived
//! for the stall timeout, the reference holds wherever the command is, and the follower
//! brakes to rest.
//!
//! A chunk is refused — the motion going on as before — when its times go back, when it is
//! wholly in the past on arrival, when a target leaves the joint's range, or when where it
//! wants the robot now is farther from the command than the settings allow.

use crate::chunk::{Chunk, ChunkError};
use crate::follow::{FollowLimits, Follower};

/// How far ahead of the robot's clock a chunk's observation may be (s): two control
/// periods of rounding between the state a policy read and the period that takes its
/// chunk; later is refused ([`Refused::Ahead`]).
pub const CLOCK_TOLERANCE_S: f64 = 0.002;

/// How the executor treats chunks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChunkSettings {
    /// Seconds without a new chunk after which the arm brakes to rest (default 0.25: a
    /// 10 Hz policy missing two chunks).
    pub stall_timeout_s: f64,
    /// The largest distance (rad, any joint) between the command and where a new chunk
    /// wants the robot at its arrival (default 0.2 rad): farther is a chunk for another
    /// state, refused.
    pub max_gap_rad: f64,
}

impl Default for ChunkSettings {
    fn default() -> Self {
        ChunkSettings {
            stall_timeout_s: 0.25,
            max_gap_rad: 0.2,
        }
    }
}

/// Why a chunk was not taken.
#[derive(Debug, Clone, PartialEq)]
pub enum Refused {
    /// The chunk itself, or its times against the one before.
    Chunk(ChunkError),
    /// Every target was due before it arrived.
    Late {
        /// Its last target's time (s).
        last_s: f64,
        /// When it arrived (s).
        now: f64,
    },
    /// A target outside the joint's range.
    Range {
        /// Which target (0-based).
        target: usize,
        /// Which joint (0-based).
        joint: usize,
        /// The target (rad).
        value: f64,
        /// The range (rad).
        lower: f64,
        /// See `lower`.
        upper: f64,
    },
    /// Observed later than the robot's clock now: a sender's clock ahead of the robot's,
    /// or a forged stamp, which would lock out every honest chunk after it.
    Ahead {
        /// Its observation time (s).
        observed_s: f64,
        /// The robot's clock at its arrival (s).
        now: f64,
    },
    /// Where it wants the robot is too far from the command.
    Far {
        /// The joint (0-based).
        joint: usize,
        /// The distance (rad).
        gap: f64,
        /// The allowed distance.
        max: f64,
    },
}

impl std::fmt::Display for Refused {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let num = |x: &f64| cps_files::number(*x, 6);
        match self {
            Refused::Chunk(e) => write!(f, "{e}"),
            Refused::Late { last_s, now } => write!(
                f,
                "the chunk arrived at {} s, after its last target was due ({} s): nothing of it is left to follow",
                num(now),
                num(last_s)
            ),
            Refused::Ahead { observed_s, now } => write!(
                f,
                "the chunk says it was observed at {} s, later than the robot's clock now ({} s): observation times come from the robot's state answers (CPS?), never ahead of them",
                num(observed_s),
                num(now)
            ),
            Refused::Range {
                target,
                joint,
                value,
                lower,
                upper,
            } => write!(
                f,
                "target {target} puts joint {} at {} rad, outside its range [{lower}, {upper}] rad",
                joint + 1,
                num(value)
            ),
            Refused::Far { joint, gap, max } => write!(
                f,
                "the chunk wants joint {} {gap:.3} rad from where the arm is commanded (at most {max} rad): a chunk for another state",
                joint + 1
            ),
        }
    }
}

/// What the executor has done, for its report.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ChunkCounts {
    /// Chunks taken.
    pub taken: usize,
    /// Chunks refused.
    pub refused: usize,
    /// Targets skipped as already past when their chunk was taken.
    pub skipped: usize,
    /// Times the arm braked to rest for want of chunks.
    pub stalls: usize,
}

/// What became of a chunk offered to the executor: either way the caller gets a chunk
/// back to dispose of (the one replaced, or the one refused), so that nothing is freed on
/// a loop that must not allocate.
#[derive(Debug)]
pub enum Offer {
    /// Taken.
    Taken {
        /// How many of its targets were already past.
        skipped: usize,
        /// The chunk it replaced.
        replaced: Option<Chunk>,
    },
    /// Refused, the motion going on as before.
    Refused {
        /// Why.
        why: Refused,
        /// The chunk.
        chunk: Chunk,
    },
}

/// The executor (see the module's text). Nothing is allocated per period.
#[derive(Debug, Clone)]
pub struct ChunkExecutor {
    follower: Follower,
    settings: ChunkSettings,
    range: Option<(Vec<f64>, Vec<f64>)>,
    /// No chunk will come after this one: it is followed to its end, no stall timeout.
    last: bool,
    chunk: Option<Chunk>,
    stalled: bool,
    counts: ChunkCounts,
    r: Vec<f64>,
    rv: Vec<f64>,
    ra: Vec<f64>,
}

impl ChunkExecutor {
    /// An executor at rest at `q0`, stepped every `dt` seconds.
    pub fn new(
        q0: &[f64],
        limits: &[FollowLimits],
        dt: f64,
        settings: ChunkSettings,
    ) -> Result<ChunkExecutor, crate::FollowError> {
        let n = q0.len();
        Ok(ChunkExecutor {
            follower: Follower::new(q0, limits, dt)?,
            settings,
            range: None,
            last: false,
            chunk: None,
            stalled: false,
            counts: ChunkCounts::default(),
            r: vec![0.0; n],
            rv: vec![0.0; n],
            ra: vec![0.0; n],
        })
    }

    /// What it has done so far.
    pub fn counts(&self) -> &ChunkCounts {
        &self.counts
    }

    /// Whether it is braking (or at rest) for want of chunks.
    pub fn stalled(&self) -> bool {
        self.stalled
    }

    /// Whether it follows no fresh chunk: none came yet, or the last is older than the
    /// stall timeout.
    pub fn stalled_or_idle(&self) -> bool {
        self.stalled || self.chunk.is_none()
    }

    /// Marks the chunk it follows as the last (the stream is over): it is followed to its
    /// end, whatever the stall timeout.
    pub fn last_chunk(&mut self) {
        self.last = true;
    }

    /// Whether the chunk it follows (if any) has no target left after `now`.
    pub fn chunk_done(&self, now: f64) -> bool {
        self.chunk
            .as_ref()
            .is_none_or(|c| now >= c.time_of(c.targets.len() - 1))
    }

    /// Whether the command is at rest (velocity and acceleration zero).
    pub fn at_rest(&self) -> bool {
        self.follower.at_rest()
    }

    /// The chunk it follows, handed back (it then holds and brakes as after a stall).
    pub fn take_chunk(&mut self) -> Option<Chunk> {
        self.chunk.take()
    }

    /// The limits its commands keep.
    pub fn limits(&self) -> &[FollowLimits] {
        self.follower.limits()
    }

    /// The last command's velocity (its backward difference, rad/s).
    pub fn velocity(&self) -> &[f64] {
        self.follower.velocity()
    }

    /// The last command's acceleration (rad/s²).
    pub fn acceleration(&self) -> &[f64] {
        self.follower.acceleration()
    }

    /// The last command.
    pub fn position(&self) -> &[f64] {
        self.follower.position()
    }

    /// The same executor refusing chunks with a target outside `[lower, upper]` (rad per
    /// joint: the robot's range).
    pub fn with_range(mut self, lower: &[f64], upper: &[f64]) -> ChunkExecutor {
        self.range = Some((lower.to_vec(), upper.to_vec()));
        self
    }

    /// Takes `chunk`, arrived at `now` (see the module's text for the refusals): how many
    /// of its targets were already past. The chunk replaced is dropped here; a loop that
    /// must not free memory uses [`ChunkExecutor::offer`].
    pub fn push(&mut self, chunk: Chunk, now: f64) -> Result<usize, Refused> {
        match self.offer(chunk, now) {
            Offer::Taken { skipped, .. } => Ok(skipped),
            Offer::Refused { why, .. } => Err(why),
        }
    }

    /// [`ChunkExecutor::push`], handing back the chunk replaced or refused.
    pub fn offer(&mut self, chunk: Chunk, now: f64) -> Offer {
        match self.judge(&chunk, now) {
            Err(why) => {
                self.counts.refused += 1;
                Offer::Refused { why, chunk }
            }
            Ok(()) => {
                let skipped = chunk.past_at(now);
                self.counts.taken += 1;
                self.counts.skipped += skipped;
                self.stalled = false;
                self.last = false;
                Offer::Taken {
                    skipped,
                    replaced: self.chunk.replace(chunk),
                }
            }
        }
    }

    fn judge(&mut self, chunk: &Chunk, now: f64) -> Result<(), Refused> {
        // Before it is compared with the chunk followed: a chunk from the future taken
        // would make every honest one after it "go back".
        if chunk.observed_s > now + CLOCK_TOLERANCE_S {
            return Err(Refused::Ahead {
                observed_s: chunk.observed_s,
                now,
            });
        }
        if let Some(before) = &self.chunk {
            chunk.follows(before).map_err(Refused::Chunk)?;
        }
        if chunk.targets.first().map(Vec::len) != Some(self.r.len()) {
            // Made for another robot: its own check names the target.
            return Err(Refused::Chunk(ChunkError::Joints {
                target: 0,
                expected: self.r.len(),
                got: chunk.targets.first().map_or(0, Vec::len),
                what: "target",
            }));
        }
        let last_s = chunk.time_of(chunk.targets.len() - 1);
        if last_s < now {
            return Err(Refused::Late { last_s, now });
        }
        if let Some((lower, upper)) = &self.range {
            for (target, q) in chunk.targets.iter().enumerate() {
                for (joint, &value) in q.iter().enumerate() {
                    if !(lower[joint]..=upper[joint]).contains(&value) {
                        return Err(Refused::Range {
                            target,
                            joint,
                            value,
                            lower: lower[joint],
                            upper: upper[joint],
                        });
                    }
                }
            }
        }
        // Where it wants the robot now, in the reference's buffers (the next tick fills
        // them afresh): nothing allocated on a loop that takes chunks.
        reference(chunk, now, &mut self.r, &mut self.rv, &mut self.ra);
        let q = self.follower.position();
        if let Some((joint, gap)) = self
            .r
            .iter()
            .zip(q)
            .map(|(a, b)| (a - b).abs())
            .enumerate()
            .find(|(_, g)| *g > self.settings.max_gap_rad)
        {
            return Err(Refused::Far {
                joint,
                gap,
                max: self.settings.max_gap_rad,
            });
        }
        Ok(())
    }

    /// The command for the period ending at `now`.
    pub fn tick(&mut self, now: f64) -> &[f64] {
        let fresh = self
            .chunk
            .as_ref()
            .is_some_and(|c| self.last || now - c.arrived_s <= self.settings.stall_timeout_s)
            // Once stalled, only a new chunk moves the arm again.
            && !self.stalled;
        match (&self.chunk, fresh) {
            (Some(c), true) => reference(c, now, &mut self.r, &mut self.rv, &mut self.ra),
            _ => {
                if !self.stalled && self.chunk.is_some() {
                    self.counts.stalls += 1;
                }
                self.stalled = self.chunk.is_some();
                // Hold where the command is: the follower brakes to rest.
                self.r.copy_from_slice(self.follower.position());
                self.rv.fill(0.0);
                self.ra.fill(0.0);
            }
        }
        self.follower.step(&self.r, &self.rv, &self.ra)
    }
}

/// How much of the cubic's acceleration is fed forward: none. A policy's targets carry
/// millimetre-scale noise, which the second derivative of a cubic through them at 50 Hz
/// turns into accelerations beyond the limits; the velocity alone leaves the follower a
/// few milliradians behind a smooth path and keeps the noise out.
const CURVATURE_FED: f64 = 0.0;

/// The chunk's reference at `t`: a Catmull–Rom cubic through its targets (position,
/// velocity, acceleration), its first target before it starts, its last after it ends.
fn reference(c: &Chunk, t: f64, r: &mut [f64], rv: &mut [f64], ra: &mut [f64]) {
    let h = 1.0 / c.rate_hz;
    let n = c.targets.len();
    let s = ((t - c.observed_s) / h).max(0.0);
    if n == 1 || s >= (n - 1) as f64 {
        r.copy_from_slice(&c.targets[n - 1]);
        rv.fill(0.0);
        ra.fill(0.0);
        return;
    }
    let k = s.floor() as usize;
    let u = s - k as f64;
    let p = |i: isize| &c.targets[i.clamp(0, n as isize - 1) as usize];
    let (p0, p1, p2, p3) = (
        p(k as isize - 1),
        p(k as isize),
        p(k as isize + 1),
        p(k as isize + 2),
    );
    for j in 0..r.len() {
        // Hermite with the policy's velocities as tangents where it gives them, else
        // Catmull–Rom's m1 = (p2 − p0)/2, m2 = (p3 − p1)/2 (per target).
        let (m1, m2) = match &c.velocities {
            Some(v) => (v[k][j] * h, v[(k + 1).min(n - 1)][j] * h),
            None => ((p2[j] - p0[j]) / 2.0, (p3[j] - p1[j]) / 2.0),
        };
        let (a, b) = (p1[j], p2[j]);
        let (u2, u3) = (u * u, u * u * u);
        r[j] = (2.0 * u3 - 3.0 * u2 + 1.0) * a
            + (u3 - 2.0 * u2 + u) * m1
            + (-2.0 * u3 + 3.0 * u2) * b
            + (u3 - u2) * m2;
        let d1 = (6.0 * u2 - 6.0 * u) * a
            + (3.0 * u2 - 4.0 * u + 1.0) * m1
            + (-6.0 * u2 + 6.0 * u) * b
            + (3.0 * u2 - 2.0 * u) * m2;
        let d2 = (12.0 * u - 6.0) * a
            + (6.0 * u - 4.0) * m1
            + (-12.0 * u + 6.0) * b
            + (6.0 * u - 2.0) * m2;
        rv[j] = d1 / h;
        ra[j] = CURVATURE_FED * d2 / (h * h);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use crate::follow::testing::{DT, FR3, within_limits};

    /// A demonstration: 0.4 rad at 0.25 Hz on joint 1, half that on joint 2.
    fn demo(t: f64) -> [f64; 2] {
        let y = 0.4 * (std::f64::consts::FRAC_PI_2 * t).sin();
        [y, 0.5 * y]
    }

    /// A policy stand-in: every 1/`hz` s a chunk of 50 targets at 50 Hz from an
    /// observation `delay` s old, each target off by up to ±2 mrad.
    fn chunk_at(obs: f64, delay: f64, seed: &mut u64) -> Chunk {
        let mut noise = || {
            *seed ^= *seed << 13;
            *seed ^= *seed >> 7;
            *seed ^= *seed << 17;
            ((*seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.004
        };
        let targets = (0..50)
            .map(|k| {
                let q = demo(obs + k as f64 / 50.0);
                vec![q[0] + noise(), q[1] + noise()]
            })
            .collect();
        Chunk::new(obs, obs + delay, 50.0, targets, None, 2).unwrap()
    }

    #[test]
    fn a_delayed_noisy_chunk_stream_is_followed_within_every_limit() {
        for hz in [10.0_f64, 30.0] {
            let mut x =
                ChunkExecutor::new(&[0.0, 0.0], &[FR3; 2], DT, ChunkSettings::default()).unwrap();
            let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
            let (mut q, mut worst) = (vec![vec![0.0, 0.0]], 0.0_f64);
            let period = (1000.0 / hz) as usize;
            for k in 1..=6000 {
                let now = k as f64 * DT;
                if k % period == 0 {
                    // Observed 50–150 ms before it arrives (at 30 Hz 50–100 ms: one
                    // inference after another, observations never go back).
                    let delay = 0.05 + (0.75 / hz).min(0.05) * ((k / period) % 3) as f64;
                    x.push(chunk_at(now - delay, delay, &mut seed), now)
                        .unwrap();
                }
                let c = x.tick(now).to_vec();
                if k > 1000 {
                    worst = worst.max((c[0] - demo(now)[0]).abs());
                }
                q.push(c);
            }
            for j in 0..2 {
                within_limits(&q.iter().map(|c| c[j]).collect::<Vec<f64>>());
            }
            eprintln!(
                "{hz} Hz: within {worst:.4} rad of the demonstration, {:?}",
                x.counts()
            );
            assert!(worst < 0.01, "{hz} Hz: {worst} rad from the demonstration");
            assert!(
                x.counts().skipped > 0 && x.counts().refused == 0,
                "{:?}",
                x.counts()
            );
        }
    }

    #[test]
    fn a_stall_brakes_to_rest_and_bad_chunks_leave_the_motion_as_it_was() {
        let mut x =
            ChunkExecutor::new(&[0.0, 0.0], &[FR3; 2], DT, ChunkSettings::default()).unwrap();
        let mut seed = 7;
        x.push(chunk_at(0.0, 0.0, &mut seed), 0.0).unwrap();
        for k in 1..=200 {
            x.tick(k as f64 * DT);
        }
        // Refused: a chunk from the past, a late one, one for another state.
        let back = x.push(chunk_at(-0.1, 0.1, &mut seed), 0.2).unwrap_err();
        assert!(
            back.to_string().contains("times must not go back"),
            "{back}"
        );
        let late = x.push(chunk_at(0.05, 1.0, &mut seed), 1.05).unwrap_err();
        assert!(
            late.to_string().contains("after its last target was due"),
            "{late}"
        );
        let far = Chunk::new(0.2, 0.2, 50.0, vec![vec![1.0, 0.0]; 50], None, 2).unwrap();
        let e = x.push(far, 0.2).unwrap_err();
        assert!(e.to_string().starts_with("the chunk wants joint 1 "), "{e}");
        assert_eq!(x.counts().refused, 3);
        // No chunk for longer than the timeout: braked to rest, within the limits.
        for k in 201..=1500 {
            x.tick(k as f64 * DT);
        }
        assert!(x.stalled() && x.counts().stalls == 1);
        let rest = x.position().to_vec();
        assert_eq!(x.tick(1.501), &rest[..], "at rest");
    }
}
