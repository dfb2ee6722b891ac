//! Action chunks: what a learned policy (ACT, a diffusion policy, π0…) hands a robot — `H`
//! joint targets at a known rate, predicted from an observation taken one inference
//! earlier, stamped with the time of that observation and the time the chunk arrived.
//! Target `k` is meant for `observed_s + k / rate_hz`: a chunk that arrives `d` seconds
//! after its observation starts `d · rate_hz` targets in the past.
//!
//! A chunk is checked whole when it is made, so a bad one is refused with a sentence
//! before anything moves: no target, the wrong joint count, a value that is not finite, a
//! rate that is not a rate, an arrival before the observation. [`Chunk::follows`] refuses
//! one whose times go back against the chunk before it.

use std::fmt;

/// A chunk of joint targets (see the module's text).
#[derive(Debug, Clone, PartialEq)]
pub struct Chunk {
    /// When the observation it was predicted from was taken (s, the executor's clock).
    pub observed_s: f64,
    /// When it reached the executor (s, the same clock).
    pub arrived_s: f64,
    /// Targets per second.
    pub rate_hz: f64,
    /// The joint targets, one per period, each the robot's joint count long (rad).
    pub targets: Vec<Vec<f64>>,
    /// The policy's joint velocities at the targets, where it predicts them (rad/s).
    pub velocities: Option<Vec<Vec<f64>>>,
}

/// Why a chunk is refused: one sentence each, naming the target and joint at fault.
#[derive(Debug, Clone, PartialEq)]
pub enum ChunkError {
    /// No target at all.
    Empty,
    /// The rate is not a positive, finite number of targets per second.
    Rate(f64),
    /// A time stamp is not finite.
    Time(&'static str, f64),
    /// The chunk arrived before the observation it was predicted from.
    ArrivedBeforeObserved {
        /// Its observation time.
        observed_s: f64,
        /// Its arrival.
        arrived_s: f64,
    },
    /// A target (or velocity) with another joint count than the robot's.
    Joints {
        /// Which target.
        target: usize,
        /// The robot's joint count.
        expected: usize,
        /// The target's.
        got: usize,
        /// `target` or `velocity`.
        what: &'static str,
    },
    /// A value that is not finite.
    NotFinite {
        /// Which target.
        target: usize,
        /// Which joint (0-based).
        joint: usize,
        /// The value.
        value: f64,
        /// `target` or `velocity`.
        what: &'static str,
    },
    /// Velocities given for another number of targets.
    VelocityCount {
        /// Targets.
        targets: usize,
        /// Velocities.
        velocities: usize,
    },
    /// Its observation or arrival is earlier than the chunk's before it.
    Backwards {
        /// `observation` or `arrival`.
        what: &'static str,
        /// This chunk's time.
        now: f64,
        /// The chunk before's.
        before: f64,
    },
}

/// The fastest rate of a chunk's targets (Hz): ten per control period of a 1 kHz robot.
pub const MAX_RATE_HZ: f64 = 10_000.0;

impl fmt::Display for ChunkError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let num = |x: f64| cps_files::number(x, 6);
        match self {
            ChunkError::Empty => write!(f, "the chunk has no target"),
            ChunkError::Rate(r) => write!(
                f,
                "the chunk's rate {} Hz is not a rate: give a positive number of targets per second, at most {MAX_RATE_HZ}",
                num(*r)
            ),
            ChunkError::Time(which, t) => {
                write!(f, "the chunk's {which} time {} is not a time", num(*t))
            }
            ChunkError::ArrivedBeforeObserved {
                observed_s,
                arrived_s,
            } => write!(
                f,
                "the chunk arrived at {} s, before the observation it was predicted from ({} s)",
                num(*arrived_s),
                num(*observed_s)
            ),
            ChunkError::Joints {
                target,
                expected,
                got,
                what,
            } => write!(
                f,
                "{what} {target} of the chunk has {got} joint value(s); the robot has {expected} joints"
            ),
            ChunkError::NotFinite {
                target,
                joint,
                value,
                what,
            } => write!(
                f,
                "{what} {target} of the chunk, joint {}: {value} is not a number",
                joint + 1
            ),
            ChunkError::VelocityCount {
                targets,
                velocities,
            } => write!(
                f,
                "the chunk has {velocities} velocities for {targets} targets: give one per target, or none"
            ),
            ChunkError::Backwards { what, now, before } => write!(
                f,
                "the chunk's {what} time {} s is before the previous chunk's ({} s): times must not go back",
                num(*now),
                num(*before)
            ),
        }
    }
}

