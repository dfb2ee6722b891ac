//! Movements joined into one motion by planned transitions: where one movement ends away
//! from where the next starts, [`crate::plan`] finds the way between, around the robot
//! itself and its scene, and the whole — movements and transitions — is verified at the
//! control period as the guard verifies any plan before it is returned.

use std::time::Instant;

use cps_robot::{Plan, RobotModel};

use crate::{PlanError, Planned, Settings, plan};

/// Two configurations closer than this in every joint (rad) are one: no transition.
const SAME: f64 = 1e-9;

/// What a stretch of the joined motion is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// Movement `k` (0-based), as it was given.
    Movement(usize),
    /// The planned transition into movement `k` (0-based) from where the robot was.
    Transition(usize),
}

/// A stretch of the joined motion and its times.
#[derive(Debug, Clone)]
pub struct Stretch {
    /// What it is.
    pub part: Part,
    /// When it starts (s from the joined motion's start).
    pub start_s: f64,
    /// When it ends (s).
    pub end_s: f64,
    /// A transition's path as the planner found it (None for a movement).
    pub planned: Option<Planned>,
}

/// Movements joined by transitions, verified as one.
#[derive(Debug, Clone)]
pub struct Joined {
    /// The whole motion, every control period.
    pub plan: Plan,
    /// Its stretches in order: a transition (when one is needed), then a movement.
    pub stretches: Vec<Stretch>,
    /// Seconds the transitions' planning and the whole's verification took.
    pub seconds: f64,
}

/// Why movements could not be joined.
#[derive(Debug, thiserror::Error)]
pub enum JoinError {
    /// No movement was given.
    #[error("no movements to join")]
    Empty,
    /// A movement at another control period than the transitions'.
    #[error("movement {} is sampled every {got} s; the transitions are every {expected} s", .movement + 1)]
    Period {
        /// The movement (0-based).
        movement: usize,
        /// Its period (s).
        got: f64,
        /// The settings' period (s).
        expected: f64,
    },
    /// A movement for a robot of another number of joints.
    #[error("movement {} has {got} joints; the robot has {expected}", .movement + 1)]
    Joints {
        /// The movement (0-based).
        movement: usize,
        /// Its joints.
        got: usize,
        /// The robot's.
        expected: usize,
    },
    /// The transition into a movement could not be planned: its start is where the robot
    /// stands before (the previous movement's end, or the given start), its goal the
    /// movement's first point.
    #[error("{}: {source}", into_words(*.into))]
    Transition {
        /// The movement it leads into (0-based).
        into: usize,
        /// Why.
        source: PlanError,
    },
    /// The joined motion failed the guard's check: a movement of its own breaks a limit or
    /// comes within the margin, or it ends moving where a transition starts at rest.
    #[error("{}, {into_s:.3} s into it: {why}", part_words(*.part))]
    Unverified {
        /// The stretch it happens in.
        part: Part,
        /// When (s from the stretch's start).
        into_s: f64,
        /// The guard's sentence (its time from the joined motion's start).
        why: String,
    },
    /// The robot's model could not be used.
    #[error(transparent)]
    Robot(#[from] cps_robot::RobotError),
}

impl JoinError {
    /// Whether the movements given (not the search) are at fault: an end in collision or
    /// out of range, a movement that breaks a limit or hits something, a wrong period.
    pub fn is_input(&self) -> bool {
        match self {
            JoinError::Empty
            | JoinError::Period { .. }
            | JoinError::Joints { .. }
            | JoinError::Unverified { .. } => true,
            JoinError::Transition { source, .. } => source.is_input(),
            JoinError::Robot(_) => false,
        }
    }
}

impl JoinError {
    /// The movement (0-based) the error is at: the one a transition leads into, whose
    /// stretch breaks the check, or that is malformed.
    pub fn movement(&self) -> Option<usize> {
        match self {
            JoinError::Period { movement, .. } | JoinError::Joints { movement, .. } => {
                Some(*movement)
            }
            JoinError::Transition { into, .. } => Some(*into),
            JoinError::Unverified {
                part: Part::Movement(k) | Part::Transition(k),
                ..
            } => Some(*k),
            JoinError::Empty | JoinError::Robot(_) => None,
        }
    }
}

fn into_words(into: usize) -> String {
    match into {
        0 => "the transition from the start given to the start of movement 1".into(),
        k => format!(
            "the transition from the end of movement {k} to the start of movement {}",
            k + 1
        ),
    }
}

fn part_words(part: Part) -> String {
    match part {
        Part::Movement(k) => format!("movement {}", k + 1),
        Part::Transition(k) => format!("the transition into movement {}", k + 1),
    }
}

/// `movements` (each every [`Settings::dt`]) in order as one motion from `from` (None: the
/// first movement's start): wherever the robot would stand elsewhere than the next
/// movement's start, a transition planned with `settings` leads there (timed at rest at
/// both ends). The whole is verified — every limit and every pair, every control period —
/// and a breach is named by its stretch and time.
pub fn join(
    robot: &RobotModel,
    from: Option<&[f64]>,
    movements: &[Plan],
    settings: &Settings,
) -> Result<Joined, JoinError> {
    let started = Instant::now();
    let first = movements.first().ok_or(JoinError::Empty)?;
    let dt = settings.dt;
    if let Some((k, m)) = movements
        .iter()
        .enumerate()
        .find(|(_, m)| (m.dt() - dt).abs() > 1e-12 * dt)
    {
        return Err(JoinError::Period {
            movement: k,
            got: m.dt(),
            expected: dt,
        });
    }
    let mut at = from.unwrap_or(first.start()).to_vec();
    let mut whole: Option<Plan> = None;
    let mut stretches = Vec::with_capacity(2 * movements.len());
    let push = |whole: &mut Option<Plan>, part: Plan| -> Result<(f64, f64), JoinError> {
        let start_s = whole.as_ref().map_or(0.0, Plan::duration);
        let joined = match whole.take() {
            None => part,
            Some(w) => w.then(&part)?,
        };
        let end_s = joined.duration();
        *whole = Some(joined);
        Ok((start_s, end_s))
    };
    for (k, movement) in movements.iter().enumerate() {
        if movement.dof() != robot.chain.dof() {
            return Err(JoinError::Joints {
                movement: k,
                got: movement.dof(),
                expected: robot.chain.dof(),
            });
        }
        let gap = at
            .iter()
            .zip(movement.start())
            .any(|(a, b)| (a - b).abs() > SAME);
        if gap || at.len() != movement.dof() {
            let planned = plan(robot, &at, movement.start(), settings)
                .map_err(|source| JoinError::Transition { into: k, source })?;
            let (start_s, end_s) = push(&mut whole, planned.plan.clone())?;
            stretches.push(Stretch {
                part: Part::Transition(k),
                start_s,
                end_s,
                planned: Some(planned),
            });
        }
        let (start_s, end_s) = push(&mut whole, movement.clone())?;
        stretches.push(Stretch {
            part: Part::Movement(k),
            start_s,
            end_s,
            planned: None,
        });
        at = movement.end().to_vec();
    }
    let plan = whole.ok_or(JoinError::Empty)?;
    let unverified = |time: f64, why: String| {
        let s = stretches
            .iter()
            .find(|s| time <= s.end_s + 1e-9)
            .or(stretches.last());
        JoinError::Unverified {
            part: s.map_or(Part::Movement(0), |s| s.part),
            into_s: time - s.map_or(0.0, |s| s.start_s),
            why,
        }
    };
    let verdict = cps_robot::check(robot, &plan, dt)?;
    if let Some(b) = verdict.breach {
        return Err(unverified(b.time, b.to_string()));
    }
    if let Some(shapes) = &robot.shapes
        && let Some(c) = cps_robot::check_shapes(shapes, &robot.chain, &plan, dt)?
    {
        return Err(unverified(c.time, c.to_string()));
    }
    Ok(Joined {
        plan,
        stretches,
        seconds: started.elapsed().as_secs_f64(),
    })
}

// Two movements on either side of a post are joined by a transition around it: the
// movements come through unchanged at their places in the whole, every configuration of
// the whole keeps the margin (measured apart from the planner), and a movement that itself
// sweeps through the post is refused naming it and the time into it.
#[cfg(test)]
mod tests {
    use cps_robot::Plan;

