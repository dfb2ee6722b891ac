//! Retiming a joint path: the fastest timing that keeps every joint limit, and the
//! smallest uniform slowing of a given timing that does.
//!
//! # The fastest timing ([`retime`])
//! The path is the natural [`JointSpline`] through the given samples parametrised by
//! their chord length in joint space, `s` (samples closer than 10⁻⁷ of the path's length to
//! the previous one are dropped): its tangent never vanishes, so a path that starts or ends
//! at rest has no singular ends. A timing is a law `s(t)`; the joint motion is then
//! `q̇ = q'ṡ`, `q̈ = q''ṡ² + q's̈`, `q⃛ = q'''ṡ³ + 3q''ṡs̈ + q's⃛` (primes are `d/ds`).
//!
//! 1. **TOPP-RA** (H. Pham, Q.-C. Pham, "A New Approach to Time-Optimal Path
//!    Parameterization Based on Reachability Analysis", IEEE T-RO 34(3), 2018): on a grid
//!    `s_0 … s_N` the squared path speed `x = ṡ²` and the path acceleration `u = s̈`
//!    (constant on each interval, so `x_{i+1} = x_i + 2Δu_i`) meet, at every grid point,
//!    the velocity limits (`|q'|√x ≤ v`), the acceleration limits (`|q''x + q'u| ≤ a`) and,
//!    with link inertias, the torque limits (`|A(s)u + B(s)x + g(s)| ≤ τ`, where
//!    `A = M q'`, `B = M q'' + C(q, q')q'` and `g` come from three inverse-dynamics calls).
//!    Each interval holds the constraints of both its ends (the paper's first-order
//!    interpolation scheme). A backward pass computes the controllable sets (the `x` from which the end at rest
//!    stays reachable) by two-variable linear programs, solved exactly by eliminating `u`
//!    (Fourier–Motzkin: each pair of an upper and a lower bound on `u` is one bound on
//!    `x`); a forward pass from rest takes the largest `u` that stays controllable.
//! 2. **Jerk at the control rate**: the TOPP-RA law has piecewise-constant `s̈`, so joint
//!    accelerations jump. The law is passed through a moving average of width `w`
//!    (`s_w(t) = (1/w)∫_{t−w}^{t} s`), which makes `s̈` continuous and `s⃛` bounded by
//!    `Δs̈/w`, and lengthens the motion by `w`. For a rest-to-rest straight-line motion,
//!    the acceleration-limited optimum filtered with `w = a/j` is the time-optimal
//!    jerk-limited ("S-curve") profile (L. Biagiotti, C. Melchiorri, "FIR filters for
//!    online trajectory planning with time- and frequency-domain specifications", Control
//!    Engineering Practice 20(12), 2012); `w` starts at the largest `a/j` of the joints.
//! 3. **Verification**: the result is sampled at the control rate and checked as a
//!    controller sees it ([`crate::check_commands`]), and its exact velocities,
//!    accelerations and jerks are checked ten times finer. Where a limit is exceeded (the
//!    grid, the filter or the torque rate, which TOPP-RA does not model), the limits given
//!    to TOPP-RA are tightened by the excess (velocity, acceleration, torque) or `w` is
//!    widened (jerk, torque rate), and the law is computed again, at most
//!    [`MAX_ROUNDS`] times.
//!
//! # Uniform slowing ([`uniform`])
//! A timing from a DMP is kept and stretched by one factor `k` (the DMP's τ times `k`):
//! the smallest `k` whose stretched trajectory passes the same check, by bisection.

use nalgebra::Vector3;

use crate::spline::{Ends, JointSpline, PathPoint};
use crate::{CommandCheck, KinematicsError, LimitCheck, Quantity, SerialChain, check_commands};

/// Rounds of tightening before [`retime`] gives up.
pub const MAX_ROUNDS: usize = 40;

/// The fraction of the velocity, acceleration and torque limits the first round uses (see
/// [`retime`]'s loop).
const START_FRACTION: f64 = 0.998;

pub use crate::limits::RobotLimits;

/// Settings of [`retime`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RetimeOptions {
    /// Control rate (Hz): the output's sampling and the rate of the check.
    pub rate: f64,
    /// TOPP-RA grid intervals (0: as many as the path has samples, at least 1000, at
    /// most 20 000).
    pub grid: usize,
}

impl Default for RetimeOptions {
    fn default() -> Self {
        RetimeOptions {
            rate: 1000.0,
            grid: 0,
        }
    }
}

