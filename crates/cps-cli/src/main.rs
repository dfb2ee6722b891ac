//! `cps-cli`: run cps experiments from TOML files.
//!
//! ```text
//! cps-cli run experiments/viapoint.toml [--out DIR] [--seed N] [--threads N] [--force] [--quiet]
//! cps-cli check experiments/viapoint.toml
//! cps-cli default > my-experiment.toml
//! cps-cli fk --robot panda --q 0,-0.785,0,-2.356,0,1.571,0.785 [--tool hand|flange] [--json]
//! cps-cli ik --robot panda --target 0.4,0.2,0.5[,qx,qy,qz,qw] [--seed-q ...] [--json]
//! cps-cli robot show panda|configs/robots/ur3.toml|configs/robots/panda.urdf [--tool NAME] [--tip LINK]
//! cps-cli scene check configs/scenes/thesis.toml [--json]
//! cps-cli sim serve [--bind 127.0.0.1:23000] [--scene FILE] [--dt 0.05] [--ik-following]
//! cps-cli cmaes bench sphere|ellipsoid|cigar|discus|rosenbrock|rastrigin --dim N --seeds A..B [--ipop|--bipop] [--separable] [--json]
//! cps-cli imitate demo.csv [more.csv ...] [--bases N] [--method lwr|ridge|jerk] [--lambda X|auto] [--tau S] --out model.json [--plot fit.png]
//! cps-cli ros2 send traj.csv --controller /panda_arm_controller [--topic|--action] [--joint-names a,b,...] [--domain N] [--json]
//! cps-cli ros2 record --topic /joint_states --duration S --out rec.csv [--domain N]
//! cps-cli mocap show take.c3d | mocap import take.c3d --markers A,B,C [--to-robot lab.toml] --out demo.csv
//! cps-cli rollout model.json [--start ...] [--goal ...] [--tau S] [--dt S] --out traj.csv [--plot traj.png]
//! cps-cli promp fit demo*.csv [--bases N] --out p.json | condition p.json --at T --position x,y [--std S] --out q.json
//! cps-cli promp sample p.json --n K --seed S [--dt S] --out dir/ | stats p.json --out stats.csv
//! cps-cli franka state --host H | execute traj.csv --host H --record rec.csv [--retime] [--approach] | record --host H --duration S --out rec.csv
//! ```
//!
//! An experiment file's `[experiment] kind` chooses what `run` does: `viapoint` (default),
//! `imitation`, `scaling`, `viapoint_joint`, `viapoint_energy`, `viapoint_pose`, `promp`,
//! `viapoint_executed`; each
//! shipped file in `experiments/` is a commented example. Every run writes `summary.json`,
//! CSV data, figures (PNG and SVG) and `report.html`.
//!
//! `--robot` takes a built-in name (`panda`, `ur3`, `crx10ia`, `puma560`) or a robot file: TOML as in
//! `configs/robots/` or URDF.
//!
//! Exit codes: 0 success, 1 failure while running, 2 bad input (the message names the file,
//! line and column), 130 interrupted by Ctrl-C or SIGTERM (the results of the finished generations are
//! still written, with `"complete": false`).

/// Prints a line to stdout, ignoring a closed pipe (`cps-cli fk ... | head` must not panic).
macro_rules! say {
    ($($arg:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($arg)*);
    }};
}

mod cmaes_bench;
mod franka;
mod mocap;
mod movement;
mod progress;
mod promp;
mod robot;
mod ros2;
mod scene;
mod simserve;
mod studio;
mod trajectory;

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::Result;
use clap::{Parser, Subcommand};
use cps_experiment::{Experiment, ExperimentError, InputError, RunOptions, budget, experiment};
use cps_movement::lerobot_write;
use cps_report::write::{Results, WriteOptions};
use cps_robot::StopToken;

/// The commented default experiment: the file shipped as experiments/viapoint.toml.
const DEFAULT_EXPERIMENT: &str = include_str!("../../../experiments/viapoint.toml");

