//! Cleaning one marker's track (positions per frame, NaN where missing): outliers
//! rejected against a running median, short gaps filled by a cubic spline, and smoothing
//! without lag (a Butterworth low-pass run forwards and backwards).

use crate::fit::{Vec3, norm, sub};
use crate::take::runs;

fn seen(p: &Vec3) -> bool {
    p.iter().all(|v| v.is_finite())
}

/// Marks as missing every sample farther than `threshold` (metres) from the per-axis
/// median of the seen samples within `±half_window` frames (fewer near the ends) (a Hampel filter with a fixed
/// threshold: a marker swapped, a reflection, a ghost). Returns the frames rejected.
pub fn reject_outliers(track: &mut [Vec3], half_window: usize, threshold: f64) -> Vec<usize> {
    let n = track.len();
    let mut out = Vec::new();
    let mut window: [Vec<f64>; 3] = Default::default();
    for i in 0..n {
        if !seen(&track[i]) {
            continue;
        }
        // A symmetric window (narrower near the ends): its median is the sample itself
        // for any monotone motion.
        let half = half_window.min(i).min(n - 1 - i);
        let (lo, hi) = (i - half, i + half + 1);
        for w in &mut window {
            w.clear();
        }
        for p in track[lo..hi].iter().filter(|p| seen(p)) {
            for (w, v) in window.iter_mut().zip(p) {
                w.push(*v);
            }
        }
        if window[0].len() < 3 {
            continue;
        }
        let median = window.each_mut().map(|w| {
            w.sort_by(f64::total_cmp);
            let k = w.len();
            if k % 2 == 1 {
                w[k / 2]
            } else {
                (w[k / 2 - 1] + w[k / 2]) / 2.0
            }
        });
        if norm(sub(track[i], median)) > threshold {
            out.push(i);
        }
    }
    for &i in &out {
        track[i] = [f64::NAN; 3];
    }
    out
}

/// A gap the filler left open.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Gap {
    /// First missing frame.
    pub start: usize,
    /// One past the last missing frame.
    pub end: usize,
    /// Whether it touches the take's first or last frame (no sample on one side).
    pub at_edge: bool,
}

impl Gap {
    /// Frames missing.
    pub fn len(&self) -> usize {
        self.end - self.start
    }
    /// Whether it is empty.
    pub fn is_empty(&self) -> bool {
        self.end == self.start
    }
}

/// What [`fill_gaps`] did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Filled {
    /// Gaps filled.
    pub gaps: usize,
    /// Frames filled.
    pub frames: usize,
    /// The longest gap filled, frames.
    pub longest: usize,
    /// Gaps left open: longer than allowed, or at the take's edge.
    pub open: Vec<Gap>,
}

/// Fills every gap of at most `max_gap` frames with a cubic Hermite spline between the
/// samples around it; its slopes are one-sided second-order differences where two seen
/// samples lie on that side (exact for quadratics), first-order where one does. Gaps at
/// the take's edges and longer gaps stay open.
pub fn fill_gaps(track: &mut [Vec3], max_gap: usize) -> Filled {
    let n = track.len();
    let mut out = Filled::default();
    let gaps = runs(track.iter().map(|p| !seen(p)));
    for g in gaps {
        let at_edge = g.start == 0 || g.end == n;
        if at_edge || g.len() > max_gap {
            out.open.push(Gap {
                start: g.start,
                end: g.end,
                at_edge,
            });
            continue;
        }
        let (a, b) = (g.start - 1, g.end);
        let h = (b - a) as f64;
        let chord = sub(track[b], track[a]).map(|v| v / h);
        let slope_a = if a >= 2 && seen(&track[a - 1]) && seen(&track[a - 2]) {
            std::array::from_fn(|k| {
                (3.0 * track[a][k] - 4.0 * track[a - 1][k] + track[a - 2][k]) / 2.0
            })
        } else if a >= 1 && seen(&track[a - 1]) {
            sub(track[a], track[a - 1])
        } else {
            chord
        };
        let slope_b = if b + 2 < n && seen(&track[b + 1]) && seen(&track[b + 2]) {
            std::array::from_fn(|k| {
                (-3.0 * track[b][k] + 4.0 * track[b + 1][k] - track[b + 2][k]) / 2.0
            })
        } else if b + 1 < n && seen(&track[b + 1]) {
            sub(track[b + 1], track[b])
        } else {
            chord
        };
        let (pa, pb) = (track[a], track[b]);
        for i in g.clone() {
            let s = (i - a) as f64 / h;
            let (s2, s3) = (s * s, s * s * s);
            let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
            let h10 = s3 - 2.0 * s2 + s;
            let h01 = -2.0 * s3 + 3.0 * s2;
            let h11 = s3 - s2;
            track[i] = std::array::from_fn(|k| {
                h00 * pa[k] + h10 * h * slope_a[k] + h01 * pb[k] + h11 * h * slope_b[k]
            });
        }
        out.gaps += 1;
        out.frames += g.len();
        out.longest = out.longest.max(g.len());
    }
    out
}