/// A piecewise law `s(t)`: constant path acceleration on each grid interval.
#[derive(Debug, Clone)]
struct TimeLaw {
    /// Time at each grid point (the first is 0).
    t: Vec<f64>,
    /// Path parameter at each grid point.
    s: Vec<f64>,
    /// Path speed at each grid point.
    v: Vec<f64>,
    /// Path acceleration on each interval (one fewer).
    u: Vec<f64>,
    /// ∫ s dt from the start to each grid point.
    integral: Vec<f64>,
}

/// `(s, ṡ, s̈, ∫s)` of a law at one time.
type LawState = (f64, f64, f64, f64);

impl TimeLaw {
    fn duration(&self) -> f64 {
        self.t[self.t.len() - 1]
    }

    /// The state at `t`, at rest at the first point before the start and at the last after
    /// the end; for times visited in increasing order the interval is searched from `hint`
    /// (the previous call's; `usize::MAX` at first) onwards.
    fn at_after(&self, t: f64, hint: &mut usize) -> LawState {
        let n = self.t.len() - 1;
        if t <= 0.0 {
            return (self.s[0], 0.0, 0.0, self.s[0] * t);
        }
        if t >= self.t[n] {
            return (
                self.s[n],
                0.0,
                0.0,
                self.integral[n] + self.s[n] * (t - self.t[n]),
            );
        }
        if *hint >= n || self.t[*hint] > t {
            *hint = (self.t.partition_point(|&x| x <= t) - 1).min(n - 1);
        }
        while *hint < n - 1 && self.t[*hint + 1] <= t {
            *hint += 1;
        }
        let k = *hint;
        let (tau, s, v, u) = (t - self.t[k], self.s[k], self.v[k], self.u[k]);
        (
            s + v * tau + 0.5 * u * tau * tau,
            v + u * tau,
            u,
            self.integral[k] + s * tau + 0.5 * v * tau * tau + u * tau * tau * tau / 6.0,
        )
    }

    /// `(s, ṡ, s̈, s⃛)` of the law averaged over the window `w` before `t` (`w = 0`: the law
    /// itself, with no jerk).
    fn smoothed(&self, w: f64, t: f64) -> [f64; 4] {
        self.smoothed_after(w, t, &mut [usize::MAX; 2])
    }

    /// [`Self::smoothed`] for times visited in increasing order (`hints` for `t` and
    /// `t − w`, as [`Self::at_after`]).
    fn smoothed_after(&self, w: f64, t: f64, hints: &mut [usize; 2]) -> [f64; 4] {
        let now = self.at_after(t, &mut hints[0]);
        if w <= 0.0 {
            return [now.0, now.1, now.2, 0.0];
        }
        let before = self.at_after(t - w, &mut hints[1]);
        [
            (now.3 - before.3) / w,
            (now.0 - before.0) / w,
            (now.1 - before.1) / w,
            (now.2 - before.2) / w,
        ]
    }
}

/// A retimed trajectory: the law, its samples at the control rate and their check.
#[derive(Debug, Clone)]
pub struct Retimed {
    path: ArcPath,
    law: TimeLaw,
    /// Width of the moving average that limits jerk (s; 0 without jerk limits).
    pub smoothing: f64,
    /// Duration of the TOPP-RA law before smoothing (s).
    pub topp_duration: f64,
    /// Duration of the result (s): the TOPP-RA law plus the smoothing.
    pub duration: f64,
    /// The fraction of each velocity, acceleration and torque limit given to TOPP-RA in
    /// the last round (0.998 unless verification tightened it further).
    pub tightening: Vec<(Quantity, f64)>,
    /// Rounds computed.
    pub rounds: usize,
    /// Control period (s).
    pub dt: f64,
    /// Positions at `k·dt`, from 0 to the end (the last at the path's end).
    pub q: Vec<Vec<f64>>,
    /// The check of those commands.
    pub check: CommandCheck,
}

impl Retimed {
    /// Positions, velocities, accelerations and jerks at time `t` (s, from the start).
    pub fn at(&self, t: f64) -> [Vec<f64>; 4] {
        joint_state(&self.path.spline, &self.law, self.smoothing, t)
    }

    /// Sample times, `k·dt`.
    pub fn times(&self) -> Vec<f64> {
        (0..self.q.len()).map(|k| k as f64 * self.dt).collect()
    }
}

/// The path through the samples by chord length, and each kept sample's original time.
#[derive(Debug, Clone)]
struct ArcPath {
    spline: JointSpline,
    arc: Vec<f64>,
    times: Vec<f64>,
}

