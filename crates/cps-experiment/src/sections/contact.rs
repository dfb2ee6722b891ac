//! `[contact]` of `kind = "contact"`: the surface's approach, the force profile and the
//! controller's settings, read with their places in the file.
//!
//! ```toml
//! [contact]
//! above = [0.45, 0.0, 0.47]     # m, base frame: where the approach starts
//! direction = [0.0, 0.0, -1.0]  # approach and pressing direction
//! search = 0.15                 # m beyond `above` to look for the surface
//! speed = 0.03                  # m/s while searching
//! detect = 3.0                  # N along the direction: contact
//! ceiling = 30.0                # N: above it the force is dropped and the tool retreats
//! retreat = 0.05                # m lifted at the end
//! error_gain = 0.2              # 1/N: the profile's phase slows with the force error
//! stiffness = [2000.0, 150.0]   # N/m, N m/rad of the impedance
//! force_gains = [0.2, 5.0, 30.0]  # kp, ki (1/s), damping (N s/m) along the direction
//! drive = "link"                # where the torques are measured: link (a Franka) or franky-sim
//!
//! [[contact.waypoints]]         # the profile from contact on (or demonstration = "file.csv")
//! t = 0.0
//! offset = [0.0, 0.0, 0.0]      # m from the point of contact
//! force = 0.0                   # N along the direction
//! ```

use std::ops::Range;
use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use crate::InputError;
use cps_drive::contact::{ContactPlan, ContactWaypoint, ForcePrimitive};
use cps_dynamics::Drive;

/// `[contact]` as written.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactSection {
    above: Spanned<[f64; 3]>,
    #[serde(default)]
    direction: Option<Spanned<[f64; 3]>>,
    search: Option<Spanned<f64>>,
    speed: Option<Spanned<f64>>,
    detect: Option<Spanned<f64>>,
    ceiling: Option<Spanned<f64>>,
    retreat: Option<Spanned<f64>>,
    error_gain: Option<Spanned<f64>>,
    stiffness: Option<Spanned<[f64; 2]>>,
    force_gains: Option<Spanned<[f64; 3]>>,
    drive: Option<Spanned<String>>,
    #[serde(default)]
    waypoints: Vec<Spanned<WaypointSection>>,
    demonstration: Option<Spanned<String>>,
}

/// One `[[contact.waypoints]]`.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct WaypointSection {
    t: f64,
    #[serde(default)]
    offset: [f64; 3],
    force: f64,
}

/// `[contact]` checked: the plan and where the torques are measured.
#[derive(Debug, Clone)]
pub struct ContactSpec {
    /// The task.
    pub plan: ContactPlan,
    /// Where the robot measures its joint torques.
    pub drive: Drive,
    /// Where the profile came from (`waypoints` or the demonstration's path).
    pub profile: String,
}

/// The ranges of `[contact]`'s numbers: (key, lowest, highest, default).
const RANGES: [(&str, f64, f64, f64); 6] = [
    ("search", 0.005, 0.5, 0.15),
    ("speed", 0.001, 0.1, 0.03),
    ("detect", 0.5, 50.0, 3.0),
    ("ceiling", 0.5, 150.0, 30.0),
    ("retreat", 0.0, 0.3, 0.05),
    ("error_gain", 0.0, 10.0, 0.2),
];

impl ContactSection {
    /// Checks the section; `err` names a place of the file, `dir` is the experiment file's
    /// folder (a demonstration's path is relative to it).
    pub(crate) fn plan(
        &self,
        dir: &Path,
        err: &dyn Fn(&Range<usize>, String) -> InputError,
    ) -> Result<ContactSpec, InputError> {
        let number = |v: &Option<Spanned<f64>>, key: &str| -> Result<f64, InputError> {
            let (_, lo, hi, default) = RANGES
                .iter()
                .find(|r| r.0 == key)
                .copied()
                .expect("a known key");
            match v {
                None => Ok(default),
                Some(v) if v.get_ref().is_finite() && (lo..=hi).contains(v.get_ref()) => {
                    Ok(*v.get_ref())
                }
                Some(v) => Err(err(
                    &v.span(),
                    format!(
                        "[contact] `{key}` must be between {lo} and {hi} (got {:?})",
                        v.get_ref()
                    ),
                )),
            }
        };
        let (above, direction) = self.approach(err)?;
        let gains = self.gains(err)?;
        let force_gains = self.force_gains(err)?;
        let drive = match &self.drive {
            None => Drive::Rigid,
            Some(d) => Drive::parse(d.get_ref()).ok_or_else(|| {
                err(
                    &d.span(),
                    format!(
                        "[contact] drive: `{}` is not one of {}",
                        d.get_ref(),
                        Drive::NAMES
                    ),
                )
            })?,
        };
        let (primitive, profile) = self.primitive(dir, err)?;
        let plan = ContactPlan {
            above,
            direction,
            search: number(&self.search, "search")?,
            speed: number(&self.speed, "speed")?,
            detect: number(&self.detect, "detect")?,
            ceiling: number(&self.ceiling, "ceiling")?,
            retreat: number(&self.retreat, "retreat")?,
            error_gain: number(&self.error_gain, "error_gain")?,
            gains,
            force_gains,
            sensing: Default::default(),
            primitive,
        };
        plan.check().map_err(|e| {
            let span = self
                .ceiling
                .as_ref()
                .map_or(self.above.span(), |c| c.span());
            err(&span, format!("[contact] {}", e.0))
        })?;
        Ok(ContactSpec {
            plan,
            drive,
            profile,
        })
    }

