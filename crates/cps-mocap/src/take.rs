//! A motion-capture take as read from its file: labelled markers frame by frame (in the
//! file's own units and axes), analog channels, and the rigid bodies a Motive export
//! solved itself.

use std::ops::Range;

/// Which file a take came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Source {
    /// A C3D file (biomechanics' standard; Vicon, Qualisys, OptiTrack Motive…).
    C3d {
        /// Point data as 32-bit floats (`true`) or 16-bit integers times the scale.
        float: bool,
        /// The processor convention the file was written in.
        processor: Processor,
    },
    /// OptiTrack Motive's CSV export.
    MotiveCsv,
}

/// The byte and number conventions of a C3D file (the parameter section's processor
/// byte).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Processor {
    /// Little-endian, IEEE floats (PCs).
    Intel,
    /// Little-endian integers, VAX floats (DEC).
    Dec,
    /// Big-endian, IEEE floats (SGI/MIPS).
    Mips,
}

/// Analog channels sampled with the take (force plates, EMG, triggers), scaled to their
/// units.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Analog {
    /// One label per channel.
    pub labels: Vec<String>,
    /// One unit per channel (empty when the file names none).
    pub units: Vec<String>,
    /// Samples per second.
    pub rate: f64,
    /// Samples per point frame.
    pub samples_per_frame: usize,
    /// Sample-major: sample `s` (of `frames × samples_per_frame`), channel `c` at
    /// `s · channels + c`.
    pub values: Vec<f64>,
}

impl Analog {
    /// Number of channels.
    pub fn channels(&self) -> usize {
        self.labels.len()
    }
}

/// A rigid body as the capture software solved it (Motive): the pose of its pivot.
#[derive(Debug, Clone, PartialEq)]
pub struct RigidBodyTrack {
    /// Its name in the take.
    pub name: String,
    /// Position per frame, file units (NaN where untracked).
    pub position: Vec<[f64; 3]>,
    /// Orientation per frame as `[qx, qy, qz, qw]` (NaN where untracked).
    pub quaternion: Vec<[f64; 4]>,
}

/// A take: `frames` frames at `rate` Hz of `labels.len()` markers.
#[derive(Debug, Clone, PartialEq)]
pub struct Take {
    /// The file it was read from.
    pub file: String,
    /// Where it came from.
    pub source: Source,
    /// Marker labels, in the file's order.
    pub labels: Vec<String>,
    /// Frames per second.
    pub rate: f64,
    /// The number of the first frame in the capture (1 in most C3D files).
    pub first_frame: u64,
    /// The number of frames.
    pub frames: usize,
    /// The length unit as the file names it (`mm`, `m`, `Millimeters`…).
    pub units: String,
    /// Metres per file unit.
    pub metres_per_unit: f64,
    /// Frame-major marker positions in file units: marker `m` of frame `f` at
    /// `f · markers + m`. Missing samples are NaN.
    pub xyz: Vec<[f32; 3]>,
    /// The residual of each sample (file units; C3D's, or Motive's marker error); negative
    /// where the marker is missing.
    pub residual: Vec<f32>,
    /// Analog channels, if the file has any.
    pub analog: Option<Analog>,
    /// Rigid bodies solved by the capture software (Motive CSV).
    pub rigid_bodies: Vec<RigidBodyTrack>,
    /// What the reader noticed and worked around, in words (e.g. a frame count taken
    /// from the file's length).
    pub notes: Vec<String>,
}

impl Take {
    /// Number of markers.
    pub fn markers(&self) -> usize {
        self.labels.len()
    }

    /// The take's duration: from the first frame to the last, seconds.
    pub fn duration(&self) -> f64 {
        self.frames.saturating_sub(1) as f64 / self.rate
    }

    /// Whether marker `m` is seen at frame `f`.
    pub fn seen(&self, f: usize, m: usize) -> bool {
        let i = f * self.markers() + m;
        self.residual[i] >= 0.0 && self.xyz[i].iter().all(|v| v.is_finite())
    }

    /// Marker `m`'s position at frame `f` in file units (NaN where missing).
    pub fn point(&self, f: usize, m: usize) -> [f32; 3] {
        self.xyz[f * self.markers() + m]
    }

    /// The runs of frames where marker `m` is missing.
    pub fn gaps(&self, m: usize) -> Vec<Range<usize>> {
        runs((0..self.frames).map(|f| !self.seen(f, m)))
    }

    /// The index of a label: exact, or the part after a `Subject:` prefix when that is
    /// unique.
    pub fn find_label(&self, label: &str) -> Option<usize> {
        if let Some(i) = self.labels.iter().position(|l| l == label) {
            return Some(i);
        }
        let short: Vec<usize> = (0..self.labels.len())
            .filter(|&i| {
                self.labels[i]
                    .rsplit_once(':')
                    .is_some_and(|(_, s)| s == label)
            })
            .collect();
        (short.len() == 1).then(|| short[0])
    }
}

/// The runs of `true` in a sequence, as index ranges.
pub fn runs(flags: impl Iterator<Item = bool>) -> Vec<Range<usize>> {
    let mut out = Vec::new();
    let mut start = None;
    let mut n = 0;
    for (i, f) in flags.enumerate() {
        match (f, start) {
            (true, None) => start = Some(i),
            (false, Some(s)) => {
                out.push(s..i);
                start = None;
            }
            _ => {}
        }
        n = i + 1;
    }
    if let Some(s) = start {
        out.push(s..n);
    }
    out
}

/// Metres per unit for a length unit as C3D and Motive write them.
pub fn metres_per_unit(unit: &str) -> Option<f64> {
    match unit.trim().to_ascii_lowercase().as_str() {
        "m" | "meters" | "metres" | "meter" | "metre" => Some(1.0),
        "cm" | "centimeters" | "centimetres" => Some(0.01),
        "mm" | "millimeters" | "millimetres" => Some(0.001),
        _ => None,
    }
}

/// At most this many bytes of a take are read (a take of 40 markers at 240 Hz for an
/// hour, in floats, is 2.2 GB).
pub const MAX_FILE_BYTES: u64 = 4 << 30;

/// A take's bytes, refused above [`MAX_FILE_BYTES`]; the file's name for messages.
pub(crate) fn read_file(path: &std::path::Path) -> Result<(Vec<u8>, String), crate::MocapError> {
    let name = path.display().to_string();
    let bytes = cps_files::read::read_bytes(path, MAX_FILE_BYTES, "take").map_err(|e| {
        crate::MocapError::Io {
            file: name.clone(),
            message: e.reason(),
        }
    })?;
    Ok((bytes, name))
}
