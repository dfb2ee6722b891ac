//! A take to a demonstration: the tool's pose per frame, from labelled markers fitted as
//! one rigid body (or from a rigid body Motive solved), cleaned, and carried into the
//! robot's frame.
//!
//! The steps, in order: the markers picked by label; each marker's track cut to the
//! frames asked for, outliers rejected (a sample far from its neighbours' median),
//! smoothed without lag, and gaps of at most `max_gap` frames filled by a cubic spline. The
//! body is defined at the first frame that sees every marker (its origin the markers'
//! centroid or one marker; its axes the take's, or built from three markers), and fitted
//! at every frame that sees three or more (Horn's least squares; a marker far off the fit
//! is dropped and the frame fitted again). Frames the body cannot be fitted at are cut at
//! the take's ends and refused inside it. Then the take's axes (Y up) or a registration
//! carry the pose into the robot's frame; time starts at 0 at the first frame kept.

use std::ops::Range;
use std::path::Path;

use serde::Serialize;

use crate::clean::{Gap, fill_gaps, reject_outliers, smooth_track};
use crate::error::MocapError;
use crate::fit::{
    IDENTITY, Mat3, Rigid, Vec3, centroid, cross, dot, fit, norm, planarity, quaternion_of,
    rotation_of, scale, sub, transpose,
};
use crate::register::{Calibration, Registration};
use crate::take::{Take, runs};

/// Where the body's origin is.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub enum Origin {
    /// The centroid of its markers.
    #[default]
    Centroid,
    /// One of its markers.
    Marker(String),
}

/// The take's vertical axis, for a take not registered to the robot.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Up {
    /// Keep the take's axes.
    #[default]
    AsRecorded,
    /// The take is Y up (Motive's default): turn it to Z up (x stays, y ← −z, z ← y).
    Y,
}

/// How to make a demonstration of a take.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// The body's markers (three or more), by label.
    pub markers: Vec<String>,
    /// Take this rigid body as Motive solved it instead of fitting markers.
    pub rigid_body: Option<String>,
    /// The body's origin.
    pub origin: Origin,
    /// The body's axes from three of its markers `[O, X, P]`: x from O towards X, z normal
    /// to the plane O-X-P, y = z × x. Without: the take's axes at the reference frame.
    pub axes: Option<[String; 3]>,
    /// The longest gap filled, frames.
    pub max_gap: usize,
    /// Smoothing cut-off, Hz (`None`: not smoothed).
    pub cutoff_hz: Option<f64>,
    /// A marker sample farther than this from its neighbours' median, or from the body's
    /// fit, is an outlier (metres).
    pub outlier_m: f64,
    /// The frames used (indices into the take, from 0); all when `None`.
    pub frames: Option<Range<usize>>,
    /// The take's vertical axis.
    pub up: Up,
    /// Carry the pose into the robot's frame.
    pub calibration: Option<Calibration>,
}

/// [`Settings`] as the command line, Python and experiment files give them: words and
/// numbers, checked by [`Words::settings`].
#[derive(Debug, Clone, PartialEq)]
pub struct Words {
    /// The body's markers.
    pub markers: Vec<String>,
    /// Motive's rigid body instead.
    pub rigid_body: Option<String>,
    /// `centroid` or a marker's label.
    pub origin: String,
    /// Three labels `O, X, P`.
    pub axes: Option<Vec<String>>,
    /// The take is Y up.
    pub y_up: bool,
    /// The longest gap filled, frames.
    pub max_gap: usize,
    /// Smoothing cut-off, Hz (0: none).
    pub cutoff_hz: f64,
    /// Outlier distance, mm.
    pub outlier_mm: f64,
    /// `FIRST..END` frame indices from 0.
    pub frames: Option<String>,
}

impl Default for Words {
    fn default() -> Self {
        Self {
            markers: Vec::new(),
            rigid_body: None,
            origin: "centroid".into(),
            axes: None,
            y_up: false,
            max_gap: 10,
            cutoff_hz: 10.0,
            outlier_mm: 20.0,
            frames: None,
        }
    }
}

