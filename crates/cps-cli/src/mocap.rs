//! `cps-cli mocap ...`: motion-capture takes (C3D, Motive CSV) to demonstrations.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::{Args, Subcommand};
use cps_mocap::demo::Words;
use cps_movement::mocap::{self, ImportFiles};

use crate::robot::print;

/// `cps-cli mocap ...`. Exit codes: 0 done; 2 bad input (a file that cannot be read, an
/// unknown label, a take refused: nothing is written).
#[derive(Subcommand, Debug)]
pub enum MocapCommand {
    /// A take's labels, rate, frames, units and gaps.
    Show {
        /// The take (`.c3d`, or a Motive `.csv` export).
        file: PathBuf,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// A take to a demonstration CSV `t,x,y,z,qx,qy,qz,qw` (metres, seconds from 0) that
    /// `imitate` and `promp fit` read: labelled markers fitted as one rigid body, or a
    /// Motive rigid body; gaps filled, outliers rejected, smoothed without lag.
    Import(Box<ImportArgs>),
}

/// `cps-cli mocap import`'s arguments.
#[derive(Args, Debug)]
pub struct ImportArgs {
    /// The take (`.c3d`, or a Motive `.csv` export).
    file: PathBuf,
    /// The body's markers, three or more (`A,B,C`).
    #[arg(long, value_delimiter = ',', required_unless_present = "rigid_body")]
    markers: Vec<String>,
    /// Motive's own rigid body instead of markers.
    #[arg(long, conflicts_with = "markers")]
    rigid_body: Option<String>,
    /// The body's origin: `centroid` of its markers, or one marker's label.
    #[arg(long, default_value = "centroid")]
    origin: String,
    /// The body's axes from three markers `O,X,P` (x from O to X, z normal to O-X-P);
    /// default: the take's axes at the first frame that sees every marker.
    #[arg(long, value_delimiter = ',', num_args = 1)]
    axes: Option<Vec<String>>,
    /// A registration file (points measured in both frames): the pose in the robot's
    /// frame.
    #[arg(long)]
    to_robot: Option<PathBuf>,
    /// The take is Y up (Motive's default): turn it Z up (without --to-robot).
    #[arg(long, conflicts_with = "to_robot")]
    y_up: bool,
    /// The longest gap filled, frames (longer gaps inside the take are refused).
    #[arg(long, default_value_t = 10)]
    max_gap: usize,
    /// Smoothing cut-off, Hz (0: none).
    #[arg(long, default_value_t = 10.0)]
    cutoff: f64,
    /// A sample farther than this from its neighbours or the body's fit is an
    /// outlier, mm.
    #[arg(long, default_value_t = 20.0)]
    outlier_mm: f64,
    /// Only these frames (indices from 0, `FIRST..END`).
    #[arg(long)]
    frames: Option<String>,
    /// The CSV to write.
    #[arg(long)]
    out: PathBuf,
    /// Figures: `<stem>_markers.png` and `<stem>_demonstration.png` beside this path.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// The robot whose reach the figure shows and the report checks (the pose in its
    /// base frame).
    #[arg(long)]
    robot: Option<String>,
    /// Or a scene (`thesis`, `fr3`, a file) whose placed robot's reach is shown (the
    /// pose in its world frame).
    #[arg(long, conflicts_with = "robot")]
    scene: Option<String>,
    /// Replace an existing --out.
    #[arg(long)]
    force: bool,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// `cps-cli mocap`.
pub fn mocap(cmd: &MocapCommand) -> Result<ExitCode> {
    match cmd {
        MocapCommand::Show { file, json } => print(&mocap::show(file)?, *json),
        MocapCommand::Import(a) => {
            let words = Words {
                markers: a.markers.clone(),
                rigid_body: a.rigid_body.clone(),
                origin: a.origin.clone(),
                axes: a.axes.clone(),
                y_up: a.y_up,
                max_gap: a.max_gap,
                cutoff_hz: a.cutoff,
                outlier_mm: a.outlier_mm,
                frames: a.frames.clone(),
            };
            let settings = words.settings().map_err(mocap::mocap_error)?;
            let files = ImportFiles {
                calibration: a.to_robot.clone(),
                plot: a.plot.clone(),
                robot: a.robot.clone(),
                scene: a.scene.clone(),
                force: a.force,
            };
            let answer = mocap::import(&a.file, &settings, &files, &a.out)?;
            print(&answer, a.json)
        }
    }
}
