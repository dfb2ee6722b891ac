//! `cps-cli`: cps from the command line. Every command, its arguments and its help are in
//! docs/cli.md (written from `--help`); an experiment file's `[experiment] kind` chooses what
//! `run` does, and each shipped file in `experiments/` is a commented example. `--robot`
//! takes a built-in name (`panda`, `ur3`, `crx10ia`, `puma560`) or a robot file (TOML as in
//! `configs/robots/`, or URDF).
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
mod lerobot;
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
    Check(CheckArgs),
    /// Print a commented default experiment (the thesis's via-point task).
    Default,
    /// Forward kinematics: the tool pose at joint angles `--q`.
    Fk(robot::FkArgs),
    /// Inverse kinematics: joint angles that reach `--target`.
    Ik(robot::IkArgs),
    /// Identify a robot's joint controller and drives from a recording of `cps-cli franka
    /// execute` or `franka record` (t, q, dq, tau, q_d at 1 kHz), its last quarter held
    /// back to judge the fit; writes a calibration for `[robot] calibration`.
    Identify(robot::IdentifyArgs),
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
    /// A collision-free joint path from one configuration to another, or movements joined
    /// by such paths (`--join`), around the robot itself and its scene at the guard's margin
    /// (RRT-Connect, shortcut), timed within every limit and verified as the guard checks a
    /// plan: exit 1 when none is found.
    Plan(trajectory::PlanArgs),
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
        command: lerobot::LeRobotCommand,
    },
    /// Scenes: a placed robot and named way points.
    Scene {
        #[command(subcommand)]
        command: scene::SceneCommand,
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

/// Arguments of `cps-cli check`.
#[derive(clap::Args, Debug)]
struct CheckArgs {
    /// The experiment file (TOML).
    file: PathBuf,
    #[command(flatten)]
    ceilings: CeilingArgs,
    /// Worker threads the time estimate assumes (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
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
            // A cause is said once: one whose words the sentence already holds is left out.
            let mut said = e.to_string();
            for cause in e.chain().skip(1).map(|c| c.to_string()) {
                if !said.contains(&cause) {
                    eprintln!("  caused by: {cause}");
                    said.push_str(&cause);
                }
            }
            // Bad input is exit 2 whether it came alone or inside a library's error.
            let input = matches!(e.downcast_ref(), Some(ExperimentError::Input(_)))
                || e.downcast_ref::<cps_drive::DriveError>()
                    .is_some_and(|d| d.is_input());
            if input || e.downcast_ref::<InputError>().is_some() {
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
        Command::Plan(args) => trajectory::plan(&args),
        Command::Retime(args) => trajectory::retime(&args),
        Command::Export(args) => trajectory::export(&args),
        Command::Imitate(args) => movement::run_imitate(&args),
        Command::Cmaes { command } => cmaes_bench::bench(&command),
        Command::Sim { command } => simserve::sim(&command, stop.flag()),
        Command::Rollout(args) => movement::run_rollout(&args),
        Command::Promp { command } => promp::promp(&command),
        Command::Studio(args) => studio::studio(&args, stop.flag()),
        Command::Franka { command } => franka::franka(&command, stop),
        Command::Identify(args) => robot::identify(&args, stop),
        Command::Ros2 { command } => ros2::ros2(&command, stop),
        Command::Mocap { command } => mocap::mocap(&command),
        Command::Lerobot { command } => lerobot::lerobot(&command),
        Command::Check(args) => check(&args),
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

/// `cps-cli check`: the experiment's summary and estimate, a line each.
fn check(args: &CheckArgs) -> Result<ExitCode> {
    let exp = experiment::load(&args.file, None, &args.ceilings.ceilings()?)?;
    let options = RunOptions {
        threads: args.threads,
        ..RunOptions::default()
    };
    options.check()?;
    for line in exp.check_lines(options.threads())? {
        say!("{line}");
    }
    Ok(ExitCode::SUCCESS)
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
    let outcome = cps_experiment::run_into(&exp, &options, &observer, Some(results))?;
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