impl Words {
    /// The settings these words give (no calibration: the caller reads its file).
    pub fn settings(&self) -> Result<Settings, MocapError> {
        if self.markers.is_empty() && self.rigid_body.is_none() {
            return Err(MocapError::Input(
                "give the tool's markers (three or more) or a Motive rigid body".into(),
            ));
        }
        let frames = match &self.frames {
            None => None,
            Some(f) => Some(
                f.split_once("..")
                    .and_then(|(a, b)| Some(a.trim().parse().ok()?..b.trim().parse().ok()?))
                    .ok_or_else(|| {
                        MocapError::Input(format!(
                            "frames {f}: expected FIRST..END (frame indices from 0)"
                        ))
                    })?,
            ),
        };
        Ok(Settings {
            markers: self.markers.clone(),
            rigid_body: self.rigid_body.clone(),
            origin: Settings::origin_of(&self.origin),
            axes: Settings::axes_of(self.axes.as_deref())?,
            max_gap: self.max_gap,
            cutoff_hz: (self.cutoff_hz != 0.0).then_some(self.cutoff_hz),
            outlier_m: self.outlier_mm / 1e3,
            frames,
            up: if self.y_up { Up::Y } else { Up::AsRecorded },
            calibration: None,
        })
    }
}

impl Settings {
    /// The origin from a word: `centroid`, or a marker's label.
    pub fn origin_of(word: &str) -> Origin {
        if word == "centroid" {
            Origin::Centroid
        } else {
            Origin::Marker(word.to_string())
        }
    }

    /// The axes from three labels `[O, X, P]`.
    pub fn axes_of(labels: Option<&[String]>) -> Result<Option<[String; 3]>, MocapError> {
        match labels {
            None => Ok(None),
            Some([o, x, p]) => Ok(Some([o.clone(), x.clone(), p.clone()])),
            Some(other) => Err(MocapError::Input(format!(
                "the axes take three markers O,X,P (got {})",
                other.len()
            ))),
        }
    }
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            markers: Vec::new(),
            rigid_body: None,
            origin: Origin::Centroid,
            axes: None,
            max_gap: 10,
            cutoff_hz: Some(10.0),
            outlier_m: 0.02,
            frames: None,
            up: Up::AsRecorded,
            calibration: None,
        }
    }
}

/// One marker's cleaning.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MarkerReport {
    /// Its label.
    pub label: String,
    /// Frames it was missing in the take (within the frames used).
    pub missing_frames: usize,
    /// Samples rejected as outliers (against its neighbours or the body's fit).
    pub outliers: usize,
    /// Gaps filled and their frames.
    pub gaps_filled: usize,
    /// Frames filled.
    pub frames_filled: usize,
    /// The longest gap filled, frames.
    pub longest_filled: usize,
    /// Gaps left open (too long, or at an end): `[first, last]` frame numbers.
    pub open_gaps: Vec<[u64; 2]>,
}

/// What was done to make the demonstration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Report {
    /// The take.
    pub file: String,
    /// Its frame rate, Hz.
    pub rate_hz: f64,
    /// Frames in the take.
    pub frames_in_take: usize,
    /// The first and last frame kept (the take's frame numbers).
    pub kept_frames: [u64; 2],
    /// Frames kept.
    pub frames: usize,
    /// Seconds kept.
    pub duration_s: f64,
    /// Frames cut at the start and at the end (the body could not be fitted there).
    pub cut: [usize; 2],
    /// `markers` or `rigid body NAME`.
    pub from: String,
    /// Each marker's cleaning.
    pub markers: Vec<MarkerReport>,
    /// RMS distance of the markers from the fitted body: mean and largest over frames,
    /// metres.
    pub fit_rms_mean_m: f64,
    /// The largest.
    pub fit_rms_max_m: f64,
    /// Frames fitted with fewer than all the markers.
    pub frames_with_fewer_markers: usize,
    /// The smoothing cut-off, Hz.
    pub cutoff_hz: Option<f64>,
    /// Into the robot's frame: `registration`, `y-up to z-up`, or `as recorded`.
    pub frame: String,
    /// The registration, if one was used.
    pub registration: Option<Registration>,
    /// What the reader noticed.
    pub notes: Vec<String>,
}