impl std::error::Error for ChunkError {}

fn check_rows(rows: &[Vec<f64>], dof: usize, what: &'static str) -> Result<(), ChunkError> {
    for (k, row) in rows.iter().enumerate() {
        if row.len() != dof {
            return Err(ChunkError::Joints {
                target: k,
                expected: dof,
                got: row.len(),
                what,
            });
        }
        if let Some((joint, &value)) = row.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(ChunkError::NotFinite {
                target: k,
                joint,
                value,
                what,
            });
        }
    }
    Ok(())
}

impl Chunk {
    /// A chunk for a robot of `dof` joints, checked (see the module's text).
    pub fn new(
        observed_s: f64,
        arrived_s: f64,
        rate_hz: f64,
        targets: Vec<Vec<f64>>,
        velocities: Option<Vec<Vec<f64>>>,
        dof: usize,
    ) -> Result<Chunk, ChunkError> {
        if targets.is_empty() {
            return Err(ChunkError::Empty);
        }
        if !(rate_hz > 0.0 && rate_hz <= MAX_RATE_HZ) {
            return Err(ChunkError::Rate(rate_hz));
        }
        for (which, t) in [("observation", observed_s), ("arrival", arrived_s)] {
            if !t.is_finite() {
                return Err(ChunkError::Time(which, t));
            }
        }
        if arrived_s < observed_s {
            return Err(ChunkError::ArrivedBeforeObserved {
                observed_s,
                arrived_s,
            });
        }
        check_rows(&targets, dof, "target")?;
        if let Some(v) = &velocities {
            if v.len() != targets.len() {
                return Err(ChunkError::VelocityCount {
                    targets: targets.len(),
                    velocities: v.len(),
                });
            }
            check_rows(v, dof, "velocity")?;
        }
        Ok(Chunk {
            observed_s,
            arrived_s,
            rate_hz,
            targets,
            velocities,
        })
    }

    /// When target `k` is due (s): `observed_s + k / rate_hz`.
    pub fn time_of(&self, k: usize) -> f64 {
        self.observed_s + k as f64 / self.rate_hz
    }

    /// The inference delay: from the observation to the chunk's arrival (s).
    pub fn delay(&self) -> f64 {
        self.arrived_s - self.observed_s
    }

    /// How many targets are already in the past at `now` (due before it): the ones an
    /// executor skips when it aligns the chunk to `now`. All of them when the whole chunk
    /// is late.
    pub fn past_at(&self, now: f64) -> usize {
        let behind = (now - self.observed_s) * self.rate_hz;
        if behind <= 0.0 {
            0
        } else {
            (behind.ceil() as usize).min(self.targets.len())
        }
    }

    /// Checks that this chunk may follow `before`: neither its observation nor its
    /// arrival earlier.
    pub fn follows(&self, before: &Chunk) -> Result<(), ChunkError> {
        for (what, now, then) in [
            ("observation", self.observed_s, before.observed_s),
            ("arrival", self.arrived_s, before.arrived_s),
        ] {
            if now < then {
                return Err(ChunkError::Backwards {
                    what,
                    now,
                    before: then,
                });
            }
        }
        Ok(())
    }
}

/// A policy stand-in, for tests, benchmarks and tuning an execution before a policy
/// exists: a demonstration replayed as chunks of `horizon` targets at `target_hz`, one
/// every 1/`chunk_hz` s, each predicted from an observation `delay_s` old (drawn anew for
/// each chunk within the range, never letting observations go back) with every target
/// off by up to ±`noise_rad`. Seeded: the same seed, the same chunks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StandIn {
    /// Targets per chunk (H).
    pub horizon: usize,
    /// The targets' rate (Hz).
    pub target_hz: f64,
    /// Chunks per second.
    pub chunk_hz: f64,
    /// The inference delay's range (s).
    pub delay_s: (f64, f64),
    /// The largest error of a target (rad).
    pub noise_rad: f64,
    /// The seed.
    pub seed: u64,
}

