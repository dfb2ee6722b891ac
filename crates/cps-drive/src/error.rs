//! Why driving a robot failed: [`DriveError`], the one error of this crate. Each variant
//! keeps what caused it as its `source`; the command line maps [`DriveError::Input`] to
//! exit 2 and the rest to exit 1.

use cps_chunks::FollowError;
use cps_dmp::DmpError;
use cps_franka::FrankaError;
use cps_kinematics::KinematicsError;
use cps_outcome::{ExperimentError, InputError};
use cps_robot::RobotError;
use cps_ros2::Ros2Error;

/// A failure of a command that drives a robot.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum DriveError {
    /// Bad input (exit 2 on the command line): its sentence names the place.
    #[error(transparent)]
    Input(#[from] InputError),
    /// The robot, its connection or its controller (the contract's error).
    #[error(transparent)]
    Robot(#[from] RobotError),
    /// The Franka client: the connection, the robot's answer, its loop.
    #[error(transparent)]
    Franka(#[from] FrankaError),
    /// The chunk executor refused a setting or a chunk, or its robot failed.
    #[error(transparent)]
    Chunks(#[from] FollowError),
    /// The ROS 2 participant.
    #[error(transparent)]
    Ros2(#[from] Ros2Error),
    /// The robot's kinematics: its chain's limits, an inverse kinematics.
    #[error(transparent)]
    Kinematics(#[from] KinematicsError),
    /// A DMP stepped online.
    #[error(transparent)]
    Dmp(#[from] DmpError),
    /// A motion refused before anything was sent: `sentence` says what and what to pass
    /// to get past it; `source` is the guard's refusal.
    #[error("{sentence}")]
    Refused {
        /// The refusal in the words of the command.
        sentence: String,
        /// The guard's refusal (the limit broken, the collision, the start missed); boxed,
        /// so that every result of the crate stays small. [`DriveError::refusal`] reads it.
        #[source]
        source: Box<RobotError>,
    },
    /// `doing` failed because of `source`; the sentence ends with the source's.
    #[error("{doing}: {source}")]
    While {
        /// What was being done, naming its file or robot.
        doing: String,
        /// Why it failed.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A result (a recording, its report, chunks, a calibration) could not be written.
    #[error(transparent)]
    Output(ExperimentError),
    /// The one reader and writer's error: a staged file not put in place.
    #[error(transparent)]
    File(#[from] cps_files::FileError),
    /// A file put in place, or a socket's own address, failed at the system's level.
    #[error(transparent)]
    System(#[from] std::io::Error),
    /// What the command cannot go on from, in a sentence of its own: a goal the
    /// controller aborted, a run that left no report, a loop that panicked, a model that
    /// lacks what identification needs.
    #[error("{0}")]
    Failed(String),
}

impl DriveError {
    /// `doing` failed because of `source`.
    pub fn during(
        doing: impl Into<String>,
        source: impl std::error::Error + Send + Sync + 'static,
    ) -> Self {
        Self::While {
            doing: doing.into(),
            source: Box::new(source),
        }
    }

    /// What the guard refused, when it did: the limit broken, the collision, the start
    /// missed.
    pub fn refusal(&self) -> Option<&cps_robot::Refusal> {
        match self {
            Self::Refused { source, .. } => match source.as_ref() {
                RobotError::Refused { reason, .. } => Some(reason),
                _ => None,
            },
            Self::Robot(RobotError::Refused { reason, .. })
            | Self::Chunks(FollowError::Robot(RobotError::Refused { reason, .. })) => Some(reason),
            _ => None,
        }
    }

    /// Whether it is the user's input (exit 2 on the command line), its own or a client's.
    pub fn is_input(&self) -> bool {
        matches!(
            self,
            Self::Input(_)
                | Self::Output(ExperimentError::Input(_))
                | Self::Franka(FrankaError::Input(_) | FrankaError::Setting(_))
                | Self::Ros2(Ros2Error::Input(_))
        )
    }
}

impl From<ExperimentError> for DriveError {
    fn from(e: ExperimentError) -> Self {
        match e {
            ExperimentError::Input(e) => Self::Input(e),
            other => Self::Output(other),
        }
    }
}

/// An experiment that drives a robot fails with the same sentence; bad input stays bad
/// input.
impl From<DriveError> for ExperimentError {
    fn from(e: DriveError) -> Self {
        match e {
            DriveError::Input(e) => ExperimentError::Input(e),
            DriveError::Output(e) => e,
            e if e.is_input() => ExperimentError::Input(InputError(e.to_string())),
            other => ExperimentError::Failed {
                context: other.to_string(),
                source: Box::new(other),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use std::error::Error as _;

    use cps_robot::Refusal;

    use super::*;

    fn start_refused() -> RobotError {
        RobotError::Refused {
            robot: "fr3".into(),
            reason: Refusal::Start {
                joint: 4,
                robot: -2.0,
                plan: -1.5,
            },
        }
    }

    #[test]
    fn a_refusal_keeps_the_guards_reason_as_its_source() {
        let e = DriveError::Refused {
            sentence: "traj.csv: refused before sending anything".into(),
            source: Box::new(start_refused()),
        };
        assert_eq!(e.to_string(), "traj.csv: refused before sending anything");
        assert!(
            matches!(e.refusal(), Some(Refusal::Start { joint: 4, .. })),
            "{:?}",
            e.refusal()
        );
        let source = e.source().map(|s| s.to_string()).unwrap_or_default();
        assert!(source.contains("joint 4"), "{source}");
        // An experiment that drives the robot fails with the same sentence, its cause kept.
        let run: ExperimentError = e.into();
        assert_eq!(run.to_string(), "traj.csv: refused before sending anything");
        assert!(run.source().is_some());
    }

    #[test]
    fn bad_input_stays_bad_input_whichever_layer_found_it() {
        let cases = [
            DriveError::Input(InputError("--arm: `ur5` is not a Franka arm".into())),
            DriveError::Franka(FrankaError::Input("--host: no port".into())),
            DriveError::Ros2(Ros2Error::Input("--domain: 300 is over 232".into())),
        ];
        for e in cases {
            let text = e.to_string();
            assert!(e.is_input(), "{text}");
            match ExperimentError::from(e) {
                ExperimentError::Input(i) => assert_eq!(i.0, text),
                other => panic!("{other:?} is not input"),
            }
        }
        let lost = DriveError::during("fr3", start_refused());
        assert!(!lost.is_input());
        assert!(
            lost.to_string()
                .starts_with("fr3: fr3: refused before sending anything")
        );
        assert!(matches!(
            ExperimentError::from(lost),
            ExperimentError::Failed { .. }
        ));
    }
}