/// A demonstration: the tool's pose over time.
#[derive(Debug, Clone, PartialEq)]
pub struct Demonstration {
    /// Seconds from 0.
    pub t: Vec<f64>,
    /// Position, metres.
    pub position: Vec<Vec3>,
    /// Orientation `[qx, qy, qz, qw]`, continuous (no sign flips between frames).
    pub quaternion: Vec<[f64; 4]>,
    /// The markers used, cleaned, in the output frame (metres; NaN where missing), for
    /// figures: one track per marker (empty for a Motive rigid body).
    pub markers: Vec<Vec<Vec3>>,
    /// Their labels.
    pub labels: Vec<String>,
    /// Per kept frame and marker: whether the sample was seen (not filled).
    pub seen: Vec<Vec<bool>>,
    /// What was done.
    pub report: Report,
}

impl Demonstration {
    /// The demonstration as cps's CSV: `t,x,y,z,qx,qy,qz,qw`.
    pub fn csv(&self) -> String {
        let mut s = String::with_capacity(self.t.len() * 96 + 32);
        s.push_str("t,x,y,z,qx,qy,qz,qw\n");
        for ((t, p), q) in self.t.iter().zip(&self.position).zip(&self.quaternion) {
            use std::fmt::Write;
            let _ = writeln!(
                s,
                "{t},{},{},{},{},{},{},{}",
                p[0], p[1], p[2], q[0], q[1], q[2], q[3]
            );
        }
        s
    }
}

/// Reads a take by its extension: `.c3d`, or `.csv` (Motive).
pub fn read_take(path: &Path) -> Result<Take, MocapError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("c3d") => crate::c3d::read(path),
        Some("csv") => crate::motive::read(path),
        _ => Err(MocapError::Input(format!(
            "{}: a take is a .c3d file or a Motive .csv export",
            path.display()
        ))),
    }
}