#[derive(Parser, Debug)]
#[command(
    name = "cps-cli",
    version,
    about = "Learn smooth robot movements from way points (cps)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Run an experiment and write its results, plots and summary.
    Run(RunArgs),
    /// Validate an experiment file without running it.
    Check {
        /// The experiment file (TOML).
        file: PathBuf,
        #[command(flatten)]
        ceilings: CeilingArgs,
        /// Worker threads the time estimate assumes (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
    },
    /// Print a commented default experiment (the thesis's via-point task).
    Default,
    /// Forward kinematics: the tool pose at joint angles `--q`.
    Fk(robot::FkArgs),
    /// Inverse kinematics: joint angles that reach `--target`.
    Ik(robot::IkArgs),
    /// Identify a robot's joint controller and drives from a recording of `cps-cli franka
    /// execute` or `franka record` (t, q, dq, tau, q_d at 1 kHz), its last quarter held
    /// back to judge the fit; writes a calibration for `[robot] calibration`.
    Identify {
        /// The recording (CSV).
        recording: PathBuf,
        /// The robot recorded (its model, with the hand's inertias).
        #[arg(long, default_value = "fr3")]
        robot: String,
        /// The calibration file to write (TOML).
        #[arg(long)]
        out: PathBuf,
        /// Replace an existing calibration.
        #[arg(long)]
        force: bool,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Robot models.
    Robot {
        #[command(subcommand)]
        command: robot::RobotCommand,
    },
    /// The stand-in CoppeliaSim server.
    Sim {
        #[command(subcommand)]
        command: simserve::SimCommand,
    },
    /// The optimiser alone: standard test functions in the reference set-up.
    Cmaes {
        #[command(subcommand)]
        command: cmaes_bench::CmaesCommand,
    },
    /// Learn a DMP model (JSON) from demonstrations (CSV).
    Imitate(movement::ImitateArgs),
    /// Roll out a DMP model into a trajectory (CSV), with optional new start, goal, τ.
    Rollout(movement::RolloutArgs),
    /// Probabilistic movement primitives: fit from demonstrations, condition on via
    /// points, sample, statistics.
    Promp {
        #[command(subcommand)]
        command: promp::ProMpCommand,
    },
    /// Robot limits: check a joint trajectory against them.
    Limits {
        #[command(subcommand)]
        command: robot::LimitsCommand,
    },
    /// Check a joint trajectory (CSV) for collisions of the robot with itself and its
    /// scene, as the guard will before sending it: the closest pair and the worst row, exit
    /// 1 on a collision. `--json` lists each row's pairs within 10 cm, in metres.
    Collide(robot::CollideArgs),
    /// Retime a joint trajectory (CSV) within the robot's limits: the fastest timing of
    /// its path, or the smallest uniform slowing.
    Retime(trajectory::RetimeArgs),
    /// Export a joint trajectory (CSV) for ROS 2 and viewers: JointTrajectory YAML, MCAP,
    /// or a 1 kHz CSV of positions, velocities and accelerations.
    Export(trajectory::ExportArgs),
    /// A local web workbench: drag via points, watch the movement re-learned.
    Studio(studio::StudioArgs),
    /// A Franka (FR3, or a Panda on a protocol-10 system) over the Franka Control
    /// Interface: its state, a trajectory executed and recorded at 1 kHz within its limits.
    Franka {
        #[command(subcommand)]
        command: franka::FrankaCommand,
    },
    /// A ROS 2 graph over DDS (no ROS needed): a trajectory to a ros2_control controller,
    /// joint states recorded.
    Ros2 {
        #[command(subcommand)]
        command: ros2::Ros2Command,
    },
    /// Motion capture: a take (C3D, Motive CSV) shown, or made a demonstration in the
    /// robot's frame.
    Mocap {
        #[command(subcommand)]
        command: mocap::MocapCommand,
    },
    /// LeRobot datasets (format v3.0, a local folder): shown, or written from recordings.
    /// `imitate` and `promp fit` take a dataset's folder as demonstrations.
    Lerobot {
        #[command(subcommand)]
        command: LeRobotCommand,
    },
    /// Scenes: a placed robot and named way points.
    Scene {
        #[command(subcommand)]
        command: scene::SceneCommand,
    },
}