impl StandIn {
    /// The chunks of `demo` (joint positions at a time, s) from `start_s` (the first
    /// chunk's arrival) for `duration_s`.
    pub fn chunks(
        &self,
        demo: &dyn Fn(f64) -> Vec<f64>,
        start_s: f64,
        duration_s: f64,
    ) -> Vec<Chunk> {
        let mut state = self.seed ^ 0x9e37_79b9_7f4a_7c15;
        let mut uniform = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let period = 1.0 / self.chunk_hz;
        let count = (duration_s * self.chunk_hz).floor() as usize + 1;
        let (lo, hi) = self.delay_s;
        let mut delay = lo + (hi - lo) * uniform();
        let mut out = Vec::with_capacity(count);
        for k in 0..count {
            if k > 0 {
                // At most one period later than the last: observations never go back.
                let top = hi.min(delay + period);
                delay = lo + (top - lo).max(0.0) * uniform();
            }
            let arrived = start_s + k as f64 * period;
            let observed = arrived - delay;
            let targets = (0..self.horizon)
                .map(|i| {
                    demo(observed + i as f64 / self.target_hz)
                        .into_iter()
                        .map(|q| q + self.noise_rad * (2.0 * uniform() - 1.0))
                        .collect()
                })
                .collect::<Vec<Vec<f64>>>();
            let dof = targets[0].len();
            if let Ok(c) = Chunk::new(observed, arrived, self.target_hz, targets, None, dof) {
                out.push(c);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chunk(observed: f64, arrived: f64) -> Result<Chunk, ChunkError> {
        Chunk::new(observed, arrived, 10.0, vec![vec![0.0, 0.1]; 5], None, 2)
    }

    #[test]
    fn a_chunk_is_aligned_to_its_observation() {
        let c = chunk(1.0, 1.12).unwrap();
        assert!((c.delay() - 0.12).abs() < 1e-12);
        assert!((c.time_of(3) - 1.3).abs() < 1e-12);
        // At its arrival, targets 0 and 1 (due at 1.0 and 1.1 s) are past; 1.2 s is not.
        assert_eq!(c.past_at(c.arrived_s), 2);
        assert_eq!(c.past_at(0.5), 0);
        assert_eq!(c.past_at(1.0), 0, "target 0 is due now, not past");
        assert_eq!(c.past_at(9.0), 5, "a chunk late as a whole");
    }

    #[test]
    fn bad_chunks_are_refused_with_their_place() {
        let say = |r: Result<Chunk, ChunkError>| r.unwrap_err().to_string();
        assert_eq!(
            say(Chunk::new(0.0, 0.0, 10.0, vec![], None, 2)),
            "the chunk has no target"
        );
        assert!(
            say(Chunk::new(0.0, 0.0, 0.0, vec![vec![0.0; 2]], None, 2))
                .contains("0 Hz is not a rate")
        );
        assert!(
            say(Chunk::new(0.0, 0.0, f64::NAN, vec![vec![0.0; 2]], None, 2)).contains("NaN Hz")
        );
        assert!(
            say(Chunk::new(
                f64::INFINITY,
                0.0,
                10.0,
                vec![vec![0.0; 2]],
                None,
                2
            ))
            .contains("observation time inf")
        );
        assert!(say(chunk(1.0, 0.9)).contains("arrived at 0.9 s, before the observation"));
        assert_eq!(
            say(Chunk::new(
                0.0,
                0.0,
                10.0,
                vec![vec![0.0; 2], vec![0.0; 3]],
                None,
                2
            )),
            "target 1 of the chunk has 3 joint value(s); the robot has 2 joints"
        );
        assert_eq!(
            say(Chunk::new(
                0.0,
                0.0,
                10.0,
                vec![vec![0.0, f64::NAN]],
                None,
                2
            )),
            "target 0 of the chunk, joint 2: NaN is not a number"
        );
        assert!(
            say(Chunk::new(
                0.0,
                0.0,
                10.0,
                vec![vec![0.0; 2]; 2],
                Some(vec![vec![0.0; 2]]),
                2
            ))
            .contains("1 velocities for 2 targets")
        );
        assert!(
            say(Chunk::new(
                0.0,
                0.0,
                10.0,
                vec![vec![0.0; 2]],
                Some(vec![vec![f64::INFINITY, 0.0]]),
                2
            ))
            .starts_with("velocity 0 of the chunk, joint 1: inf")
        );
        let (a, b) = (chunk(1.0, 1.1).unwrap(), chunk(0.9, 1.2).unwrap());
        assert_eq!(
            b.follows(&a).unwrap_err().to_string(),
            "the chunk's observation time 0.9 s is before the previous chunk's (1 s): times must not go back"
        );
        assert!(
            chunk(1.0, 1.05)
                .unwrap()
                .follows(&a)
                .unwrap_err()
                .to_string()
                .contains("arrival time 1.05 s")
        );
        assert!(chunk(1.1, 1.2).unwrap().follows(&a).is_ok());
    }
}