impl ArcPath {
    fn new(times: &[f64], points: &[Vec<f64>]) -> Result<Self, KinematicsError> {
        // The knots' checks (count, order, finiteness) first, on the original clock.
        JointSpline::new(times, points)?;
        let chord = |a: &[f64], b: &[f64]| -> f64 {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y) * (x - y))
                .sum::<f64>()
                .sqrt()
        };
        let length: f64 = points.windows(2).map(|w| chord(&w[0], &w[1])).sum();
        if length.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return Err(KinematicsError::InvalidConfig(
                "the trajectory never moves: there is no path to retime".into(),
            ));
        }
        let (mut arc, mut kept, mut at) = (vec![0.0], vec![points[0].clone()], vec![times[0]]);
        for (k, row) in points.iter().enumerate().skip(1) {
            let c = chord(row, &kept[kept.len() - 1]);
            if c > 1e-7 * length {
                arc.push(arc[arc.len() - 1] + c);
                kept.push(row.clone());
                at.push(times[k]);
            } else if k + 1 == points.len() && kept.len() > 1 {
                // The last sample ends the path: it replaces the kept one it is close to.
                kept.pop();
                arc.pop();
                at.pop();
                let c = chord(row, &kept[kept.len() - 1]);
                arc.push(arc[arc.len() - 1] + c);
                kept.push(row.clone());
                at.push(times[k]);
            }
        }
        Ok(ArcPath {
            spline: JointSpline::with_ends(&arc, &kept, Ends::Natural)?,
            arc,
            times: at,
        })
    }

    /// The original time of arc length `s` (linear between the kept samples).
    fn time_at(&self, s: f64) -> f64 {
        let k = self
            .arc
            .partition_point(|&a| a <= s)
            .clamp(1, self.arc.len() - 1);
        let (a0, a1) = (self.arc[k - 1], self.arc[k]);
        let f = ((s - a0) / (a1 - a0)).clamp(0.0, 1.0);
        self.times[k - 1] + f * (self.times[k] - self.times[k - 1])
    }
}

/// The joint state on `path` under `law` smoothed over `w`, at `t`.
fn joint_state(path: &JointSpline, law: &TimeLaw, w: f64, t: f64) -> [Vec<f64>; 4] {
    let n = path.dof();
    let mut p = PathPoint {
        q: vec![0.0; n],
        d1: vec![0.0; n],
        d2: vec![0.0; n],
        d3: vec![0.0; n],
    };
    let mut out = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
    joint_state_into(path, law, w, t, &mut p, &mut out, &mut [usize::MAX; 3]);
    let [v, a, j] = out;
    [p.q, v, a, j]
}

/// [`joint_state`] into reused buffers, for times visited in increasing order: the path
/// point in `p` (positions in `p.q`), and velocities, accelerations and jerks in `out`;
/// `hints` remember where the law and the path were last evaluated.
fn joint_state_into(
    path: &JointSpline,
    law: &TimeLaw,
    w: f64,
    t: f64,
    p: &mut PathPoint,
    out: &mut [Vec<f64>; 3],
    hints: &mut [usize; 3],
) {
    let mut law_hints = [hints[0], hints[1]];
    let [s, sd, sdd, sddd] = law.smoothed_after(w, t, &mut law_hints);
    [hints[0], hints[1]] = law_hints;
    path.point_after(s, p, &mut hints[2]);
    let [v, a, j] = out;
    for i in 0..p.q.len() {
        v[i] = p.d1[i] * sd;
        a[i] = p.d2[i] * sd * sd + p.d1[i] * sdd;
        j[i] = p.d3[i] * sd * sd * sd + 3.0 * p.d2[i] * sd * sdd + p.d1[i] * sddd;
    }
}

/// One inequality `a·u + b·x ≤ d` on the path acceleration `u` and squared speed `x`.
#[derive(Debug, Clone, Copy)]
struct Row {
    a: f64,
    b: f64,
    d: f64,
}

/// The constraints of one grid point: rows, and the largest `x` the velocity limits allow.
#[derive(Debug, Clone, Default)]
struct GridPoint {
    rows: Vec<Row>,
    x_max: f64,
}

/// The interval of `x ≥ 0` for which some `u` satisfies every row, or `None`.
fn x_range(rows: &[Row], x_max: f64) -> Option<(f64, f64)> {
    let (mut lo, mut hi) = (0.0_f64, x_max);
    let mut bound = |c: f64, rhs: f64| {
        // c·x ≤ rhs
        if c > 0.0 {
            hi = hi.min(rhs / c);
        } else if c < 0.0 {
            lo = lo.max(rhs / c);
        } else if rhs < -1e-12 {
            hi = f64::NEG_INFINITY;
        }
    };
    for r in rows.iter().filter(|r| r.a == 0.0) {
        bound(r.b, r.d);
    }
    for p in rows.iter().filter(|r| r.a > 0.0) {
        for n in rows.iter().filter(|r| r.a < 0.0) {
            // u ≤ (d_p − b_p x)/a_p and u ≥ (d_n − b_n x)/a_n need
            // (b_n a_p − b_p a_n) x ≤ d_n a_p − d_p a_n.
            bound(n.b * p.a - p.b * n.a, n.d * p.a - p.d * n.a);
        }
    }
    let tol = 1e-9 * (1.0 + hi.abs().min(1e12));
    (lo <= hi + tol).then_some((lo, hi.max(lo)))
}