    /// Where the approach starts and the direction it moves in.
    fn approach(
        &self,
        err: &dyn Fn(&Range<usize>, String) -> InputError,
    ) -> Result<([f64; 3], [f64; 3]), InputError> {
        let above = *self.above.get_ref();
        if above.iter().any(|v| !v.is_finite() || v.abs() > 1.5) {
            return Err(err(
                &self.above.span(),
                "[contact] `above` must be three finite coordinates within 1.5 m of the robot's base".into(),
            ));
        }
        let direction = self
            .direction
            .as_ref()
            .map_or([0.0, 0.0, -1.0], |d| *d.get_ref());
        let norm = direction.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !(norm.is_finite() && norm > 1e-6) {
            let span = self
                .direction
                .as_ref()
                .map_or(self.above.span(), |d| d.span());
            return Err(err(
                &span,
                "[contact] `direction` must be a non-zero, finite vector".into(),
            ));
        }
        Ok((above, direction))
    }

    /// The Cartesian impedance's gains.
    fn gains(
        &self,
        err: &dyn Fn(&Range<usize>, String) -> InputError,
    ) -> Result<cps_franka::control::CartesianGains, InputError> {
        let gains_default = cps_franka::control::CartesianGains {
            translation: [2000.0; 3],
            rotation: [150.0; 3],
            damping_ratio: 1.0,
            nullspace: 5.0,
        };
        let gains = match &self.stiffness {
            None => gains_default,
            Some(s) => {
                let [kt, kr] = *s.get_ref();
                let g = cps_franka::control::CartesianGains {
                    translation: [kt; 3],
                    rotation: [kr; 3],
                    ..gains_default
                };
                cps_franka::control::CartesianImpedance::new(g, [0.0; 7])
                    .map_err(|e| err(&s.span(), format!("[contact] `stiffness`: {e}")))?;
                g
            }
        };
        Ok(gains)
    }

    /// The force loop's gains: kp, ki, damping.
    fn force_gains(
        &self,
        err: &dyn Fn(&Range<usize>, String) -> InputError,
    ) -> Result<(f64, f64, f64), InputError> {
        let force_gains = match &self.force_gains {
            None => (0.2, 5.0, 30.0),
            Some(f) => {
                let [kp, ki, d] = *f.get_ref();
                let ok = |v: f64, hi: f64| v.is_finite() && (0.0..=hi).contains(&v);
                if !(ok(kp, 2.0) && ok(ki, 50.0) && ok(d, 200.0)) {
                    return Err(err(
                        &f.span(),
                        format!(
                            "[contact] `force_gains` = [kp, ki, damping] must lie in [0, 2], [0, 50] /s and [0, 200] N s/m (got {:?})",
                            f.get_ref()
                        ),
                    ));
                }
                (kp, ki, d)
            }
        };
        Ok(force_gains)
    }