/// `cps-cli lerobot ...`. Exit codes: 0 done; 2 a dataset that cannot be read.
#[derive(Subcommand, Debug)]
enum LeRobotCommand {
    /// A dataset's rate, robot, features (type, shape, entry names) and episodes (frames,
    /// duration, tasks).
    Show {
        /// The dataset's folder (it holds meta/info.json).
        dataset: PathBuf,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Recordings (`franka execute --record`, `franka record`, `franka guide`, `ros2
    /// record`, a joint CSV) written as a new dataset LeRobot's loader opens, one episode
    /// each: joint states (velocities, torques where recorded) and actions (the commands,
    /// or the next state), resampled to --fps, without video.
    Write {
        /// The recordings (CSV).
        #[arg(required = true)]
        recordings: Vec<PathBuf>,
        /// The dataset's folder to create.
        #[arg(long)]
        out: PathBuf,
        /// The robot recorded: its joints name the entries.
        #[arg(long, default_value = "fr3")]
        robot: String,
        /// What the episodes did (LeRobot's task).
        #[arg(long)]
        task: String,
        /// Frames per second (default: the first recording's rate).
        #[arg(long)]
        fps: Option<u32>,
        /// Replace a dataset at --out that holds nothing but the files cps writes.
        #[arg(long)]
        force: bool,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
}

/// Arguments of `cps-cli run`.
#[derive(clap::Args, Debug)]
struct RunArgs {
    /// The experiment file (TOML).
    file: PathBuf,
    /// Output directory (default: results/NAME, NAME from the experiment).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Override the experiment's seed.
    #[arg(long)]
    seed: Option<u64>,
    /// Worker threads (default: all cores). Results do not depend on it.
    #[arg(long)]
    threads: Option<usize>,
    /// Replace cps's own results already in the output directory (nothing else).
    #[arg(long)]
    force: bool,
    /// No progress bar and no summary on the terminal.
    #[arg(long)]
    quiet: bool,
    #[command(flatten)]
    ceilings: CeilingArgs,
}

/// The ceilings on what an experiment may ask of the machine.
#[derive(clap::Args, Debug)]
struct CeilingArgs {
    /// Refuse an experiment estimated to need more memory than this, in GiB.
    #[arg(
        long,
        default_value_t = 4.0,
        value_name = "GIB",
        allow_hyphen_values = true
    )]
    max_memory: f64,
    /// Refuse an experiment estimated to need more multiply-adds than this.
    #[arg(
        long,
        default_value_t = 1e13,
        value_name = "OPS",
        allow_hyphen_values = true
    )]
    max_work: f64,
}

impl CeilingArgs {
    fn ceilings(&self) -> Result<budget::Ceilings, InputError> {
        budget::Ceilings::new(self.max_memory, self.max_work)
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // A dependency's panic on a malformed file is said once, as a sentence naming the file.
    cps_files::read::quiet_guarded_panics();
    // Ctrl-C and SIGTERM (`timeout`, schedulers) stop the command through its one stop
    // token: a robot that moves brakes within its limits, a run ends after its generation.
    // A second one exits at once (a run's staging directory is then left behind, hidden) —
    // never while a robot moves: its brake must finish (the motion then ends by itself).
    let stop = StopToken::new();
    let handler = stop.clone();
    let signals = AtomicUsize::new(0);
    let _ = ctrlc::set_handler(move || {
        handler.stop();
        if signals.fetch_add(1, Ordering::SeqCst) >= 1 && !handler.is_moving() {
            std::process::exit(130);
        }
    });
    match run(cli, &stop) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e}");
            for cause in e.chain().skip(1) {
                eprintln!("  caused by: {cause}");
            }
            if e.downcast_ref::<InputError>().is_some() {
                ExitCode::from(2)
            } else {
                ExitCode::from(1)
            }
        }
    }
}