/// The interval of `u` the rows allow at a given `x`.
fn u_range(rows: &[Row], x: f64) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for r in rows {
        let rhs = r.d - r.b * x;
        if r.a > 0.0 {
            hi = hi.min(rhs / r.a);
        } else if r.a < 0.0 {
            lo = lo.max(rhs / r.a);
        }
    }
    (lo, hi)
}

/// Per quantity, the fraction of its limit TOPP-RA may use.
#[derive(Debug, Clone, Copy)]
struct Fractions {
    velocity: f64,
    acceleration: f64,
    torque: f64,
    /// Of the Cartesian acceleration limits, applied to each axis of the tool's
    /// translation and rotation (starting at 1, which allows up to √3 times the limit along
    /// a diagonal; verification tightens it to what the norm needs).
    translation_acceleration: f64,
    rotation_acceleration: f64,
}

/// The tool's path derivatives at `s`: translation and rotation per unit `s` (`J q'`) and
/// their derivatives along the path (central differences over `h`).
fn tool_derivatives(
    chain: &SerialChain,
    path: &JointSpline,
    s: f64,
    h: f64,
) -> Result<[Vector3<f64>; 4], KinematicsError> {
    let velocity = |s: f64| -> Result<[Vector3<f64>; 2], KinematicsError> {
        let p = path.point(s);
        let j = chain.jacobian(&p.q)?;
        let d = nalgebra::DVector::from_column_slice(&p.d1);
        let v = j * d;
        Ok([
            Vector3::new(v[0], v[1], v[2]),
            Vector3::new(v[3], v[4], v[5]),
        ])
    };
    let [p1, r1] = velocity(s)?;
    let [pa, ra] = velocity(s - h)?;
    let [pb, rb] = velocity(s + h)?;
    Ok([p1, (pb - pa) / (2.0 * h), r1, (rb - ra) / (2.0 * h)])
}

/// The path's grid and each grid point's constraints (without the controllable sets).
fn grid_constraints(
    robot: &RobotLimits,
    path: &ArcPath,
    grid: &[f64],
    f: Fractions,
) -> Result<Vec<GridPoint>, KinematicsError> {
    let n = robot.chain.dof();
    let velocity = robot.chain.velocity_limits();
    let torque = robot.limits.torque.as_deref().zip(robot.inertia);
    let zero = vec![0.0; n];
    grid.iter()
        .map(|&s| {
            let p = path.spline.point(s);
            let time = path.time_at(s);
            if let Err(KinematicsError::OutsideLimits {
                joint,
                value,
                lower,
                upper,
            }) = robot.chain.check_within_limits(&p.q)
            {
                return Err(KinematicsError::Infeasible {
                    time,
                    reason: format!(
                        "joint {joint} is at {value:.6} rad, outside its range [{lower}, {upper}]; retiming changes when the path is followed, not where it goes"
                    ),
                });
            }
            let mut point = GridPoint {
                rows: Vec::with_capacity(4 * n),
                x_max: f64::INFINITY,
            };
            if let Some(v) = velocity {
                for (v, d1) in v.iter().zip(&p.d1) {
                    if *d1 != 0.0 {
                        point.x_max = point.x_max.min((f.velocity * v / d1.abs()).powi(2));
                    }
                }
            }
            if let Some(acc) = &robot.limits.acceleration {
                for ((acc, d1), d2) in acc.iter().zip(&p.d1).zip(&p.d2) {
                    let m = f.acceleration * acc;
                    point.rows.push(Row { a: *d1, b: *d2, d: m });
                    point.rows.push(Row { a: -d1, b: -d2, d: m });
                }
            }
            if let Some(c) = robot.cartesian {
                let h = 1e-4 * (grid[grid.len() - 1] - grid[0]) / grid.len() as f64;
                let [dp, ddp, dr, ddr] = tool_derivatives(robot.chain, &path.spline, s, h)?;
                for (d1, d2, v, a, fa) in [
                    (dp, ddp, c.translation[0], c.translation[1], f.translation_acceleration),
                    (dr, ddr, c.rotation[0], c.rotation[1], f.rotation_acceleration),
                ] {
                    if d1.norm() > 0.0 {
                        point.x_max = point.x_max.min((f.velocity * v / d1.norm()).powi(2));
                    }
                    for k in 0..3 {
                        point.rows.push(Row { a: d1[k], b: d2[k], d: fa * a });
                        point.rows.push(Row { a: -d1[k], b: -d2[k], d: fa * a });
                    }
                }
            }
            if let Some((tau, links)) = torque {
                let g = robot.gravity;
                let c = robot.chain.inverse_dynamics(links, g, &p.q, &zero, &zero)?;
                let a = robot.chain.inverse_dynamics(links, Vector3::zeros(), &p.q, &zero, &p.d1)?;
                let b = robot.chain.inverse_dynamics(links, Vector3::zeros(), &p.q, &p.d1, &p.d2)?;
                for j in 0..n {
                    if c[j].abs() >= tau[j] {
                        return Err(KinematicsError::Infeasible {
                            time,
                            reason: format!(
                                "joint {} needs {:.3} N m to hold the arm against gravity at rest, beyond its {} N m torque limit",
                                j + 1,
                                c[j],
                                tau[j]
                            ),
                        });
                    }
                    // Tighten only the part of the limit left after gravity.
                    let m = c[j].abs() + f.torque * (tau[j] - c[j].abs());
                    point.rows.push(Row { a: a[j], b: b[j], d: m - c[j] });
                    point.rows.push(Row { a: -a[j], b: -b[j], d: m + c[j] });
                }
            }
            Ok(point)
        })
        .collect()
}