    /// The force profile, from a demonstration file (relative to `dir`) or way points,
    /// and where it came from.
    fn primitive(
        &self,
        dir: &Path,
        err: &dyn Fn(&Range<usize>, String) -> InputError,
    ) -> Result<(ForcePrimitive, String), InputError> {
        let (primitive, profile) = match (&self.demonstration, self.waypoints.first()) {
            (Some(d), Some(_)) => {
                return Err(err(
                    &d.span(),
                    "[contact] give either `demonstration` (a profile file) or [[contact.waypoints]], not both".into(),
                ));
            }
            (None, None) => {
                return Err(err(
                    &self.above.span(),
                    "[contact] needs the force profile: [[contact.waypoints]] (t, offset, force) or `demonstration` = a CSV file (t, dx, dy, dz, force)".into(),
                ));
            }
            (Some(d), None) => {
                let path = dir.join(d.get_ref());
                let (times, rows) = read_profile(&path)
                    .map_err(|m| err(&d.span(), format!("[contact] `demonstration`: {m}")))?;
                let p = ForcePrimitive::imitate(times, &rows)
                    .map_err(|e| err(&d.span(), format!("[contact] `demonstration`: {e}")))?;
                (p, path.display().to_string())
            }
            (None, Some(_)) => {
                let points: Vec<ContactWaypoint> = self
                    .waypoints
                    .iter()
                    .map(|w| {
                        let w = w.get_ref();
                        ContactWaypoint {
                            t: w.t,
                            offset: w.offset,
                            force: w.force,
                        }
                    })
                    .collect();
                let p = ForcePrimitive::from_waypoints(&points).map_err(|e| {
                    // The message names the way point's index: point at it.
                    let msg = e.to_string();
                    let index = msg
                        .strip_prefix("waypoints[")
                        .and_then(|r| r.split(']').next())
                        .and_then(|i| i.parse::<usize>().ok());
                    let span = index
                        .and_then(|i| self.waypoints.get(i))
                        .map_or(self.waypoints[0].span(), |w| w.span());
                    err(&span, format!("[[contact.waypoints]] {msg}"))
                })?;
                (p, "waypoints".to_string())
            }
        };
        Ok((primitive, profile))
    }
}

impl ContactSpec {
    /// The task's length without contact delays (s): tare, the move above (at 5 cm/s),
    /// settling, the whole search, the profile, release and lift.
    pub fn nominal_seconds(&self) -> f64 {
        let p = &self.plan;
        0.3 + 2.0 + 0.3 + p.search / p.speed + p.primitive.duration() + 0.3 + 1.3
    }

    /// What `cps-cli check` says of it.
    pub fn describe(&self, robot: Option<String>) -> Vec<String> {
        let p = &self.plan;
        let mut lines = vec![
            format!(
                "touches: from {:?} m along {:?}, searching {} m at {} m/s for {} N; then the profile ({}, {:.1} s, up to {:.1} N) with the phase slowed by the force error; ceiling {} N",
                p.above,
                p.direction,
                p.search,
                p.speed,
                p.detect,
                self.profile,
                p.primitive.duration(),
                p.primitive.peak_force(),
                p.ceiling
            ),
            format!(
                "control: Cartesian impedance {} N/m, {} N m/rad; force loop kp {}, ki {} /s, damping {} N s/m; torques measured {}",
                p.gains.translation[0],
                p.gains.rotation[0],
                p.force_gains.0,
                p.force_gains.1,
                p.force_gains.2,
                match self.drive {
                    Drive::Rigid => "after the gears (a Franka)",
                    Drive::FrankySim => "before the joints' friction (franky-sim)",
                }
            ),
        ];
        if let Some(r) = robot {
            lines.push(format!("robot: {r} in torque mode"));
        }
        lines
    }
}

/// A force profile file: a header naming `t, dx, dy, dz, force` (in any order, other
/// columns ignored), then numbers; at most 10⁶ rows.
fn read_profile(path: &Path) -> Result<(Vec<f64>, Vec<Vec<f64>>), String> {
    let text = cps_outcome::source::read_text(path, 64 << 20, "force profile").map_err(|e| e.0)?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, header) = lines
        .next()
        .ok_or_else(|| format!("{} is empty", path.display()))?;
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let mut at = [0usize; 5];
    for (k, want) in ["t", "dx", "dy", "dz", "force"].iter().enumerate() {
        at[k] = names.iter().position(|n| n == want).ok_or_else(|| {
            format!(
                "{}: the header has no `{want}` column (it needs t, dx, dy, dz, force)",
                path.display()
            )
        })?;
    }
    let (mut times, mut rows) = (Vec::new(), Vec::new());
    for (i, line) in lines {
        if times.len() >= 1_000_000 {
            return Err(format!("{}: more than 10^6 rows", path.display()));
        }
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let value = |k: usize| -> Result<f64, String> {
            cells
                .get(at[k])
                .and_then(|c| c.parse::<f64>().ok())
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    format!(
                        "{}:{}: column {} is not a finite number",
                        path.display(),
                        i + 1,
                        at[k] + 1
                    )
                })
        };
        times.push(value(0)?);
        rows.push(vec![value(1)?, value(2)?, value(3)?, value(4)?]);
    }
    Ok((times, rows))
}
