//! Demonstrations from motion capture: a take recorded by an optical system (OptiTrack
//! Motive, Vicon, Qualisys) becomes the tool's pose over time in the robot's frame, ready
//! for imitation.
//!
//! Layers: [`take`] (what a take holds), [`c3d`] and [`motive`] (the two readers, cps's
//! own, every size checked), [`fit`] (rigid transforms, Horn's best fit), [`clean`]
//! (outliers, gap filling, zero-phase smoothing), [`register`] (the motion-capture frame
//! to the robot's, from points measured in both), and [`demo`], which strings them
//! together. Files, figures and words for the command line live in `cps-experiment`'s
//! `mocap` module.
//!
//! # Example
//!
//! ```no_run
//! use std::path::Path;
//! use cps_mocap::demo::{Settings, demonstrate, read_take};
//! use cps_mocap::register::Calibration;
//!
//! let take = read_take(Path::new("takes/pour.c3d"))?;
//! let settings = Settings {
//!     markers: vec!["tool1".into(), "tool2".into(), "tool3".into()],
//!     calibration: Some(Calibration::read(Path::new("lab.toml"))?),
//!     ..Settings::default()
//! };
//! let demo = demonstrate(&take, &settings)?;
//! println!(
//!     "{} poses over {:.2} s, markers within {:.2} mm of the body",
//!     demo.t.len(),
//!     demo.report.duration_s,
//!     demo.report.fit_rms_max_m * 1e3
//! );
//! std::fs::write("demo.csv", demo.csv())?;
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

pub mod c3d;
pub mod clean;
pub mod demo;
mod error;
pub mod fit;
pub mod motive;
pub mod register;
pub mod synthetic;
pub mod take;

pub use error::MocapError;
pub use take::Take;