/// The rows of interval `i` (length `delta`): grid point `i`'s constraints at its start,
/// grid point `i + 1`'s at its end (where `x_{i+1} = x + 2Δu`: TOPP-RA's first-order
/// interpolation scheme, which also holds the constraints between the two), and the end in
/// `next`, the controllable set of point `i + 1`.
fn interval_rows(
    rows: &mut Vec<Row>,
    points: &[GridPoint],
    i: usize,
    delta: f64,
    next: (f64, f64),
) {
    rows.clear();
    rows.extend_from_slice(&points[i].rows);
    rows.extend(points[i + 1].rows.iter().map(|r| Row {
        a: r.a + 2.0 * delta * r.b,
        b: r.b,
        d: r.d,
    }));
    rows.push(Row {
        a: 2.0 * delta,
        b: 1.0,
        d: next.1,
    });
    rows.push(Row {
        a: -2.0 * delta,
        b: -1.0,
        d: -next.0,
    });
}

/// TOPP-RA on the grid: the time-optimal law from rest to rest.
fn topp_ra(path: &ArcPath, grid: &[f64], points: &[GridPoint]) -> Result<TimeLaw, KinematicsError> {
    let n = grid.len() - 1;
    let delta: Vec<f64> = grid.windows(2).map(|w| w[1] - w[0]).collect();
    // Backward: controllable sets, ending at rest.
    let mut sets = vec![(0.0, 0.0); n + 1];
    let mut rows = Vec::new();
    for i in (0..n).rev() {
        let (lo, hi) = sets[i + 1];
        interval_rows(&mut rows, points, i, delta[i], (lo, hi));
        sets[i] = x_range(&rows, points[i].x_max).ok_or_else(|| KinematicsError::Infeasible {
            time: path.time_at(grid[i]),
            reason:
                "no path speed there keeps every limit and still lets the robot stop at the end"
                    .into(),
        })?;
    }
    // Forward: from rest, the largest acceleration that stays controllable.
    let mut x = vec![0.0; n + 1];
    let mut u = vec![0.0; n];
    for i in 0..n {
        let (lo, hi) = sets[i + 1];
        interval_rows(&mut rows, points, i, delta[i], (lo, hi));
        let (u_lo, u_hi) = u_range(&rows, x[i]);
        let ui = if u_hi >= u_lo { u_hi } else { u_lo };
        x[i + 1] = (x[i] + 2.0 * delta[i] * ui).clamp(lo, hi).max(0.0);
        if x[i] <= 0.0 && x[i + 1] <= 0.0 && i + 1 < n {
            return Err(KinematicsError::Infeasible {
                time: path.time_at(grid[i]),
                reason: "the robot cannot start moving there without exceeding a limit".into(),
            });
        }
        u[i] = (x[i + 1] - x[i]) / (2.0 * delta[i]);
    }
    let v: Vec<f64> = x.iter().map(|x| x.sqrt()).collect();
    let mut t = vec![0.0; n + 1];
    let mut integral = vec![0.0; n + 1];
    for i in 0..n {
        let dt = 2.0 * delta[i] / (v[i] + v[i + 1]);
        t[i + 1] = t[i] + dt;
        integral[i + 1] =
            integral[i] + grid[i] * dt + 0.5 * v[i] * dt * dt + u[i] * dt * dt * dt / 6.0;
    }
    Ok(TimeLaw {
        t,
        s: grid.to_vec(),
        v,
        u,
        integral,
    })
}