/// Makes a demonstration of a take.
pub fn demonstrate(take: &Take, s: &Settings) -> Result<Demonstration, MocapError> {
    let file = &take.file;
    if s.outlier_m.is_nan() || s.outlier_m <= 0.0 {
        return Err(MocapError::Input(format!(
            "the outlier distance must be positive (got {} m)",
            s.outlier_m
        )));
    }
    if let Some(c) = s.cutoff_hz
        && !(c > 0.0 && c < take.rate / 2.0)
    {
        return Err(MocapError::Input(format!(
            "{file}: a smoothing cut-off of {c} Hz is not below half the take's {} Hz",
            take.rate
        )));
    }
    let range = match &s.frames {
        None => 0..take.frames,
        Some(r) if r.start < r.end && r.end <= take.frames => r.clone(),
        Some(r) => {
            return Err(MocapError::Input(format!(
                "{file}: frames {}..{} are not within the take's {} frames",
                r.start, r.end, take.frames
            )));
        }
    };
    let (to_output, frame_words, registration) = output_frame(s)?;
    if let Some(name) = &s.rigid_body {
        return rigid_body(take, s, name, range, &to_output, frame_words, registration);
    }
    if s.markers.len() < 3 {
        return Err(MocapError::Input(format!(
            "{file}: a rigid body needs three or more markers (got {}); its markers are: {}",
            s.markers.len(),
            list(&take.labels)
        )));
    }
    let (index, origin, axes) = marker_indices(take, s)?;
    let k = take.metres_per_unit;
    // Tracks in metres, cleaned.
    let mut tracks: Vec<Vec<Vec3>> = index
        .iter()
        .map(|&m| {
            range
                .clone()
                .map(|f| {
                    if take.seen(f, m) {
                        take.point(f, m).map(|v| f64::from(v) * k)
                    } else {
                        [f64::NAN; 3]
                    }
                })
                .collect()
        })
        .collect();
    let seen: Vec<Vec<bool>> = tracks
        .iter()
        .map(|t| t.iter().map(|p| p[0].is_finite()).collect())
        .collect();
    let mut reports = Vec::new();
    for (j, t) in tracks.iter_mut().enumerate() {
        let missing = seen[j].iter().filter(|s| !**s).count();
        let outliers = reject_outliers(t, 3, s.outlier_m).len();
        // Smoothed before the gaps are filled: the spline's slopes come from smoothed
        // samples, not from noise.
        if let Some(c) = s.cutoff_hz {
            smooth_track(t, c, take.rate);
        }
        let filled = fill_gaps(t, s.max_gap);
        reports.push((missing, outliers, filled));
    }
    let body = body_frame(take, s, &range, &tracks, origin, axes)?;
    let Fitted {
        poses,
        rms_all,
        fewer,
        fit_outliers,
    } = fit_frames(&mut tracks, &body, s.outlier_m);
    let (first, last) = tracked_span(take, s, &range, &poses, &tracks)?;
    let mut position = Vec::with_capacity(last - first);
    let mut quaternion: Vec<[f64; 4]> = Vec::with_capacity(last - first);
    for p in poses[first..last].iter().flatten() {
        let p = to_output.then_after(p);
        position.push(p.translation);
        quaternion.push(continuous(quaternion.last(), quaternion_of(&p.rotation)));
    }
    let markers_out: Vec<Vec<Vec3>> = tracks
        .iter()
        .map(|t| {
            t[first..last]
                .iter()
                .map(|p| {
                    if p[0].is_finite() {
                        to_output.apply(*p)
                    } else {
                        [f64::NAN; 3]
                    }
                })
                .collect()
        })
        .collect();
    let kept = Kept {
        take,
        range: &range,
        first,
        last,
    };
    let markers = reports
        .into_iter()
        .enumerate()
        .map(|(j, (missing, outliers, filled))| {
            kept.marker(
                &take.labels[index[j]],
                missing,
                outliers + fit_outliers[j],
                &filled,
            )
        })
        .collect();
    let report = kept.report(
        s,
        format!("markers {}", s.markers.join(", ")),
        markers,
        &rms_all,
        fewer,
        frame_words,
        registration,
    );
    Ok(Demonstration {
        t: kept.times(),
        position,
        quaternion,
        markers: markers_out,
        labels: s.markers.clone(),
        seen: seen.iter().map(|v| v[first..last].to_vec()).collect(),
        report,
    })
}

/// The body's markers in its own frame: their places at the first frame that sees them
/// all, about the origin (a marker, or their centroid) and along the axes the settings
/// name (else the take's).
fn body_frame(
    take: &Take,
    s: &Settings,
    range: &Range<usize>,
    tracks: &[Vec<Vec3>],
    origin: Option<usize>,
    axes: Option<[usize; 3]>,
) -> Result<Vec<Vec3>, MocapError> {
    let file = &take.file;
    let n = range.len();
    let nm = tracks.len();
    // The reference frame: the first that sees every marker.
    let reference = (0..n)
        .find(|&f| tracks.iter().all(|t| t[f][0].is_finite()))
        .ok_or_else(|| {
            MocapError::Refused(format!(
                "{file}: no frame sees all {nm} markers ({}) even after filling gaps of up to {} frames; the body needs one complete frame to be defined",
                s.markers.join(", "),
                s.max_gap
            ))
        })?;
    let refs: Vec<Vec3> = tracks.iter().map(|t| t[reference]).collect();
    let spread = planarity(&refs);
    if spread < crate::register::MIN_PLANARITY {
        return Err(MocapError::Input(format!(
            "{file}: markers {} are (nearly) on one line at frame {}: they fix no rotation about it; pick markers that span a triangle",
            s.markers.join(", "),
            take.first_frame + (range.start + reference) as u64
        )));
    }
    let o = origin.map_or_else(|| centroid(&refs), |m| refs[m]);
    let r0: Mat3 = match axes {
        None => IDENTITY,
        Some([a, b, c]) => {
            let x = sub(refs[b], refs[a]);
            let z = cross(x, sub(refs[c], refs[a]));
            if norm(x) < 1e-9 || norm(z) < 1e-12 {
                return Err(MocapError::Input(format!(
                    "{file}: the axis markers {} do not span a plane",
                    s.axes.as_ref().map_or(String::new(), |a| a.join(", "))
                )));
            }
            let x = scale(x, 1.0 / norm(x));
            let z = scale(z, 1.0 / norm(z));
            let y = cross(z, x);
            // Columns x, y, z: body axes in the take's frame.
            transpose(&[x, y, z])
        }
    };
    let body: Vec<Vec3> = refs
        .iter()
        .map(|p| crate::fit::mul(&transpose(&r0), sub(*p, o)))
        .collect();

    Ok(body)
}

