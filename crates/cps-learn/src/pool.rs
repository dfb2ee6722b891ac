//! A pool of robot backends (simulators, local or on other hosts) that evaluates numbered
//! jobs: each job goes to a free simulator, one thread per simulator. The results come
//! back in job order, so whatever the pool's size and whichever simulator ran a job, the
//! same jobs give the same results (each job's result must depend on the job alone: the
//! backend is reset at its start).
//!
//! A simulator that fails (it died, timed out, broke the protocol) has its job put back
//! for another and is dropped from the pool, with the reason; no job is lost or counted
//! twice. When every simulator is gone, [`SimulatorPool::run`] says so and the caller keeps
//! what it finished before.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex};

use cps_robot::Robot;
use serde::Serialize;

/// An opened backend named by its endpoint.
pub type NamedBackend = (String, Box<dyn Robot>);

/// Why a job did not give a result.
#[derive(Debug, Clone, PartialEq)]
pub enum JobError {
    /// The simulator failed: the job is run again on another, this one is dropped.
    Simulator(String),
    /// The job itself cannot be done (the same on any simulator): the run stops.
    Fatal(String),
    /// The run was asked to stop (Ctrl-C): no further job is started.
    Stopped,
}

/// Why [`SimulatorPool::run`] gave no results.
#[derive(Debug, Clone, PartialEq)]
pub enum PoolError {
    /// Every simulator was dropped before the jobs were done.
    Exhausted,
    /// A job failed for a reason no simulator can change.
    Fatal(String),
    /// A job said the run was asked to stop ([`JobError::Stopped`]).
    Stopped,
}

/// A simulator dropped from the pool.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Dropped {
    /// Its endpoint.
    pub endpoint: String,
    /// What failed.
    pub reason: String,
    /// Jobs it finished before.
    pub evaluations: u64,
}

struct Member {
    endpoint: String,
    backend: Box<dyn Robot>,
    evaluations: u64,
}

/// Simulators that evaluate jobs together.
pub struct SimulatorPool {
    members: Vec<Member>,
    dropped: Vec<Dropped>,
}

impl std::fmt::Debug for SimulatorPool {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimulatorPool")
            .field("endpoints", &self.endpoints())
            .field("dropped", &self.dropped)
            .finish()
    }
}

struct Queue<T> {
    pending: VecDeque<usize>,
    in_flight: usize,
    results: Vec<Option<T>>,
    fatal: Option<PoolError>,
}

impl SimulatorPool {
    /// A pool of opened backends, each named by its endpoint.
    pub fn new(members: Vec<NamedBackend>) -> Self {
        Self {
            members: members
                .into_iter()
                .map(|(endpoint, backend)| Member {
                    endpoint,
                    backend,
                    evaluations: 0,
                })
                .collect(),
            dropped: Vec::new(),
        }
    }

    /// The simulators still in the pool.
    pub fn endpoints(&self) -> Vec<String> {
        self.members.iter().map(|m| m.endpoint.clone()).collect()
    }

    /// Jobs each simulator still in the pool has finished, in [`Self::endpoints`] order.
    pub fn evaluations(&self) -> Vec<u64> {
        self.members.iter().map(|m| m.evaluations).collect()
    }

    /// The simulators dropped so far, in the order they failed.
    pub fn dropped(&self) -> &[Dropped] {
        &self.dropped
    }

    /// True when no simulator is left.
    pub fn is_empty(&self) -> bool {
        self.members.is_empty()
    }

    /// Runs jobs `0..n`, each on a free simulator, and returns their results in job
    /// order. A simulator whose job fails with [`JobError::Simulator`] is dropped and the
    /// job goes to another; [`PoolError::Exhausted`] when none is left with jobs undone.
    /// A job that fails with [`JobError::Fatal`] or [`JobError::Stopped`] ends the run:
    /// no further job starts, the running ones finish.
    pub fn run<T: Send>(
        &mut self,
        n: usize,
        job: &(dyn Fn(usize, &mut dyn Robot) -> Result<T, JobError> + Sync),
    ) -> Result<Vec<T>, PoolError> {
        let queue = Mutex::new(Queue {
            pending: (0..n).collect(),
            in_flight: 0,
            results: (0..n).map(|_| None).collect(),
            fatal: None,
        });
        let wake = Condvar::new();
        let failures: Vec<Option<String>> = std::thread::scope(|scope| {
            let workers: Vec<_> = self
                .members
                .iter_mut()
                .map(|m| {
                    let (queue, wake) = (&queue, &wake);
                    scope.spawn(move || serve(m, queue, wake, job))
                })
                .collect();
            workers
                .into_iter()
                .map(|w| {
                    w.join()
                        .unwrap_or_else(|_| Some("its worker thread panicked".into()))
                })
                .collect()
        });
        // Drop the failed simulators, in pool order (deterministic).
        let mut kept = Vec::with_capacity(self.members.len());
        for (m, failure) in self.members.drain(..).zip(failures) {
            match failure {
                Some(reason) => self.dropped.push(Dropped {
                    endpoint: m.endpoint,
                    reason,
                    evaluations: m.evaluations,
                }),
                None => kept.push(m),
            }
        }
        self.members = kept;
        let q = queue.into_inner().unwrap_or_else(|e| e.into_inner());
        if let Some(e) = q.fatal {
            return Err(e);
        }
        q.results
            .into_iter()
            .collect::<Option<Vec<T>>>()
            .ok_or(PoolError::Exhausted)
    }
}