/// The largest usage (percent) of each quantity over the joints, from a check and from
/// a finer look at the law's exact derivatives.
fn worst_usage(check: &LimitCheck, fine: &[(Quantity, f64)]) -> Vec<(Quantity, f64)> {
    let mut out: Vec<(Quantity, f64)> = check
        .peak_usage
        .iter()
        .map(|(q, u)| (*q, u.iter().copied().fold(0.0, f64::max)))
        .collect();
    for (q, u) in fine {
        match out.iter_mut().find(|(k, _)| k == q) {
            Some(entry) => entry.1 = entry.1.max(*u),
            None => out.push((*q, *u)),
        }
    }
    out
}

/// The fastest timing of the path through `points` (one row of joint positions per
/// sample at the strictly increasing `times`) that keeps `robot`'s limits, from rest to
/// rest; see the module documentation for the method.
///
/// # Errors
/// [`KinematicsError::Infeasible`] when a point of the path leaves the joint range or
/// needs more torque at rest than allowed, and when the rounds of tightening run out;
/// [`KinematicsError::InvalidModel`] for bad samples or options.
pub fn retime(
    robot: &RobotLimits,
    times: &[f64],
    points: &[Vec<f64>],
    options: &RetimeOptions,
) -> Result<Retimed, KinematicsError> {
    let n = robot.chain.dof();
    robot.limits.validate(n)?;
    if !(options.rate.is_finite() && options.rate > 0.0) {
        return Err(KinematicsError::InvalidConfig(format!(
            "the control rate must be finite and > 0 Hz (got {})",
            options.rate
        )));
    }
    if let Some(row) = points.iter().find(|r| r.len() != n) {
        return Err(KinematicsError::JointCount {
            expected: n,
            got: row.len(),
        });
    }
    let path = ArcPath::new(times, points)?;
    if robot.chain.velocity_limits().is_none() && robot.limits.acceleration.is_none() {
        return Err(KinematicsError::InvalidConfig(
            "retiming needs velocity or acceleration limits, and the robot has neither".into(),
        ));
    }
    let (s0, s1) = path.spline.span();
    let intervals = match options.grid {
        0 => times.len().clamp(1000, 20_000),
        g => g,
    };
    let grid: Vec<f64> = (0..=intervals)
        .map(|i| s0 + (s1 - s0) * i as f64 / intervals as f64)
        .collect();
    let dt = 1.0 / options.rate;
    let jerk = robot.limits.jerk.as_deref();
    let mut w = match (jerk, robot.limits.acceleration.as_deref()) {
        (Some(j), Some(a)) => a.iter().zip(j).map(|(a, j)| a / j).fold(dt, f64::max),
        (Some(_), None) => 2.0 * dt,
        _ => 0.0,
    };
    if robot.limits.torque_rate.is_some() && robot.inertia.is_some() {
        w = w.max(2.0 * dt);
    }
    // A margin of 0.2 % from the start: TOPP-RA holds the limits at the grid points;
    // between them (the path's derivatives vary within an interval) the motion can exceed
    // them by up to about 0.1 % on a 1000-interval grid, and without the margin nearly
    // every path would need a second round.
    let mut f = Fractions {
        velocity: START_FRACTION,
        acceleration: START_FRACTION,
        torque: START_FRACTION,
        translation_acceleration: 1.0,
        rotation_acceleration: 1.0,
    };
    let mut last = String::new();
    for round in 1..=MAX_ROUNDS {
        let constraints = grid_constraints(robot, &path, &grid, f)?;
        let law = topp_ra(&path, &grid, &constraints)?;
        let duration = law.duration() + w;
        let steps = (duration / dt - 1e-9).ceil().max(1.0) as usize;
        let q: Vec<Vec<f64>> = (0..=steps)
            .map(|k| {
                let s = law.smoothed(w, (k as f64 * dt).min(duration))[0];
                path.spline.positions(s)
            })
            .collect();
        let check = check_commands(robot, 0.0, dt, &q)?;
        let fine = fine_usage(robot, &path, &law, w, dt, steps, grid[0]);
        // Quantities over their limit, with the ratio: beyond a tolerance of 10⁻⁹ in the
        // exact derivatives, or violated in the commands' check at all.
        let over: Vec<(Quantity, f64)> = worst_usage(&check.joints, &fine)
            .into_iter()
            .filter_map(|(q, u)| {
                let violated = check.joints.violations.iter().any(|v| v.quantity == q);
                (violated || u > 100.0 * (1.0 + 1e-9)).then_some((q, (u / 100.0).max(1.0 + 1e-9)))
            })
            .collect();
        let cartesian_over: Vec<(&str, f64)> = check.cartesian.as_ref().map_or(Vec::new(), |c| {
            c.peak_usage
                .iter()
                .filter(|(name, u)| *u > 100.0 || c.violations.iter().any(|v| v.quantity == *name))
                .map(|(name, u)| (*name, (u / 100.0).max(1.0 + 1e-9)))
                .collect()
        });
        if over.is_empty() && cartesian_over.is_empty() {
            return Ok(Retimed {
                path,
                smoothing: w,
                topp_duration: law.duration(),
                duration,
                law,
                tightening: vec![
                    (Quantity::Velocity, f.velocity),
                    (Quantity::Acceleration, f.acceleration),
                    (Quantity::Torque, f.torque),
                ],
                rounds: round,
                dt,
                q,
                check,
            });
        }
        last = over
            .iter()
            .map(|(q, r)| (q.name(), *r))
            .chain(cartesian_over.iter().copied())
            .map(|(q, r)| format!("{q} at {:.1} %", 100.0 * r))
            .collect::<Vec<_>>()
            .join(", ");
        tighten(&mut f, &mut w, over, cartesian_over, dt, duration);
    }
    Err(KinematicsError::Infeasible {
        time: times[0],
        reason: format!(
            "after {MAX_ROUNDS} rounds of tightening the timing still exceeds limits ({last})"
        ),
    })
}