/// Every frame's pose of the body (`body`: its markers in its own frame), fitted to the
/// markers seen there; a marker farther than half `outlier_m` from the fit is dropped
/// from that frame (and from `tracks`) and the frame fitted again.
fn fit_frames(tracks: &mut [Vec<Vec3>], body: &[Vec3], outlier_m: f64) -> Fitted {
    let n = tracks.first().map_or(0, Vec::len);
    let nm = tracks.len();
    let mut poses: Vec<Option<Rigid>> = vec![None; n];
    let mut rms_all = Vec::with_capacity(n);
    let mut fewer = 0usize;
    let mut fit_outliers = vec![0usize; nm];
    let (mut from, mut to, mut which) = (
        Vec::with_capacity(nm),
        Vec::with_capacity(nm),
        Vec::with_capacity(nm),
    );
    for f in 0..n {
        from.clear();
        to.clear();
        which.clear();
        for (j, t) in tracks.iter().enumerate() {
            if t[f][0].is_finite() {
                from.push(body[j]);
                to.push(t[f]);
                which.push(j);
            }
        }
        if from.len() < 3 || planarity(&from) < crate::register::MIN_PLANARITY {
            continue;
        }
        let Some((mut pose, mut rms)) = fit(&from, &to) else {
            continue;
        };
        if rms > outlier_m / 2.0 && from.len() >= 4 {
            // Drop the marker farthest from the fit and fit again.
            let worst = (0..from.len())
                .max_by(|&a, &b| {
                    let da = norm(sub(pose.apply(from[a]), to[a]));
                    let db = norm(sub(pose.apply(from[b]), to[b]));
                    da.total_cmp(&db)
                })
                .unwrap_or(0);
            fit_outliers[which[worst]] += 1;
            tracks[which[worst]][f] = [f64::NAN; 3];
            from.remove(worst);
            to.remove(worst);
            if planarity(&from) < crate::register::MIN_PLANARITY {
                continue;
            }
            if let Some(refit) = fit(&from, &to) {
                (pose, rms) = refit;
            }
        }
        if from.len() < nm {
            fewer += 1;
        }
        rms_all.push(rms);
        poses[f] = Some(pose);
    }
    Fitted {
        poses,
        rms_all,
        fewer,
        fit_outliers,
    }
}

/// What [`fit_frames`] found: each frame's pose (None: too few markers seen), the fits'
/// RMS, the frames fitted with fewer than every marker, and each marker's drops.
struct Fitted {
    poses: Vec<Option<Rigid>>,
    rms_all: Vec<f64>,
    fewer: usize,
    fit_outliers: Vec<usize>,
}