fn run(cli: Cli, stop: &StopToken) -> Result<ExitCode> {
    match cli.command {
        Command::Default => {
            say!("{}", DEFAULT_EXPERIMENT.trim_end());
            Ok(ExitCode::SUCCESS)
        }
        Command::Fk(args) => robot::fk(&args),
        Command::Ik(args) => robot::ik(&args),
        Command::Robot { command } => robot::robot(&command),
        Command::Scene { command } => scene::scene(&command),
        Command::Limits { command } => robot::limits(&command),
        Command::Collide(args) => robot::collide(&args),
        Command::Retime(args) => trajectory::retime(&args),
        Command::Export(args) => trajectory::export(&args),
        Command::Imitate(args) => movement::run_imitate(&args),
        Command::Cmaes { command } => cmaes_bench::bench(&command),
        Command::Sim { command } => simserve::sim(&command, stop.flag()),
        Command::Rollout(args) => movement::run_rollout(&args),
        Command::Promp { command } => promp::promp(&command),
        Command::Studio(args) => studio::studio(&args, stop.flag()),
        Command::Franka { command } => franka::franka(&command, stop),
        Command::Identify {
            recording: r,
            robot: arm,
            out,
            force,
            json,
        } => match cps_drive::identify::identify_recording(&r, &arm, &out, force, stop) {
            Err(e) if stop.is_stopped() => {
                eprintln!("interrupted: {e}");
                Ok(status(cps_outcome::Ended::Stopped))
            }
            done => robot::print(&done.map_err(cli_error)?, json),
        },
        Command::Ros2 { command } => ros2::ros2(&command, stop),
        Command::Mocap { command } => mocap::mocap(&command),
        Command::Lerobot { command } => match command {
            LeRobotCommand::Show { dataset, json } => {
                robot::print(&cps_movement::lerobot::describe(&dataset)?, json)
            }
            LeRobotCommand::Write {
                recordings,
                out,
                robot: arm,
                task,
                fps,
                force,
                json,
            } => {
                let export = lerobot_write::Export {
                    robot: arm,
                    task,
                    fps,
                };
                let answer = lerobot_write::write_recordings(&out, &recordings, &export, force)?;
                robot::print(&answer, json)
            }
        },
        Command::Check {
            file,
            ceilings,
            threads,
        } => {
            let exp = experiment::load(&file, None, &ceilings.ceilings()?)?;
            let options = RunOptions {
                threads,
                ..RunOptions::default()
            };
            options.check()?;
            for line in exp.check_lines(options.threads())? {
                say!("{line}");
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Run(args) => run_experiment(&args, stop),
    }
}

/// The exit status of how a command that moves a robot ended: 0, 1, or 130 (stopped, as a
/// shell reports an interrupt).
pub(crate) fn status(ended: cps_outcome::Ended) -> ExitCode {
    match ended {
        cps_outcome::Ended::Completed => ExitCode::SUCCESS,
        cps_outcome::Ended::Failed => ExitCode::from(1),
        cps_outcome::Ended::Stopped => ExitCode::from(130),
    }
}

/// A library error as the command line reports it: input problems keep their own type
/// (exit 2), the rest their chain of causes (exit 1).
pub(crate) fn cli_error(e: ExperimentError) -> anyhow::Error {
    match e {
        ExperimentError::Input(e) => anyhow::Error::new(e),
        other => anyhow::Error::new(other),
    }
}

fn run_experiment(args: &RunArgs, stop: &StopToken) -> Result<ExitCode> {
    let ceilings = &args.ceilings.ceilings()?;
    let exp: Experiment = experiment::load(&args.file, args.seed, ceilings)?;
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| Path::new("results").join(&exp.name));
    let options = RunOptions {
        threads: args.threads,
        stop: stop.clone(),
    };
    options.check()?;
    // The output is checked, and its staging directory made, before any work.
    let results = Results::prepare(&out, args.force, WriteOptions { figures: exp.plots })?;
    let observer = progress::Terminal::new(!args.quiet, stop.flag());
    let outcome =
        cps_experiment::run_into(&exp, &options, &observer, Some(results)).map_err(cli_error)?;
    observer.clear();
    if !args.quiet {
        for line in &outcome.lines {
            say!("{line}");
        }
        say!("  results and report.html in {}", out.display());
    }
    // A run the stop ended is interrupted, whatever its robot said of the stop.
    let interrupted = stop.is_stopped() && !outcome.complete();
    if let Some(failure) = outcome.failure().filter(|_| !interrupted) {
        if outcome.complete() {
            eprintln!(
                "error: the run failed: {failure}\n  what it made is in {} (summary.json says why)",
                out.display()
            );
        } else {
            eprintln!(
                "error: the run stopped early: {failure}\n  what was finished is in {} (summary.json says \"complete\": false and counts what was done)",
                out.display()
            );
        }
        return Ok(status(cps_outcome::Ended::Failed));
    }
    if !outcome.complete() {
        eprintln!(
            "interrupted: the finished part is in {} (complete: false)",
            out.display()
        );
        return Ok(status(cps_outcome::Ended::Stopped));
    }
    Ok(ExitCode::SUCCESS)
}