/// One simulator's thread: take a job, run it, put the result (or the job, if the
/// simulator failed) back; end when no job is pending or running, or when it failed.
fn serve<T>(
    m: &mut Member,
    queue: &Mutex<Queue<T>>,
    wake: &Condvar,
    job: &(dyn Fn(usize, &mut dyn Robot) -> Result<T, JobError> + Sync),
) -> Option<String> {
    let lock = || queue.lock().unwrap_or_else(|e| e.into_inner());
    loop {
        let index = {
            let mut q = lock();
            loop {
                if q.fatal.is_some() {
                    return None;
                }
                if let Some(i) = q.pending.pop_front() {
                    q.in_flight += 1;
                    break i;
                }
                if q.in_flight == 0 {
                    return None;
                }
                q = wake.wait(q).unwrap_or_else(|e| e.into_inner());
            }
        };
        let result = job(index, m.backend.as_mut());
        let mut q = lock();
        q.in_flight -= 1;
        let end = match result {
            Ok(v) => {
                q.results[index] = Some(v);
                m.evaluations += 1;
                None
            }
            Err(JobError::Simulator(reason)) => {
                q.pending.push_front(index);
                Some(reason)
            }
            Err(JobError::Fatal(reason)) => {
                q.fatal.get_or_insert(PoolError::Fatal(reason));
                None
            }
            Err(JobError::Stopped) => {
                q.fatal.get_or_insert(PoolError::Stopped);
                None
            }
        };
        wake.notify_all();
        if end.is_some() {
            return end;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cps_kinematics::robots::{PandaTool, panda};
    use cps_robot::KinematicRobot;

    const READY: [f64; 7] = cps_kinematics::robots::PANDA_READY;

    fn robots(n: usize) -> Vec<NamedBackend> {
        (0..n)
            .map(|i| {
                let r = KinematicRobot::new(panda(PandaTool::HandTcp), &READY, 0.01).unwrap();
                (format!("robot{i}"), Box::new(r) as Box<dyn Robot>)
            })
            .collect()
    }

    /// Job i: reset, move joint 1 by i mrad in i steps, report the clock and joint 1.
    fn job(i: usize, b: &mut dyn Robot) -> Result<(f64, f64), JobError> {
        b.teleport(&READY)
            .map_err(|e| JobError::Simulator(e.to_string()))?;
        let b = b.stepped().expect("the in-process robot steps");
        for k in 0..i {
            let mut q = READY.to_vec();
            q[0] = 1e-3 * (k + 1) as f64;
            b.command_joint_positions(&q).unwrap();
            b.step().unwrap();
        }
        Ok((b.time().unwrap(), b.joint_positions().unwrap()[0]))
    }

    #[test]
    fn results_come_in_job_order_whatever_the_pool_size() {
        let one = SimulatorPool::new(robots(1)).run(40, &job).unwrap();
        let mut pool = SimulatorPool::new(robots(4));
        let four = pool.run(40, &job).unwrap();
        assert_eq!(one, four);
        assert!((four[7].1 - 7e-3).abs() < 1e-15 && (four[7].0 - 0.07).abs() < 1e-12);
        assert_eq!(pool.evaluations().iter().sum::<u64>(), 40);
        assert!(pool.dropped().is_empty());
    }

    /// Simulators that fail on given jobs are dropped, their jobs run elsewhere, every
    /// job is done exactly once; with none left, the pool says so.
    #[test]
    fn failing_simulators_are_dropped_and_their_jobs_rerun() {
        use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
        let calls = AtomicUsize::new(0);
        let failed = [AtomicBool::new(false), AtomicBool::new(false)];
        // The simulator that first takes job 5, and the one that first takes job 17, die.
        let flaky = |i: usize, b: &mut dyn Robot| {
            calls.fetch_add(1, Ordering::SeqCst);
            let slot = match i {
                5 => Some(&failed[0]),
                17 => Some(&failed[1]),
                _ => None,
            };
            if slot.is_some_and(|f| !f.swap(true, Ordering::SeqCst)) {
                return Err(JobError::Simulator(format!("died on job {i}")));
            }
            job(i, b)
        };
        let mut pool = SimulatorPool::new(robots(4));
        let got = pool.run(30, &flaky).unwrap();
        assert_eq!(got, SimulatorPool::new(robots(1)).run(30, &job).unwrap());
        assert_eq!(pool.dropped().len(), 2);
        assert_eq!(pool.endpoints().len(), 2);
        assert_eq!(
            calls.load(Ordering::SeqCst),
            32,
            "two jobs run twice, none lost"
        );
        assert_eq!(
            pool.evaluations().iter().sum::<u64>()
                + pool.dropped().iter().map(|d| d.evaluations).sum::<u64>(),
            30
        );
        // Every simulator fails: exhausted.
        let dead = |_: usize, _: &mut dyn Robot| -> Result<(), JobError> {
            Err(JobError::Simulator("gone".into()))
        };
        assert_eq!(pool.run(3, &dead), Err(PoolError::Exhausted));
        assert!(pool.is_empty() && pool.dropped().len() == 4);
        // A fatal job stops the run without dropping anyone.
        let mut pool = SimulatorPool::new(robots(3));
        let fatal = |i: usize, b: &mut dyn Robot| {
            if i == 4 {
                Err(JobError::Fatal("bad job".into()))
            } else {
                job(i, b)
            }
        };
        assert_eq!(
            pool.run(10, &fatal),
            Err(PoolError::Fatal("bad job".into()))
        );
        assert_eq!(pool.endpoints().len(), 3);
    }
}