/// Per quantity (velocity, acceleration, jerk), the largest share of its limit (%) the
/// joints' exact derivatives reach, sampled ten times finer than the commands of period
/// `dt` (`steps` of them); no limit: 0, never over.
fn fine_usage(
    robot: &RobotLimits,
    path: &ArcPath,
    law: &TimeLaw,
    w: f64,
    dt: f64,
    steps: usize,
    s0: f64,
) -> [(Quantity, f64); 3] {
    let n = robot.chain.dof();
    let velocity = robot.chain.velocity_limits();
    let jerk = robot.limits.jerk.as_deref();
    let mut fine = [
        (Quantity::Velocity, 0.0_f64),
        (Quantity::Acceleration, 0.0),
        (Quantity::Jerk, 0.0),
    ];
    let mut point = path.spline.point(s0);
    let mut state = [vec![0.0; n], vec![0.0; n], vec![0.0; n]];
    let mut worst = [[0.0_f64; 3]; 1].repeat(n);
    let mut hints = [usize::MAX; 3];
    for k in 0..=10 * steps {
        let t = k as f64 * dt / 10.0;
        joint_state_into(&path.spline, law, w, t, &mut point, &mut state, &mut hints);
        for (i, m) in worst.iter_mut().enumerate() {
            for (q, x) in m.iter_mut().zip(&state) {
                *q = q.max(x[i].abs());
            }
        }
    }
    for (i, m) in worst.iter().enumerate() {
        for (k, limit) in [velocity, robot.limits.acceleration.as_deref(), jerk]
            .iter()
            .enumerate()
        {
            if let Some(l) = limit {
                fine[k].1 = fine[k].1.max(100.0 * m[k] / l[i]);
            }
        }
    }
    fine
}

/// The next round's fractions `f` and smoothing `w` from the quantities `over` their
/// limit and the Cartesian ones, each with its ratio to the limit (`duration`: this
/// round's).
fn tighten(
    f: &mut Fractions,
    w: &mut f64,
    over: Vec<(Quantity, f64)>,
    cartesian_over: Vec<(&str, f64)>,
    dt: f64,
    duration: f64,
) {
    // Cartesian excess acts on the knob that governs it.
    let mut over = over;
    for (name, ratio) in cartesian_over {
        match name {
            "translation_acceleration" => f.translation_acceleration *= 0.999 / ratio,
            "rotation_acceleration" => f.rotation_acceleration *= 0.999 / ratio,
            n if n.ends_with("_velocity") => over.push((Quantity::Velocity, ratio)),
            "elbow_acceleration" => over.push((Quantity::Acceleration, ratio)),
            _ => over.push((Quantity::Jerk, ratio)),
        }
    }
    for (quantity, ratio) in over {
        // Tighten a little beyond the excess so that rounds converge.
        let shrink = 0.999 / ratio;
        match quantity {
            Quantity::Velocity => f.velocity *= shrink,
            Quantity::Acceleration => f.acceleration *= shrink,
            Quantity::Torque => f.torque *= shrink,
            Quantity::Jerk | Quantity::TorqueRate => {
                // Widen the smoothing, or start it: a robot whose jerk limits are
                // Cartesian only begins without one.
                *w = (*w * ratio.max(1.05)).max(2.0 * dt);
                // Beyond a tenth of the motion, the path's own jerk is the cause:
                // slow the motion itself.
                if *w > 0.1 * duration {
                    f.velocity *= ratio.cbrt().recip();
                    f.acceleration *= ratio.cbrt().powi(2).recip();
                }
            }
            Quantity::Position => {}
        }
    }
}