/// A second-order Butterworth low-pass (bilinear transform, cut-off pre-warped):
/// `(b0, b1, b2, a1, a2)`.
fn butterworth(cutoff: f64, rate: f64) -> [f64; 5] {
    let k = (std::f64::consts::PI * cutoff / rate).tan();
    let q = std::f64::consts::SQRT_2;
    let norm = 1.0 / (1.0 + q * k + k * k);
    let b0 = k * k * norm;
    [
        b0,
        2.0 * b0,
        b0,
        2.0 * (k * k - 1.0) * norm,
        (1.0 - q * k + k * k) * norm,
    ]
}

/// One pass of the filter (transposed direct form II), started in its steady state for
/// the first value.
fn pass(c: &[f64; 5], x: &mut [f64]) {
    let [b0, b1, b2, a1, a2] = *c;
    let Some(&x0) = x.first() else { return };
    let (mut z1, mut z2) = ((1.0 - b0) * x0, (b2 - a2) * x0);
    for v in x.iter_mut() {
        let y = b0 * *v + z1;
        z1 = b1 * *v - a1 * y + z2;
        z2 = b2 * *v - a2 * y;
        *v = y;
    }
}

/// Zero-phase low-pass of a uniformly sampled signal: the Butterworth filter forwards
/// then backwards (magnitude `1/(1 + (f/fc)⁴)`, no lag), the ends extended by odd
/// reflection over `3·rate/cutoff` samples so they do not ring (about a line fitted to
/// the end's samples, so one noisy end sample does not pull the whole extension). Signals shorter than 4
/// samples and cut-offs at or above Nyquist are left as they are.
pub fn smooth(x: &mut [f64], cutoff: f64, rate: f64) {
    let n = x.len();
    if n < 4 || !(cutoff > 0.0 && cutoff < rate / 2.0) {
        return;
    }
    let c = butterworth(cutoff, rate);
    let pad = ((3.0 * rate / cutoff).ceil() as usize).min(n - 1);
    // Odd reflection about each end's value on a straight line fitted to the samples of
    // half a cut-off period there, not about the last (noisy) sample itself.
    let m = ((rate / cutoff / 2.0).ceil() as usize).clamp(2, n);
    let start = line_at_end(&x[..m]);
    let rev: Vec<f64> = x[n - m..].iter().rev().copied().collect();
    let end = line_at_end(&rev);
    let mut y = Vec::with_capacity(n + 2 * pad);
    y.extend((1..=pad).rev().map(|i| 2.0 * start - x[i]));
    y.extend_from_slice(x);
    y.extend((1..=pad).map(|i| 2.0 * end - x[n - 1 - i]));
    pass(&c, &mut y);
    y.reverse();
    pass(&c, &mut y);
    y.reverse();
    x.copy_from_slice(&y[pad..pad + n]);
}