/// The frames from the first to the last the body was fitted in; refused when it never
/// was, or when it was lost in between for longer than the gaps filled.
fn tracked_span(
    take: &Take,
    s: &Settings,
    range: &Range<usize>,
    poses: &[Option<Rigid>],
    tracks: &[Vec<Vec3>],
) -> Result<(usize, usize), MocapError> {
    let file = &take.file;
    let nm = tracks.len();
    let tracked = runs(poses.iter().map(Option::is_some));
    let span = match (tracked.first(), tracked.last()) {
        (Some(a), Some(b)) => (a.start, b.end),
        _ => {
            return Err(MocapError::Refused(format!(
                "{file}: the body is never seen by three markers that span a triangle"
            )));
        }
    };
    if tracked.len() > 1 {
        let hole = tracked[0].end..tracked[1].start;
        let missing: Vec<String> = (0..nm)
            .filter(|&j| hole.clone().any(|f| !tracks[j][f][0].is_finite()))
            .map(|j| s.markers[j].clone())
            .collect();
        let f0 = take.first_frame + (range.start + hole.start) as u64;
        return Err(MocapError::Refused(format!(
            "{file}: frames {}–{} (t = {:.3}–{:.3} s, {} frames): fewer than three markers of the body are seen (missing: {}), longer than --max-gap {} frames fills; cut the take around them (--frames) or allow longer gaps",
            f0,
            f0 + hole.len() as u64 - 1,
            (range.start + hole.start) as f64 / take.rate,
            (range.start + hole.end - 1) as f64 / take.rate,
            hole.len(),
            missing.join(", "),
            s.max_gap
        )));
    }
    Ok(span)
}

/// Where the settings' markers are in the take, and which of them are the origin and the
/// axes.
#[allow(clippy::type_complexity)]
fn marker_indices(
    take: &Take,
    s: &Settings,
) -> Result<(Vec<usize>, Option<usize>, Option<[usize; 3]>), MocapError> {
    let file = &take.file;
    let mut index = Vec::new();
    for m in &s.markers {
        let i = take.find_label(m).ok_or_else(|| {
            MocapError::Input(format!(
                "{file}: no marker labelled \"{m}\"; its markers are: {}",
                list(&take.labels)
            ))
        })?;
        if index.contains(&i) {
            return Err(MocapError::Input(format!(
                "{file}: marker \"{m}\" is named twice"
            )));
        }
        index.push(i);
    }
    let pick = |name: &str| -> Result<usize, MocapError> {
        s.markers.iter().position(|m| m == name).ok_or_else(|| {
            MocapError::Input(format!(
                "{file}: \"{name}\" is not one of the body's markers ({})",
                s.markers.join(", ")
            ))
        })
    };
    let origin = match &s.origin {
        Origin::Centroid => None,
        Origin::Marker(m) => Some(pick(m)?),
    };
    let axes = match &s.axes {
        None => None,
        Some([o, x, p]) => Some([pick(o)?, pick(x)?, pick(p)?]),
    };
    Ok((index, origin, axes))
}

/// The frames kept of a take (`first..last` within `range`): frame numbers, times and the
/// report's common fields.
struct Kept<'a> {
    take: &'a Take,
    range: &'a Range<usize>,
    first: usize,
    last: usize,
}

impl Kept<'_> {
    /// The take's frame number of index `i` within the range.
    fn frame_no(&self, i: usize) -> u64 {
        self.take.first_frame + (self.range.start + i) as u64
    }

    fn times(&self) -> Vec<f64> {
        (0..self.last - self.first)
            .map(|i| i as f64 / self.take.rate)
            .collect()
    }

    fn marker(
        &self,
        label: &str,
        missing: usize,
        outliers: usize,
        filled: &crate::clean::Filled,
    ) -> MarkerReport {
        MarkerReport {
            label: label.to_string(),
            missing_frames: missing,
            outliers,
            gaps_filled: filled.gaps,
            frames_filled: filled.frames,
            longest_filled: filled.longest,
            open_gaps: filled
                .open
                .iter()
                .map(|g: &Gap| [self.frame_no(g.start), self.frame_no(g.end - 1)])
                .collect(),
        }
    }

    #[allow(clippy::too_many_arguments)]
    fn report(
        &self,
        s: &Settings,
        from: String,
        markers: Vec<MarkerReport>,
        rms: &[f64],
        fewer: usize,
        frame_words: &str,
        registration: Option<Registration>,
    ) -> Report {
        let (take, kept) = (self.take, self.last - self.first);
        Report {
            file: take.file.clone(),
            rate_hz: take.rate,
            frames_in_take: take.frames,
            kept_frames: [self.frame_no(self.first), self.frame_no(self.last - 1)],
            frames: kept,
            duration_s: kept.saturating_sub(1) as f64 / take.rate,
            cut: [
                self.first + self.range.start,
                take.frames - (self.range.start + self.last),
            ],
            from,
            markers,
            fit_rms_mean_m: rms.iter().sum::<f64>() / rms.len().max(1) as f64,
            fit_rms_max_m: rms.iter().copied().fold(0.0, f64::max),
            frames_with_fewer_markers: fewer,
            cutoff_hz: s.cutoff_hz,
            frame: frame_words.to_string(),
            registration,
            notes: take.notes.clone(),
        }
    }
}