/// The outcome of [`uniform`].
#[derive(Debug, Clone)]
pub struct UniformSlowing {
    /// The smallest stretch factor that keeps every limit (below 1: the trajectory may be
    /// sped up).
    pub factor: f64,
    /// The stretched trajectory's duration (s).
    pub duration: f64,
    /// Control period (s).
    pub dt: f64,
    /// Positions of the stretched trajectory at `k·dt` from its start.
    pub q: Vec<Vec<f64>>,
    /// Their check.
    pub check: CommandCheck,
}

/// The smallest factor `k` (to 0.01 %) by which the trajectory through `points` at
/// `times` can be stretched in time (`q_k(t) = q(t/k)`, a DMP's τ times `k`) so that,
/// sampled at `rate` Hz, it keeps every limit of `robot`.
///
/// # Errors
/// [`KinematicsError::Infeasible`] when even a thousandfold slowing breaks a limit
/// (named: a position out of range or a torque against gravity).
pub fn uniform(
    robot: &RobotLimits,
    times: &[f64],
    points: &[Vec<f64>],
    rate: f64,
) -> Result<UniformSlowing, KinematicsError> {
    if !(rate.is_finite() && rate > 0.0) {
        return Err(KinematicsError::InvalidConfig(format!(
            "the control rate must be finite and > 0 Hz (got {rate})"
        )));
    }
    let path = JointSpline::new(times, points)?;
    let (s0, s1) = path.span();
    let dt = 1.0 / rate;
    // The stretched motion ends on a command: `k` is rounded up to a whole number of
    // control periods, so that the end is not reached within a fraction of one (which
    // would make the check depend on that fraction, not on `k`).
    let attempt = |k: f64| -> Result<UniformSlowing, KinematicsError> {
        let steps = ((s1 - s0) * k / dt - 1e-9).ceil().max(1.0) as usize;
        let duration = steps as f64 * dt;
        let k = duration / (s1 - s0);
        let q: Vec<Vec<f64>> = (0..=steps)
            .map(|i| path.positions(s0 + (i as f64 * dt).min(duration) / k))
            .collect();
        let check = check_commands(robot, 0.0, dt, &q)?;
        Ok(UniformSlowing {
            factor: k,
            duration,
            dt,
            q,
            check,
        })
    };
    let first = attempt(1.0)?;
    let (mut lo, mut hi, mut best) = if first.check.ok() {
        // Faster may do: halve until a limit breaks.
        let mut best = first;
        let mut lo = 0.5;
        loop {
            let r = attempt(lo)?;
            if !r.check.ok() || lo < 1e-3 {
                break;
            }
            best = r;
            lo *= 0.5;
        }
        (lo, best.factor, best)
    } else {
        let mut hi = 2.0;
        loop {
            let r = attempt(hi)?;
            if r.check.ok() {
                break (hi / 2.0, hi, r);
            }
            if hi >= 1000.0 {
                let (time, what) = match (r.check.joints.violations.first(), &r.check.cartesian) {
                    (Some(v), _) => (
                        v.time,
                        format!(
                            "joint {} {} reaches {:.6} {}, beyond its limit {}",
                            v.joint,
                            v.quantity.name(),
                            v.value,
                            v.quantity.unit(),
                            v.limit
                        ),
                    ),
                    (None, Some(c)) => {
                        let v = c.violations[0];
                        (
                            v.time,
                            format!(
                                "the tool's {} reaches {:.6}, beyond its limit {}",
                                v.quantity.replace('_', " "),
                                v.value,
                                v.limit
                            ),
                        )
                    }
                    (None, None) => (0.0, "a limit is exceeded".to_string()),
                };
                return Err(KinematicsError::Infeasible {
                    time: s0 + time / hi,
                    reason: format!("even slowed a thousandfold, {what}"),
                });
            }
            hi *= 2.0;
        }
    };
    while (hi - lo) > 1e-4 * hi {
        let mid = 0.5 * (lo + hi);
        let r = attempt(mid)?;
        if r.check.ok() {
            hi = mid;
            best = r;
        } else {
            lo = mid;
        }
    }
    Ok(best)
}
