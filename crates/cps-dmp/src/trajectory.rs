//! Rolled-out trajectories on the DMP's time grid.

/// Position, velocity and acceleration of every dimension on a uniform time grid.
///
/// All values are in SI units of the task: if positions are metres, velocities are m/s
/// and accelerations m/s². Velocities are the **physical** `ẏ = z / tau` (not the scaled
/// state `z`) and accelerations are `ÿ = ż / tau`. Each quantity is stored one
/// contiguous slice per dimension.
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    dims: usize,
    times: Vec<f64>,
    pub(crate) position: Vec<f64>,
    pub(crate) velocity: Vec<f64>,
    pub(crate) acceleration: Vec<f64>,
    pub(crate) forcing: Vec<f64>,
}

impl Trajectory {
    /// An all-zero trajectory on the given time grid, ready to be filled by a rollout.
    pub fn zeros(dims: usize, times: Vec<f64>) -> Self {
        let n = dims * times.len();
        Self {
            dims,
            times,
            position: vec![0.0; n],
            velocity: vec![0.0; n],
            acceleration: vec![0.0; n],
            forcing: vec![0.0; n],
        }
    }

    /// A trajectory from its samples, one vector per dimension for each quantity (e.g. a
    /// reference that did not come from a DMP); the forcing term is zero.
    ///
    /// # Panics
    /// If the three quantities do not have the same number of dimensions, or a vector's
    /// length differs from the number of time stamps.
    pub fn from_parts(
        times: Vec<f64>,
        position: &[Vec<f64>],
        velocity: &[Vec<f64>],
        acceleration: &[Vec<f64>],
    ) -> Self {
        let dims = position.len();
        assert!(
            velocity.len() == dims && acceleration.len() == dims,
            "one vector per dimension for each quantity"
        );
        let flat = |parts: &[Vec<f64>]| -> Vec<f64> {
            parts
                .iter()
                .flat_map(|p| {
                    assert_eq!(p.len(), times.len(), "one value per time stamp");
                    p.iter().copied()
                })
                .collect()
        };
        Self {
            dims,
            position: flat(position),
            velocity: flat(velocity),
            acceleration: flat(acceleration),
            forcing: vec![0.0; dims * times.len()],
            times,
        }
    }

    /// Number of dimensions.
    pub fn dims(&self) -> usize {
        self.dims
    }

    /// Number of samples on the grid (steps + 1).
    pub fn n_samples(&self) -> usize {
        self.times.len()
    }

    /// The sample times in seconds, from 0 to `tau`.
    pub fn times(&self) -> &[f64] {
        &self.times
    }

    fn slice<'a>(&self, data: &'a [f64], dim: usize) -> &'a [f64] {
        let n = self.times.len();
        &data[dim * n..(dim + 1) * n]
    }

    /// Positions of dimension `dim` at every sample.
    ///
    /// # Panics
    /// If `dim >= dims()`.
    pub fn position(&self, dim: usize) -> &[f64] {
        self.slice(&self.position, dim)
    }

    /// Physical velocities `ẏ` of dimension `dim` (units per second).
    ///
    /// # Panics
    /// If `dim >= dims()`.
    pub fn velocity(&self, dim: usize) -> &[f64] {
        self.slice(&self.velocity, dim)
    }

    /// Physical accelerations `ÿ` of dimension `dim` (units per second²).
    ///
    /// # Panics
    /// If `dim >= dims()`.
    pub fn acceleration(&self, dim: usize) -> &[f64] {
        self.slice(&self.acceleration, dim)
    }

    /// The forcing term `f` of dimension `dim` at every sample (units of `tau² ÿ`).
    ///
    /// # Panics
    /// If `dim >= dims()`.
    pub fn forcing(&self, dim: usize) -> &[f64] {
        self.slice(&self.forcing, dim)
    }

    /// Position of dimension `dim` at time `t` seconds, interpolated linearly between
    /// samples (exact on the grid; clamped to the ends outside it).
    ///
    /// # Panics
    /// If `dim >= dims()`.
    pub fn position_at(&self, dim: usize, t: f64) -> f64 {
        let (k, frac) = self.locate(t);
        let p = self.position(dim);
        if frac == 0.0 {
            p[k]
        } else {
            p[k] + frac * (p[k + 1] - p[k])
        }
    }

    /// The grid interval holding `t`: index `k` and the fraction of the way to `k + 1`
    /// (see [`locate_on_grid`]).
    pub fn locate(&self, t: f64) -> (usize, f64) {
        locate_on_grid(&self.times, t)
    }
}

/// Where time `t` falls on a uniform grid `times`: the sample `k` at or before it and the
/// fraction of the way to `k + 1`. Times on the grid up to rounding (fraction within 1e-9)
/// count as grid points; times outside the grid are clamped to its ends.
pub fn locate_on_grid(times: &[f64], t: f64) -> (usize, f64) {
    let n = times.len();
    if n < 2 || t <= times[0] {
        return (0, 0.0);
    }
    let s = (t - times[0]) / (times[1] - times[0]);
    if s >= (n - 1) as f64 {
        return (n - 1, 0.0);
    }
    let k = s.floor() as usize;
    let frac = s - k as f64;
    if frac < 1e-9 {
        (k, 0.0)
    } else if frac > 1.0 - 1e-9 {
        (k + 1, 0.0)
    } else {
        (k, frac)
    }
}
