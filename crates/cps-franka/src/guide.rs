//! Teaching by guiding: the arm floats (the robot compensates gravity, cps adds light
//! damping) so that a person can move it by hand, while every state is recorded at the
//! robot's rate — a demonstration to imitate.
//!
//! The law is `τ = −D·q̇ + τ_wall`, with `τ_wall` a spring pushing a joint back from the
//! last `margin` before either end of its range (so a hand cannot drive it into the
//! robot's own limit), all through [`crate::run_torques`]: torques and their rate limited,
//! a joint driven past 90 % of its speed limit or Ctrl-C bringing the arm to a damped
//! rest.

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use crate::limits::RateLimits;
use crate::wire::JOINTS;
use crate::{Connection, FrankaError, LoopOptions, MotionReport, Torques, run_torques};

/// Settings of a guided demonstration.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Guiding {
    /// Damping per joint (N m s/rad, 0 to 20): light enough to move by hand, enough that
    /// the arm does not drift.
    pub damping: [f64; JOINTS],
    /// How near either end of its range a joint is pushed back (rad, 0.05 to 0.5).
    pub margin: f64,
    /// The push's stiffness (N m/rad per radian inside the margin, 0 to 200).
    pub wall: f64,
    /// How long to record (s, up to 3600); Ctrl-C ends it earlier.
    pub duration: f64,
}

impl Default for Guiding {
    fn default() -> Self {
        Guiding {
            damping: [3.0, 3.0, 3.0, 3.0, 1.0, 1.0, 0.5],
            margin: 0.15,
            wall: 50.0,
            duration: 30.0,
        }
    }
}

impl Guiding {
    /// Checks every setting; the sentence names the one out of range.
    pub fn check(&self) -> Result<(), FrankaError> {
        let within = |what: String, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err(FrankaError::Input(format!(
                    "guiding: {what} {v} is out of range: it must lie in [{lo}, {hi}]"
                )))
            }
        };
        for (i, d) in self.damping.iter().enumerate() {
            within(
                format!("joint {} damping (N m s/rad)", i + 1),
                *d,
                0.0,
                20.0,
            )?;
        }
        within("margin (rad)".into(), self.margin, 0.05, 0.5)?;
        within("wall stiffness (N m/rad)".into(), self.wall, 0.0, 200.0)?;
        within("duration (s)".into(), self.duration, 0.001, 3600.0)
    }
}

/// The guiding torque of joint `i` at `q`, `dq`.
fn torque(g: &Guiding, limits: &RateLimits, i: usize, q: f64, dq: f64) -> f64 {
    let (lo, hi) = (limits.q_min[i] + g.margin, limits.q_max[i] - g.margin);
    let wall = if q > hi {
        -g.wall * (q - hi)
    } else if q < lo {
        g.wall * (lo - q)
    } else {
        0.0
    };
    wall - g.damping[i] * dq
}

/// Floats the arm for `guiding.duration` seconds (or until `stop`) and records it: the
/// [`MotionReport`]'s samples are the demonstration (the columns of `franka execute
/// --record`). Refuses settings out of range before anything moves.
pub fn run_guiding(
    conn: &mut Connection,
    limits: RateLimits,
    options: &LoopOptions,
    stop: &AtomicBool,
    guiding: &Guiding,
) -> Result<MotionReport, FrankaError> {
    guiding.check()?;
    let ticks = (guiding.duration * 1000.0).ceil() as usize + crate::rt::BRAKE_RESERVE + 1;
    let options = LoopOptions {
        max_ticks: options.max_ticks.max(ticks),
        state_timeout: options.state_timeout.max(Duration::from_millis(1)),
        ..*options
    };
    let g = *guiding;
    run_torques(conn, limits, &options, stop, move |state, t| {
        let mut tau = [0.0; JOINTS];
        for (i, x) in tau.iter_mut().enumerate() {
            *x = torque(&g, &limits, i, state.q[i], state.dq[i]);
        }
        Torques {
            tau,
            finished: t >= g.duration,
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::limits::Arm;

    #[test]
    fn damps_and_pushes_back_from_the_range_s_ends() {
        let g = Guiding::default();
        let l = RateLimits::of(Arm::Fr3);
        assert_eq!(torque(&g, &l, 0, 0.0, 0.5), -1.5);
        // 0.05 rad inside the margin at the upper end: pushed down by 50 × 0.05.
        let q = l.q_max[0] - g.margin + 0.05;
        assert!((torque(&g, &l, 0, q, 0.0) + 2.5).abs() < 1e-12);
        let q = l.q_min[3] + g.margin - 0.1;
        assert!((torque(&g, &l, 3, q, 0.0) - 5.0).abs() < 1e-12);
    }

    #[test]
    fn settings_out_of_range_are_named() {
        let mut g = Guiding::default();
        g.damping[6] = 50.0;
        assert_eq!(
            g.check().unwrap_err().to_string(),
            "guiding: joint 7 damping (N m s/rad) 50 is out of range: it must lie in [0, 20]"
        );
        let g = Guiding {
            duration: f64::INFINITY,
            ..Default::default()
        };
        assert!(
            g.check()
                .unwrap_err()
                .to_string()
                .contains("duration (s) inf")
        );
    }
}