    use super::*;
    use crate::tests::{LEFT, RIGHT, robot};

    /// A slow turn of joint 7 by 0.2 rad from `q`, at rest at both ends (1 kHz).
    fn wrist_turn(q: &[f64; 7]) -> Plan {
        let points = (0..=1000)
            .map(|k| {
                let s = k as f64 / 1000.0;
                let mut p = q.to_vec();
                p[6] += 0.2 * (10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5));
                p
            })
            .collect();
        Plan::new(0.001, points).unwrap()
    }

    #[test]
    fn movements_on_either_side_of_a_post_are_joined_around_it() {
        let model = robot();
        let (a, b) = (wrist_turn(&LEFT), wrist_turn(&RIGHT));
        let joined = join(&model, None, &[a.clone(), b.clone()], &Settings::default()).unwrap();
        let parts: Vec<Part> = joined.stretches.iter().map(|s| s.part).collect();
        assert_eq!(
            parts,
            [Part::Movement(0), Part::Transition(1), Part::Movement(1)]
        );
        let points = joined.plan.points();
        for (stretch, movement) in [(&joined.stretches[0], &a), (&joined.stretches[2], &b)] {
            let first = (stretch.start_s / 0.001).round() as usize;
            assert_eq!(
                &points[first..first + movement.points().len()],
                movement.points()
            );
        }
        let around = joined.stretches[1].planned.as_ref().unwrap();
        assert!(around.waypoints.len() >= 3, "{:?}", around.waypoints);
        let shapes = model.shapes.as_ref().unwrap();
        let mut frames = Vec::new();
        for q in points {
            model.chain.frames_into(q, &mut frames).unwrap();
            assert!(shapes.model().within(&frames, shapes.margin()).is_empty());
        }
        // From a start given: a transition first.
        let from_right = join(&model, Some(&RIGHT[..]), &[a], &Settings::default()).unwrap();
        assert_eq!(from_right.stretches[0].part, Part::Transition(0));
        assert_eq!(from_right.plan.start(), &RIGHT[..]);
        // A movement of its own through the post.
        let sweep = Plan::new(
            0.001,
            (0..=3000)
                .map(|k| {
                    let s = k as f64 / 3000.0;
                    let mut p = LEFT.to_vec();
                    p[0] += 2.0 * (10.0 * s.powi(3) - 15.0 * s.powi(4) + 6.0 * s.powi(5));
                    p
                })
                .collect(),
        )
        .unwrap();
        let e = join(&model, None, &[b, sweep], &Settings::default()).unwrap_err();
        assert!(e.is_input());
        let text = e.to_string();
        assert!(
            text.starts_with("movement 2, ") && text.contains("`post`"),
            "{text}"
        );
    }
}
