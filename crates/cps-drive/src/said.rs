//! What the Franka commands return: typed results, each saying itself as JSON
//! (`Serialize`, what `--json` prints and, for a recording, the report written beside it)
//! and as text (`Display`, a line each). The command line chooses which. (An execution's,
//! `franka::ExecutedTo`, is beside what it says, `franka::Executed`.)

use std::fmt;
use std::path::PathBuf;

use cps_franka::{GripperState, RobotState};
use serde::{Serialize, Serializer};
use serde_json::{Value, json};

/// Seven numbers as `franka` commands print them.
pub(crate) fn fmt7(x: &[f64]) -> String {
    x.iter()
        .map(|v| format!("{v:.4}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// `franka state`: one state of the robot at `host`.
#[derive(Debug, Clone)]
pub struct StateAt {
    /// The robot's address.
    pub host: String,
    /// What it said.
    pub state: RobotState,
}

/// `{"host", "message_id", "q", "dq", "tau_J", "q_d", "O_T_EE", "tool_position",
/// "robot_mode", "errors", "control_command_success_rate"}`.
impl Serialize for StateAt {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let st = &self.state;
        json!({
            "host": self.host,
            "message_id": st.message_id,
            "q": st.q, "dq": st.dq, "tau_J": st.tau_j, "q_d": st.q_d,
            "O_T_EE": st.o_t_ee, "tool_position": st.tool_position(),
            "robot_mode": st.robot_mode.name(),
            "errors": st.errors.names(),
            "control_command_success_rate": st.control_command_success_rate,
        })
        .serialize(s)
    }
}

impl fmt::Display for StateAt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = &self.state;
        let p = s.tool_position();
        let mode = s.robot_mode;
        writeln!(f, "{}: {} ({})", self.host, mode.name(), mode.sentence())?;
        writeln!(f, "  q      [{}] rad", fmt7(&s.q))?;
        writeln!(f, "  dq     [{}] rad/s", fmt7(&s.dq))?;
        writeln!(f, "  tau_J  [{}] N m", fmt7(&s.tau_j))?;
        let (x, y, z) = (p[0], p[1], p[2]);
        writeln!(f, "  tool   ({x:.4}, {y:.4}, {z:.4}) m in the base frame")?;
        write!(f, "  errors {}", s.errors.describe())
    }
}

/// `franka gripper`: the hand's state after the action, and whether a grasp held.
#[derive(Debug, Clone)]
pub struct HandAt {
    /// The robot's address.
    pub host: String,
    /// The hand's state after the action.
    pub state: GripperState,
    /// A grasp's outcome (None for any other action).
    pub grasped: Option<bool>,
}

/// `{"host", "width", "max_width", "is_grasped", "temperature", "grasped"?}`.
impl Serialize for HandAt {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let st = &self.state;
        let mut json = json!({ "host": self.host, "width": st.width, "max_width": st.max_width,
            "is_grasped": st.is_grasped, "temperature": st.temperature });
        if let Some(g) = self.grasped {
            json["grasped"] = json!(g);
        }
        json.serialize(s)
    }
}

impl fmt::Display for HandAt {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.grasped {
            Some(true) => writeln!(f, "grasped")?,
            Some(false) => writeln!(f, "nothing grasped within the tolerances")?,
            None => {}
        }
        let s = &self.state;
        let holding = if s.is_grasped {
            "holding"
        } else {
            "not holding"
        };
        write!(
            f,
            "{} gripper: width {:.4} m of {:.4} m, {holding}, {} °C",
            self.host, s.width, s.max_width, s.temperature
        )
    }
}

/// `franka record` and `franka guide`: a recording written, and its report.
#[derive(Debug, Clone)]
pub struct Recorded {
    /// The robot's address.
    pub host: String,
    /// The recording written.
    pub out: PathBuf,
    /// Its samples.
    pub samples: usize,
    /// Its duration (s).
    pub duration_s: f64,
    /// Taught by guiding (`franka guide`), or recorded standing (`franka record`).
    pub guided: bool,
    /// The report written beside it (`<stem>.report.json`): `{"complete", "ending",
    /// "host", "samples", "duration_s", …}`.
    pub report: Value,
}

/// The report.
impl Serialize for Recorded {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        self.report.serialize(s)
    }
}

impl fmt::Display for Recorded {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ending = self.report["ending"].as_str().unwrap_or_default();
        let (n, d, out) = (self.samples, self.duration_s, self.out.display());
        if self.guided {
            writeln!(f, "{}: guided by hand; {ending}", self.host)?;
            write!(
                f,
                "  {n} samples over {d:.3} s in {out} (imitate it: cps-cli imitate {out} --columns q1,q2,q3,q4,q5,q6,q7 --out model.json)"
            )
        } else {
            writeln!(f, "{}: {ending}", self.host)?;
            write!(f, "  {n} samples over {d:.3} s in {out}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hand(grasped: Option<bool>) -> HandAt {
        HandAt {
            host: "127.0.0.1".into(),
            state: GripperState {
                message_id: 7,
                width: 0.0312,
                max_width: 0.0801,
                is_grasped: grasped == Some(true),
                temperature: 31,
            },
            grasped,
        }
    }

    #[test]
    fn the_hand_says_its_state_and_a_grasps_outcome_in_json_and_in_words() {
        let held = hand(Some(true));
        let json = serde_json::to_value(&held).expect("a JSON value");
        assert_eq!(json["width"], 0.0312);
        assert_eq!(json["grasped"], true);
        assert_eq!(
            held.to_string(),
            "grasped\n127.0.0.1 gripper: width 0.0312 m of 0.0801 m, holding, 31 °C"
        );
        // Only a grasp says whether it held.
        let moved = hand(None);
        let json = serde_json::to_value(&moved).expect("a JSON value");
        assert!(json.get("grasped").is_none(), "{json}");
        assert_eq!(
            moved.to_string(),
            "127.0.0.1 gripper: width 0.0312 m of 0.0801 m, not holding, 31 °C"
        );
    }

    #[test]
    fn a_recording_says_its_report_and_where_it_is() {
        let report =
            json!({"complete": true, "ending": "recorded for the whole duration", "samples": 3});
        let recorded = |guided| Recorded {
            host: "h".into(),
            out: "rec.csv".into(),
            samples: 3,
            duration_s: 0.002,
            guided,
            report: report.clone(),
        };
        let standing = recorded(false);
        assert_eq!(serde_json::to_value(&standing).expect("JSON"), report);
        assert_eq!(
            standing.to_string(),
            "h: recorded for the whole duration\n  3 samples over 0.002 s in rec.csv"
        );
        let taught = recorded(true).to_string();
        assert!(taught.starts_with("h: guided by hand; recorded for the whole duration\n"));
        assert!(taught.ends_with(
            "(imitate it: cps-cli imitate rec.csv --columns q1,q2,q3,q4,q5,q6,q7 --out model.json)"
        ));
    }
}