/// The transform into the output frame, its name and the registration.
fn output_frame(s: &Settings) -> Result<(Rigid, &'static str, Option<Registration>), MocapError> {
    match (&s.calibration, s.up) {
        (Some(c), Up::AsRecorded) => {
            let r = c.register()?;
            Ok((r.transform, "registration", Some(r)))
        }
        (Some(c), Up::Y) => Err(MocapError::Input(format!(
            "{}: a registration already carries the take's axes into the robot's; leave out the up axis",
            c.file
        ))),
        (None, Up::Y) => Ok((
            Rigid {
                rotation: [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]],
                translation: [0.0; 3],
            },
            "y-up to z-up",
            None,
        )),
        (None, Up::AsRecorded) => Ok((Rigid::default(), "as recorded", None)),
    }
}

/// `q` or `−q`, whichever is nearer the previous quaternion.
fn continuous(prev: Option<&[f64; 4]>, q: [f64; 4]) -> [f64; 4] {
    match prev {
        Some(p) if p.iter().zip(&q).map(|(a, b)| a * b).sum::<f64>() < 0.0 => q.map(|v| -v),
        _ => q,
    }
}

fn list(labels: &[String]) -> String {
    if labels.is_empty() {
        return "(none)".into();
    }
    let shown: Vec<&str> = labels.iter().take(40).map(String::as_str).collect();
    let more = labels.len().saturating_sub(40);
    if more > 0 {
        format!("{} … and {more} more", shown.join(", "))
    } else {
        shown.join(", ")
    }
}