/// The value at index 0 of the least-squares line through `x`.
fn line_at_end(x: &[f64]) -> f64 {
    let n = x.len() as f64;
    let mean_i = (n - 1.0) / 2.0;
    let mean_x = x.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, v) in x.iter().enumerate() {
        let d = i as f64 - mean_i;
        sxy += d * (v - mean_x);
        sxx += d * d;
    }
    let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    mean_x - slope * mean_i
}

/// [`smooth`] on each axis of each run of seen samples of a track.
pub fn smooth_track(track: &mut [Vec3], cutoff: f64, rate: f64) {
    let mut buf = Vec::new();
    for r in runs(track.iter().map(seen)) {
        for k in 0..3 {
            buf.clear();
            buf.extend(track[r.clone()].iter().map(|p| p[k]));
            smooth(&mut buf, cutoff, rate);
            for (p, v) in track[r.clone()].iter_mut().zip(&buf) {
                p[k] = *v;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_filter_halves_a_sine_at_the_cutoff_and_does_not_delay_it() {
        let (rate, fc) = (240.0, 6.0);
        let n = 2400;
        let w = 2.0 * std::f64::consts::PI * fc;
        let mut x: Vec<f64> = (0..n).map(|i| (w * i as f64 / rate).sin()).collect();
        smooth(&mut x, fc, rate);
        // Away from the ends: amplitude |H|² = 1/2, phase 0.
        for (i, v) in x.iter().enumerate().skip(400).take(1600) {
            let want = 0.5 * (w * i as f64 / rate).sin();
            assert!((v - want).abs() < 2e-3, "sample {i}: {v} vs {want}");
        }
        // Well below the cut-off a signal passes unchanged; a constant exactly.
        let mut slow: Vec<f64> = (0..n).map(|i| (0.5 * i as f64 / rate).sin()).collect();
        let orig = slow.clone();
        smooth(&mut slow, fc, rate);
        let err = slow
            .iter()
            .zip(&orig)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        // (the ends within 2e-4: the reflection pivots on a fitted line, not on the curve)
        assert!(err < 2e-4, "{err}");
        let mut c = vec![3.25; 50];
        smooth(&mut c, fc, rate);
        assert!(c.iter().all(|v| (v - 3.25).abs() < 1e-12));
    }

    #[test]
    fn a_gap_in_a_quadratic_is_filled_exactly_and_long_gaps_stay_open() {
        let f = |i: usize| {
            let t = i as f64 * 0.01;
            [0.3 * t * t - t, 2.0 * t + 0.5, -0.7 * t * t]
        };
        let mut track: Vec<Vec3> = (0..100).map(f).collect();
        track[40..46].fill([f64::NAN; 3]);
        track[60..80].fill([f64::NAN; 3]);
        track[0] = [f64::NAN; 3];
        let r = fill_gaps(&mut track, 10);
        assert_eq!((r.gaps, r.frames, r.longest), (1, 6, 6));
        for (i, p) in track.iter().enumerate().take(46).skip(40) {
            assert!(norm(sub(*p, f(i))) < 1e-12, "{i}");
        }
        assert_eq!(r.open.len(), 2);
        assert!(r.open[0].at_edge && r.open[0].len() == 1);
        assert_eq!(
            (r.open[1].start, r.open[1].end, r.open[1].at_edge),
            (60, 80, false)
        );
    }

    #[test]
    fn a_spike_is_rejected_and_a_smooth_track_is_not() {
        let mut track: Vec<Vec3> = (0..200)
            .map(|i| [(i as f64 * 0.05).sin(), 0.0, 1.0])
            .collect();
        assert!(reject_outliers(&mut track.clone(), 3, 0.01).is_empty());
        track[50][1] += 0.05;
        track[120][2] -= 0.02;
        assert_eq!(reject_outliers(&mut track, 3, 0.01), vec![50, 120]);
        assert!(!seen(&track[50]));
    }
}
