//! Movements and the robots they are for, as files — everything cps reads and writes
//! about a movement without learning it or driving a robot:
//!
//! - [`calibration`]: a robot's controller and drives as identified (`cps-cli identify`);
//! - [`robot_file`]: `--robot` values (a built-in name, a TOML robot file, URDF) as
//!   [`RobotModel`](cps_robot::RobotModel)s with their limits, in words ([`robot_file::Describe`]);
//! - [`scene`]: scene files (a placed robot, its start, named way points and obstacles);
//! - [`movement`]: demonstration CSVs, imitation into DMP models, a model's rollout;
//! - [`limits`]: a joint trajectory file at a control rate against a robot's limits;
//! - [`collision`]: a robot's collision shapes (a URDF's `<collision>` elements, the
//!   built-in Franka meshes), with [`left_out`]: the pairs a description leaves out,
//!   verified over the joint ranges; [`collide`]: a joint trajectory file against them and
//!   a scene's obstacles;
//! - [`retiming`]: a trajectory retimed for a robot (the fastest timing of its path, or the
//!   smallest uniform slowing);
//! - [`export`]: joint trajectories for ROS 2 and viewers (YAML, MCAP, 1 kHz CSV, URDF);
//! - [`planning`]: a collision-free path between two configurations (`cps-cli plan`);
//! - [`promp`]: ProMPs from demonstration files (fit, condition, sample, statistics);
//! - [`mocap`]: motion-capture takes (C3D, Motive CSV) as demonstrations in a robot's
//!   frame, with their report — and `[demonstrations] takes` of experiment files.
//!
//! Every error names the file (and line) and the rule broken. Driving a robot is
//! `cps-drive`'s; experiments are `cps-experiment`'s.
//!
//! # Example
//! ```
//! let panda = cps_movement::robot_file::load_robot("panda", Some("hand"), None)?;
//! assert_eq!(panda.chain.dof(), 7);
//! assert_eq!(panda.published_joint_names()[0], "panda_joint1");
//! # Ok::<(), cps_outcome::InputError>(())
//! ```
#![deny(missing_docs)]

/// `Serialize` as the report's `json()` and `Display` as its `lines()`, a line each: for
/// the reports that say themselves both ways (`limits check`, `collide`, `retime`).
macro_rules! says_itself_by_json_and_lines {
    ($($report:ty),+) => {$(
        impl serde::Serialize for $report {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                self.json().serialize(s)
            }
        }

        impl std::fmt::Display for $report {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(&self.lines().join("\n"))
            }
        }
    )+};
}

pub mod calibration;
pub mod chunks;
pub mod collide;
pub mod collision;
pub mod dae;
pub mod export;
pub mod left_out;
pub mod lerobot;
pub mod lerobot_write;
pub mod limits;
pub mod mocap;
pub mod movement;
pub mod planning;
pub mod promp;
pub mod retiming;
pub mod robot_file;
pub mod scene;