/// A Motive rigid body: its solved pose, gaps filled (position by the spline, orientation
/// by spherical interpolation), smoothed, carried into the output frame.
fn rigid_body(
    take: &Take,
    s: &Settings,
    name: &str,
    range: Range<usize>,
    to_output: &Rigid,
    frame_words: &str,
    registration: Option<Registration>,
) -> Result<Demonstration, MocapError> {
    let file = &take.file;
    let body = take
        .rigid_bodies
        .iter()
        .find(|b| b.name == name)
        .ok_or_else(|| {
            let names: Vec<String> = take.rigid_bodies.iter().map(|b| b.name.clone()).collect();
            MocapError::Input(format!(
                "{file}: no rigid body \"{name}\"; its rigid bodies are: {}",
                list(&names)
            ))
        })?;
    if body.quaternion.iter().all(|q| q.iter().any(|v| v.is_nan()))
        && take.notes.iter().any(|n| n.contains("Euler"))
    {
        return Err(MocapError::Input(format!(
            "{file}: rigid body \"{name}\" has Euler angles; export the take with Rotation Type Quaternion"
        )));
    }
    let k = take.metres_per_unit;
    let mut pos: Vec<Vec3> = Vec::with_capacity(range.len());
    let mut quat: Vec<[f64; 4]> = Vec::with_capacity(range.len());
    for f in range.clone() {
        let p = body.position[f];
        let q = body.quaternion[f];
        let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
        if p.iter().chain(&q).all(|v| v.is_finite()) && n > 0.5 {
            pos.push(p.map(|v| v * k));
            quat.push(continuous(
                quat.iter().rev().find(|q| q[0].is_finite()),
                q.map(|v| v / n),
            ));
        } else {
            pos.push([f64::NAN; 3]);
            quat.push([f64::NAN; 4]);
        }
    }
    let seen: Vec<bool> = pos.iter().map(|p| p[0].is_finite()).collect();
    let missing = seen.iter().filter(|s| !**s).count();
    let filled = fill_gaps(&mut pos, s.max_gap);
    // Orientation over the same gaps: spherical interpolation.
    for g in runs(quat.iter().map(|q| !q[0].is_finite())) {
        if g.start == 0 || g.end == quat.len() || g.len() > s.max_gap {
            continue;
        }
        let (a, b) = (quat[g.start - 1], quat[g.end]);
        let h = (g.end - g.start + 1) as f64;
        for i in g.clone() {
            quat[i] = slerp(a, b, (i - g.start + 1) as f64 / h);
        }
    }
    if let Some(c) = s.cutoff_hz {
        smooth_track(&mut pos, c, take.rate);
        // Components of a continuous quaternion, smoothed and normalised again.
        let mut xyz: Vec<Vec3> = quat.iter().map(|q| [q[0], q[1], q[2]]).collect();
        let mut w: Vec<Vec3> = quat.iter().map(|q| [q[3], 0.0, 0.0]).collect();
        smooth_track(&mut xyz, c, take.rate);
        smooth_track(&mut w, c, take.rate);
        for ((q, a), b) in quat.iter_mut().zip(&xyz).zip(&w) {
            let v = [a[0], a[1], a[2], b[0]];
            let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            *q = v.map(|x| x / n);
        }
    }
    let tracked = runs(pos.iter().map(|p| p[0].is_finite()));
    let (Some(a), Some(b)) = (tracked.first(), tracked.last()) else {
        return Err(MocapError::Refused(format!(
            "{file}: rigid body \"{name}\" is never tracked"
        )));
    };
    let (first, last) = (a.start, b.end);
    if tracked.len() > 1 {
        let hole = tracked[0].end..tracked[1].start;
        let f0 = take.first_frame + (range.start + hole.start) as u64;
        return Err(MocapError::Refused(format!(
            "{file}: rigid body \"{name}\" is lost for frames {}–{} ({} frames, t = {:.3} s), longer than --max-gap {} frames fills; cut the take around them (--frames) or allow longer gaps",
            f0,
            f0 + hole.len() as u64 - 1,
            hole.len(),
            (range.start + hole.start) as f64 / take.rate,
            s.max_gap
        )));
    }
    let mut position = Vec::new();
    let mut quaternion: Vec<[f64; 4]> = Vec::new();
    for i in first..last {
        let p = to_output.then_after(&Rigid {
            rotation: rotation_of(quat[i]),
            translation: pos[i],
        });
        position.push(p.translation);
        quaternion.push(continuous(quaternion.last(), quaternion_of(&p.rotation)));
    }
    let kept = Kept {
        take,
        range: &range,
        first,
        last,
    };
    let marker = kept.marker(name, missing, 0, &filled);
    Ok(Demonstration {
        t: kept.times(),
        position,
        quaternion,
        markers: Vec::new(),
        labels: Vec::new(),
        seen: vec![seen[first..last].to_vec()],
        report: kept.report(
            s,
            format!("rigid body {name}"),
            vec![marker],
            &[],
            0,
            frame_words,
            registration,
        ),
    })
}

/// Spherical interpolation between unit quaternions (`[x, y, z, w]`, same hemisphere).
fn slerp(a: [f64; 4], b: [f64; 4], s: f64) -> [f64; 4] {
    let c = dot([a[0], a[1], a[2]], [b[0], b[1], b[2]]) + a[3] * b[3];
    let b = if c < 0.0 { b.map(|v| -v) } else { b };
    let c = c.abs().min(1.0);
    let th = c.acos();
    let (wa, wb) = if th < 1e-9 {
        (1.0 - s, s)
    } else {
        (((1.0 - s) * th).sin() / th.sin(), (s * th).sin() / th.sin())
    };
    let q: [f64; 4] = std::array::from_fn(|i| wa * a[i] + wb * b[i]);
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    q.map(|v| v / n)
}
